"""Shared fixtures of the Python tests. The suite imports the relit found on PYTHONPATH (CTest points it at
the build tree)."""
import os
import subprocess
import sys

import pytest

import relit


@pytest.fixture(scope="session")
def device():
    """The first device under test (RELIT_TEST_DEVICES or every device): fails, never skips, without one."""
    return relit.Device.select_all(os.environ.get("RELIT_TEST_DEVICES", "all"))[0]


def run_python(code_or_args, env_extra=None, **kwargs):
    """Runs a Python child process with the same relit on its path; returns CompletedProcess (text)."""
    env = dict(os.environ)
    env.update(env_extra or {})
    args = [sys.executable] + (["-c", code_or_args] if isinstance(code_or_args, str) else list(code_or_args))
    return subprocess.run(args, env=env, capture_output=True, text=True, timeout=300, **kwargs)


def cloud_dataset(tmp_path_factory, device, name, scene_seed, scene_resolution, **settings):
    """A small path-traced dataset of the built-in cloud in a fresh temporary folder: its path. `settings` go to
    relit.generate_dataset (resolution, train, val, test, spp, seed, ...)."""
    out = str(tmp_path_factory.mktemp(name) / "cloud")
    scene = relit.Scene.builtin("cloud", seed=scene_seed, resolution=scene_resolution)
    relit.generate_dataset(scene, out, device=device, **settings)
    return out
