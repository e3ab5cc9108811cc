// flip.cl: the FLIP image difference (Andersson, Nilsson, Akenine-Möller, Oskarsson, Åström, Fairchild, HPG 2020)
// and its HDR form (Andersson, Nilsson, Shirley, Akenine-Möller, Eurographics 2021; Ray Tracing Gems II, 2021), one
// exposure at a time. The host (lib/src/metrics/flip.cpp) builds the filters, picks the exposures and keeps the
// per-pixel maximum over them in `error` (docs/renderer.md, Metrics).
//
// Per exposure, for the test image (a, "prediction") and the reference (b):
//   flip_prepare   linear RGB -> exposed, tone-mapped (ACES) or clamped -> YCxCz, in planes (ycc)
//   flip_rows      the 1-D filters of TAPS along x (rows)
//   flip_columns   the same along y (columns)
//   flip_error     the colour error (clamped to the RGB cube, Hunt-adjusted L*a*b*, HyAB, redistributed) and the
//                  feature error (edges, points) of the filtered images; FLIP = colour^(1 - feature), its maximum
//                  over the exposures so far in error
//
// TAPS (2 radius + 1 float8, from the host): the separated filters of the two pipelines, zero-padded to one radius:
//   s0 Y  (achromatic CSF)   s1 Cx (red-green CSF)   s2, s3 Cz (blue-yellow CSF: a sum of two Gaussians, each
//   separable, their results added)   s4 Gaussian   s5 its 1st derivative   s6 its 2nd derivative (the edge
//   and point detectors: derivative along one axis times the Gaussian along the other)   s7 unused
// The filters' edges clamp (the nearest pixel repeats), as in NVIDIA's implementation.
//
// The input images are interleaved, `channels` floats per pixel (R, G, B from the first three; one channel is
// grey), row-major; the planes between the kernels and `error` have rows of `pitch` floats (below).

// D65 white and the sRGB primaries (linear RGB -> XYZ; flip_colour16 has the inverse), as FLIP defines them.
// No contraction of a * b + c into fma: the test image and the reference go through the same arithmetic, and the
// compiler must not fuse it differently for the two (NVIDIA's did: identical images differed by 6e-7).
#pragma OPENCL FP_CONTRACT OFF

#define FLIP_WHITE_X 0.950428545f
#define FLIP_WHITE_Z 1.088900371f

inline float3 flip_rgb_to_xyz(float3 c) {
  return (float3)(dot(c, (float3)(10135552.0f / 24577794.0f, 8788810.0f / 24577794.0f, 4435075.0f / 24577794.0f)),
                  dot(c, (float3)(2613072.0f / 12288897.0f, 8788810.0f / 12288897.0f, 887015.0f / 12288897.0f)),
                  dot(c, (float3)(1425312.0f / 73733382.0f, 8788810.0f / 73733382.0f, 70074185.0f / 73733382.0f)));
}

inline float3 flip_xyz_to_ycxcz(float3 c) {
  c /= (float3)(FLIP_WHITE_X, 1.0f, FLIP_WHITE_Z);
  return (float3)(116.0f * c.y - 16.0f, 500.0f * (c.x - c.y), 200.0f * (c.y - c.z));
}

// ACES filmic curve (Narkowicz's fit) with the 0.6 pre-exposure folded into its coefficients, clamped to [0, 1].
inline float3 flip_aces(float3 x) {
  const float3 num = x * (0.6f * 0.6f * 2.51f * x + 0.6f * 0.03f);
  const float3 den = x * (0.6f * 0.6f * 2.43f * x + 0.6f * 0.59f) + 0.14f;
  return clamp(num / den, 0.0f, 1.0f);
}

// Rows of the planes below are padded: `pitch` (a multiple of FLIP_CHUNK, >= width) floats, so that the filters
// work on whole chunks of FLIP_CHUNK pixels in float16 arithmetic (the CPU drivers do not vectorise these loops
// across work-items); what lands in the padding is never read back into the error.
#define FLIP_CHUNK 16

