"""A learned medium in other tools (docs/interop.md): `relit export` to OpenVDB (read back by relit's scene loader)
and to a Mitsuba 3 scene (rendered by Mitsuba and compared with relit's path tracer on the same exported medium
with z-tests, as test_mitsuba_parity.py), and relighting videos from `relit render` (PNG frames and an MP4 that
ffprobe reads; ffmpeg comes from scripts/setup.sh)."""
import json
import math
import os
import subprocess
import sys

import mitsuba as mi  # scripts/setup.sh installs it into the venv; missing, the test fails (never skips)
import numpy as np
import pytest

import relit
from conftest import run_python

mi.set_variant("scalar_rgb")


def cli(args):
    r = run_python(["-m", "relit"] + [str(a) for a in args])
    out = r.stdout + r.stderr
    for sign in ("Traceback", "terminate called", "Aborted", "Segmentation fault"):
        assert sign not in out, f"relit {args} crashed:\n{out}"
    return r.returncode, out


@pytest.fixture(scope="module")
def run(tmp_path_factory, device):
    tmp = tmp_path_factory.mktemp("interop")
    relit.generate_dataset(relit.Scene.builtin("cloud", resolution=16), str(tmp / "ds"), train=2, val=1, test=1,
                           resolution=12, spp=1, device=device)
    code, text = cli(["train", tmp / "ds", "--config", "fast", "--steps", "2", "--out", tmp / "run"])
    assert code == 0, text
    return tmp / "run"


@pytest.fixture(scope="module")
def model(run, device):
    return relit.Model.load(str(run / "checkpoint.relit"), device=device)


def test_cli_export_vdb_reads_back_as_the_models_density(run, model, tmp_path):
    res = 20
    sigma = relit.sample_medium(model, res)["sigma"]
    threshold = float(np.median(sigma))
    out = tmp_path / "medium.vdb"
    code, text = cli(["export", run, "--vdb", out, "--resolution", res, "--threshold", threshold])
    assert code == 0 and "written to" in text, text
    scene = relit.Scene.load(str(out))
    got = scene.medium_density
    want = np.where(sigma > threshold, sigma, 0)
    assert got.shape == (res, res, res)
    err = np.abs(got - want).max()
    print(f"VDB round trip at {res}^3: max |density error| {err:.3g} of max sigma {sigma.max():.3g}")
    assert err <= 1e-6 * sigma.max()
    assert 0.3 < (got > 0).mean() < 0.7
    medium = scene.description["medium"]
    assert medium["density_scale"] == 1 and medium["albedo"] == "grid"
    assert medium["source"]["placement"] == "world"
    # relit generate takes the file as its scene.
    code, text = cli(["generate", "--scene", out, "--out", tmp_path / "ds", "--resolution", 8, "--train", 1, "--val", 0,
                      "--test", 0, "--spp", 1, "--no-previews"])
    assert code == 0, text
    assert (tmp_path / "ds" / "transforms_train.json").is_file()


def test_cli_export_errors_are_clear_and_damage_nothing(run, tmp_path):
    kept = tmp_path / "kept.vdb"
    kept.write_text("precious")
    (tmp_path / "scene").mkdir()
    probes = [
        (["export", tmp_path / "no-run", "--vdb", tmp_path / "a.vdb"], "run folder"),
        (["export", run, "--vdb", tmp_path / "missing" / "a.vdb"], "missing' does not exist"),
        (["export", run, "--vdb", tmp_path / "a.vdb", "--resolution", 4], "must be an integer in [8, 512]"),
        (["export", run, "--vdb", tmp_path / "a.vdb", "--threshold", "nan"], "finite number"),
        (["export", run], "--vdb OUT.vdb and/or --mitsuba DIR"),
        (["export", run, "--vdb", kept, "--mitsuba", tmp_path / "scene"], "it exists"),
    ]
    before = {p: p.read_bytes() if p.is_file() else None for p in tmp_path.rglob("*")}
    for args, message in probes:
        code, text = cli(args)
        assert code != 0 and message in text, (args, text)
    assert {p: p.read_bytes() if p.is_file() else None for p in tmp_path.rglob("*")} == before


