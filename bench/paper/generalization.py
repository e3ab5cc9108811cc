#!/usr/bin/env python3
"""Generalisation over light distance and intensity (Zheng, Singh, Seidel, NeurIPS 2021: appendix H, Figs. 2-3).

- Distance: train with the point light at distances stratified in (3, 5), test at 3, 5, 7 and 10 (intensity 600).
- Intensity: train with intensities stratified in [50, 900], test at 400, 800, 1200 and 1600 (distance 4).
The test sets share their cameras and light directions (`relit generate --generalization`).

    python bench/paper/generalization.py --scale laptop --out results/generalization
"""
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import common  # noqa: E402

DISTANCES = [3, 5, 7, 10]
INTENSITIES = [400, 800, 1200, 1600]


def main():
    args = common.parse_args(__doc__.splitlines()[0], "results/generalization")
    r = common.Relit(args.out, args.scale, args.seed, args.device, args.steps)
    results = {"experiment": "generalization"}
    tables = []
    # Light distance: the default protocol trains in (3, 5).
    data = r.dataset("cloud-point-gen", scene="cloud", lighting="point", generalization=True, light_distance=(3, 5))
    run = r.train("distance", data, r.config())
    m = r.evaluate(run, splits=["test_distance_%d" % d for d in DISTANCES])
    dist = {d: common.split_means(m, "test_distance_%d" % d) for d in DISTANCES}
    dist_obj = {d: common.object_means(m, "test_distance_%d" % d) for d in DISTANCES}
    results["distance"] = {"dataset": data, "run": run, "train_range": [3, 5],
                           "psnr": {str(d): v[0] for d, v in dist.items()},
                           "ssim": {str(d): v[1] for d, v in dist.items()},
                           "object": {str(d): v for d, v in dist_obj.items()}}
    tables.append(["## Light distance (trained in (3, 5))", ""] + common.markdown_table(
        ["", *("d = %d" % d for d in DISTANCES)],
        [["PSNR [dB]", *(dist[d][0] for d in DISTANCES)], ["SSIM", *(dist[d][1] for d in DISTANCES)],
         ["object PSNR [dB]", *(dist_obj[d]["psnr"] for d in DISTANCES)],
         ["object FLIP", *(dist_obj[d]["flip"] for d in DISTANCES)]]))
    # Light intensity: train on intensities in [50, 900].
    data = r.dataset("cloud-point-intensity", scene="cloud", lighting="point", generalization=True,
                     intensity=(50, 900))
    run = r.train("intensity", data, r.config())
    m = r.evaluate(run, splits=["test_intensity_%d" % i for i in INTENSITIES])
    inten = {i: common.split_means(m, "test_intensity_%d" % i) for i in INTENSITIES}
    inten_obj = {i: common.object_means(m, "test_intensity_%d" % i) for i in INTENSITIES}
    results["intensity"] = {"dataset": data, "run": run, "train_range": [50, 900],
                            "psnr": {str(i): v[0] for i, v in inten.items()},
                            "ssim": {str(i): v[1] for i, v in inten.items()},
                            "object": {str(i): v for i, v in inten_obj.items()}}
    tables.append(["## Light intensity (trained in [50, 900])", ""] + common.markdown_table(
        ["", *("I = %d" % i for i in INTENSITIES)],
        [["PSNR [dB]", *(inten[i][0] for i in INTENSITIES)], ["SSIM", *(inten[i][1] for i in INTENSITIES)],
         ["object PSNR [dB]", *(inten_obj[i]["psnr"] for i in INTENSITIES)],
         ["object FLIP", *(inten_obj[i]["flip"] for i in INTENSITIES)]]))
    common.plot(os.path.join(args.out, "distance.png"), "Light distance (trained in (3, 5))", "light distance",
                {"PSNR": (DISTANCES, [dist[d][0] for d in DISTANCES])}, xticks=DISTANCES)
    common.plot(os.path.join(args.out, "intensity.png"), "Light intensity (trained in [50, 900])", "intensity [W/sr]",
                {"PSNR": (INTENSITIES, [inten[i][0] for i in INTENSITIES])}, xticks=INTENSITIES)
    p = results["distance"]["psnr"]
    results["checks"] = {"PSNR decreases beyond the training range": p["5"] >= p["7"] >= p["10"],
                         "intensity 1200 and 1600 within 0.5 dB of 800":
                             max(abs(inten[1200][0] - inten[800][0]), abs(inten[1600][0] - inten[800][0])) <= 0.5}
    tables.append(["Checks: " + "; ".join("%s: %s" % (k, "yes" if v else "no") for k, v in results["checks"].items()),
                   "", "![distance](distance.png) ![intensity](intensity.png)"])
    r.write_results("Generalisation over light distance and intensity", results, tables)


if __name__ == "__main__":
    main()
