"""relit.metrics: PSNR and SSIM of linear images, measured on their clamped sRGB encodings (in OpenCL).

    relit.metrics.compare(prediction, reference)   # {'mse': ..., 'psnr': ..., 'ssim': ...}
"""
from ._core import metrics as _metrics

compare = _metrics.compare
psnr = _metrics.psnr
ssim = _metrics.ssim

__all__ = ["compare", "psnr", "ssim"]
