"""relit.metrics.flip (kernels/flip.cl) against NVIDIA's reference implementation, flip-evaluator, on real renders:
the path tracer's view of a small cloud at 64 and 4 samples per pixel.

Tolerance: 1e-4 on the mean and 2e-3 on any pixel. Both implementations compute in float and differ by rounding
(measured on this pair: 6e-6 on the HDR mean, 5e-4 on its worst pixel; 6e-7 and 5e-5 for LDR), most where the
feature error's square root and the colour error's power amplify it. A real difference in the algorithm moves the
mean by far more: a viewing distance of 60 instead of 67 pixels per degree by 2.3e-3, an exposure range one stop
brighter by 5.1e-3; the test checks that both exceed ten times the tolerance."""
import flip_evaluator as flip  # NVIDIA's reference implementation (scripts/setup.sh installs it)
import numpy as np
import pytest

import relit
import relit.metrics

MEAN_TOL, PIXEL_TOL = 1e-4, 2e-3


@pytest.fixture(scope="module")
def renders(device):
    d = relit.Scene.builtin("cloud", seed=1, resolution=16).description
    d["cameras"] = [{"position": [0, -3.2, 0.4], "width": 48, "height": 40}]
    d["lights"] = [{"position": [2, -3, 2], "intensity": [80, 80, 80]}]
    scene = relit.Scene.from_json(d)
    ref = relit.render_reference(scene, spp=64, seed=1, device=device)[..., :3]
    test = relit.render_reference(scene, spp=4, seed=2, device=device)[..., :3]
    return np.ascontiguousarray(test, np.float32), np.ascontiguousarray(ref, np.float32)


def nvidia(test, ref, mode, **parameters):
    error, mean, used = flip.evaluate(ref, test, mode, inputsRGB=False, applyMagma=False, parameters=parameters)
    return error[..., 0], mean, used


def test_hdr_flip_matches_flip_evaluator(device, renders):
    test, ref = renders
    ours = relit.metrics.flip(test, ref, device=device)
    error, mean, used = nvidia(test, ref, "HDR")
    assert ours["exposures"]["start"] == pytest.approx(used["startExposure"], abs=1e-5)
    assert ours["exposures"]["stop"] == pytest.approx(used["stopExposure"], abs=1e-5)
    assert ours["exposures"]["count"] == used["numExposures"]
    assert ours["mean"] > 0.01  # a real difference to measure
    assert ours["mean"] == pytest.approx(mean, abs=MEAN_TOL)
    assert np.abs(ours["error"] - error).max() < PIXEL_TOL
    # The same mean through compare(), as the reports use it.
    assert relit.metrics.compare(test, ref, device=device)["flip"] == pytest.approx(ours["mean"], abs=1e-12)

    # The check can fail: a wrong viewing distance or exposure range is far outside the tolerance.
    wrong_ppd = relit.metrics.flip(test, ref, pixels_per_degree=60.0, device=device)["mean"]
    assert abs(wrong_ppd - mean) > 10 * MEAN_TOL
    e = ours["exposures"]
    shifted = relit.metrics.flip(test, ref, start_exposure=e["start"] + 1, stop_exposure=e["stop"] + 1,
                                 exposures=e["count"], device=device)["mean"]
    assert abs(shifted - mean) > 10 * MEAN_TOL
    # ... and flip-evaluator agrees with those too (its parameters are the same as ours).
    assert wrong_ppd == pytest.approx(nvidia(test, ref, "HDR", ppd=60.0)[1], abs=MEAN_TOL)
    assert shifted == pytest.approx(nvidia(test, ref, "HDR", startExposure=e["start"] + 1, stopExposure=e["stop"] + 1,
                                           numExposures=e["count"])[1], abs=MEAN_TOL)


def test_ldr_flip_matches_flip_evaluator(device, renders):
    """LDR-FLIP of the images clamped to [0, 1] (linear in, as flip-evaluator's inputsRGB=False)."""
    test, ref = renders
    ours = relit.metrics.flip(test, ref, range="ldr", device=device)
    error, mean, _ = nvidia(np.clip(test, 0, 1), np.clip(ref, 0, 1), "LDR")
    assert ours["mean"] > 0.01 and ours["exposures"]["count"] == 1
    assert ours["mean"] == pytest.approx(mean, abs=MEAN_TOL)
    assert np.abs(ours["error"] - error).max() < PIXEL_TOL


def test_flip_errors(device, renders):
    test, ref = renders
    with pytest.raises(ValueError, match="range"):
        relit.metrics.flip(test, ref, range="sdr", device=device)
    with pytest.raises(ValueError, match="start"):
        relit.metrics.flip(test, ref, start_exposure=2.0, stop_exposure=1.0, device=device)
    with pytest.raises(ValueError, match="same shape"):
        relit.metrics.flip(test, ref[:-1], device=device)