def test_cli_light_orbit_video_has_its_frames_and_mp4(run, tmp_path):
    code, text = cli(["render", run, "--out", tmp_path / "orbit.png", "--orbit-light", 4, "--resolution", 16,
                      "--light", 3, 0, 1.5])
    assert code == 0, text
    frames = sorted(p.name for p in tmp_path.iterdir() if p.suffix == ".png")
    assert frames == [f"orbit_{i:04d}.png" for i in range(4)]
    probe = subprocess.run(["ffprobe", "-v", "error", "-count_frames", "-select_streams", "v:0", "-show_entries",
                            "stream=nb_read_frames", "-of", "csv=p=0", str(tmp_path / "orbit.mp4")],
                           capture_output=True, text=True)
    assert probe.returncode == 0 and probe.stdout.strip() == "4", probe.stdout + probe.stderr
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")], "temporaries left"
    # A keyframe path from Python, frames only.
    path = tmp_path / "path.json"
    path.write_text(json.dumps([{"eye": [0, -4, 1], "light": [3, -3, 2]}, {"light": [-3, -3, 2], "intensity": 900}]))
    paths = relit.render_path(relit.Model.load(str(run / "checkpoint.relit")), str(tmp_path / "p"), str(path),
                              width=8, mp4=False)
    assert [os.path.basename(p) for p in paths] == ["p_0000.png", "p_0001.png"]
    assert not (tmp_path / "p.mp4").exists()
    code, text = cli(["render", run, "--out", tmp_path / "x.png", "--orbit-light", 2, "--orbit-camera", 2])
    assert code != 0 and "one of --orbit-camera" in text, text


SPP = 512
SIZE = 12


def mitsuba_mean_and_variance(xml, renders=32):
    """Mitsuba's image of the exported scene and the variance of its per-pixel mean, from independent renders
    (seeds) of SPP / renders samples each (its moment integrator gives the moments of XYZ, not of RGB)."""
    scene = mi.load_file(str(xml))
    images = np.stack([np.array(mi.render(scene, spp=SPP // renders, seed=100 + i))[..., :3] for i in range(renders)])
    images = images.astype(np.float64)
    return images.mean(axis=0), images.var(axis=0, ddof=1) / renders


def test_mitsuba_export_renders_like_relits_path_tracer(run, model, device, tmp_path):
    res = 16
    camera = relit.Camera.look_at((0.3, -4.0, 0.6), (0, 0, 0), (0, 0, 1), 0.6, SIZE, SIZE)
    light = relit.PointLight((2.0, -3.0, 2.5), 40.0)
    stats = relit.export_mitsuba(model, str(tmp_path / "mitsuba"), camera, light, resolution=res, spp=SPP,
                                 run="test")
    xml = tmp_path / "mitsuba" / "scene.xml"
    assert sorted(os.listdir(tmp_path / "mitsuba")) == ["albedo.vol", "density.vol", "scene.xml"]
    # relit's side: the same medium through the VDB export (every voxel active) and relit's scene loader.
    vdb = relit.export_vdb(model, str(tmp_path / "m.vdb"), resolution=res, threshold=0.0)
    assert vdb["active_voxels"] == res ** 3 and abs(vdb["mean_g"] - stats["mean_g"]) < 1e-6
    scene = relit.Scene.load(str(tmp_path / "m.vdb"))
    img, var = relit.render_reference(scene, camera, [light], spp=SPP, seed=9, device=device, with_variance=True)
    relit_mean, relit_var = img[..., :3].astype(np.float64), var[..., :3].astype(np.float64) / SPP  # RGB of RGBA
    mitsuba_mean, mitsuba_var = mitsuba_mean_and_variance(xml)
    assert mitsuba_mean.shape == relit_mean.shape == (SIZE, SIZE, 3)
    se2 = relit_var + mitsuba_var
    lit = se2 > 0
    assert lit.mean() > 0.3, "the medium must cover a good part of the image"
    z = (relit_mean - mitsuba_mean)[lit] / np.sqrt(se2[lit])
    z_mean = (relit_mean.sum() - mitsuba_mean.sum()) / math.sqrt(se2.sum())
    report = (f"exported medium: image mean relit {relit_mean.mean():.6f}, Mitsuba {mitsuba_mean.mean():.6f}, "
              f"z {z_mean:.2f}; {lit.sum()} pixel channels, worst |z| {np.abs(z).max():.2f}, "
              f"mean z^2 {np.mean(z * z):.3f}")
    print(report)
    assert abs(z_mean) < 4, report
    assert np.abs(z).max() < 5.5, report
    assert 0.6 < np.mean(z * z) < 1.6, report


def test_cli_mitsuba_export_uses_the_datasets_first_test_view(run, tmp_path):
    code, text = cli(["export", run, "--mitsuba", tmp_path / "scene", "--resolution", 8, "--spp", 4])
    assert code == 0 and "first test view" in text, text
    scene = mi.load_file(str(tmp_path / "scene" / "scene.xml"))
    assert tuple(scene.sensors()[0].film().size()) == (12, 12)  # the dataset's views are 12 x 12
    image = np.array(mi.render(scene))
    assert image.shape[:2] == (12, 12) and np.isfinite(image).all() and image.max() > 0
    # Mitsuba's own command line renders it (next to the venv's python) into scene.exr.
    mitsuba = os.path.join(os.path.dirname(sys.executable), "mitsuba")
    r = subprocess.run([mitsuba, "-m", "scalar_rgb", "scene.xml"], cwd=tmp_path / "scene", capture_output=True,
                       text=True, timeout=120)
    assert r.returncode == 0 and (tmp_path / "scene" / "scene.exr").is_file(), r.stdout + r.stderr
