#!/usr/bin/env python3
"""SH-band ablation (Zheng, Singh, Seidel, NeurIPS 2021: appendix E, Fig. 1, and main paper Fig. 9): the "Ours"
model without indirect light and with SH bands l_max = 1, 3, 5, 7, 9, trained on the same 'point' cloud dataset
for the same steps, tested on novel views under novel lights.

    python bench/paper/sh_ablation.py --scale laptop --out results/sh_ablation
"""
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import common  # noqa: E402

SETTINGS = [("w/o SH", "none"), ("SH-1", "1"), ("SH-3", "3"), ("SH-5", "5"), ("SH-7", "7"), ("SH-9", "9")]


def main():
    args = common.parse_args(__doc__.splitlines()[0], "results/sh_ablation")
    r = common.Relit(args.out, args.scale, args.seed, args.device, args.steps)
    data = r.dataset("cloud-point", scene="cloud", lighting="point")
    rows, results = [], {"experiment": "sh_ablation", "dataset": data, "runs": {}}
    for label, sh in SETTINGS:
        run = r.train("sh-" + sh, data, r.config(model={"renderer": {"sh": sh}}))
        m = r.evaluate(run, splits=["test"])
        psnr, ssim = common.split_means(m, "test")
        obj = common.object_means(m, "test")
        results["runs"][label] = {"sh": sh, "run": run, "psnr": psnr, "ssim": ssim, "object": obj,
                                  "convergence": common.convergence(run)}
        rows.append([label, psnr, ssim, obj["psnr"], obj["ssim"], obj["flip"]])
    xs = list(range(len(SETTINGS)))
    common.plot(os.path.join(args.out, "sh_ablation.png"), "SH band ablation (test views, novel lights)",
                "indirect light", {"PSNR": (xs, [v["psnr"] for v in results["runs"].values()])},
                xticks=[s[0] for s in SETTINGS])
    best = max(results["runs"], key=lambda k: results["runs"][k]["psnr"])
    sh5 = results["runs"]["SH-5"]["psnr"]
    results["checks"] = {"SH-5 >= SH-1": sh5 >= results["runs"]["SH-1"]["psnr"],
                         "SH-5 >= w/o SH": sh5 >= results["runs"]["w/o SH"]["psnr"]}
    r.write_results("SH-band ablation", results,
                    [common.markdown_table(["setting", "PSNR [dB]", "SSIM", "object PSNR [dB]", "object SSIM",
                                           "object FLIP"], rows),
                     ["Best: %s. Orderings of the paper: %s." % (
                         best, ", ".join("%s %s" % (k, "holds" if v else "does not hold")
                                         for k, v in results["checks"].items())),
                      "", "![PSNR per setting](sh_ablation.png)"]])


if __name__ == "__main__":
    main()
