"""relit.metrics: image metrics of linear images, computed in OpenCL (docs/evaluation.md).

    relit.metrics.compare(prediction, reference)   # {'mse', 'psnr', 'ssim', 'flip', 'object'}
    mask = relit.metrics.object_mask(reference[..., 3], prediction[..., 3])
    m = relit.metrics.compare(prediction[..., :3], reference[..., :3], mask=mask)
    m["object"]["psnr"], m["object"]["rel_mse"], m["object"]["clipped"], m["object"]["flip"]
    f = relit.metrics.flip(prediction, reference)   # HDR-FLIP: f["error"] (H, W), f["mean"], f["exposures"]
"""
from ._core import metrics as _metrics

compare = _metrics.compare
flip = _metrics.flip
object_mask = _metrics.object_mask
psnr = _metrics.psnr
ssim = _metrics.ssim

__all__ = ["compare", "flip", "object_mask", "psnr", "ssim"]
