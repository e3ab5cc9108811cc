// metrics.cl: image metrics (docs/evaluation.md). On the clamped, sRGB-encoded image (docs/design.md §6): PSNR and
// SSIM with an 11x11 Gaussian window, sigma 1.5 (Wang et al. 2004; the same as scikit-image's
// structural_similarity with gaussian_weights=True, use_sample_covariance=False, data_range=1), over the whole
// image and over the object's pixels (a mask). On the linear image: the object's relative MSE and how many of
// its pixels clip.
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

// Per row y, on the linear images (before to_srgb), over the object's pixels (mask != 0), all channels:
// row_sums[3y] = sum of (a - b)^2 / (b^2 + rel_eps) (b is the reference), row_sums[3y + 1] = the object's
// pixels, row_sums[3y + 2] = those of them whose reference has a channel above 1 (clips in sRGB).
__kernel void object_rows(const uint width, const uint height, const uint channels, const float rel_eps,
                          __global const float* restrict a, __global const float* restrict b,
                          __global const uchar* restrict mask, __global float* restrict row_sums) {
  const uint y = get_global_id(0);
  if (y >= height) return;
  float rel = 0.0f, pixels = 0.0f, clipped = 0.0f;
  for (uint x = 0; x < width; ++x) {
    const size_t p = (size_t)y * width + x;
    if (!mask[p]) continue;
    pixels += 1.0f;
    bool clips = false;
    for (uint c = 0; c < channels; ++c) {
      const float va = a[p * channels + c], vb = b[p * channels + c];
      const float d = va - vb;
      rel += d * d / fma(vb, vb, rel_eps);
      clips = clips || vb > 1.0f;
    }
    if (clips) clipped += 1.0f;
  }
  row_sums[3 * y] = rel;
  row_sums[3 * y + 1] = pixels;
  row_sums[3 * y + 2] = clipped;
}

// Per row y of the sRGB images: row_sums[2y] = the sum of squared differences over the row, row_sums[2y + 1]
// the same over the object's pixels (mask != 0).
__kernel void squared_error_rows(const uint width, const uint height, const uint channels,
                                 __global const float* restrict a, __global const float* restrict b,
                                 __global const uchar* restrict mask, __global float* restrict row_sums) {
  const uint y = get_global_id(0);
  if (y >= height) return;
  float s = 0.0f, s_object = 0.0f;
  for (uint x = 0; x < width; ++x) {
    const size_t p = (size_t)y * width + x;
    float sp = 0.0f;
    for (uint c = 0; c < channels; ++c) {
      const float d = a[p * channels + c] - b[p * channels + c];
      sp = fma(d, d, sp);
    }
    s += sp;
    if (mask[p]) s_object += sp;
  }
  row_sums[2 * y] = s;
  row_sums[2 * y + 1] = s_object;
}

// SSIM over the interior pixels of row y (those whose window lies inside the image), summed over the pixels and
// all channels: row_sums[3 row] over every interior pixel, row_sums[3 row + 1] over the object's (mask != 0),
// row_sums[3 row + 2] = how many interior pixels of the row are the object's.
// `weights`: the normalised 1-D Gaussian, 2 SSIM_RADIUS + 1 taps (the 2-D window is its outer product).
__kernel void ssim_rows(const uint width, const uint height, const uint channels, __global const float* restrict a,
                        __global const float* restrict b, __global const uchar* restrict mask,
                        __constant float* weights, __global float* restrict row_sums) {
  const uint row = get_global_id(0);
  const uint n_rows = height - 2 * SSIM_RADIUS;
  if (row >= n_rows) return;
  const uint y = row + SSIM_RADIUS;
  float total = 0.0f, total_object = 0.0f, pixels_object = 0.0f;
  for (uint x = SSIM_RADIUS; x + SSIM_RADIUS < width; ++x) {
    float pixel = 0.0f;
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
      pixel +=
          ((2.0f * ma * mb + SSIM_C1) * (2.0f * cov + SSIM_C2)) / ((ma * ma + mb * mb + SSIM_C1) * (va + vb + SSIM_C2));
    }
    total += pixel;
    if (mask[(size_t)y * width + x]) {
      total_object += pixel;
      pixels_object += 1.0f;
    }
  }
  row_sums[3 * row] = total;
  row_sums[3 * row + 1] = total_object;
  row_sums[3 * row + 2] = pixels_object;
}
