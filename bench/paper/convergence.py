#!/usr/bin/env python3
"""Convergence against each model's floor (docs/results.md, "Convergence"): every media method trained on a medium
as the method comparison renders it (every bounce) and on the same medium rendered with single scattering only,
light that all three models can render (Bi et al.: single scattering with marched shadows; NeRV: direct light and
one bounce; Ours: direct light and the SH head). Beside each run: the loss around step 200 and over the last 10 % of
the steps, their ratio (the comparison's target: at most half, so that a run that stalls or rises shows), and the
same ratio above the training references' own Monte-Carlo noise, which no model can fit. A loss that stalls on the
multiply scattered data but falls on the singly scattered one has reached what its model can render; it did not run
away.

    python bench/paper/convergence.py --scale laptop128 --out results/convergence
    python bench/paper/convergence.py --scale laptop128 --datasets cloud-point thin-point --methods bi \\
        --rates bi=3e-3 --out results/convergence
"""
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import common  # noqa: E402
import comparison  # noqa: E402

# The rates the comparison's sweep chose at laptop128 (docs/results.md, "Media at 128x128").
RATES = {"bi": 3e-3, "nerv": 1e-2, "ours": 3e-3}
# Views of the noise estimate: each path-traced twice more with seeds no dataset view uses.
NOISE_VIEWS = {"ci": 2}
NOISE_SEED = 0x6e6f6973


def parse_args():
    methods = [m for _, m in comparison.MEDIA_METHODS]
    media = [comparison.dataset_name(*p) for p in comparison.MEDIA]
    p = common.parser(__doc__.splitlines()[0], "results/convergence", "laptop128")
    p.add_argument("--datasets", nargs="+", default=["cloud-point"], choices=media, metavar="NAME",
                   help="media of the comparison (%s; default: cloud-point)" % " ".join(media))
    p.add_argument("--methods", nargs="+", default=methods, choices=methods, metavar="METHOD",
                   help="methods (default: %s)" % " ".join(methods))
    p.add_argument("--rates", nargs="+", type=comparison.rate, default=[], metavar="METHOD=LR",
                   help="learning rates (default: those the comparison's sweep chose, %s)" % " ".join(
                       "%s=%g" % kv for kv in RATES.items()))
    comparison.add_ours_shadow(p)
    p.add_argument("--noise-views", type=int, default=None,
                   help="training views path-traced again for the references' noise (default: 10, 2 at ci)")
    args = p.parse_args()
    args.rates = {**RATES, **dict(args.rates)}
    unknown = sorted(set(args.rates) - set(methods))
    if unknown:
        p.error("--rates: unknown method(s) " + ", ".join(unknown))
    if args.noise_views is None:
        args.noise_views = NOISE_VIEWS.get(args.scale, 10)
    if args.noise_views < 1:
        p.error("--noise-views must be at least 1")
    return args


def reference_noise(path, views, max_bounces, device=None):
    """The training references' Monte-Carlo noise in the render loss's space (SrgbL2: the sRGB curve, unclamped
    above 1): the first `views` training views path-traced twice more at the split's samples per pixel with seeds
    no dataset view uses, half the mean squared difference of the two renders' RGB (the expected loss of the
    noise-free image against one reference, over uniformly drawn pixels, as the training batches draw them)."""
    import numpy as np
    import relit
    meta = common.read_json(os.path.join(path, "transforms_train.json"))
    scene = relit.Scene.from_json(common.read_json(os.path.join(path, meta["scene"])), path)
    dev = relit.Device(device) if device else None

    def srgb(x):
        a = np.abs(x)
        return np.sign(x) * np.where(a <= 0.0031308, 12.92 * a, 1.055 * np.power(np.maximum(a, 0.0031308),
                                                                                  1 / 2.4) - 0.055)

    total = 0.0
    frames = meta["frames"][:views]
    for i, f in enumerate(frames):
        cam = relit.Camera.look_at([0.0, 0.0, 4.0], camera_angle_x=meta["camera_angle_x"], width=meta["w"],
                                   height=meta["h"])
        cam.transform = f["transform_matrix"]
        light = relit.PointLight(f["light"]["position"], f["light"]["intensity"])
        a, b = (srgb(relit.render_reference(scene, cam, [light], spp=meta["spp"], seed=NOISE_SEED + 2 * i + k,
                                            max_bounces=max_bounces or 0, device=dev)[..., :3].astype(np.float64))
                for k in (0, 1))
        total += float(np.mean((a - b) ** 2)) / 2.0
    return total / len(frames)


def above(conv, floor):
    """The convergence ratio of the loss above the noise floor, or None when step 200's loss is not above it."""
    if conv["ratio"] is None or conv["early"] <= floor:
        return None
    return max(conv["last"] - floor, 0.0) / (conv["early"] - floor)


