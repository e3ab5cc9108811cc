#!/usr/bin/env python3
"""Method comparison (Zheng, Singh, Seidel, NeurIPS 2021: Tables 1-3, appendices D, F, G): Bi et al. vs NeRV vs Ours
on participating media under 'point' and 'env + point' training light, and Bi et al. vs NeRV vs Ours + BRDF vs
Ours on glossy solids; every method trained on the same dataset for the same steps and rays per step, with its
learning rate chosen by the same sweep on the validation split, and tested on novel views under novel point
lights with both protocols (the whole image, and the object's pixels; docs/evaluation.md).

    python bench/paper/comparison.py --scale laptop128 --out results/comparison        # docs/results.md
    python bench/paper/comparison.py --scale laptop --part media --scenes cloud thin
    python bench/paper/comparison.py --scale laptop --lr-sweep 0.01                   # no sweep: one rate
    python bench/paper/comparison.py --scale laptop128 --part media --datasets smoke-point --methods nerv \
        --rates bi=3e-3 nerv=1e-2 ours=3e-3                                           # an earlier sweep's rates

Runs are deterministic (counter-based randomness, fixed-order reductions), so a table can be completed over several
invocations: --datasets and --methods pick its cells, --rates gives the rates an earlier sweep chose.
"""
import argparse
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import common  # noqa: E402

MEDIA_METHODS = [("Bi et al.", "bi"), ("NeRV", "nerv"), ("Ours", "ours")]
SOLID_METHODS = [("Bi et al.", "bi"), ("NeRV", "nerv"), ("Ours + BRDF", "ours_brdf"), ("Ours", "ours")]
MEDIA = [("cloud", "point"), ("cloud", "env+point"), ("smoke", "point"), ("smoke", "env+point"), ("thin", "point")]
SOLIDS = [("spheres", "point"), ("torus", "point")]
# The media share one learning-rate sweep (on their first dataset); each solid has its own, since the rate is the
# surface's: Ours on the 128x128 torus grows a haze at 1e-2 and scores 26.0 dB at 3e-3, the spheres 27.6 at 1e-2
# (docs/results.md, "Solids at 128x128").
# On solids Ours shades its training renders with the density grid's march toward the light and passes the render
# loss's gradient through that shadow, as the presets of the baselines and of Ours + BRDF do on every scene: the
# surface's self-shadow is sharp, the visibility network trails it, and the property network learns to make up for
# its errors per training light instead of the shading. Its SH head sees that V (a phase function has no normal,
# so the head paints the terminator), and it renders with the march its head was trained on, as Ours + BRDF's
# presets do (docs/results.md, "Solids at 128x128").
SOLID_MODEL = {"ours": {**common.MARCHED_SHADOW, "inference_visibility": "march",
                        "indirect": {"visibility_input": True}}}
# On media Ours trains the same way by default (--ours-shadow network gives its preset's isolated visibility
# network): every method then shades its training renders with the same march, and on the five 128x128 media that
# scores 0.1-0.5 dB above the isolated network (docs/results.md, "Media at 128x128"), as in the SH ablation; on
# single-scattering data the isolated network leaves a haze its shadow does not see ("Convergence against the
# models' floors").
MEDIA_MODEL = {"ours": {**common.MARCHED_SHADOW, "inference_visibility": "march"}}
# A thin medium of the paper's kind (its Bunny and Buddha clouds): the smoke's fine structure at a quarter of
# the cloud's density scale, so that single scattering carries much of the image.
THIN = {"medium": {"source": {"type": "smoke", "resolution": 64, "seed": 3}, "density_scale": 5.0,
                   "albedo": [0.95, 0.95, 0.95], "g": 0.3}}
# The `ci` scale checks the script end to end on one scene of each part.
CI_SCENES = {"cloud", "spheres"}
# The paper's numbers (PSNR [dB], its Tables 1-3 on its media and solids), printed beside ours.
PAPER = {"media": {"bi": (22.5, 24.2), "nerv": (24.6, 27.4)},
         "gaps": {"ours - nerv": (5.4, 8.9), "ours - bi": (8.5, 11.0)},
         "solids": {"ours": (26.5, 28.5)}}


