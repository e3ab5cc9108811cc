// loss.cl: training losses on BatchMatrix tiles, and a fixed-order reduction of their partial sums.
//
// One work-item per 16-sample tile: it walks the tile's `cols` features, each a float16 of 16 samples,
// writes dL/dprediction (already divided by the element count, times `scale`) and the tile's loss sum to
// partials[tile]. Rows at or past `batch` (padding) get zero loss and zero gradient, so weight gradients
// that sum over rows are unaffected. reduce_sum adds the partials in a fixed order: deterministic.
//
//   LOSS 0  L2             (p - t)^2
//   LOSS 1  RelativeL2     (p - t)^2 / (sg(p)^2 + eps)             (sg: no gradient through the denominator)
//   LOSS 2  ToneMappedL2   (m(p) - m(t))^2,  m(x) = x / (1 + |x|)  (x/(1+x) for radiance x >= 0)
//   LOSS 3  SrgbL2         (s(p) - s(t))^2,  s = the sRGB transfer curve of linear radiance, unclamped above 1
//                          and odd below 0: s(x) = 12.92 x for |x| <= 0.0031308, else sign(x) (1.055 |x|^(1/2.4) -
//                          0.055)
#include "common.clh"
#include "layout.clh"

#ifndef LOSS
#define LOSS 0
#endif
#ifndef RELATIVE_EPS
#define RELATIVE_EPS 0.01f
#endif

inline float16 tone_map(float16 x) { return x / (1.0f + fabs(x)); }

#define SRGB_KNEE 0.0031308f
// The sRGB encoding of linear x (see LOSS 3) and its derivative.
inline float16 srgb(float16 x) {
  const float16 a = fabs(x);
  const float16 curve = fma((float16)1.055f, pow(fmax(a, SRGB_KNEE), (float16)(1.0f / 2.4f)), (float16)-0.055f);
  return copysign(select(curve, 12.92f * a, a <= SRGB_KNEE), x);
}
inline float16 srgb_slope(float16 x) {
  const float16 a = fmax(fabs(x), SRGB_KNEE);
  const float16 slope = (1.055f / 2.4f) * pow(a, (float16)(1.0f / 2.4f - 1.0f));
  return select(slope, (float16)12.92f, fabs(x) <= SRGB_KNEE);
}

__kernel void loss_forward_backward(const uint batch, const uint cols, const float scale, const float inv_count,
                                    __global const float16* restrict prediction,
                                    __global const float16* restrict target, __global float16* restrict gradient,
                                    __global float* restrict partials, const uint n_tiles) {
  const uint tile = get_global_id(0);
  if (tile >= n_tiles) return;
  // Lane mask: 1 for real samples, 0 for padding rows.
  const int16 lane = (int16)(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15);
  const int16 valid = (int16)((int)(tile * RELIT_TILE)) + lane < (int16)((int)batch);
  const float16 mask = select((float16)(0.0f), (float16)(1.0f), valid);
  float16 sum = (float16)(0.0f);
  for (uint f = 0; f < cols; ++f) {
    const size_t i = (size_t)tile * cols + f;
    const float16 p = prediction[i], t = target[i];
#if LOSS == 0
    const float16 d = p - t;
    const float16 value = d * d;
    const float16 grad = 2.0f * d;
#elif LOSS == 1
    const float16 d = p - t;
    const float16 denom = fma(p, p, (float16)(RELATIVE_EPS));
    const float16 value = d * d / denom;
    const float16 grad = 2.0f * d / denom;
#elif LOSS == 2
    const float16 d = tone_map(p) - tone_map(t);
    const float16 one_plus = 1.0f + fabs(p);
    const float16 value = d * d;
    const float16 grad = 2.0f * d / (one_plus * one_plus);
#else
    const float16 d = srgb(p) - srgb(t);
    const float16 value = d * d;
    const float16 grad = 2.0f * d * srgb_slope(p);
#endif
    sum = fma(value, mask, sum);
    gradient[i] = grad * mask * (scale * inv_count);
  }
  partials[tile] = relit_sum16(sum) * inv_count;
}

// out[0] = sum of n values, added in a fixed order (one work-item; the inputs are one per tile, few).
__kernel void reduce_sum(const uint n, __global const float* restrict values, __global float* restrict out) {
  if (get_global_id(0) != 0) return;
  float s = 0.0f;
  for (uint i = 0; i < n; ++i) s += values[i];
  out[0] = s;
}
