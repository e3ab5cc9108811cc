"""Bad input through the command line and the Python API, as a careless or hostile user would give it: every
probe gets a clear error that names what is wrong, a non-zero exit (or a relit.Error subclass), never a
traceback, an abort or a hang, and no file that existed before is changed."""
import json
import math
import os
import struct

import pytest

import relit
from conftest import run_python

ABORT_SIGNS = ("Traceback", "terminate called", "Aborted", "Segmentation fault", "core dumped", "what():")


def cli(args, env=None, timeout=120):
    r = run_python(["-m", "relit"] + [str(a) for a in args], env_extra=env)
    out = r.stdout + r.stderr
    for sign in ABORT_SIGNS:
        assert sign not in out, f"relit {args} crashed:\n{out}"
    return r.returncode, out


def snapshot(folder):
    files = {}
    for root, dirs, names in os.walk(folder):
        for n in names + dirs:
            p = os.path.join(root, n)
            files[os.path.relpath(p, folder)] = open(p, "rb").read() if os.path.isfile(p) else b"<dir>"
    return files


@pytest.fixture(scope="module")
def dataset(tmp_path_factory, device):
    out = tmp_path_factory.mktemp("rel") / "ds"
    relit.generate_dataset(relit.Scene.builtin("cloud", resolution=16), str(out), train=2, val=1, test=1,
                           resolution=12, spp=1, device=device)
    return out


@pytest.fixture(scope="module")
def run(tmp_path_factory, dataset):
    out = tmp_path_factory.mktemp("rel") / "run"
    code, text = cli(["train", dataset, "--config", "fast", "--steps", "2", "--out", out])
    assert code == 0, text
    return out


def probes(tmp, dataset, run):
    """(arguments, environment, text the message must contain). Files are prepared here."""
    a_file = tmp / "a_file.txt"
    a_file.write_text("precious")
    scene_huge = tmp / "huge.json"
    scene_huge.write_text('{"medium": {"type": "procedural", "name": "cloud", "density_scale": 1e999}}')
    bad_json = tmp / "bad.json"
    bad_json.write_text("{ not json")
    half_run = tmp / "half_run"
    half_run.mkdir()
    (half_run / "checkpoint.relit").write_bytes((run / "checkpoint.relit").read_bytes())
    (half_run / "config.json").write_text((run / "config.json").read_text()[:40])
    ds, out = dataset, tmp / "new_run"
    return [
        (["nonsense"], None, "unknown command 'nonsense'"),
        (["train", ds, "--out", a_file], None, "is an existing file"),
        (["train", ds, "--out", tmp / ("r" * 300)], None, "name too long"),
        (["train", ds, "--out", a_file / "sub"], None, "Not a directory"),
        (["train", ds, "--steps", "-5", "--out", out], None, "--steps: must be an integer in [0,"),
        (["train", ds, "--seed", "-7", "--out", out], None, "--seed: must be an integer in [0, 4294967295]"),
        (["train", ds, "--minutes", "nan", "--out", out], None, "--minutes: must be a finite number"),
        (["train", ds, "--resume", "--out", half_run], None, "config.json' is not valid JSON"),
        (["render", run, "--out", tmp / "a.png", "--resolution", "0"], None, "must be an integer in [1, 16384]"),
        (["render", run, "--out", tmp / "a.png", "--spp", "4294967295"], None, "must be an integer in [1, 65536]"),
        (["render", run, "--out", tmp / "a.png", "--eye", "0", "0", "nan"], None, "finite number"),
        (["render", run, "--out", tmp / "a.png", "--light", "0", "0", "0.5"], None, "inside the scene box"),
        (["render", run, "--out", tmp / "a.png", "--view", f"{ds}:train:x"], None, "view index must be"),
        (["render", run, "--out", tmp / "a.png", "--eye", "0", "0", "0", "--target", "0", "0", "0"], None,
         "same point"),
        (["generate", "--scene", scene_huge, "--out", tmp / "g"], None, "outside the range of a double"),
        (["generate", "--out", tmp, "--overwrite", "--resolution", "8"], None, "is not a dataset relit wrote"),
        (["generate", "--out", a_file, "--overwrite", "--resolution", "8"], None, "is a file"),
        (["generate", "--out", tmp / "g", "--fov", "inf"], None, "finite number"),
        (["bench", "--compare", bad_json, bad_json], None, "is not valid JSON"),
        (["devices"], {"RELIT_LOG": "bogus"}, "RELIT_LOG='bogus'"),
        (["generate", "--out", tmp / "g", "--resolution", "8"], {"RELIT_DEVICE": "99999999999999999999"},
         "matches no OpenCL device"),
    ]


def test_every_cli_probe_is_a_clear_error_and_damages_nothing(tmp_path, dataset, run):
    cases = probes(tmp_path, dataset, run)
    before = {p: snapshot(p) for p in (tmp_path, dataset, run)}
    failures = []
    for args, env, expected in cases:
        code, text = cli(args, env)
        if code == 0 or expected not in text or "relit: error" not in text and "Error" not in text:
            failures.append(f"relit {' '.join(map(str, args))} (exit {code}): expected '{expected}', got:\n{text}")
    assert not failures, "\n\n".join(failures)
    after = {p: snapshot(p) for p in (tmp_path, dataset, run)}
    for p in before:
        assert after[p] == before[p], f"files under {p} changed"


def test_python_errors_are_relit_errors_of_the_documented_kinds(tmp_path, run):
    with pytest.raises(relit.InvalidArgument, match="n_input_dims must be at most"):
        relit.nn.Network({"type": "FullyFusedMLP"}, 2**31, 16)
    with pytest.raises(relit.InvalidArgument, match="same point"):
        relit.Camera.look_at(eye=(1, 2, 3), target=(1, 2, 3))
    with pytest.raises(relit.ConfigError, match="appears twice"):
        relit.nn.Network('{"type": "FullyFusedMLP", "n_neurons": 16, "n_neurons": 32}', 3, 1)
    with pytest.raises(relit.ConfigError, match="disagree"):
        relit.nn.Network({"type": "FullyFusedMLP", "otype": "CutlassMLP"}, 3, 1)
    with pytest.raises(relit.ConfigError, match="cannot be written as JSON"):
        relit.nn.Network({"type": "FullyFusedMLP", "n_neurons": math.nan}, 3, 1)
    with pytest.raises(relit.IOError):
        relit.Model.load(str(tmp_path / "missing.relit"))
    assert issubclass(relit.InvalidArgument, ValueError) and issubclass(relit.IOError, OSError)
    assert issubclass(relit.DeviceError, RuntimeError) and issubclass(relit.ConfigError, relit.Error)


def test_a_checkpoint_with_nan_weights_is_refused_not_rendered(tmp_path, run):
    # Rewrite one weight as NaN and fix the checksum: the file is intact, its content is not usable.
    data = bytearray((run / "checkpoint.relit").read_bytes())
    header_len = struct.unpack_from("<Q", data, 12)[0]
    header = json.loads(bytes(data[20:20 + header_len]))
    theta = next(t for t in header["tensors"] if t["name"] == "theta")
    struct.pack_into("<f", data, 20 + header_len + theta["offset"], math.nan)
    h = 1469598103934665603
    for b in bytes(data[:-8]):
        h = ((h ^ b) * 1099511628211) & 0xFFFFFFFFFFFFFFFF
    struct.pack_into("<Q", data, len(data) - 8, h)
    bad = tmp_path / "nan.relit"
    bad.write_bytes(bytes(data))
    with pytest.raises(relit.IOError, match="NaN or infinite"):
        relit.Model.load(str(bad))
