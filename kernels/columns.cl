// columns.cl: moving column ranges between BatchMatrix objects (tiled layout, see relit/nn/batch.hpp) — how
// the method assembles the renderer's per-sample properties from its networks' outputs, and splits the
// property gradients back. One work-item per 16-sample tile, one float16 per column.
#include "layout.clh"

// dst[:, dst_col + j] = scale * src[:, src_col + j] (+ dst[:, dst_col + j] when accumulate), j < count.
__kernel void copy_columns(const uint n_tiles, const uint count, __global const float* restrict src,
                           const uint src_cols, const uint src_col, __global float* restrict dst, const uint dst_cols,
                           const uint dst_col, const float scale, const uint accumulate) {
  const size_t t = get_global_id(0);
  if (t >= n_tiles) return;
  for (uint j = 0; j < count; ++j) {
    const float16 v = scale * tile_load(src, t, src_cols, src_col + j);
    __global float* out = dst + tile_offset(t, dst_cols, dst_col + j);
    vstore16(accumulate ? v + vload16(0, out) : v, 0, out);
  }
}

// m[:, col + j] *= factor[:, 0] for j < count, in place (factor: a 1-column tiled matrix of the same batch).
__kernel void multiply_columns(const uint n_tiles, const uint count, __global const float* restrict factor,
                               __global float* restrict m, const uint cols, const uint col) {
  const size_t t = get_global_id(0);
  if (t >= n_tiles) return;
  const float16 f = tile_load(factor, t, 1, 0);
  for (uint j = 0; j < count; ++j) {
    __global float* p = m + tile_offset(t, cols, col + j);
    vstore16(f * vload16(0, p), 0, p);
  }
}
