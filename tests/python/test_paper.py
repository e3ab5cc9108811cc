"""The paper experiments (bench/paper/) end to end at the `ci` scale: they run, write their tables, JSON and
figures, and a rerun finds everything done (deterministic, resumable). The numbers mean nothing at this scale."""
import json
import os
import subprocess
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
PAPER = os.path.join(ROOT, "bench", "paper")


def script(name, args, out, check=True):
    """bench/paper/<name> at the ci scale into `out`; asserts it succeeded unless check is False."""
    r = subprocess.run([sys.executable, os.path.join(PAPER, name), "--scale", "ci", "--out", str(out)] + args,
                       capture_output=True, text=True)
    assert not check or r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:]
    return r


def run(args, tmp_path):
    return script("run.py", args, tmp_path)


def compare(args, out, check=True):
    return script("comparison.py", args, out, check)


def test_paper_experiments_run_end_to_end_and_resume(tmp_path):
    run([], tmp_path)
    sh = json.load(open(tmp_path / "sh_ablation" / "results.json"))
    assert list(sh["runs"]) == ["w/o SH", "SH-1", "SH-3", "SH-5", "SH-7", "SH-9"]
    assert all(0 < v["psnr"] < 100 and -1 <= v["ssim"] <= 1 for v in sh["runs"].values())
    assert sh["scale"] == "ci" and set(sh["checks"]) == {"SH-5 >= SH-1", "SH-5 >= w/o SH"}
    # Every setting trains and renders with the marched shadow and its gradient, at one learning rate.
    assert sh["shadow"] == "march" and sh["lr"] == 3e-3
    for v in sh["runs"].values():
        model = json.load(open(os.path.join(v["run"], "config.json")))["model"]
        assert model["training_visibility"] == "march" and model["inference_visibility"] == "march"
        assert model["shadow_gradient"]["enabled"] and os.path.basename(v["run"]).endswith("-march-lr0.003")
    gen = json.load(open(tmp_path / "generalization" / "results.json"))
    assert list(gen["distance"]["psnr"]) == ["3", "5", "7", "10"]
    assert list(gen["intensity"]["psnr"]) == ["400", "800", "1200", "1600"]
    cmp = json.load(open(tmp_path / "comparison" / "results.json"))
    assert set(cmp["media"]) == {"cloud-point", "cloud-envpoint"} and set(cmp["solids"]) == {"spheres-point"}
    assert all(set(runs) == {"bi", "nerv", "ours"} for runs in cmp["media"].values())
    assert set(cmp["solids"]["spheres-point"]) == {"bi", "nerv", "ours_brdf", "ours"}
    assert all(0 < v["psnr"] < 100 and v["minutes"] >= 0 for part in ("media", "solids")
               for runs in cmp[part].values() for v in runs.values())
    assert "cloud-point: ours > nerv > bi" in cmp["checks"]
    # Every method's learning rate comes from the same three-value sweep on the validation split (the media share
    # the sweep of their first dataset, every solid has its own), and every run reports the object's protocol and
    # its convergence beside the paper's numbers.
    for part, methods in (("media", {"bi", "nerv", "ours"}), ("solids", {"bi", "nerv", "ours_brdf", "ours"})):
        sweeps = cmp["lr_sweep"][part]
        assert set(sweeps) == ({"cloud-point"} if part == "media" else set(cmp["solids"])), part
        for sweep in sweeps.values():
            assert set(sweep) == methods and all(len(v["val_psnr"]) == 3 for v in sweep.values())
        for name, runs in cmp[part].items():
            sweep = sweeps[name if part == "solids" else "cloud-point"]
            for method, v in runs.items():
                scores = sweep[method]["val_psnr"]
                assert v["lr"] == sweep[method]["chosen"] and "%g" % v["lr"] == max(scores, key=scores.get)
                assert 0 < v["object"]["psnr"] < 100 and 0 <= v["object"]["flip"] <= 1
                assert set(v["convergence"]) == {"early", "last", "ratio", "converged", "rising"}
    # Ours and Ours + BRDF train and render with the marched shadow (and its gradient), as the baselines do; on
    # solids Ours' SH head sees it. The marched runs of Ours on media are named so (another protocol's folder of
    # runs is not resumed as theirs).
    assert cmp["ours_shadow_on_media"] == "march"
    for part, method in (("solids", "ours"), ("solids", "ours_brdf"), ("media", "ours")):
        for runs in cmp[part].values():
            model = json.load(open(os.path.join(runs[method]["run"], "config.json")))["model"]
            assert model["training_visibility"] == "march" and model["inference_visibility"] == "march", part
            assert model["shadow_gradient"]["enabled"], (part, method)
            assert model["indirect"]["visibility_input"] == (part == "solids" and method == "ours"), (part, method)
            assert ("-march-" in os.path.basename(runs[method]["run"])) == (part == "media"), runs[method]["run"]
    assert set(cmp["gaps"]) == {"cloud-point", "cloud-envpoint"}
    assert any(k.startswith("no run runs away") for k in cmp["checks"])
    assert any(k.startswith("no run's loss rises") for k in cmp["checks"])
    assert "| Ours + BRDF |" in (tmp_path / "comparison" / "results.md").read_text()
    for f in ["sh_ablation/results.md", "sh_ablation/sh_ablation.png", "generalization/results.md",
              "generalization/distance.png", "generalization/intensity.png", "comparison/comparison.png"]:
        assert os.path.getsize(tmp_path / f) > 0, f
    assert "| SH-5 |" in (tmp_path / "sh_ablation" / "results.md").read_text()
    # One cell of the comparison, trained afresh in another folder with the rate the sweep chose, scores what it
    # scored in the whole table (runs are deterministic, so a table can be completed over several invocations).
    nerv = cmp["media"]["cloud-envpoint"]["nerv"]
    part = compare(["--part", "media", "--datasets", "cloud-envpoint", "--methods", "nerv",
                    "--rates", "nerv=%g" % nerv["lr"]], tmp_path / "cell")
    assert "relit train" in part.stdout and "sweep" not in part.stdout, part.stdout
    cell = json.load(open(tmp_path / "cell" / "results.json"))
    assert set(cell["media"]) == {"cloud-envpoint"} and set(cell["media"]["cloud-envpoint"]) == {"nerv"}
    assert cell["media"]["cloud-envpoint"]["nerv"]["psnr"] == nerv["psnr"]
    assert cell["lr_sweep"]["media"]["cloud-envpoint"]["nerv"] == {"chosen": nerv["lr"], "given": True}
    # --ours-shadow network trains Ours on media with its preset's isolated visibility network, under the old names.
    net = compare(["--part", "media", "--datasets", "cloud-point", "--methods", "ours", "--rates", "ours=0.01",
                   "--ours-shadow", "network", "--steps", "30"], tmp_path / "network")
    run_dir = json.load(open(tmp_path / "network" / "results.json"))["media"]["cloud-point"]["ours"]["run"]
    model = json.load(open(os.path.join(run_dir, "config.json")))["model"]
    assert os.path.basename(run_dir) == "cloud-point-ours-lr0.01", net.stdout[-2000:]
    assert model["training_visibility"] != "march" and not model["shadow_gradient"]["enabled"]
    for bad, why in ((["--rates", "nerv"], "expected METHOD=LR"), (["--rates", "nerv=nan"], "positive finite"),
                     (["--rates", "bi=0.01"], "no learning rate for"),
                     (["--datasets", "fog-point"], "unknown dataset"), (["--methods", "mlp"], "unknown method")):
        r = compare(["--part", "media"] + bad, tmp_path / "bad", check=False)
        assert r.returncode != 0 and why in r.stderr, (bad, r.stderr[-2000:])
    # A rerun trains nothing and evaluates nothing; an evaluation that went missing is redone alone.
    ckpt = os.path.join(sh["runs"]["SH-5"]["run"], "checkpoint.relit")
    before = os.path.getmtime(ckpt)
    os.remove(os.path.join(sh["runs"]["SH-3"]["run"], "eval", "metrics.json"))
    r = run(["--only", "sh_ablation"], tmp_path)
    assert "relit train" not in r.stdout and r.stdout.count("+ relit eval") == 1, r.stdout
    assert os.path.getmtime(ckpt) == before
    again = json.load(open(tmp_path / "sh_ablation" / "results.json"))
    assert {k: v["psnr"] for k, v in again["runs"].items()} == {k: v["psnr"] for k, v in sh["runs"].items()}


