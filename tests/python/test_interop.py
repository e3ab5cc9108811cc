"""A learned medium in other tools (docs/interop.md): `relit export` to OpenVDB, read back by relit's scene loader."""
import os

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