// Seven planes' FLIP_CHUNK pixels at out, out + m, ..., out + 6 m (flip_rows and flip_columns write alike).
inline void flip_store7(__global float* out, const size_t m, float16 a, float16 b, float16 c, float16 d, float16 e,
                        float16 f, float16 g) {
  vstore16(a, 0, out);
  vstore16(b, 0, out + m);
  vstore16(c, 0, out + 2 * m);
  vstore16(d, 0, out + 3 * m);
  vstore16(e, 0, out + 4 * m);
  vstore16(f, 0, out + 5 * m);
  vstore16(g, 0, out + 6 * m);
}

// ycc: the YCxCz of the tone-mapped pixels, plane 3 i + c (i: 0 the test image a, 1 the reference b; c: Y, Cx, Cz)
// with rows of span = pitch + 2 radius floats: entry j of row y is pixel x = j - radius, clamped to the image, so
// that flip_rows reads past the edges without tests. Work-items (span, height). hdr != 0: ACES(scale * rgb) (scale
// = 2^exposure); hdr == 0: rgb clamped to [0, 1] (LDR-FLIP of linear images).
__kernel void flip_prepare(const uint width, const uint height, const uint span, const int radius, const uint channels,
                           const float scale, const uint hdr, __global const float* restrict a,
                           __global const float* restrict b, __global float* restrict ycc) {
  const int j = get_global_id(0);
  const size_t y = get_global_id(1);
  if (j >= (int)span || y >= height) return;
  const size_t i = (y * width + clamp(j - radius, 0, (int)width - 1)) * channels;
  const uint g = channels >= 3 ? 1 : 0;  // grey: every channel from the first
  float3 ca = (float3)(a[i], a[i + g], a[i + 2 * g]), cb = (float3)(b[i], b[i + g], b[i + 2 * g]);
  if (hdr) {
    ca = flip_aces(scale * ca);
    cb = flip_aces(scale * cb);
  } else {
    ca = clamp(ca, 0.0f, 1.0f);
    cb = clamp(cb, 0.0f, 1.0f);
  }
  ca = flip_xyz_to_ycxcz(flip_rgb_to_xyz(ca));
  cb = flip_xyz_to_ycxcz(flip_rgb_to_xyz(cb));
  const size_t m = (size_t)span * height, o = y * span + j;
  ycc[o] = ca.x;
  ycc[m + o] = ca.y;
  ycc[2 * m + o] = ca.z;
  ycc[3 * m + o] = cb.x;
  ycc[4 * m + o] = cb.y;
  ycc[5 * m + o] = cb.z;
}

// rows: the TAPS filters along x, plane 7 i + l (i: image, l: lane s0..s6 of TAPS) with rows of `pitch` floats: pixel
// (x, y) at (7 i + l) pitch height + y pitch + x. One work-item per FLIP_CHUNK pixels of a row (work-items
// (pitch / FLIP_CHUNK, height)).
__kernel void flip_rows(const uint height, const uint pitch, const int radius, __constant float8* taps,
                        __global const float* restrict ycc, __global float* restrict rows) {
  const size_t x0 = get_global_id(0) * FLIP_CHUNK, y = get_global_id(1);
  if (x0 >= pitch || y >= height) return;
  const size_t span = pitch + 2 * radius, my = span * height, m = (size_t)pitch * height;
  for (int i = 0; i < 2; ++i) {
    __global const float* c = ycc + 3 * i * my + y * span + radius + x0;  // pixel x0
    float16 s0 = 0.0f, s1 = 0.0f, s2 = 0.0f, s3 = 0.0f, s4 = 0.0f, s5 = 0.0f, s6 = 0.0f;
    for (int k = -radius; k <= radius; ++k) {
      const float8 t = taps[k + radius];
      const float16 lum = vload16(0, c + k), cz = vload16(0, c + 2 * my + k);
      const float16 grey = (lum + 16.0f) / 116.0f;
      s0 = fma(t.s0, lum, s0);
      s1 = fma(t.s1, vload16(0, c + my + k), s1);
      s2 = fma(t.s2, cz, s2);
      s3 = fma(t.s3, cz, s3);
      s4 = fma(t.s4, grey, s4);
      s5 = fma(t.s5, grey, s5);
      s6 = fma(t.s6, grey, s6);
    }
    flip_store7(rows + 7 * i * m + y * pitch + x0, m, s0, s1, s2, s3, s4, s5, s6);
  }
}

