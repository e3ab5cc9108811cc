// enc_sh.cl: real spherical harmonics of a unit direction (Zheng et al. 2021, eq. 2, Condon-Shortley phase inside
// P_l^m), degree DEGREE (bands l = 0 .. DEGREE-1, DEGREE^2 outputs; output column l*l + l + m), and the gradient with
// respect to the direction.
//
// No trigonometry: with (x, y, z) = (sin t cos p, sin t sin p, cos t),
//   P_l^m(cos t) = sin^m t * Q_l^m(z),     sin^m t cos(m p) = C_m = Re (x + i y)^m,   sin^m t sin(m p) = S_m = Im
// so  Y_l^m = N_l^m Q_l^m(z) C_m (m > 0),  N_l^0 Q_l^0(z) (m = 0),  N_l^|m| Q_l^|m|(z) S_|m| (m < 0), where
//   Q_m^m = (-1)^m (2m-1)!!,  Q_{m+1}^m = (2m+1) z Q_m^m,  Q_l^m = ((2l-1) z Q_{l-1}^m - (l+m-1) Q_{l-2}^m) / (l-m)
//   C_m = x C_{m-1} - y S_{m-1},  S_m = x S_{m-1} + y C_{m-1}      (polynomials: exact for any (x, y, z))
// The direction is used as given (not renormalised); the gradient is that of these polynomials.
#include "enc_common.clh"

#ifndef DEGREE
#define DEGREE 4
#endif
#if DEGREE < 1 || DEGREE > 10
#error "DEGREE must be in [1, 10]"
#endif

// N_l^m = sqrt((2l+1)/(4 pi) (l-m)!/(l+m)!), times sqrt(2) for m > 0; index l(l+1)/2 + m.
__constant float sh_norm[55] = {
    2.820947918e-01f, 4.886025119e-01f, 4.886025119e-01f, 6.307831305e-01f, 3.641828102e-01f, 1.820914051e-01f,
    7.463526652e-01f, 3.046971996e-01f, 9.635371475e-02f, 3.933623933e-02f, 8.462843753e-01f, 2.676186174e-01f,
    6.307831305e-02f, 1.685838828e-02f, 5.960340338e-03f, 9.356025796e-01f, 2.415715473e-01f, 4.565273129e-02f,
    9.318824751e-03f, 2.196468058e-03f, 6.945841871e-04f, 1.017107236e+00f, 2.219509952e-01f, 3.509353370e-02f,
    5.848922283e-03f, 1.067862224e-03f, 2.276689911e-04f, 6.572237664e-05f, 1.092548431e+00f, 2.064722459e-01f,
    2.809731381e-02f, 3.973560225e-03f, 5.990367431e-04f, 9.983945719e-05f, 1.958012848e-05f, 5.233009454e-06f,
    1.163106623e+00f, 1.938511038e-01f, 2.316963852e-02f, 2.851985351e-03f, 3.681897256e-04f, 5.105872827e-05f,
    7.878532816e-06f, 1.438416714e-06f, 3.596041786e-07f, 1.229622690e+00f, 1.833013281e-01f, 1.953998723e-02f,
    2.131987394e-03f, 2.414000363e-04f, 2.885282297e-05f, 3.724883429e-06f, 5.376406126e-07f, 9.220460437e-08f,
    2.173283367e-08f};

// Q_m^m = (-1)^m (2m-1)!!
inline float sh_qmm(int m) {
  float q = 1.0f;
  for (int i = 1; i <= m; ++i) q *= -(float)(2 * i - 1);
  return q;
}

