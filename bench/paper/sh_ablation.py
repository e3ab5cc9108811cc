#!/usr/bin/env python3
"""SH-band ablation (Zheng, Singh, Seidel, NeurIPS 2021: appendix E, Fig. 1, and main paper Fig. 9): the "Ours"
model without indirect light and with SH bands l_max = 1, 3, 5, 7, 9, trained on the same 'point' cloud dataset
for the same steps, tested on novel views under novel lights.

Every setting trains and renders with the shadow marched through the density grid and passes the render loss's
gradient on through it (docs/baselines.md, "Training stability"), at one learning rate: with the visibility network
isolated from the render loss (the paper's appendix C, Ours' preset on media), a model whose indirect light cannot
make the cloud as bright as its images (w/o SH, SH-1) runs away on this medium. --shadow network trains the
settings as Ours' preset does.

    python bench/paper/sh_ablation.py --scale laptop --out results/sh_ablation
"""
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import common  # noqa: E402

SETTINGS = [("w/o SH", "none"), ("SH-1", "1"), ("SH-3", "3"), ("SH-5", "5"), ("SH-7", "7"), ("SH-9", "9")]


def main():
    p = common.parser(__doc__.splitlines()[0], "results/sh_ablation")
    p.add_argument("--shadow", choices=["march", "network"], default="march",
                   help="march: every setting trains and renders with the marched shadow and its gradient (default); "
                        "network: with the visibility network, isolated from the render loss (Ours' preset)")
    p.add_argument("--lr", type=float, default=None,
                   help="every setting's learning rate (default: 3e-3 with the march, the preset's with the network)")
    args = p.parse_args()
    if args.lr is not None and not (args.lr > 0 and args.lr < float("inf")):
        p.error("--lr must be a positive finite number, not %r" % args.lr)
    r = common.Relit(args.out, args.scale, args.seed, args.device, args.steps)
    data = r.dataset("cloud-point", scene="cloud", lighting="point")
    model, training = {}, {}
    if args.shadow == "march":
        model = {**common.MARCHED_SHADOW, "inference_visibility": "march"}
    lr = args.lr if args.lr is not None else (3e-3 if args.shadow == "march" else None)
    if lr is not None:
        training = common.learning_rate(lr)
    rows = []
    results = {"experiment": "sh_ablation", "dataset": data, "shadow": args.shadow, "lr": lr, "runs": {}}
    for label, sh in SETTINGS:
        # The run's name says how it trained, so that a rerun with other settings never reuses it.
        name = "sh-%s-%s" % (sh, args.shadow) + ("" if lr is None else "-lr%g" % lr)
        run = r.train(name, data, r.config(model=common.merge(model, {"renderer": {"sh": sh}}),
                                                  training=training))
        m = r.evaluate(run, splits=["test"])
        psnr, ssim = common.split_means(m, "test")
        obj = common.object_means(m, "test")
        results["runs"][label] = {"sh": sh, "run": run, "psnr": psnr, "ssim": ssim, "object": obj,
                                  "convergence": common.convergence(run)}
        conv = results["runs"][label]["convergence"]
        rows.append([label, psnr, ssim, obj["psnr"], obj["ssim"], obj["flip"],
                     None if conv["ratio"] is None else "%.2f%s" % (conv["ratio"], " (rises)" if conv["rising"] else "")])
    xs = list(range(len(SETTINGS)))
    common.plot(os.path.join(args.out, "sh_ablation.png"), "SH band ablation (test views, novel lights)",
                "indirect light", {"PSNR": (xs, [v["psnr"] for v in results["runs"].values()])},
                xticks=[s[0] for s in SETTINGS])
    best = max(results["runs"], key=lambda k: results["runs"][k]["psnr"])
    sh5 = results["runs"]["SH-5"]["psnr"]
    results["checks"] = {"SH-5 >= SH-1": sh5 >= results["runs"]["SH-1"]["psnr"],
                         "SH-5 >= w/o SH": sh5 >= results["runs"]["w/o SH"]["psnr"]}
    r.write_results("SH-band ablation", results,
                    [["Shadow of the training renders: %s%s." % (
                        "marched through the density grid, with its gradient" if args.shadow == "march"
                        else "the visibility network, isolated from the render loss",
                        "" if lr is None else "; learning rate %g" % lr)],
                     common.markdown_table(["setting", "PSNR [dB]", "SSIM", "object PSNR [dB]", "object SSIM",
                                           "object FLIP", "loss end / step 200"], rows),
                     ["Best: %s. Orderings of the paper: %s." % (
                         best, ", ".join("%s %s" % (k, "holds" if v else "does not hold")
                                         for k, v in results["checks"].items())),
                      "", "![PSNR per setting](sh_ablation.png)"]])


if __name__ == "__main__":
    main()