def plot_losses(path, title, curves, floors, window=10):
    """The logged losses of every run (running means of `window` of them, log scale), every bounce solid, single
    scattering dashed, and each dataset's noise floor dash-dotted or dotted."""
    lines = []
    for (method, kind), losses in curves.items():
        values = [v for _, v in losses]
        smooth = [sum(values[max(0, i - window + 1):i + 1]) / (i + 1 - max(0, i - window + 1))
                  for i in range(len(values))]
        lines.append(("%s, %s" % (method, kind), [s for s, _ in losses], smooth,
                      {"linestyle": "-" if kind == "every bounce" else "--", "color": common.METHOD_COLORS[method]}))
    for kind, floor in floors.items():
        lines.append(("references' noise, %s" % kind, None, floor,
                      {"linestyle": "-." if kind == "every bounce" else ":", "color": "grey"}))
    common.plot_lines(path, title, "step", "render loss (sRGB L2, mean of %d logs)" % window, lines, logy=True)


def main():
    args = parse_args()
    r = common.Relit(args.out, args.scale, args.seed, args.device, args.steps)
    labels = dict((m, label) for label, m in comparison.MEDIA_METHODS)
    kinds = (("every bounce", None), ("single scattering", 1))
    model, tags = comparison.media_protocol(args.ours_shadow)
    results = {"experiment": "convergence", "rates": {m: args.rates[m] for m in args.methods},
               "ours_shadow": args.ours_shadow, "datasets": {}}
    tables, checks = [], {}
    for name in args.datasets:
        scene, lighting = next(p for p in comparison.MEDIA if comparison.dataset_name(*p) == name)
        scene = comparison.THIN if scene == "thin" else scene
        rows, curves, floors = [], {}, {}
        for kind, bounces in kinds:
            data_name = name if bounces is None else "%s-single" % name
            path = r.dataset(data_name, scene=scene, lighting=lighting, max_bounces=bounces)
            floor = floors[kind] = reference_noise(path, args.noise_views, bounces, args.device)
            entry = results["datasets"].setdefault(name, {}).setdefault(kind, {"data": path, "noise": floor,
                                                                                "runs": {}})
            for method in args.methods:
                lr = args.rates[method]
                run = r.train("%s-%s%s-lr%g" % (data_name, method, (tags or {}).get(method, ""), lr), path,
                              comparison.with_lr(r, method, lr, model))
                m = r.evaluate(run, splits=["test"])
                psnr, _ = common.split_means(m, "test")
                conv = common.convergence(run)
                ratio_above = above(conv, floor)
                curves[(labels[method], kind)] = common.logged_losses(run)
                entry["runs"][method] = {"run": run, "lr": lr, "psnr": psnr,
                                         "object_psnr": common.object_means(m, "test")["psnr"],
                                         "convergence": conv, "ratio_above_noise": ratio_above,
                                         "minutes": round((common.training_seconds(run) or 0.0) / 60.0, 2)}
                rows.append([labels[method], kind, "%g" % lr, psnr, entry["runs"][method]["object_psnr"],
                             common.fmt_sci(conv["early"]), common.fmt_sci(conv["last"]),
                             "–" if conv["ratio"] is None else "%.2f%s" % (
                                 conv["ratio"], comparison.convergence_mark(conv)),
                             common.fmt_sci(floor), "–" if ratio_above is None else "%.2f" % ratio_above])
        for method in args.methods:
            runs = {kind: results["datasets"][name][kind]["runs"][method] for kind, _ in kinds}
            checks["%s, %s: the loss never rises" % (name, method)] = all(
                v["convergence"]["rising"] is not True for v in runs.values())
            checks["%s, %s: single scattering, loss end at most half of step 200's" % (name, method)] = (
                runs["single scattering"]["convergence"]["converged"] is not False)
        figure = "%s_losses.png" % name
        plot_losses(os.path.join(args.out, figure), "%s: training loss" % name, curves, floors)
        tables.append(["## " + name, ""] + common.markdown_table(
            ["method", "data", "lr", "PSNR", "object PSNR", "loss @200", "loss end", "end / @200",
             "references' noise", "end / @200 above the noise"], rows) + ["", "![losses](%s)" % figure, ""])
    results["checks"] = checks
    notes = ["The loss around step 200 is the mean of the logged losses in steps 150-250, the loss at the end the "
             "mean over the last 10 %% of the steps; the references' noise is the loss a noise-free image would "
             "score against the training references (%d training views path-traced twice more)." % args.noise_views,
             "", "Checks: " + ", ".join("%s %s" % (k, "holds" if v else "does not hold") for k, v in checks.items())
             + "."]
    r.write_results("Convergence against the models' floors", results, tables + [notes])


if __name__ == "__main__":
    main()
