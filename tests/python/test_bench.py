"""`relit bench`: every case verified before it is timed, JSON results, a verification failure reported as a
failure (never a time), and --compare. The timings themselves are not judged here."""
import json

from conftest import run_python

KERNEL_CASES = {"peak_fma_f16", "peak_fma_f8", "mlp_w64_forward", "mlp_w64_train", "mlp_w128_forward",
                "mlp_w128_train", "mlp_w256_forward", "mlp_w256_train", "hashgrid_forward_backward",
                "render_forward_backward", "adam_step",
                "pathtrace_cloud"}


def bench(tmp_path, name, *args):
    out = tmp_path / name
    r = run_python(["-m", "relit", "bench", "--quick", "--repeats", "2", "--json", str(out)] + list(args))
    return r, (json.loads(out.read_text()) if out.exists() else None)


def test_kernel_suite_verifies_and_times_every_case(tmp_path):
    r, doc = bench(tmp_path, "a.json", "--suite", "kernels")
    assert r.returncode == 0, r.stdout + r.stderr
    assert doc["format"] == "relit-bench" and doc["suite"] == "kernels" and doc["machine"]["cpu"]
    dev = doc["devices"][0]
    assert dev["device"] and dev["driver"] and dev["peak_gflops"] > 0
    results = {x["name"]: x for x in dev["results"]}
    assert set(results) == KERNEL_CASES
    for x in results.values():
        assert x["status"] == "ok", x
        assert x["verify_worst_over_tolerance"] <= 1
        assert 0 < x["min_s"] <= x["median_s"] <= x["max_s"] and x["repeats"] == 2
        assert x["first_call_s"] > 0 and x["compile_s"] >= 0
    assert results["mlp_w64_train"]["gflops"] > 0 and "percent_of_peak" in results["mlp_w64_train"]
    assert results["hashgrid_forward_backward"]["throughput"]["unit"] == "samples/s"
    assert "mlp_w256_train" in r.stdout and "GFLOP/s" in r.stdout

    # --compare of the file with itself: every ratio is 1.
    c = run_python(["-m", "relit", "bench", "--compare", str(tmp_path / "a.json"), str(tmp_path / "a.json")])
    assert c.returncode == 0, c.stderr
    ratios = [line.split()[-1] for line in c.stdout.splitlines() if line.strip().startswith(("mlp_", "peak_"))]
    assert len(ratios) == 8 and set(ratios) == {"1.00"}


def test_a_wrong_result_is_a_failure_not_a_time(tmp_path):
    r, doc = bench(tmp_path, "bad.json", "--suite", "kernels", "--filter", "mlp_w64", "--inject-error",
                   "mlp_w64_forward")
    assert r.returncode == 1
    assert "failed verification" in r.stderr
    results = {x["name"]: x for x in doc["devices"][0]["results"]}
    # The filter keeps the peak calibration: "% of peak" is always against the same run's peak.
    assert set(results) == {"peak_fma_f16", "peak_fma_f8", "mlp_w64_forward", "mlp_w64_train"}
    assert results["mlp_w64_forward"]["status"] == "failed" and "median_s" not in results["mlp_w64_forward"]
    assert "reference" in results["mlp_w64_forward"]["error"]
    assert results["mlp_w64_train"]["status"] == "ok" and "percent_of_peak" in results["mlp_w64_train"]


def test_end_to_end_suite(tmp_path):
    r, doc = bench(tmp_path, "e2e.json", "--suite", "e2e", "--filter", "fast")
    assert r.returncode == 0, r.stdout + r.stderr
    results = {x["name"]: x for x in doc["devices"][0]["results"]}
    assert set(results) == {"train_step_fast", "train_step_bi_fast", "train_step_nerv_fast", "train_step_ours_brdf_fast",
                            "relit_frame_fast"}
    assert all(x["status"] == "ok" and x["throughput"]["unit"] == "rays/s" for x in results.values())
