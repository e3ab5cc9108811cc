"""A learned medium in other tools (docs/interop.md): `relit export` to OpenVDB (read back by relit's scene loader),
and relighting videos from `relit render` (PNG frames and an MP4 that
ffprobe reads; ffmpeg comes from scripts/setup.sh)."""
import json
import os
import subprocess

import numpy as np
import pytest

import relit
from conftest import run_python


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
    probes = [
        (["export", tmp_path / "no-run", "--vdb", tmp_path / "a.vdb"], "run folder"),
        (["export", run, "--vdb", tmp_path / "missing" / "a.vdb"], "missing' does not exist"),
        (["export", run, "--vdb", tmp_path / "a.vdb", "--resolution", 4], "must be an integer in [8, 512]"),
        (["export", run, "--vdb", tmp_path / "a.vdb", "--threshold", "nan"], "finite number"),
        (["export", run], "--vdb OUT.vdb"),
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