// columns: rows' filters along y (edges clamp), laid out like rows: plane 7 i + l of image i holds, for l = 0..6,
// the CSF-filtered Y, Cx, Cz, then d/dx, d/dy, d2/dx2, d2/dy2 of the normalised achromatic value (a derivative
// along one axis, the Gaussian along the other). Work-items as flip_rows.
__kernel void flip_columns(const uint height, const uint pitch, const int radius, __constant float8* taps,
                           __global const float* restrict rows, __global float* restrict columns) {
  const size_t x0 = get_global_id(0) * FLIP_CHUNK, y = get_global_id(1);
  if (x0 >= pitch || y >= height) return;
  const size_t m = (size_t)pitch * height;
  for (int i = 0; i < 2; ++i) {
    __global const float* r = rows + 7 * i * m + x0;
    float16 c0 = 0.0f, c1 = 0.0f, c2 = 0.0f, dx = 0.0f, dy = 0.0f, ddx = 0.0f, ddy = 0.0f;
    for (int k = -radius; k <= radius; ++k) {
      const size_t q = (size_t)clamp((int)y + k, 0, (int)height - 1) * pitch;
      const float8 t = taps[k + radius];
      c0 = fma(t.s0, vload16(0, r + q), c0);
      c1 = fma(t.s1, vload16(0, r + m + q), c1);
      c2 = fma(t.s2, vload16(0, r + 2 * m + q), fma(t.s3, vload16(0, r + 3 * m + q), c2));
      const float16 g = vload16(0, r + 4 * m + q);
      dx = fma(t.s4, vload16(0, r + 5 * m + q), dx);  // d/dx along x, the Gaussian along y
      dy = fma(t.s5, g, dy);                          // the Gaussian along x, d/dy along y
      ddx = fma(t.s4, vload16(0, r + 6 * m + q), ddx);
      ddy = fma(t.s6, g, ddy);
    }
    flip_store7(columns + 7 * i * m + y * pitch + x0, m, c0, c1, c2, dx, dy, ddx, ddy);
  }
}

// The error's arithmetic on FLIP_CHUNK pixels at a time, one float16 per channel. x^y for x >= 0 (0^y = 0) through
// exp2 and log2, and lengths through sqrt: pow, cbrt and hypot are several times slower on the CPU drivers.
inline float16 flip_pow16(float16 x, float16 y) { return select((float16)0.0f, exp2(y * log2(x)), x > 0.0f); }

inline float16 flip_lab_f16(float16 t) {
  const float delta = 6.0f / 29.0f;
  return select(t / (3.0f * delta * delta) + 4.0f / 29.0f, flip_pow16(t, (float16)(1.0f / 3.0f)),
                t > delta * delta * delta);
}