def test_convergence_trains_on_every_bounce_and_on_single_scattering(tmp_path):
    # Long enough at the ci scale for the loss around step 200 and at the end to exist.
    r = script("convergence.py", ["--methods", "nerv", "--rates", "nerv=0.01", "--steps", "400"], tmp_path / "conv")
    res = json.load(open(tmp_path / "conv" / "results.json"))
    kinds = res["datasets"]["cloud-point"]
    assert set(kinds) == {"every bounce", "single scattering"}, r.stdout[-2000:]
    for kind, entry in kinds.items():
        run = entry["runs"]["nerv"]
        assert run["lr"] == 0.01 and 0 < run["psnr"] < 100
        conv = run["convergence"]
        assert conv["ratio"] is not None and conv["ratio"] == conv["last"] / conv["early"]
        # The references' noise is a positive loss; the ratio above it is the ratio of the losses minus it.
        assert 0 < entry["noise"] < 1
        if conv["early"] > entry["noise"]:
            want = max(conv["last"] - entry["noise"], 0.0) / (conv["early"] - entry["noise"])
            assert abs(run["ratio_above_noise"] - want) < 1e-12
    # The single-scattering data were rendered with one scattering event per path: darker than every bounce of
    # the same views (same cameras, lights and seeds).
    import matplotlib.pyplot as plt
    data = tmp_path / "data"
    every = [plt.imread(str(data / "cloud-point-ci" / "train" / ("r_%03d.png" % i))).mean() for i in range(4)]
    single = [plt.imread(str(data / "cloud-point-single-ci" / "train" / ("r_%03d.png" % i))).mean() for i in range(4)]
    assert all(s < e for s, e in zip(single, every)), (single, every)
    assert os.path.getsize(tmp_path / "conv" / "cloud-point_losses.png") > 0
    assert "| NeRV | single scattering |" in (tmp_path / "conv" / "results.md").read_text()
    for bad, why in ((["--rates", "mlp=0.01"], "unknown method"), (["--noise-views", "0"], "at least 1"),
                     (["--datasets", "fog-point"], "invalid choice")):
        r = script("convergence.py", bad, tmp_path / "bad", check=False)
        assert r.returncode != 0 and why in r.stderr, (bad, r.stderr[-2000:])
    assert not os.path.exists(tmp_path / "bad")
