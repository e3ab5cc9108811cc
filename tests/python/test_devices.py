"""The Python binding of the OpenCL layer: devices, selection, errors, and the CLI as `python -m relit`."""
import re

import pytest

import relit
from conftest import run_python


def test_devices_lists_at_least_one_device_with_capabilities():
    devs = relit.devices()
    assert devs, "no OpenCL device"
    for i, d in enumerate(devs):
        assert d.index == i
        assert d.name and d.type in ("cpu", "gpu", "accelerator", "other")
        assert d.compute_units > 0 and d.global_memory >= d.max_allocation > 0
        assert d.name in repr(d)


def test_select_by_index_substring_and_platform_device():
    first = relit.devices()[0]
    assert relit.Device.select("0").info.index == 0
    assert relit.Device.select(first.name[:5].upper()).info.name.startswith(first.name[:5])
    assert relit.Device.select(f"{first.platform_index}:{first.device_index}").info.index == first.index
    assert relit.Device.select("0") == relit.Device.select("0")


def test_select_from_environment(monkeypatch):
    last = relit.devices()[-1]
    monkeypatch.setenv("RELIT_DEVICE", str(last.index))
    assert relit.Device.select().info.index == last.index


def test_no_match_raises_device_error_which_is_a_runtime_error(monkeypatch):
    monkeypatch.setenv("RELIT_DEVICE", "no-such-device-xyz")
    with pytest.raises(relit.DeviceError, match=r"RELIT_DEVICE='no-such-device-xyz' matches no OpenCL device") as e:
        relit.Device.select()
    assert isinstance(e.value, RuntimeError) and isinstance(e.value, relit.Error)


def test_every_program_builds(device):
    checks = device.check_programs()
    assert checks and all(c.ok for c in checks), [c.error for c in checks if not c.ok]


def test_build_error_carries_log_and_options(tmp_path, monkeypatch, device):
    (tmp_path / "broken.cl").write_text("__kernel void k(__global float* x) {\n  x[0] = 1.0f +;\n}\n")
    monkeypatch.setenv("RELIT_KERNEL_DIR", str(tmp_path))
    with pytest.raises(relit.BuildError) as e:
        device.program("broken.cl", {"WIDTH": "64"})
    assert "broken.cl:2" in e.value.log
    assert "-DWIDTH=64" in e.value.options and "-DWIDTH=64" in str(e.value)
    assert open(e.value.source_path).read().count("1.0f +;") == 1


def test_missing_kernel_file_is_an_os_error(device):
    with pytest.raises(OSError, match="no kernel source 'nope.cl'"):
        device.program("nope.cl")


def test_no_opencl_platform_message_names_the_package(tmp_path):
    r = run_python("import relit; relit.devices()", {"OCL_ICD_VENDORS": str(tmp_path), "OCL_ICD_FILENAMES": ""})
    assert r.returncode != 0
    assert "relit.DeviceError" in r.stderr and "apt-get install pocl-opencl-icd" in r.stderr, r.stderr


def test_python_dash_m_relit_version_and_devices():
    r = run_python(["-m", "relit", "--version"])
    assert r.returncode == 0 and re.match(r"relit \d+\.\d+\.\d+", r.stdout), r.stdout + r.stderr
    assert relit.__version__ in r.stdout
    # The test build has images and OpenVDB (the suite reads and writes both); MPI where it was found.
    mpi = "MPI" if relit._core.parallel.built_with_mpi() else "no MPI"
    assert relit.build_features() == "OpenImageIO, OpenVDB, " + mpi
    assert relit.build_features() in r.stdout
    r = run_python(["-m", "relit", "devices"])
    assert r.returncode == 0, r.stderr
    assert re.search(r"relit kernels +build OK", r.stdout), r.stdout


def test_python_dash_m_relit_bad_device_exits_nonzero_with_message():
    r = run_python(["-m", "relit", "devices", "--device", "no-such-device-xyz"])
    assert r.returncode == 1
    assert "relit: error: device selector 'no-such-device-xyz' matches no OpenCL device" in r.stderr
