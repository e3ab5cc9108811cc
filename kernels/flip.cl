// flip.cl: the FLIP image difference (Andersson, Nilsson, Akenine-Möller, Oskarsson, Åström, Fairchild, HPG 2020)
// and its HDR form (Andersson, Nilsson, Shirley, Akenine-Möller, Eurographics 2021; Ray Tracing Gems II, 2021), one
// exposure at a time. The host (lib/src/metrics/flip.cpp) builds the filters, picks the exposures and keeps the
// per-pixel maximum over them in `error` (docs/renderer.md, Metrics).
//
// Per exposure, for the test image (a, "prediction") and the reference (b):
//   flip_prepare   linear RGB -> exposed, tone-mapped (ACES) or clamped -> YCxCz: ycc[p] = (Y, Cx, Cz, -)
//   flip_rows      the 1-D filters along x (clamp-to-edge): rows[p], a float8 (see TAPS)
//   flip_columns   the same along y, then the colour error (Hunt-adjusted L*a*b*, HyAB, redistributed), the
//                  feature error (edges, points), FLIP = colour^(1 - feature), max into error[p]
//
// TAPS (2 radius + 1 float8, from the host): the separated filters of the two pipelines, zero-padded to one radius:
//   s0 Y  (achromatic CSF)   s1 Cx (red-green CSF)   s2, s3 Cz (blue-yellow CSF: a sum of two Gaussians, each
//   separable, their results added)   s4 Gaussian   s5 its 1st derivative   s6 its 2nd derivative (the edge
//   and point detectors: derivative along one axis times the Gaussian along the other)   s7 unused
// rows[p] holds the same lanes filtered along x: s0..s3 the colour channels, s4..s6 the normalised
// achromatic value (Y + 16) / 116 convolved with the Gaussian, 1st and 2nd derivative.
//
// Pixels are row-major, p = y * width + x; images are interleaved with `channels` floats per pixel (R, G, B
// from the first three; one channel is grey).

// D65 white and the sRGB primaries (linear RGB <-> XYZ), as the FLIP reference uses them.
#define FLIP_WHITE_X 0.950428545f
#define FLIP_WHITE_Z 1.088900371f

inline float3 flip_rgb_to_xyz(float3 c) {
  return (float3)(dot(c, (float3)(10135552.0f / 24577794.0f, 8788810.0f / 24577794.0f, 4435075.0f / 24577794.0f)),
                  dot(c, (float3)(2613072.0f / 12288897.0f, 8788810.0f / 12288897.0f, 887015.0f / 12288897.0f)),
                  dot(c, (float3)(1425312.0f / 73733382.0f, 8788810.0f / 73733382.0f, 70074185.0f / 73733382.0f)));
}

inline float3 flip_xyz_to_rgb(float3 c) {
  return (float3)(dot(c, (float3)(3.241003275f, -1.537398934f, -0.498615861f)),
                  dot(c, (float3)(-0.969224334f, 1.875930071f, 0.041554224f)),
                  dot(c, (float3)(0.055639423f, -0.204011202f, 1.057148933f)));
}

inline float3 flip_xyz_to_ycxcz(float3 c) {
  c /= (float3)(FLIP_WHITE_X, 1.0f, FLIP_WHITE_Z);
  return (float3)(116.0f * c.y - 16.0f, 500.0f * (c.x - c.y), 200.0f * (c.y - c.z));
}

inline float3 flip_ycxcz_to_xyz(float3 c) {
  const float y = (c.x + 16.0f) / 116.0f;
  return (float3)(y + c.y / 500.0f, y, y - c.z / 200.0f) * (float3)(FLIP_WHITE_X, 1.0f, FLIP_WHITE_Z);
}

inline float flip_lab_f(float t) {
  const float delta = 6.0f / 29.0f;
  return t > delta * delta * delta ? cbrt(t) : t / (3.0f * delta * delta) + 4.0f / 29.0f;
}

// CIE L*a*b* with the Hunt adjustment (a*, b* scaled by L* / 100).
inline float3 flip_hunt_lab(float3 rgb) {
  float3 c = flip_rgb_to_xyz(rgb) / (float3)(FLIP_WHITE_X, 1.0f, FLIP_WHITE_Z);
  c = (float3)(flip_lab_f(c.x), flip_lab_f(c.y), flip_lab_f(c.z));
  const float l = 116.0f * c.y - 16.0f;
  return (float3)(l, 0.01f * l * 500.0f * (c.x - c.y), 0.01f * l * 200.0f * (c.y - c.z));
}

// ACES filmic curve (Narkowicz's fit) with the 0.6 pre-exposure folded into its coefficients, clamped to [0, 1].
inline float3 flip_aces(float3 x) {
  const float3 num = x * (0.6f * 0.6f * 2.51f * x + 0.6f * 0.03f);
  const float3 den = x * (0.6f * 0.6f * 2.43f * x + 0.6f * 0.59f) + 0.14f;
  return clamp(num / den, 0.0f, 1.0f);
}

