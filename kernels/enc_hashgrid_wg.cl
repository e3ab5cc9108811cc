// enc_hashgrid_wg.cl: the work-group variant of the hash-grid kernels (enc_hashgrid.cl has the SIMD variant
// and the grid convention): the same forward pass, parameter gradient and input gradient, shaped for GPUs.
// One work-item per (sample, level) rather than per (16-sample tile, level): consecutive work-items take
// consecutive samples of one level, so their loads of a column of the tiled inputs and stores of an output
// column are coalesced (a tile's 16 samples of one column are 64 contiguous bytes, layout.clh).
//
// Forward (WG_ITEMS samples of one level per group, level-major as in tiny-cuda-nn's kernel_grid, so that the
// groups running at one time read one level's table from cache).
//
// Parameter gradient, deterministic, without atomics: as in the SIMD variant every table entry has one owner
// that adds its contributions in a fixed order, but here a work-group of GRAD_ITEMS owners covers a slab of
// the level's table (work-item i owns range slab * GRAD_ITEMS + i of the level's groups * GRAD_ITEMS ranges).
// The group walks the batch in chunks of GRAD_CHUNK samples: its work-items compute the chunk's corner indices
// and weighted gradients once into local memory (instead of every owner recomputing them, the SIMD variant's
// cost per range), then every owner reads the chunk's pairs in order (the same address for the whole group:
// a broadcast) and adds those that fall into its range to its entries. The pairs are laid out in the order
// (tile, corner, lane), the order in which the SIMD kernel adds them, so every entry receives its additions
// in one fixed order whatever the group count, the chunk size and the device.
//
//   local ids[GRAD_CHUNK * N_CORNERS], weighted gradients wg[.. * FEATS]: pair p = (tile * N_CORNERS + corner)
//   * 16 + lane of the chunk's samples (invalid: samples past the batch, id 0xffffffff, owned by nobody)
//
// Input gradient: one work-item per (sample, level) as in the forward pass; a group holds IN_S samples of
// every level (local id level * IN_S + i), writes each level's dL/dx into local memory and then sums the
// levels of each (sample, axis) in level order.
#include "enc_hashgrid.clh"

#ifndef WG_ITEMS
#define WG_ITEMS 64
#endif
#ifndef GRAD_ITEMS
#define GRAD_ITEMS 64
#endif
#ifndef GRAD_CHUNK
#define GRAD_CHUNK 64
#endif
#ifndef IN_S
#define IN_S 4
#endif
#if GRAD_CHUNK % RELIT_TILE != 0
#error "GRAD_CHUNK must be a multiple of 16"
#endif

#define NO_ENTRY 0xffffffffu

// Cell (first corner) and in-cell position of one sample at `level`: enc_hashgrid.cl's grid_cell, per sample.
inline void grid_cell1(const float* x, uint level, uint* cell, float* frac) {
  const float scale = level_scale[level];
  for (int d = 0; d < DIMS; ++d) {
    const float p = fma(fmin(fmax(x[d], 0.0f), 1.0f), scale, 0.5f);
    const float f = floor(p);
    frac[d] = p - f;
    cell[d] = (uint)f;
  }
}

inline uint grid_index1(const uint* cell, uint level, int c) {
  uint index = 0u;
  if (level_hashed[level]) {
    for (int d = 0; d < DIMS; ++d) index ^= (cell[d] + (uint)((c >> d) & 1)) * grid_prime[d];
    index &= level_size[level] - 1u;
  } else {
    uint stride = 1u;
    for (int d = 0; d < DIMS; ++d) {
      index += (cell[d] + (uint)((c >> d) & 1)) * stride;
      stride *= level_res[level];
    }
  }
  return index;
}

inline float grid_weight1(const float* frac, int c) {
  float w = 1.0f;
  for (int d = 0; d < DIMS; ++d) w *= ((c >> d) & 1) ? frac[d] : 1.0f - frac[d];
  return w;
}