__kernel void sh_forward(const uint n_tiles, __global const float* restrict in, const uint in_cols, const uint in_col,
                         __global float* restrict out, const uint out_cols, const uint out_col) {
  const size_t t = get_global_id(0);
  if (t >= n_tiles) return;
  const float16 x = tile_load(in, t, in_cols, in_col), y = tile_load(in, t, in_cols, in_col + 1),
                z = tile_load(in, t, in_cols, in_col + 2);
  float16 cm = (float16)1.0f, sm = (float16)0.0f;  // C_m, S_m
#pragma unroll
  for (int m = 0; m < DEGREE; ++m) {
    if (m > 0) {
      const float16 c = fma(x, cm, -y * sm);
      sm = fma(x, sm, y * cm);
      cm = c;
    }
    float16 q2 = (float16)0.0f, q1 = (float16)0.0f;  // Q_{l-2}^m, Q_{l-1}^m
#pragma unroll
    for (int l = m; l < DEGREE; ++l) {
      float16 q;
      if (l == m)
        q = (float16)sh_qmm(m);
      else if (l == m + 1)
        q = (float)(2 * m + 1) * z * q1;
      else
        q = ((float)(2 * l - 1) * z * q1 - (float)(l + m - 1) * q2) * (1.0f / (float)(l - m));
      q2 = q1;
      q1 = q;
      const float16 nq = sh_norm[l * (l + 1) / 2 + m] * q;
      if (m == 0) {
        tile_store(out, t, out_cols, out_col + l * l + l, nq);
      } else {
        tile_store(out, t, out_cols, out_col + l * l + l + m, nq * cm);
        tile_store(out, t, out_cols, out_col + l * l + l - m, nq * sm);
      }
    }
  }
}

// dL/d(x, y, z) = sum_lm dL/dY_lm * grad Y_lm, with
//   d C_m/dx = m C_{m-1}, d C_m/dy = -m S_{m-1}, d S_m/dx = m S_{m-1}, d S_m/dy = m C_{m-1}
//   dQ_l^m/dz = ((2l-1) (Q_{l-1}^m + z dQ_{l-1}^m) - (l+m-1) dQ_{l-2}^m) / (l-m),  dQ_m^m = 0
__kernel void sh_backward(const uint n_tiles, __global const float* restrict in, const uint in_cols, const uint in_col,
                          __global const float* restrict d_out, const uint out_cols, const uint out_col,
                          __global float* restrict d_in, const uint d_in_cols) {
  const size_t t = get_global_id(0);
  if (t >= n_tiles) return;
  const float16 x = tile_load(in, t, in_cols, in_col), y = tile_load(in, t, in_cols, in_col + 1),
                z = tile_load(in, t, in_cols, in_col + 2);
  float16 gx = (float16)0.0f, gy = (float16)0.0f, gz = (float16)0.0f;
  float16 cm = (float16)1.0f, sm = (float16)0.0f, cp = (float16)0.0f, sp = (float16)0.0f;  // C_m, S_m, C_{m-1}, S_{m-1}
#pragma unroll
  for (int m = 0; m < DEGREE; ++m) {
    if (m > 0) {
      cp = cm;
      sp = sm;
      cm = fma(x, cp, -y * sp);
      sm = fma(x, sp, y * cp);
    }
    float16 q2 = (float16)0.0f, q1 = (float16)0.0f, dq2 = (float16)0.0f, dq1 = (float16)0.0f;
#pragma unroll
    for (int l = m; l < DEGREE; ++l) {
      float16 q, dq;
      if (l == m) {
        q = (float16)sh_qmm(m);
        dq = (float16)0.0f;
      } else if (l == m + 1) {
        q = (float)(2 * m + 1) * z * q1;
        dq = (float)(2 * m + 1) * q1;
      } else {
        const float inv = 1.0f / (float)(l - m);
        q = ((float)(2 * l - 1) * z * q1 - (float)(l + m - 1) * q2) * inv;
        dq = ((float)(2 * l - 1) * fma(z, dq1, q1) - (float)(l + m - 1) * dq2) * inv;
      }
      q2 = q1;
      q1 = q;
      dq2 = dq1;
      dq1 = dq;
      const float n = sh_norm[l * (l + 1) / 2 + m];
      if (m == 0) {
        gz = fma(tile_load(d_out, t, out_cols, out_col + l * l + l), n * dq, gz);
      } else {
        const float16 gc = tile_load(d_out, t, out_cols, out_col + l * l + l + m);
        const float16 gs = tile_load(d_out, t, out_cols, out_col + l * l + l - m);
        const float16 a = (n * (float)m) * q;  // common factor of the x and y derivatives
        gx = fma(a, fma(gc, cp, gs * sp), gx);
        gy = fma(a, fma(gs, cp, -gc * sp), gy);
        gz = fma(n * dq, fma(gc, cm, gs * sm), gz);
      }
    }
  }
  tile_store(d_in, t, d_in_cols, in_col, gx);
  tile_store(d_in, t, d_in_cols, in_col + 1, gy);
  tile_store(d_in, t, d_in_cols, in_col + 2, gz);
}
