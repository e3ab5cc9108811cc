"""Training and relighting from Python (relit.Trainer, relit.Model), and `relit train` / `relit render` on the CLI."""
import json
import math
import os

import numpy as np
import pytest

import relit
from conftest import cloud_dataset, run_python


def png_size(path):
    with open(path, "rb") as f:
        head = f.read(24)
    assert head[:8] == b"\x89PNG\r\n\x1a\n"
    return int.from_bytes(head[16:20], "big"), int.from_bytes(head[20:24], "big")

MLP = {"type": "FullyFusedMLP", "n_neurons": 16, "n_hidden_layers": 1}
FREQ = {"type": "Frequency", "n_frequencies": 2, "include_input": True}
CONFIG = {
    "model": {
        "renderer": {"n_samples": 16, "sh": "1", "n_dirs": 8},
        "n_features": 4,
        "density_grid": {"resolution": 8, "march_steps": 16},
        "property": {"encoding": FREQ, "network": MLP},
        "indirect": {"light_encoding": FREQ, "network": MLP},
        "visibility": {"position_encoding": FREQ, "direction_encoding": FREQ, "network": MLP},
    },
    "training": {"batch_rays": 64, "validate_every": 4, "validation_views": 1, "checkpoint_every": 0, "log_every": 2},
}


@pytest.fixture(scope="module")
def dataset(tmp_path_factory, device):
    return cloud_dataset(tmp_path_factory, device, "method", 1, 16, resolution=12, train=4, val=1, test=1, spp=2, seed=3)


def test_trainer_yields_stats_and_the_model_renders(dataset, device, tmp_path):
    run = str(tmp_path / "run")
    trainer = relit.Trainer(dataset, config=CONFIG, out=run, device=device)
    seen = [s for s in trainer.run(6)]
    assert [s.step for s in seen] == [2, 4, 6]
    assert all(math.isfinite(s.loss) and s.skipped == 0 for s in seen)
    assert math.isfinite(seen[-1].val_psnr)
    assert trainer.steps == 6
    assert trainer.config["model"]["n_features"] == 4
    cam = relit.Camera.look_at((0, -4, 0.5), width=10, height=8)
    img = trainer.model.render(cam, relit.PointLight((2, -3, 2), 300))
    assert img.shape == (8, 10, 3) and img.dtype == np.float32 and np.isfinite(img).all()
    brighter = trainer.model.render(cam, relit.PointLight((2, -3, 2), 600))
    assert np.allclose(brighter, 2 * img, rtol=1e-4, atol=1e-6)  # linear in the intensity
    smooth = trainer.model.render(cam, relit.PointLight((2, -3, 2), 300), spp=4)  # 2 x 2 rays per pixel
    assert smooth.shape == img.shape and np.isfinite(smooth).all() and not np.array_equal(smooth, img)
    with pytest.raises(relit.InvalidArgument, match="square"):
        trainer.model.render(cam, relit.PointLight((2, -3, 2), 300), spp=2)
    # The run folder: config, log, checkpoint; the checkpoint reloads to the same model.
    assert json.load(open(os.path.join(run, "config.json")))["model"]["n_features"] == 4
    lines = [json.loads(x) for x in open(os.path.join(run, "log.jsonl"))]
    assert [x["step"] for x in lines] == [2, 4, 6]
    model = relit.Model.load(os.path.join(run, "checkpoint.relit"), device=device)
    assert np.array_equal(model.render(cam, relit.PointLight((2, -3, 2), 300)), img)


def test_presets_and_config_errors(dataset, device):
    assert {"fast", "paper"} <= set(relit.presets())
    assert relit.preset("fast")["model"]["property"]["encoding"]["type"] == "HashGrid"
    bad = json.loads(json.dumps(CONFIG))
    bad["training"]["learning_rate"] = 1
    with pytest.raises(relit.ConfigError, match="/training/learning_rate"):
        relit.Trainer(dataset, config=bad, device=device)
    with pytest.raises(relit.InvalidArgument, match="presets"):
        relit.preset("fastest")
    with pytest.raises(relit.Error):
        relit.Trainer(dataset + "-missing", config=CONFIG, device=device)


