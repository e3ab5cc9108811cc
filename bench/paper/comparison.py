#!/usr/bin/env python3
"""Method comparison (Zheng, Singh, Seidel, NeurIPS 2021: Tables 1-3, appendices D, F, G): Bi et al. vs NeRV vs Ours
on participating media under 'point' and 'env + point' training light, and Bi et al. vs NeRV vs Ours + BRDF vs
Ours on glossy solids; every method trained on the same dataset for the same steps and tested on novel views
under novel point lights.

    python bench/paper/comparison.py --scale laptop --out results/comparison
    python bench/paper/comparison.py --scale laptop --part media --scenes cloud
"""
import argparse
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import common  # noqa: E402

MEDIA_METHODS = [("Bi et al.", "bi"), ("NeRV", "nerv"), ("Ours", "ours")]
SOLID_METHODS = [("Bi et al.", "bi"), ("NeRV", "nerv"), ("Ours + BRDF", "ours_brdf"), ("Ours", "ours")]
MEDIA = [("cloud", "point"), ("cloud", "env+point"), ("smoke", "point"), ("smoke", "env+point")]
SOLIDS = [("spheres", "point"), ("torus", "point")]
# The `ci` scale checks the script end to end on one scene of each part.
CI_SCENES = {"cloud", "spheres"}


def parse_args():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--scale", choices=sorted(common.SCALES), default="laptop")
    p.add_argument("--out", default="results/comparison")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--device", default=None)
    p.add_argument("--steps", type=int, default=None, help="training steps per run (default: the scale's)")
    p.add_argument("--part", choices=["media", "solids", "all"], default="all")
    p.add_argument("--scenes", nargs="+", default=None,
                   help="only these scenes (cloud smoke spheres torus; default: all, or cloud and spheres at ci)")
    return p.parse_args()


def compare(r, datasets, methods, results, title):
    """Trains and evaluates every method on every dataset; a Markdown table of PSNR / SSIM / training minutes."""
    header = ["method"]
    for scene, lighting in datasets:
        header += ["%s %s PSNR" % (scene, lighting), "SSIM", "min"]
    rows = []
    for label, method in methods:
        row = [label]
        for scene, lighting in datasets:
            name = "%s-%s" % (scene, lighting.replace("+", ""))
            data = r.dataset(name, scene=scene, lighting=lighting)
            run = r.train("%s-%s" % (name, method), data, r.config(method=method))
            psnr, ssim = common.split_means(r.evaluate(run, splits=["test"]), "test")
            minutes = (common.training_seconds(run) or 0.0) / 60.0
            results.setdefault(name, {})[method] = {"run": run, "psnr": psnr, "ssim": ssim, "minutes": round(minutes, 2)}
            row += [psnr, ssim, "%.1f" % minutes]
        rows.append(row)
    return ["## " + title, ""] + common.markdown_table(header, rows)


def orderings(results, order):
    """{"<dataset>: A > B > C": bool} for the PSNR ordering `order` (method names, best first)."""
    checks = {}
    for name, runs in results.items():
        if all(m in runs for m in order):
            psnr = [runs[m]["psnr"] for m in order]
            checks["%s: %s" % (name, " > ".join(order))] = all(a > b for a, b in zip(psnr, psnr[1:]))
    return checks


def main():
    args = parse_args()
    r = common.Relit(args.out, args.scale, args.seed, args.device, args.steps)
    scenes = set(args.scenes) if args.scenes else (CI_SCENES if args.scale == "ci" else None)
    pick = lambda pairs: [p for p in pairs if scenes is None or p[0] in scenes]  # noqa: E731
    results = {"experiment": "comparison", "media": {}, "solids": {}}
    tables, checks = [], {}
    if args.part in ("media", "all") and pick(MEDIA):
        tables.append(compare(r, pick(MEDIA), MEDIA_METHODS, results["media"], "Participating media"))
        checks.update(orderings(results["media"], ["ours", "nerv", "bi"]))
    if args.part in ("solids", "all") and pick(SOLIDS):
        tables.append(compare(r, pick(SOLIDS), SOLID_METHODS, results["solids"], "Glossy solids"))
        checks.update(orderings(results["solids"], ["ours", "nerv", "bi"]))
    results["checks"] = checks
    series = {}
    for part in ("media", "solids"):
        for name, runs in results[part].items():
            for method, v in runs.items():
                series.setdefault(method, ([], []))
                series[method][0].append(len(series[method][0]))
                series[method][1].append(v["psnr"])
    names = [n for part in ("media", "solids") for n in results[part]]
    if names:
        common.plot(os.path.join(args.out, "comparison.png"), "Methods (test views, novel lights)", "dataset", series,
                    xticks=names)
    notes = ["Orderings of the paper (PSNR): " + (", ".join("%s %s" % (k, "holds" if v else "does not hold")
                                                           for k, v in checks.items()) or "none checked") + ".",
             "", "![PSNR per dataset and method](comparison.png)"]
    r.write_results("Method comparison", results, tables + [notes])


if __name__ == "__main__":
    main()