def parse_args():
    p = common.parser(__doc__.splitlines()[0], "results/comparison")
    p.add_argument("--part", choices=["media", "solids", "all"], default="all")
    p.add_argument("--scenes", nargs="+", default=None,
                   help="only these scenes (cloud smoke thin spheres torus; default: all, or cloud and spheres at ci)")
    p.add_argument("--lr-sweep", nargs="+", type=float, default=[3e-3, 1e-2, 3e-2], metavar="LR",
                   help="learning rates each method is tried with on the media's first dataset and on every solid "
                        "(one value: no sweep); the best on the validation split trains the part's datasets, or the "
                        "solid")
    p.add_argument("--datasets", nargs="+", default=None, metavar="NAME",
                   help="only these datasets (<scene>-<lighting> without '+': cloud-point cloud-envpoint ...; run in the "
                        "table's order)")
    p.add_argument("--methods", nargs="+", default=None, metavar="METHOD",
                   help="only these methods (bi nerv ours ours_brdf; default: all of the part's)")
    p.add_argument("--rates", nargs="+", type=rate, default=None, metavar="METHOD=LR",
                   help="the learning rate of each method, as an earlier sweep chose it: no sweep (every method run "
                        "needs one)")
    add_ours_shadow(p)
    p.add_argument("--sweep-steps", type=int, default=None,
                   help="training steps of a sweep run (default: a third of the steps, at least 30)")
    return p.parse_args()


def add_ours_shadow(p):
    """The --ours-shadow option of the scripts that train Ours on media."""
    p.add_argument("--ours-shadow", choices=["march", "network"], default="march",
                   help="Ours' training shadow on media: the density grid's march with its gradient, as every "
                        "method's (default), or its preset's visibility network, isolated from the render loss")


def media_protocol(ours_shadow):
    """(model overrides, run-name tags) of the media methods for --ours-shadow: the marched runs are named
    '<dataset>-ours-march-lr<lr>', so that a folder of runs trained with the network is not resumed as theirs."""
    if ours_shadow == "march":
        return MEDIA_MODEL, {"ours": "-march"}
    return None, None


def rate(text):
    """'METHOD=LR' of --rates as (method, lr)."""
    method, sep, lr = text.partition("=")
    try:
        value = float(lr)
        if not sep or not method or not 0 < value < float("inf"):
            raise ValueError(text)
        return method, value
    except ValueError:
        raise argparse.ArgumentTypeError("expected METHOD=LR with a positive finite LR (e.g. ours=3e-3), got %r" % text)


def dataset_name(scene, lighting):
    """The name of a (scene, lighting) pair: its data, runs and table, e.g. 'cloud-envpoint'."""
    return "%s-%s" % (scene, lighting.replace("+", ""))


def with_lr(r, method, lr, model=None):
    """The method's config at this scale with learning rate `lr` for both optimisers (render and visibility) and
    the part's `model` overrides ({method: model config})."""
    return r.config(method=method, model=(model or {}).get(method), training=common.learning_rate(lr))


def sweep(r, args, dataset, name, methods, results, model=None, tags=None):
    """{method: learning rate}: each method trained args.sweep_steps steps at every rate of args.lr_sweep on
    `dataset`, scored by the validation split's PSNR (the paper's protocol)."""
    chosen = {}
    for _, method in methods:
        if args.rates is not None:
            chosen[method] = args.rates[method]
            results[method] = {"chosen": chosen[method], "given": True}
            continue
        if len(args.lr_sweep) == 1:
            chosen[method] = args.lr_sweep[0]
            continue
        scores = {}
        for lr in args.lr_sweep:
            cfg = with_lr(r, method, lr, model)
            cfg["training"]["steps"] = args.sweep_steps
            run = r.train("sweep-%s-%s%s-lr%g" % (name, method, (tags or {}).get(method, ""), lr), dataset, cfg)
            scores[lr] = common.split_means(r.evaluate(run, splits=["val"]), "val")[0]
        chosen[method] = max(scores, key=lambda lr: scores[lr])
        results[method] = {"steps": args.sweep_steps, "val_psnr": {"%g" % k: v for k, v in scores.items()},
                           "chosen": chosen[method]}
    return chosen


