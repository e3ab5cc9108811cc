// hierarchical.cl: the hierarchical (importance) sampling of Bi et al.'s Neural Reflectance Field (docs/design.md
// §4.5), as NeRF: N_FINE more samples per ray drawn from the coarse pass's compositing weights, merged with the coarse
// samples into N_COARSE + N_FINE sorted samples for the fine network.
//
// The coarse sample i stands for the stratum [t_near + i h, t_near + (i + 1) h), h = (t_far - t_near) / N_COARSE;
// its weight w_i = T_i (1 - exp(-sigma_i delta_i)) (+ 1e-5, so empty rays sample uniformly) is spread uniformly
// over the stratum. Fine sample j inverts that piecewise-linear CDF at u_j = (j + v_j) / N_FINE, v_j = 1/2 or
// jittered by (seed, ray, j): sorted by construction, stratified in u. No gradient flows through the sample
// placement (as NeRF); the fine pass is differentiable in its properties at the placed samples.
//
// Layouts as render.cl: t, delta per sample (ray-major), positions and props tiled (16-sample tiles).
#include "common.clh"
#include "layout.clh"

#ifndef N_COARSE  // set by sample_fine() (relit/method/bi.hpp)
#define N_COARSE 64
#endif
#ifndef N_FINE
#define N_FINE 128
#endif
#ifndef N_ALL
#define N_ALL (N_COARSE + N_FINE)
#endif

__kernel void sample_fine(const uint n_rays, const uint jitter, const uint seed, __global const float* restrict rays,
                          __global const float* restrict t_coarse, __global const float* restrict delta_coarse,
                          __global const float* restrict props_coarse, const uint prop_cols,
                          __global float* restrict t_fine_only, __global float* restrict t_out,
                          __global float* restrict delta_out, __global float* restrict positions, const uint ray_first,
                          const uint ray_stride) {
  const uint r = get_global_id(0);
  if (r >= n_rays) return;
  __global const float* ray = RAY_RECORD(rays, r);
  const float3 o = ray_origin(ray);
  const float3 d = ray_direction(ray);
  const float tn = ray_t_near(ray), tf = ray_t_far(ray);
  const float h = (tf - tn) / N_COARSE;
  const size_t c0 = (size_t)r * N_COARSE;
  // Total weight, then one sweep through the strata that places the (sorted) fine samples.
  float total = 0.0f, T = 1.0f;
  for (uint i = 0; i < N_COARSE; ++i) {
    const float sd = props_coarse[TILED_AT(prop_cols, c0 + i, 0)] * delta_coarse[c0 + i];
    total += T * (1.0f - exp(-sd)) + 1e-5f;
    T *= exp(-sd);
  }
  __global float* fine = t_fine_only + (size_t)r * N_FINE;
  T = 1.0f;
  float cdf = 0.0f;
  uint i = 0;
  float w_i = 0.0f;
  {
    const float sd = props_coarse[TILED_AT(prop_cols, c0, 0)] * delta_coarse[c0];
    w_i = (T * (1.0f - exp(-sd)) + 1e-5f) / total;
    T *= exp(-sd);
  }
  for (uint j = 0; j < N_FINE; ++j) {
    const float v = jitter ? relit_uniform(relit_hash2(seed, (ray_first + ray_stride * r) * N_FINE + j)) : 0.5f;
    const float u = ((float)j + v) / N_FINE;
    while (i + 1 < N_COARSE && cdf + w_i < u) {
      cdf += w_i;
      ++i;
      const float sd = props_coarse[TILED_AT(prop_cols, c0 + i, 0)] * delta_coarse[c0 + i];
      w_i = (T * (1.0f - exp(-sd)) + 1e-5f) / total;
      T *= exp(-sd);
    }
    const float f = clamp((u - cdf) / fmax(w_i, 1e-20f), 0.0f, 1.0f);
    fine[j] = fma((float)i + f, h, tn);
  }
  // Merge the two sorted lists; deltas span the midpoints to the neighbours (t_near and t_far at the ends).
  const size_t s0 = (size_t)r * N_ALL;
  uint a = 0, b = 0;
  float t_prev = 0.0f, lower = tn;
  for (uint k = 0; k < N_ALL; ++k) {
    const float t = (b >= N_FINE || (a < N_COARSE && t_coarse[c0 + a] <= fine[b])) ? t_coarse[c0 + a++] : fine[b++];
    t_out[s0 + k] = t;
    if (k > 0) {
      const float mid = 0.5f * (t_prev + t);
      delta_out[s0 + k - 1] = mid - lower;
      lower = mid;
    }
    t_prev = t;
    const float3 x = fma(t, d, o);
    store_tiled3(positions, 3, s0 + k, 0, x);
  }
  delta_out[s0 + N_ALL - 1] = tf - lower;
}
