"""scripts/device-check.sh run, with stand-in programs: the steps, their filters and what a build without images
skips. The script runs for real only on a GPU machine (docs/benchmarks.md, "On a GPU"); these tests check its
logic here, where each real step would take minutes."""
import os
import stat
import subprocess

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
SCRIPT = os.path.join(ROOT, "scripts", "device-check.sh")


def fake_bundle(tmp_path, features):
    """A bundle whose programs record their arguments; `relit --version` names `features`."""
    bundle = tmp_path / "bundle"
    (bundle / "bin").mkdir(parents=True)
    (bundle / "lib").mkdir()
    calls = tmp_path / "calls.txt"
    for name in ("relit", "relit_tests", "bench_mlp"):
        program = bundle / "bin" / name
        program.write_text(
            "#!/bin/sh\n"
            'if [ "$1" = --version ]; then echo "relit 0.1.0 (OpenCL C 1.2 kernels; %s)"; exit 0; fi\n'
            'echo "%s $*" >> "%s"\n'
            'echo "[  PASSED  ] 1 test."\n' % (features, name, calls))
        program.chmod(program.stat().st_mode | stat.S_IXUSR)
    return bundle, calls


def run_check(bundle, out, **env):
    return subprocess.run(["bash", SCRIPT, "run", str(bundle), str(out)], capture_output=True, text=True,
                          env=dict(os.environ, RELIT_CHECK_DEVICE="cpu", **env), timeout=120)


def test_every_step_runs_with_its_filter_and_the_mlp_cases_apart(tmp_path):
    bundle, calls = fake_bundle(tmp_path, "OpenImageIO, OpenVDB, MPI")
    r = run_check(bundle, tmp_path / "out", RELIT_CHECK_QUICK="1")
    assert r.returncode == 0, r.stdout + r.stderr
    lines = calls.read_text().splitlines()
    steps = [line.split(" ")[0] + " " + line.split(" ")[1] for line in lines]
    assert steps == ["relit devices", "relit_tests --gtest_filter=KernelsBuild.*:FullyFusedMLP*:MlpCase*:Enc*:"
                     "SphericalHarmonics.*:Loss.*:Adam.*:Columns.*:Metrics.*:Flip.*:VolumeRenderer*:Visibility.*:"
                     "Rays.*:PathTrace*:Environment*:-FullyFusedMLP/MlpCase.*",
                     "relit_tests --gtest_filter=FullyFusedMLP/MlpCase.*", "bench_mlp --device",
                     "relit bench", "relit bench"], lines
    assert "--suite kernels" in lines[4] and "--suite e2e" in lines[5] and "--quick" in lines[5]
    assert "--smoke" in lines[3]
    out = tmp_path / "out"
    assert "OpenImageIO, OpenVDB, MPI" in (out / "devices.txt").read_text()
    assert "[  PASSED  ] 1 test." in r.stdout  # the tests' summary is printed


def test_a_build_without_images_skips_the_exr_fixture_tests_and_the_end_to_end_cases(tmp_path):
    bundle, calls = fake_bundle(tmp_path, "no OpenImageIO, no OpenVDB, no MPI")
    r = run_check(bundle, tmp_path / "out")
    assert r.returncode == 0, r.stdout + r.stderr
    lines = calls.read_text().splitlines()
    assert lines[1].split(" ")[1].endswith(":-FullyFusedMLP/MlpCase.*:PathTraceSampling.EnvironmentSampler*")
    assert not any("--suite e2e" in line for line in lines), lines
    assert "--smoke" not in lines[3]
    assert "no end-to-end cases: this build reads and writes no images" in (tmp_path / "out" / "bench.txt").read_text()


def test_a_failing_step_sets_the_status_and_the_others_still_run(tmp_path):
    bundle, calls = fake_bundle(tmp_path, "OpenImageIO, OpenVDB, MPI")
    tests = bundle / "bin" / "relit_tests"
    tests.write_text(tests.read_text().replace('echo "[  PASSED  ] 1 test."', 'echo "[  FAILED  ] X.Y"; exit 1'))
    r = run_check(bundle, tmp_path / "out")
    assert r.returncode == 1
    assert "[  FAILED  ] X.Y" in r.stdout
    assert sum("relit bench" in line for line in calls.read_text().splitlines()) == 2


def test_no_bundle_and_a_bad_mode_are_errors(tmp_path):
    r = run_check(tmp_path / "missing", tmp_path / "out")
    assert r.returncode == 1 and "no bundle at" in r.stderr
    assert not (tmp_path / "out").exists()
    r = subprocess.run(["bash", SCRIPT, "frobnicate"], capture_output=True, text=True)
    assert r.returncode == 2 and "usage:" in r.stderr
