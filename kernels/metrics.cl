// metrics.cl: image metrics on the clamped, sRGB-encoded image (docs/design.md §6): PSNR and SSIM with an 11x11
// Gaussian window, sigma 1.5 (Wang et al. 2004; the same as scikit-image's structural_similarity with
// gaussian_weights=True, use_sample_covariance=False, data_range=1).
//
// Images are interleaved row-major float: pixel (x, y) channel c at (y * width + x) * channels + c, linear
// radiance in. Partial sums come out per image row (the host adds them in double, in a fixed order).
#ifndef SSIM_RADIUS
#define SSIM_RADIUS 5
#endif
#define SSIM_C1 0.0001f  // (0.01 * data range)^2
#define SSIM_C2 0.0009f  // (0.03 * data range)^2

inline float srgb_encode(float linear) {
  const float x = clamp(linear, 0.0f, 1.0f);
  return x <= 0.0031308f ? 12.92f * x : fma(1.055f, pow(x, 1.0f / 2.4f), -0.055f);
}

// In place: linear → clamped sRGB in [0, 1].
__kernel void to_srgb(const uint n, __global float* restrict image) {
  const size_t i = get_global_id(0);
  if (i >= n) return;
  image[i] = srgb_encode(image[i]);
}

// Sum over one row of squared differences (both images already sRGB).
__kernel void squared_error_rows(const uint width, const uint height, const uint channels,
                                 __global const float* restrict a, __global const float* restrict b,
                                 __global float* restrict row_sums) {
  const uint y = get_global_id(0);
  if (y >= height) return;
  const size_t n = (size_t)width * channels, base = (size_t)y * n;
  float s = 0.0f;
  for (size_t i = 0; i < n; ++i) {
    const float d = a[base + i] - b[base + i];
    s = fma(d, d, s);
  }
  row_sums[y] = s;
}

// SSIM summed over the interior pixels of row y (those whose window lies inside the image) and all channels.
// `weights`: the normalised 1-D Gaussian, 2 SSIM_RADIUS + 1 taps (the 2-D window is its outer product).
__kernel void ssim_rows(const uint width, const uint height, const uint channels, __global const float* restrict a,
                        __global const float* restrict b, __constant float* weights,
                        __global float* restrict row_sums) {
  const uint row = get_global_id(0);
  const uint n_rows = height - 2 * SSIM_RADIUS;
  if (row >= n_rows) return;
  const uint y = row + SSIM_RADIUS;
  float total = 0.0f;
  for (uint x = SSIM_RADIUS; x + SSIM_RADIUS < width; ++x) {
    for (uint c = 0; c < channels; ++c) {
      float ma = 0.0f, mb = 0.0f, saa = 0.0f, sbb = 0.0f, sab = 0.0f;
      for (int dy = -SSIM_RADIUS; dy <= SSIM_RADIUS; ++dy) {
        for (int dx = -SSIM_RADIUS; dx <= SSIM_RADIUS; ++dx) {
          const float w = weights[dy + SSIM_RADIUS] * weights[dx + SSIM_RADIUS];
          const size_t i = ((size_t)(y + dy) * width + (x + dx)) * channels + c;
          const float va = a[i], vb = b[i];
          ma = fma(w, va, ma);
          mb = fma(w, vb, mb);
          saa = fma(w, va * va, saa);
          sbb = fma(w, vb * vb, sbb);
          sab = fma(w, va * vb, sab);
        }
      }
      const float va = saa - ma * ma, vb = sbb - mb * mb, cov = sab - ma * mb;
      total +=
          ((2.0f * ma * mb + SSIM_C1) * (2.0f * cov + SSIM_C2)) / ((ma * ma + mb * mb + SSIM_C1) * (va + vb + SSIM_C2));
    }
  }
  row_sums[row] = total;
}