// ycc_a[p], ycc_b[p] = YCxCz of the tone-mapped pixel: hdr != 0: ACES(scale * rgb) (scale = 2^exposure);
// hdr == 0: rgb clamped to [0, 1] (LDR-FLIP of linear images).
__kernel void flip_prepare(const uint n, const uint channels, const float scale, const uint hdr,
                           __global const float* restrict a, __global const float* restrict b,
                           __global float4* restrict ycc_a, __global float4* restrict ycc_b) {
  const size_t p = get_global_id(0);
  if (p >= n) return;
  const size_t i = p * channels;
  const uint g = channels >= 3 ? 1 : 0;  // grey: every channel from the first
  float3 ca = (float3)(a[i], a[i + g], a[i + 2 * g]), cb = (float3)(b[i], b[i + g], b[i + 2 * g]);
  if (hdr) {
    ca = flip_aces(scale * ca);
    cb = flip_aces(scale * cb);
  } else {
    ca = clamp(ca, 0.0f, 1.0f);
    cb = clamp(cb, 0.0f, 1.0f);
  }
  ycc_a[p] = (float4)(flip_xyz_to_ycxcz(flip_rgb_to_xyz(ca)), 0.0f);
  ycc_b[p] = (float4)(flip_xyz_to_ycxcz(flip_rgb_to_xyz(cb)), 0.0f);
}

inline float8 flip_row_taps(float4 c, float8 t) {
  const float grey = (c.x + 16.0f) / 116.0f;
  return t * (float8)(c.x, c.y, c.z, c.z, grey, grey, grey, 0.0f);
}

// rows_*[p] = the TAPS filters along x at pixel p (edges clamp).
__kernel void flip_rows(const uint width, const uint height, const int radius, __constant float8* taps,
                        __global const float4* restrict ycc_a, __global const float4* restrict ycc_b,
                        __global float8* restrict rows_a, __global float8* restrict rows_b) {
  const size_t p = get_global_id(0);
  if (p >= (size_t)width * height) return;
  const int x = (int)(p % width);
  const size_t row = p - x;
  float8 sa = 0.0f, sb = 0.0f;
  for (int k = -radius; k <= radius; ++k) {
    const size_t q = row + clamp(x + k, 0, (int)width - 1);
    const float8 t = taps[k + radius];
    sa += flip_row_taps(ycc_a[q], t);
    sb += flip_row_taps(ycc_b[q], t);
  }
  rows_a[p] = sa;
  rows_b[p] = sb;
}

// The filters along y of one image at pixel (x, y): the CSF-filtered YCxCz in `colour` and the edge and point
// responses' magnitudes in `features` (x: edge, y: point).
inline void flip_filter_columns(const uint width, const uint height, const int radius, __constant float8* taps,
                                __global const float8* restrict rows, const int x, const int y, float3* colour,
                                float2* features) {
  float3 c = 0.0f;
  float4 d = 0.0f;  // x: d/dx, y: d/dy, z: d2/dx2, w: d2/dy2
  for (int k = -radius; k <= radius; ++k) {
    const float8 r = rows[(size_t)clamp(y + k, 0, (int)height - 1) * width + x];
    const float8 t = taps[k + radius];
    c += (float3)(t.s0 * r.s0, t.s1 * r.s1, fma(t.s2, r.s2, t.s3 * r.s3));
    d += (float4)(t.s4 * r.s5, t.s5 * r.s4, t.s4 * r.s6, t.s6 * r.s4);
  }
  *colour = flip_hunt_lab(clamp(flip_xyz_to_rgb(flip_ycxcz_to_xyz(c)), 0.0f, 1.0f));
  *features = (float2)(hypot(d.x, d.y), hypot(d.z, d.w));
}

// error[p] = max(error[p], FLIP of this exposure); first != 0: error[p] = FLIP (the first exposure).
// cmax: the largest colour difference (HyAB of green and blue)^0.7; pccmax = 0.4 cmax.
__kernel void flip_columns(const uint width, const uint height, const int radius, __constant float8* taps,
                           __global const float8* restrict rows_a, __global const float8* restrict rows_b,
                           const float cmax, const float pccmax, const uint first, __global float* restrict error) {
  const size_t p = get_global_id(0);
  if (p >= (size_t)width * height) return;
  const int x = (int)(p % width), y = (int)(p / width);
  float3 ca, cb;
  float2 fa, fb;
  flip_filter_columns(width, height, radius, taps, rows_a, x, y, &ca, &fa);
  flip_filter_columns(width, height, radius, taps, rows_b, x, y, &cb, &fb);

  // HyAB: city-block in L, Euclidean in (a, b); then compressed and redistributed so that pccmax maps to 0.95.
  const float hyab = fabs(ca.x - cb.x) + hypot(ca.y - cb.y, ca.z - cb.z);
  const float e = pow(hyab, 0.7f);
  const float colour = e < pccmax ? e * (0.95f / pccmax) : 0.95f + (e - pccmax) / (cmax - pccmax) * 0.05f;

  const float2 df = fabs(fa - fb);
  const float feature = sqrt(fmax(df.x, df.y) * M_SQRT1_2_F);  // (max / sqrt 2)^0.5
  const float flip = pow(colour, 1.0f - feature);
  error[p] = first ? flip : fmax(error[p], flip);
}