def test_cli_train_resume_and_render(dataset, tmp_path):
    cfg = tmp_path / "tiny.json"
    cfg.write_text(json.dumps(CONFIG))
    run = str(tmp_path / "run")
    r = run_python(["-m", "relit", "train", dataset, "--config", str(cfg), "--out", run, "--steps", "4"])
    assert r.returncode == 0, r.stderr
    assert "trained 4 steps" in r.stdout
    r = run_python(["-m", "relit", "train", dataset, "--config", str(cfg), "--out", run, "--steps", "4"])
    assert r.returncode != 0 and "--resume" in r.stderr  # an existing run is never overwritten
    r = run_python(["-m", "relit", "train", dataset, "--out", run, "--steps", "6", "--resume"])
    assert r.returncode == 0, r.stderr
    assert "trained 6 steps" in r.stdout
    # A run's config.json (which names the dataset it trained on) trains another run as it is.
    again = str(tmp_path / "again")
    r = run_python(["-m", "relit", "train", dataset, "--config", os.path.join(run, "config.json"), "--out", again,
                    "--steps", "2"])
    assert r.returncode == 0, r.stderr
    assert json.load(open(os.path.join(again, "config.json")))["model"] == json.load(
        open(os.path.join(run, "config.json")))["model"]
    png = str(tmp_path / "relit.png")
    r = run_python(["-m", "relit", "render", run, "--view", dataset + ":test:0", "--out", png])
    assert r.returncode == 0, r.stderr
    assert os.path.getsize(png) > 0
    big = str(tmp_path / "big.png")  # a dataset view's camera at another resolution, 4 rays per pixel
    r = run_python(["-m", "relit", "render", run, "--view", dataset + ":test:0", "--resolution", "24", "--spp", "4",
                    "--out", big])
    assert r.returncode == 0, r.stderr
    (w, h), (bw, bh) = png_size(png), png_size(big)
    assert (bw, bh) == (24, round(24 * h / w))
    report = str(tmp_path / "eval")
    r = run_python(["-m", "relit", "eval", run, "--out", report, "--spp", "4"])
    assert r.returncode == 0, r.stderr
    lines = r.stdout.splitlines()
    psnr = [float(x.split()[1]) for x in lines if x.startswith("PSNR ")]
    ssim = [float(x.split()[1]) for x in lines if x.startswith("SSIM ")]
    assert len(psnr) == 1 and len(ssim) == 1 and math.isfinite(psnr[0]) and -1 <= ssim[0] <= 1
    metrics = json.load(open(os.path.join(report, "metrics.json")))
    assert metrics["splits"]["test"]["n_views"] == 1 and metrics["meta"]["step"] == 6
    assert metrics["meta"]["spp"] == 4
    assert abs(metrics["mean"]["psnr"] - psnr[0]) < 1e-3
    # The object's metrics: the mask is the reference's alpha or the model's (its rendered 1 - transmittance).
    view = metrics["views"][0]
    assert 0 < view["object"]["pixels"] <= 12 * 12 and math.isfinite(view["object"]["psnr"])
    assert view["object"]["rel_mse"] > 0 and 0 <= view["object"]["clipped"] <= 1
    assert 0 <= view["flip"] <= 1 and 0 <= view["object"]["flip"] <= 1
    assert os.path.exists(os.path.join(report, "contact_sheet_test.png"))
    assert os.path.exists(os.path.join(report, "metrics.md"))
    r = run_python(["-m", "relit", "render", run, "--eye", "0", "-4", "1", "--resolution", "16", "--light", "1", "-3",
                    "2", "--intensity", "300", "200", "100", "--out", str(tmp_path / "x.exr")])
    assert r.returncode == 0, r.stderr


def test_cli_render_light_options_given_at_their_default_values_override_the_view(device, tmp_path):
    # `relit render --view` keeps the view's light unless --light / --intensity are given, also when they are
    # given the values they default to without --view (0 -3 3 and 600).
    from skimage.io import imread

    ds = str(tmp_path / "ds")
    scene = relit.Scene.builtin("cloud", seed=1, resolution=16)
    relit.generate_dataset(scene, ds, resolution=12, train=2, val=1, test=1, spp=1, seed=3, intensity=300,
                           device=device)
    light = json.load(open(os.path.join(ds, "transforms_test.json")))["frames"][0]["light"]
    assert light["intensity"] == [300, 300, 300] and light["position"] != [0, -3, 3]
    run = str(tmp_path / "run")
    list(relit.Trainer(ds, config=CONFIG, out=run, device=device).run(2))

    def render(name, *extra):
        out = str(tmp_path / (name + ".png"))
        r = run_python(["-m", "relit", "render", run, "--view", ds + ":test:0", "--out", out] + list(extra))
        assert r.returncode == 0, r.stderr
        return imread(out).astype(int)

    view = render("view")
    assert view.max() > 0
    assert np.array_equal(render("view_intensity", "--intensity", "300"), view)  # the view's own: the same image
    brighter = render("default_intensity", "--intensity", "600")
    assert (brighter >= view).all() and (brighter > view).any()
    assert not np.array_equal(render("default_light", "--light", "0", "-3", "3"), view)


