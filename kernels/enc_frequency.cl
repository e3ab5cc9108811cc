// enc_frequency.cl: NeRF positional encoding, sin and cos of 2^k * pi * x for k = 0 .. N_FREQ-1, per input
// dimension, and its input gradient.
//
// Output columns (relative to out_col), for n_dims inputs:
//   [x_0 .. x_{n_dims-1}]                       only with INCLUDE_INPUT
//   then for dim i, octave k:  sin(2^k pi x_i) at base + i*2*N_FREQ + 2k,  cos(2^k pi x_i) at ... + 1
//
// Octaves come from the double-angle recurrences sin 2a = 2 sin a cos a, cos 2a = 1 - 2 sin^2 a, which cost
// 3 FMAs instead of a sin and a cos (a sin costs 30-70 FMA lanes on PoCL). Each step roughly doubles the
// absolute error, so every ANCHOR octaves the recurrence restarts from an exact evaluation: sinpi/cospi of
// 2^k x reduced modulo 2 (2^k x and the reduction are exact in float, so the anchor is accurate to an ulp
// even at high octaves, unlike sin(2^k * pi * x) whose argument already carries a rounding of 2^k*pi*|x|*eps).
// Measured worst absolute error against double over x in [-1, 1] (PoCL, 230k values): re-anchoring every
// 1 octave 1.1e-7, 2: 3.1e-7, 3: 6.7e-7, 4: 2.1e-6, 6 or more: above 1e-5. ANCHOR = 3 is the default.
#include "enc_common.clh"

#ifndef N_FREQ
#define N_FREQ 6
#endif
#ifndef INCLUDE_INPUT
#define INCLUDE_INPUT 0
#endif
#ifndef ANCHOR
#define ANCHOR 3
#endif

// sin(pi * y), cos(pi * y) for y = x * 2^k, with exact reduction of y to [-1, 1].
inline void freq_anchor(float16 x, int k, float16* s, float16* c) {
  // x * 2^k is exact (k < 24; an encoding's inputs are far from overflow), as ldexp(x, k) would be; but
  // Oclgrind 21.10 gets ldexp(float16, int) wrong (sines off by up to 2 in tests/cpp/test_encodings.cpp).
  const float16 y = x * (float)(1u << k);
  const float16 r = y - 2.0f * rint(0.5f * y);  // exact: y and 2*rint(y/2) are floats of the same binade or less
  *s = sinpi(r);
  *c = cospi(r);
}

// sin and cos of octave k from those of octave k - 1 (double-angle), re-anchored every ANCHOR octaves.
inline void freq_octave(float16 x, int k, float16* s, float16* c) {
  if (k % ANCHOR == 0) {
    freq_anchor(x, k, s, c);
  } else {
    const float16 s2 = 2.0f * *s * *c;
    *c = fma(-2.0f * *s, *s, (float16)1.0f);
    *s = s2;
  }
}

__kernel void frequency_forward(const uint n_tiles, const uint n_dims, __global const float* restrict in,
                                const uint in_cols, const uint in_col, __global float* restrict out,
                                const uint out_cols, const uint out_col) {
  const size_t t = get_global_id(0);
  if (t >= n_tiles) return;
  const uint base = out_col + (INCLUDE_INPUT ? n_dims : 0);
  for (uint d = 0; d < n_dims; ++d) {
    const float16 x = tile_load(in, t, in_cols, in_col + d);
    if (INCLUDE_INPUT) tile_store(out, t, out_cols, out_col + d, x);
    float16 s, c;
#pragma unroll
    for (int k = 0; k < N_FREQ; ++k) {
      freq_octave(x, k, &s, &c);
      tile_store(out, t, out_cols, base + d * 2 * N_FREQ + 2 * k, s);
      tile_store(out, t, out_cols, base + d * 2 * N_FREQ + 2 * k + 1, c);
    }
  }
}

// dL/dx_i = [dL/dx_i from the included input] + sum_k 2^k pi (dL/dsin_k cos_k - dL/dcos_k sin_k)
__kernel void frequency_backward(const uint n_tiles, const uint n_dims, __global const float* restrict in,
                                 const uint in_cols, const uint in_col, __global const float* restrict d_out,
                                 const uint out_cols, const uint out_col, __global float* restrict d_in,
                                 const uint d_in_cols) {
  const size_t t = get_global_id(0);
  if (t >= n_tiles) return;
  const uint base = out_col + (INCLUDE_INPUT ? n_dims : 0);
  for (uint d = 0; d < n_dims; ++d) {
    const float16 x = tile_load(in, t, in_cols, in_col + d);
    float16 g = INCLUDE_INPUT ? tile_load(d_out, t, out_cols, out_col + d) : (float16)0.0f;
    float16 s, c;
#pragma unroll
    for (int k = 0; k < N_FREQ; ++k) {
      freq_octave(x, k, &s, &c);
      const float16 gs = tile_load(d_out, t, out_cols, base + d * 2 * N_FREQ + 2 * k);
      const float16 gc = tile_load(d_out, t, out_cols, base + d * 2 * N_FREQ + 2 * k + 1);
      g = fma((float16)(M_PI_F * (float)(1 << k)), fma(gs, c, -gc * s), g);
    }
    tile_store(d_in, t, d_in_cols, in_col + d, g);
  }
}
