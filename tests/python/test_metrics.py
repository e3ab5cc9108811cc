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