inline void load_input1(__global const float* in, uint in_cols, uint in_col, size_t s, float* x) {
  for (int d = 0; d < DIMS; ++d) x[d] = TILED(in, in_cols, s, in_col + d);
}

// Work-item (level, s) for s < n_padded (the padded batch), `per_level` = n_padded rounded up to WG_ITEMS.
__kernel void hashgrid_wg_forward(const uint n_padded, const uint per_level, __global const float* restrict params,
                                  const uint param_offset, __global const float* restrict in, const uint in_cols,
                                  const uint in_col, __global float* restrict out, const uint out_cols,
                                  const uint out_col) {
  const size_t gid = get_global_id(0);
  const uint level = (uint)(gid / per_level);
  const uint s = (uint)(gid % per_level);
  if (level >= N_LEVELS || s >= n_padded) return;
  __global const float* table = params + param_offset + level_offset[level];
  float x[DIMS], frac[DIMS];
  uint cell[DIMS];
  load_input1(in, in_cols, in_col, s, x);
  grid_cell1(x, level, cell, frac);
  float acc[FEATS];
  for (int f = 0; f < FEATS; ++f) acc[f] = 0.0f;
  for (int c = 0; c < N_CORNERS; ++c) {
    __global const float* entry = table + (size_t)grid_index1(cell, level, c) * FEATS;
    const float w = grid_weight1(frac, c);
    for (int f = 0; f < FEATS; ++f) acc[f] = fma(w, entry[f], acc[f]);
  }
  for (int f = 0; f < FEATS; ++f) TILED(out, out_cols, s, out_col + level * FEATS + f) = acc[f];
}

// dL/d(table): one group per (level, slab), `groups` slabs per level; see the file comment. `n` = logical
// batch size (padding rows contribute nothing), `zero` != 0: overwrite instead of accumulate.
__kernel __attribute__((reqd_work_group_size(GRAD_ITEMS, 1, 1))) void hashgrid_wg_backward_params(
    const uint n, const uint groups, __global const float* restrict in, const uint in_cols, const uint in_col,
    __global const float* restrict d_out, const uint out_cols, const uint out_col, __global float* restrict grads,
    const uint grad_offset, const uint zero) {
  __local uint ids[GRAD_CHUNK * N_CORNERS];
  __local float contrib[GRAD_CHUNK * N_CORNERS * FEATS];
  const uint lid = get_local_id(0);
  const uint level = get_group_id(0) / groups;  // the same for the whole group: no barrier is skipped
  if (level >= N_LEVELS) return;
  const uint range = (get_group_id(0) % groups) * GRAD_ITEMS + lid;
  const ulong n_ranges = (ulong)groups * GRAD_ITEMS;
  const uint lo = (uint)(((ulong)level_size[level] * range) / n_ranges);
  const uint hi = (uint)(((ulong)level_size[level] * (range + 1)) / n_ranges);
  __global float* table = grads + grad_offset + level_offset[level];
  if (zero)
    for (size_t i = (size_t)lo * FEATS; i < (size_t)hi * FEATS; ++i) table[i] = 0.0f;

  for (uint base = 0; base < n; base += GRAD_CHUNK) {
    // Stage the chunk's pairs: work-item i computes every corner of sample base + i (+ GRAD_ITEMS ...).
    for (uint i = lid; i < GRAD_CHUNK; i += GRAD_ITEMS) {
      const uint s = base + i;
      const uint first = (i / RELIT_TILE) * N_CORNERS * RELIT_TILE + i % RELIT_TILE;  // pair of corner 0
      if (s < n) {
        float x[DIMS], frac[DIMS], g[FEATS];
        uint cell[DIMS];
        load_input1(in, in_cols, in_col, s, x);
        grid_cell1(x, level, cell, frac);
        for (int f = 0; f < FEATS; ++f) g[f] = TILED(d_out, out_cols, s, out_col + level * FEATS + f);
        for (int c = 0; c < N_CORNERS; ++c) {
          const uint p = first + c * RELIT_TILE;
          ids[p] = grid_index1(cell, level, c);
          const float w = grid_weight1(frac, c);
          for (int f = 0; f < FEATS; ++f) contrib[p * FEATS + f] = w * g[f];
        }
      } else {
        for (int c = 0; c < N_CORNERS; ++c) ids[first + c * RELIT_TILE] = NO_ENTRY;
      }
    }
    barrier(CLK_LOCAL_MEM_FENCE);
    // Every owner reads every pair in order and keeps its own.
    for (uint p = 0; p < GRAD_CHUNK * N_CORNERS; ++p) {
      const uint id = ids[p];
      if (id < lo || id >= hi) continue;
      __global float* entry = table + (size_t)id * FEATS;
      for (int f = 0; f < FEATS; ++f) entry[f] += contrib[p * FEATS + f];
    }
    barrier(CLK_LOCAL_MEM_FENCE);  // before the next chunk overwrites the pairs
  }
}