// An image's filtered colour at q (FLIP_CHUNK pixels, c: its planes of columns): YCxCz -> XYZ -> linear RGB,
// clamped to the RGB cube -> XYZ -> CIE L*a*b* with the Hunt adjustment (a*, b* scaled by L* / 100), in lab[0..2].
inline void flip_colour16(__global const float* restrict c, const size_t m, const size_t q, float16* lab) {
  const float16 fy = (vload16(0, c + q) + 16.0f) / 116.0f;
  const float16 x = (fy + vload16(0, c + m + q) / 500.0f) * FLIP_WHITE_X,
                z = (fy - vload16(0, c + 2 * m + q) / 200.0f) * FLIP_WHITE_Z;
  const float16 r = clamp(3.241003275f * x - 1.537398934f * fy - 0.498615861f * z, 0.0f, 1.0f);
  const float16 g = clamp(-0.969224334f * x + 1.875930071f * fy + 0.041554224f * z, 0.0f, 1.0f);
  const float16 b = clamp(0.055639423f * x - 0.204011202f * fy + 1.057148933f * z, 0.0f, 1.0f);
  const float16 lx =
      flip_lab_f16(((10135552.0f / 24577794.0f) * r + (8788810.0f / 24577794.0f) * g + (4435075.0f / 24577794.0f) * b) /
                   FLIP_WHITE_X);
  const float16 ly =
      flip_lab_f16((2613072.0f / 12288897.0f) * r + (8788810.0f / 12288897.0f) * g + (887015.0f / 12288897.0f) * b);
  const float16 lz =
      flip_lab_f16(((1425312.0f / 73733382.0f) * r + (8788810.0f / 73733382.0f) * g + (70074185.0f / 73733382.0f) * b) /
                   FLIP_WHITE_Z);
  lab[0] = 116.0f * ly - 16.0f;
  lab[1] = 0.01f * lab[0] * 500.0f * (lx - ly);
  lab[2] = 0.01f * lab[0] * 200.0f * (ly - lz);
}

inline float16 flip_length16(float16 x, float16 y) { return sqrt(fma(x, x, y * y)); }

// error[q] = max(error[q], FLIP of this exposure) for the FLIP_CHUNK pixels from q = y pitch + x0 (error has rows
// of pitch floats too; work-items as flip_rows); first != 0: error[q] = FLIP (the first exposure). cmax: the largest
// colour difference (HyAB of green and blue)^0.7; pccmax = 0.4 cmax.
__kernel void flip_error(const uint height, const uint pitch, __global const float* restrict columns, const float cmax,
                         const float pccmax, const uint first, __global float* restrict error) {
  const size_t x0 = get_global_id(0) * FLIP_CHUNK, y = get_global_id(1);
  if (x0 >= pitch || y >= height) return;
  const size_t m = (size_t)pitch * height, q = y * pitch + x0;
  __global const float* cb = columns + 7 * m;
  float16 la[3], lb[3];
  flip_colour16(columns, m, q, la);
  flip_colour16(cb, m, q, lb);
  // HyAB: city-block in L, Euclidean in (a, b); then compressed and redistributed so that pccmax maps to 0.95.
  const float16 hyab = fabs(la[0] - lb[0]) + flip_length16(la[1] - lb[1], la[2] - lb[2]);
  const float16 e = flip_pow16(hyab, (float16)0.7f);
  const float16 colour = select(0.95f + (e - pccmax) / (cmax - pccmax) * 0.05f, e * (0.95f / pccmax), e < pccmax);

  const float16 edges = fabs(flip_length16(vload16(0, columns + 3 * m + q), vload16(0, columns + 4 * m + q)) -
                             flip_length16(vload16(0, cb + 3 * m + q), vload16(0, cb + 4 * m + q)));
  const float16 points = fabs(flip_length16(vload16(0, columns + 5 * m + q), vload16(0, columns + 6 * m + q)) -
                              flip_length16(vload16(0, cb + 5 * m + q), vload16(0, cb + 6 * m + q)));
  const float16 feature = sqrt(fmax(edges, points) * M_SQRT1_2_F);  // (max / sqrt 2)^0.5
  // x^0 = 1, 0^0 included
  const float16 flip = select((float16)1.0f, flip_pow16(colour, 1.0f - feature), feature < 1.0f);
  vstore16(first ? flip : fmax(vload16(0, error + q), flip), 0, error + q);
}