def compare(r, args, datasets, methods, results, sweeps, title, model=None, sweep_each=False, tags=None):
    """Sweeps the learning rates (on the first dataset, or with `sweep_each` on every one; sweeps[dataset][method]),
    trains and evaluates every method on every dataset (with the `model` overrides of SOLID_MODEL's form; `tags`
    {method: suffix} names the runs those overrides change, so that a folder of runs of another protocol is not
    resumed); Markdown tables."""
    data = {}
    for scene, lighting in datasets:
        name = dataset_name(scene, lighting)
        data[name] = r.dataset(name, scene=THIN if scene == "thin" else scene, lighting=lighting)
    lines = ["## " + title, ""]
    header = ["method", "lr", "PSNR", "SSIM", "object PSNR", "object SSIM", "object relMSE", "object FLIP", "min",
              "loss end / step 200"]
    lrs = None
    for name, path in data.items():
        if lrs is None or sweep_each:
            lrs = sweep(r, args, path, name, methods, sweeps.setdefault(name, {}), model, tags)
        rows = []
        for label, method in methods:
            run = r.train("%s-%s%s-lr%g" % (name, method, (tags or {}).get(method, ""), lrs[method]), path,
                          with_lr(r, method, lrs[method], model))
            m = r.evaluate(run, splits=["test"])
            psnr, ssim = common.split_means(m, "test")
            obj = common.object_means(m, "test")
            conv = common.convergence(run)
            minutes = (common.training_seconds(run) or 0.0) / 60.0
            results.setdefault(name, {})[method] = {"run": run, "lr": lrs[method], "psnr": psnr, "ssim": ssim,
                                                    "object": obj, "minutes": round(minutes, 2),
                                                    "convergence": conv}
            ratio = conv["ratio"]
            rows.append([label, "%g" % lrs[method], psnr, ssim, obj["psnr"], obj["ssim"],
                         None if obj["rel_mse"] is None else "%.3g" % obj["rel_mse"], obj["flip"], "%.1f" % minutes,
                         "–" if ratio is None else "%.2f%s" % (ratio, convergence_mark(conv))])
        clipped = results[name][methods[-1][1]]["object"]["clipped"]
        lines += ["### " + name + ("" if clipped is None else " (%.1f %% of the object's pixels clip)" % (100 * clipped)),
                  ""] + common.markdown_table(header, rows) + [""]
    return lines


def convergence_mark(conv):
    """The table's note on a run's loss: nothing when it halved after step 200, else whether it still fell."""
    return "" if conv["converged"] else " (runaway)" if conv["rising"] else " (fell less than half)"


def orderings(results, order):
    """{"<dataset>: A > B > C": bool} for the PSNR ordering `order` (method names, best first)."""
    checks = {}
    for name, runs in results.items():
        if all(m in runs for m in order):
            psnr = [runs[m]["psnr"] for m in order]
            checks["%s: %s" % (name, " > ".join(order))] = all(a > b for a, b in zip(psnr, psnr[1:]))
    return checks


def gaps(results):
    """Ours' lead over NeRV and Bi et al. per media dataset beside the paper's range; lines of Markdown."""
    rows, out = [], {}
    for name, runs in results.items():
        if not all(m in runs for m in ("ours", "nerv", "bi")):
            continue
        g = {"ours - nerv": runs["ours"]["psnr"] - runs["nerv"]["psnr"],
             "ours - bi": runs["ours"]["psnr"] - runs["bi"]["psnr"]}
        out[name] = g
        row = [name]
        for k, (lo, hi) in PAPER["gaps"].items():
            off = 0.0 if lo <= g[k] <= hi else min(abs(g[k] - lo), abs(g[k] - hi))
            row.append("%+.2f (paper %.1f-%.1f%s)" % (g[k], lo, hi, "" if off <= 3 else "; %.1f dB outside" % off))
        rows.append(row)
    lines = []
    if rows:
        lines = ["### Ours' lead over the baselines (PSNR [dB], the paper's range beside)", ""] + common.markdown_table(
            ["dataset", "Ours - NeRV", "Ours - Bi et al."], rows) + [""]
    return out, lines