// dL/dx = sum_levels sum_corners sum_f dL/dout_f * value_f * dw/dx; the clamp makes it 0 outside (0, 1).
// Groups of IN_S * N_LEVELS work-items: IN_S samples from s0 = group * IN_S, every level.
__kernel __attribute__((reqd_work_group_size(IN_S * N_LEVELS, 1, 1))) void hashgrid_wg_backward_input(
    const uint n_padded, __global const float* restrict params, const uint param_offset,
    __global const float* restrict in, const uint in_cols, const uint in_col, __global const float* restrict d_out,
    const uint out_cols, const uint out_col, __global float* restrict d_in, const uint d_in_cols) {
  __local float part[N_LEVELS * IN_S * DIMS];  // [level][sample][axis]
  const uint lid = get_local_id(0);
  const uint level = lid / IN_S, i = lid % IN_S;
  const size_t s = (size_t)get_group_id(0) * IN_S + i;
  float gx[DIMS];
  for (int d = 0; d < DIMS; ++d) gx[d] = 0.0f;
  if (s < n_padded) {  // no return: every work-item must reach the barrier
    __global const float* table = params + param_offset + level_offset[level];
    float x[DIMS], frac[DIMS], g[FEATS];
    uint cell[DIMS];
    load_input1(in, in_cols, in_col, s, x);
    grid_cell1(x, level, cell, frac);
    for (int f = 0; f < FEATS; ++f) g[f] = TILED(d_out, out_cols, s, out_col + level * FEATS + f);
    for (int c = 0; c < N_CORNERS; ++c) {
      __global const float* entry = table + (size_t)grid_index1(cell, level, c) * FEATS;
      float gv = 0.0f;  // dL/dw_c
      for (int f = 0; f < FEATS; ++f) gv = fma(g[f], entry[f], gv);
      for (int d = 0; d < DIMS; ++d) {
        float dw = ((c >> d) & 1) ? 1.0f : -1.0f;  // d w_c / d frac_d
        for (int e = 0; e < DIMS; ++e)
          if (e != d) dw *= ((c >> e) & 1) ? frac[e] : 1.0f - frac[e];
        gx[d] = fma(level_scale[level] * dw, gv, gx[d]);
      }
    }
  }
  for (int d = 0; d < DIMS; ++d) part[(level * IN_S + i) * DIMS + d] = gx[d];
  barrier(CLK_LOCAL_MEM_FENCE);
  for (uint q = lid; q < IN_S * DIMS; q += IN_S * N_LEVELS) {  // a loop: with 1 or 2 levels, fewer items than sums
    const uint j = q / DIMS, d = q % DIMS;
    const size_t sj = (size_t)get_group_id(0) * IN_S + j;
    if (sj >= n_padded) continue;
    float sum = 0.0f;
    for (uint l = 0; l < N_LEVELS; ++l) sum += part[(l * IN_S + j) * DIMS + d];
    const float x = TILED(in, in_cols, sj, in_col + d);
    TILED(d_in, d_in_cols, sj, in_col + d) = x > 0.0f && x < 1.0f ? sum : 0.0f;
  }
}
