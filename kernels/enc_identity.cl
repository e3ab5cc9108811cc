// enc_identity.cl: the Identity encoding, y = scale * x + offset, and its input gradient.
// One work-item per tile of 16 samples (see enc_common.clh); `n_tiles` = padded batch / 16.
#include "enc_common.clh"

__kernel void identity_forward(const uint n_tiles, const uint n_dims, const float scale, const float offset,
                               __global const float* restrict in, const uint in_cols, const uint in_col,
                               __global float* restrict out, const uint out_cols, const uint out_col) {
  const size_t t = get_global_id(0);
  if (t >= n_tiles) return;
  for (uint d = 0; d < n_dims; ++d)
    tile_store(out, t, out_cols, out_col + d,
               fma((float16)scale, tile_load(in, t, in_cols, in_col + d), (float16)offset));
}

__kernel void identity_backward(const uint n_tiles, const uint n_dims, const float scale,
                                __global const float* restrict d_out, const uint out_cols, const uint out_col,
                                __global float* restrict d_in, const uint in_cols, const uint in_col) {
  const size_t t = get_global_id(0);
  if (t >= n_tiles) return;
  for (uint d = 0; d < n_dims; ++d)
    tile_store(d_in, t, in_cols, in_col + d, scale * tile_load(d_out, t, out_cols, out_col + d));
}