def main():
    args = parse_args()
    scenes = set(args.scenes) if args.scenes else (CI_SCENES if args.scale == "ci" else None)
    pick = lambda pairs: [p for p in pairs if (scenes is None or p[0] in scenes)  # noqa: E731
                          and (args.datasets is None or dataset_name(*p) in args.datasets)]
    only = lambda methods: [m for m in methods if args.methods is None or m[1] in args.methods]  # noqa: E731
    if args.rates is not None:
        args.rates = dict(args.rates)
        parts = {"media": MEDIA_METHODS, "solids": SOLID_METHODS}
        needed = {m for part, methods in parts.items() if args.part in (part, "all") for _, m in only(methods)}
        missing = sorted(needed - set(args.rates))
        if missing:
            sys.exit("comparison: --rates gives no learning rate for " + ", ".join(missing))
    for kind, given, known in (("dataset", args.datasets, {dataset_name(*p) for p in MEDIA + SOLIDS}),
                               ("method", args.methods, {m for _, m in MEDIA_METHODS + SOLID_METHODS})):
        if given is not None and set(given) - known:
            sys.exit("comparison: unknown %s(s) %s (known: %s)" % (kind, ", ".join(sorted(set(given) - known)),
                                                                   ", ".join(sorted(known))))
    media = (pick(MEDIA), only(MEDIA_METHODS)) if args.part in ("media", "all") else ([], [])
    solids = (pick(SOLIDS), only(SOLID_METHODS)) if args.part in ("solids", "all") else ([], [])
    if not all(media) and not all(solids):
        sys.exit("comparison: --part, --scenes, --datasets and --methods select no run")
    r = common.Relit(args.out, args.scale, args.seed, args.device, args.steps)
    if args.sweep_steps is None:
        args.sweep_steps = max(30, r.steps // 3)
    results = {"experiment": "comparison", "media": {}, "solids": {}, "lr_sweep": {"media": {}, "solids": {}},
               "paper": PAPER, "learning_rates": args.lr_sweep}
    tables, checks = [], {}
    if all(media):
        model, tags = media_protocol(args.ours_shadow)
        results["ours_shadow_on_media"] = args.ours_shadow
        tables.append(compare(r, args, *media, results["media"], results["lr_sweep"]["media"], "Participating media",
                              model, tags=tags))
        checks.update(orderings(results["media"], ["ours", "nerv", "bi"]))
        results["gaps"], lines = gaps(results["media"])
        tables.append(lines)
    if all(solids):
        tables.append(compare(r, args, *solids, results["solids"],
                              results["lr_sweep"]["solids"], "Glossy solids", SOLID_MODEL, sweep_each=True))
        checks.update(orderings(results["solids"], ["ours", "nerv", "bi"]))
    runs = [v for part in ("media", "solids") for d in results[part].values() for v in d.values()]
    checks["no run runs away (loss over the last 10 % at most half of step 200's)"] = all(
        v["convergence"]["converged"] is not False for v in runs)
    checks["no run's loss rises (loss over the last 10 % below step 200's)"] = all(
        v["convergence"]["rising"] is not True for v in runs)
    results["checks"] = checks
    sweep_lines = []
    for part, by_dataset in results["lr_sweep"].items():
        for name, sw in by_dataset.items():
            for method, v in sw.items():
                scores = ", ".join("%s: %.2f" % kv for kv in v.get("val_psnr", {}).items()) or "given (--rates)"
                sweep_lines.append([part, method, name, v.get("steps", "–"), scores, "%g" % v["chosen"]])
    if sweep_lines:
        tables.append(["## Learning rates (validation PSNR [dB] of the sweep)", ""] + common.markdown_table(
            ["part", "method", "dataset", "steps", "val PSNR per rate", "chosen"], sweep_lines))
    series = {}
    for part in ("media", "solids"):
        for name, by_method in results[part].items():
            for method, v in by_method.items():
                series.setdefault(method, ([], []))
                series[method][0].append(len(series[method][0]))
                series[method][1].append(v["psnr"])
    names = [n for part in ("media", "solids") for n in results[part]]
    if names:
        common.plot(os.path.join(args.out, "comparison.png"), "Methods (test views, novel lights)", "dataset", series,
                    xticks=names)
    notes = ["PSNR and SSIM over the whole image (the paper's protocol) and over the object's pixels "
             "(docs/evaluation.md); the paper reports Bi et al. 22.5-24.2 dB and NeRV 24.6-27.4 dB on its media, "
             "Ours 26.5-28.5 dB on its solids.", "",
             "On media Ours trains with " + ("the shadow marched through the density grid and its gradient, as "
                                             "every method does" if args.ours_shadow == "march" else
                                             "its preset's visibility network, isolated from the render loss") +
             "; on solids with the march.", "",
             "Checks: " + (", ".join("%s %s" % (k, "holds" if v else "does not hold")
                                      for k, v in checks.items()) or "none") + ".",
             "", "![PSNR per dataset and method](comparison.png)"]
    r.write_results("Method comparison", results, tables + [notes])


if __name__ == "__main__":
    main()
