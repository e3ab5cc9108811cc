// columns.cl: moving column ranges between BatchMatrix objects (tiled layout, see relit/nn/batch.hpp) — how
// the method assembles the renderer's per-sample properties from its networks' outputs, and splits the
// property gradients back. One work-item per 16-sample tile, one float16 per column.

// dst[:, dst_col + j] = scale * src[:, src_col + j] (+ dst[:, dst_col + j] when accumulate), j < count.
__kernel void copy_columns(const uint n_tiles, const uint count, __global const float* restrict src,
                           const uint src_cols, const uint src_col, __global float* restrict dst, const uint dst_cols,
                           const uint dst_col, const float scale, const uint accumulate) {
  const size_t t = get_global_id(0);
  if (t >= n_tiles) return;
  for (uint j = 0; j < count; ++j) {
    const float16 v = scale * vload16(0, src + (t * src_cols + src_col + j) * 16);
    __global float* out = dst + (t * dst_cols + dst_col + j) * 16;
    vstore16(accumulate ? v + vload16(0, out) : v, 0, out);
  }
}

// Channel-major RGB blocks of `per_channel` columns, scaled per sample by its ray's RGB intensity (ray record
// floats 12..14): dst[ch * per_channel + j] = I_ch(ray(s)) * src[ch * per_channel + j]. Indirect light is linear
// in the light's intensity, so the SH head predicts light per unit intensity (DESIGN §4.3). `scale` multiplies
// every value (the model's intensity normalisation).
__kernel void scale_rgb_by_ray_intensity(const uint n_tiles, const uint per_channel, const uint samples_per_ray,
                                         const float scale, __global const float* restrict rays,
                                         __global const float* restrict src, const uint src_cols, const uint src_col,
                                         __global float* restrict dst, const uint dst_cols, const uint dst_col) {
  const size_t t = get_global_id(0);
  if (t >= n_tiles) return;
  __global const float* ray = rays + (size_t)((t * 16) / samples_per_ray) * 20;  // samples_per_ray % 16 == 0
  for (uint ch = 0; ch < 3; ++ch) {
    const float intensity = scale * ray[12 + ch];
    for (uint j = 0; j < per_channel; ++j) {
      const uint c = ch * per_channel + j;
      vstore16(intensity * vload16(0, src + (t * src_cols + src_col + c) * 16), 0,
               dst + (t * dst_cols + dst_col + c) * 16);
    }
  }
}

// m[:, col + j] *= factor[:, 0] for j < count, in place (factor: a 1-column tiled matrix of the same batch).
__kernel void multiply_columns(const uint n_tiles, const uint count, __global const float* restrict factor,
                               __global float* restrict m, const uint cols, const uint col) {
  const size_t t = get_global_id(0);
  if (t >= n_tiles) return;
  const float16 f = vload16(0, factor + t * 16);
  for (uint j = 0; j < count; ++j) {
    __global float* p = m + (t * cols + col + j) * 16;
    vstore16(f * vload16(0, p), 0, p);
  }
}