def test_env_point_training_and_rendering_under_the_environment(dataset, device, tmp_path):
    ds = str(tmp_path / "env")
    scene = relit.Scene.builtin("cloud", seed=1, resolution=16)
    relit.generate_dataset(scene, ds, lighting="env+point", resolution=12, train=4, val=1, test=1, spp=2, seed=4,
                           device=device)
    trainer = relit.Trainer(ds, config=CONFIG, device=device)
    assert trainer.config["model"]["environment"]["enabled"] is True
    stats = list(trainer.run(4, every=2))
    assert all(math.isfinite(s.loss) for s in stats)
    model = trainer.model
    assert model.has_environment
    env = relit.EnvironmentLight.from_dataset(ds)
    assert env.file.endswith("environment.exr") and not env.visible
    cam = relit.Camera.look_at((0, -4, 0.5), width=8, height=8)
    light = relit.PointLight((2, -3, 2), 300)
    lit = model.render(cam, light, environment=env)
    dark = model.render(cam, light)
    assert lit.shape == dark.shape == (8, 8, 3) and np.isfinite(lit).all()
    assert (lit - dark).sum() > 0  # the environment adds light
    with pytest.raises(relit.Error, match="no environment"):
        relit.EnvironmentLight.from_dataset(dataset)  # 'point' lighting
    # The CLI renders a dataset view under the dataset's environment (and without it on request).
    run = str(tmp_path / "run")
    r = run_python(["-m", "relit", "train", ds, "--config", str(_write(tmp_path, CONFIG)), "--out", run, "--steps", "2"])
    assert r.returncode == 0, r.stderr
    for extra in ([], ["--environment", "none"]):
        out = str(tmp_path / ("view%d.exr" % len(extra)))
        r = run_python(["-m", "relit", "render", run, "--view", ds + ":test:0", "--out", out] + extra)
        assert r.returncode == 0, r.stderr


def _write(tmp_path, config):
    path = tmp_path / "config.json"
    path.write_text(json.dumps(config))
    return path


NERV_MODEL = {
    "renderer": {"n_samples": 16},
    "bounce": {"n_dirs": 4},
    "density_grid": {"resolution": 8, "march_steps": 16},
    "property": {"encoding": FREQ, "network": MLP},
    "visibility": {"position_encoding": FREQ, "direction_encoding": FREQ, "trunk": MLP, "network": MLP},
}


def test_baselines_train_from_python_and_the_cli(dataset, device, tmp_path):
    # A baseline is chosen by the config's "method" (or method=...), trains, checkpoints and renders like Ours.
    assert set(relit.methods()) == {"ours", "ours_brdf", "bi", "nerv"}
    assert {"bi-fast", "bi-paper", "nerv-fast", "nerv-paper", "ours_brdf-fast"} <= set(relit.presets())
    config = {"model": NERV_MODEL, "training": dict(CONFIG["training"], validate_every=0)}
    run = str(tmp_path / "nerv")
    trainer = relit.Trainer(dataset, config=config, out=run, device=device, method="nerv")
    stats = list(trainer.run(4))
    assert stats[-1].step == 4 and math.isfinite(stats[-1].loss)
    assert trainer.model.method == "nerv" and trainer.config["method"] == "nerv"
    model = relit.Model.load(os.path.join(run, "checkpoint.relit"), device=device)
    assert model.method == "nerv"
    cam = relit.Camera.look_at([0, -3.5, 1], [0, 0, 0], [0, 0, 1], 0.7, 8, 8)
    img = model.render(cam, relit.PointLight([2, -2, 3], [500, 400, 300]))
    assert img.shape == (8, 8, 3) and np.isfinite(img).all()
    with pytest.raises(relit.ConfigError, match="method"):
        relit.Trainer(dataset, config=dict(config, method="bi"), device=device, method="nerv")
    with pytest.raises(relit.InvalidArgument, match="nerv"):
        relit.Trainer(dataset, config="fast", device=device, method="nerf")
    # The CLI: --method with a config file that leaves "method" out.
    path = str(tmp_path / "nerv.json")
    with open(path, "w") as f:
        json.dump(config, f)
    out = str(tmp_path / "nerv-cli")
    r = run_python(["-m", "relit", "train", dataset, "--config", path, "--method", "nerv", "--out", out, "--steps", "2"])
    assert r.returncode == 0, r.stderr
    with open(os.path.join(out, "config.json")) as f:
        assert json.load(f)["method"] == "nerv"
    r = run_python(["-m", "relit", "train", dataset, "--config", path, "--method", "bi", "--out", str(tmp_path / "x"),
                    "--steps", "2"])
    assert r.returncode != 0
