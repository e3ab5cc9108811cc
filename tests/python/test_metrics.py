"""relit.metrics against an independent implementation (scikit-image) on the sRGB-encoded images."""
import numpy as np
import pytest
from skimage.metrics import peak_signal_noise_ratio, structural_similarity

import relit.metrics


def srgb(x):
    x = np.clip(x, 0.0, 1.0).astype(np.float64)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)


@pytest.mark.parametrize("shape", [(64, 48, 3), (31, 40), (20, 20, 4)])
def test_psnr_and_ssim_match_scikit_image(device, shape):
    rng = np.random.default_rng(sum(shape))
    ref = rng.uniform(-0.1, 1.4, size=shape).astype(np.float32)
    pred = (ref + rng.normal(0, 0.05, size=shape)).astype(np.float32)
    m = relit.metrics.compare(pred, ref, device=device)
    a, b = srgb(pred), srgb(ref)
    assert m["psnr"] == pytest.approx(peak_signal_noise_ratio(b, a, data_range=1.0), abs=1e-4)
    expected_ssim = structural_similarity(a, b, gaussian_weights=True, sigma=1.5, use_sample_covariance=False,
                                          data_range=1.0, channel_axis=-1 if len(shape) == 3 else None)
    assert m["ssim"] == pytest.approx(expected_ssim, abs=1e-5)


def test_shape_mismatch_is_a_value_error(device):
    with pytest.raises(ValueError, match="same shape"):
        relit.metrics.psnr(np.zeros((16, 16, 3), np.float32), np.zeros((16, 17, 3), np.float32), device=device)


def test_object_metrics_match_numpy(device):
    """Over a mask: PSNR of the sRGB images, the linear relative MSE, the clipped share (numpy in double)."""
    rng = np.random.default_rng(3)
    ref = rng.uniform(0, 2.0, size=(40, 36, 3)).astype(np.float32)
    pred = np.maximum(ref + rng.normal(0, 0.1, size=ref.shape), 0).astype(np.float32)
    ref_alpha = np.where(rng.uniform(size=(40, 36)) < 0.4, 0.8, 0.0).astype(np.float32)
    pred_alpha = np.zeros((40, 36), np.float32)
    pred_alpha[:4] = 0.02  # above the 0.01 threshold: object pixels too
    mask = relit.metrics.object_mask(ref_alpha, pred_alpha)
    np.testing.assert_array_equal(mask, (ref_alpha > 0.01) | (pred_alpha > 0.01))
    m = relit.metrics.compare(pred, ref, device=device, mask=mask)
    a, b = srgb(pred)[mask], srgb(ref)[mask]
    assert m["object"]["pixels"] == mask.sum()
    assert m["object"]["psnr"] == pytest.approx(10 * np.log10(1 / np.mean((a - b) ** 2)), abs=1e-4)
    p64, r64 = pred[mask].astype(np.float64), ref[mask].astype(np.float64)
    assert m["object"]["rel_mse"] == pytest.approx(np.mean((p64 - r64) ** 2 / (r64 ** 2 + 0.01)), rel=1e-5)
    assert m["object"]["clipped"] == pytest.approx(np.mean((ref[mask] > 1).any(axis=1)))
    # A boolean mask does not say which pixels only the prediction marks; a mask of 1 (the reference's alpha) and
    # 2 (only the prediction's), as relit's reports build it, does.
    assert m["object"]["prediction_only"] == 0
    coded = np.where(ref_alpha > 0.01, 1, np.where(pred_alpha > 0.01, 2, 0)).astype(np.uint8)
    m2 = relit.metrics.compare(pred, ref, device=device, mask=coded)
    assert m2["object"]["prediction_only"] == pytest.approx(np.mean(coded[mask] == 2)) and 0 < np.mean(coded[mask] == 2)
    assert m2["object"]["psnr"] == m["object"]["psnr"]
    # The whole image is unchanged by the mask; without one there are no object metrics.
    plain = relit.metrics.compare(pred, ref, device=device)
    assert plain["psnr"] == m["psnr"] and np.isnan(plain["object"]["psnr"])
    with pytest.raises(ValueError, match="mask"):
        relit.metrics.compare(pred, ref, device=device, mask=mask[:10])
