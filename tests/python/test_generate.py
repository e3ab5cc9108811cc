"""Scenes, the reference path tracer and dataset generation from Python, and `relit generate` on the CLI."""
import json
import os

import numpy as np
import pytest

import relit
from conftest import run_python


def small_scene():
    d = relit.Scene.builtin("cloud", seed=1, resolution=16).description
    d["cameras"] = [{"position": [0, -4, 0.5], "width": 12, "height": 10}]
    d["lights"] = [{"position": [2, -3, 2], "intensity": [300, 300, 300]}]
    return relit.Scene.from_json(d)


def test_render_reference_returns_rgba_array_and_is_deterministic(device):
    scene = small_scene()
    img = relit.render_reference(scene, spp=4, seed=3, device=device)
    assert img.shape == (10, 12, 4) and img.dtype == np.float32
    assert np.isfinite(img).all() and img[..., :3].max() > 0
    assert ((img[..., 3] >= 0) & (img[..., 3] <= 1)).all()
    again = relit.render_reference(scene, 0, spp=4, seed=3, device=device)
    assert np.array_equal(img, again)
    cam = relit.Camera.look_at((0, -4, 0.5), width=12, height=10)
    other = relit.render_reference(scene, cam, lights=[relit.PointLight((2, -3, 2), 300)], spp=4, seed=3, device=device)
    assert np.allclose(other, img, atol=1e-5)


def test_progress_callable_sees_progress_and_can_cancel(device, tmp_path):
    scene = small_scene()
    seen = []
    relit.render_reference(scene, spp=4, device=device, progress=lambda p: seen.append((p.done, p.total)))
    assert seen and seen[-1][0] == seen[-1][1] == 12 * 10 * 4
    with pytest.raises(relit.Error):
        relit.generate_dataset(scene, str(tmp_path / "never-written"), train=2, val=0, test=0, resolution=8, spp=1, device=device,
                               progress=lambda p: False)
    assert not os.listdir(tmp_path)  # neither the dataset nor a temporary folder


def test_bad_scene_json_raises_config_error_with_pointer():
    d = relit.Scene.builtin("cloud", resolution=16).description
    d["medium"]["g"] = 1.2
    with pytest.raises(relit.ConfigError) as e:
        relit.Scene.from_json(d)
    assert e.value.pointer == "/medium/g" and isinstance(e.value, ValueError)
    with pytest.raises(OSError):
        relit.Scene.load("no-such-scene.json")


def test_generate_dataset_writes_the_format(device, tmp_path):
    out = tmp_path / "ds"
    relit.generate_dataset(small_scene(), str(out), train=2, val=1, test=1, resolution=8, spp=2, intensity=(50, 900),
                           device=device)
    t = json.loads((out / "transforms_train.json").read_text())
    assert t["w"] == t["h"] == 8 and t["lighting"] == "point" and len(t["frames"]) == 2
    f = t["frames"][0]
    assert (out / f["file_path"]).exists() and (out / f["preview_path"]).exists()
    assert len(f["transform_matrix"]) == 4 and f["light"]["type"] == "point"
    assert 50 <= f["light"]["intensity"][0] <= 900
    with pytest.raises(OSError):  # an existing dataset is never overwritten by accident
        relit.generate_dataset(small_scene(), str(out), train=1, val=0, test=0, resolution=8, spp=1, device=device)


def test_cli_generate_writes_a_dataset_with_progress(tmp_path):
    out = tmp_path / "cli"
    r = run_python(["-m", "relit", "generate", "--scene", "smoke", "--scene-resolution", "16", "--resolution", "8",
                    "--train", "2", "--val", "1", "--test", "1", "--spp", "2", "--lighting", "env+point", "--out", str(out)])
    assert r.returncode == 0, r.stderr
    assert "generate" in r.stderr and "100.0%" in r.stderr  # plain progress lines (stderr is not a terminal)
    assert (out / "environment.exr").exists() and (out / "transforms_test.json").exists()
    bad = run_python(["-m", "relit", "generate", "--scene", "nebula", "--out", str(tmp_path / "x")])
    assert bad.returncode != 0 and "unknown built-in scene 'nebula'" in bad.stderr


def test_cli_generalization_sets_scale_with_their_intensity(tmp_path):
    out = tmp_path / "gen"
    r = run_python(["-m", "relit", "generate", "--scene", "smoke", "--scene-resolution", "8", "--resolution", "8",
                    "--train", "1", "--val", "0", "--test", "1", "--spp", "1", "--generalization",
                    "--generalization-views", "1", "--generalization-intensity", "90", "--out", str(out)])
    assert r.returncode == 0, r.stderr
    for value in (60, 120, 180, 240):  # 2/3, 4/3, 2 and 8/3 of 90 W/sr
        frames = json.loads((out / f"transforms_test_intensity_{value}.json").read_text())["frames"]
        assert frames[0]["light"]["intensity"] == [value, value, value]
    assert json.loads((out / "transforms_test_distance_7.json").read_text())["frames"][0]["light"]["intensity"] == [90] * 3
