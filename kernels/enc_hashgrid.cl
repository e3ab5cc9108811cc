// enc_hashgrid.cl: multiresolution hash encoding (Mueller et al. 2022, instant-ngp), forward, parameter
// gradient and input gradient.
//
// Level l has a grid of LEVEL_RES[l] vertices per axis over [0, 1]^DIMS; a sample x (clamped to [0, 1])
// sits at p = x * LEVEL_SCALE[l] + 0.5 in vertex units (tiny-cuda-nn's convention: the half-vertex shift
// keeps the levels' grids from aligning at 0). Its cell's 2^DIMS corner vertices map to table entries:
//   dense level (every vertex has its own entry):  index = sum_d v_d * LEVEL_RES^d
//   hashed level (table of 2^k entries):           index = (XOR_d v_d * prime_d) & (LEVEL_SIZE - 1)
// and the FEATS features of the entries are blended with d-linear weights. Parameters of one level:
//   [entry 0: f0 .. f(FEATS-1)][entry 1: ...] ...  starting at LEVEL_OFFSET[l] (in floats) in the slice.
// Output column out_col + l * FEATS + f holds level l's feature f.
//
// Work order: one work-item per (level, tile of 16 samples), level-major, so that the work-groups running
// at one time all read the same level's table and it stays in cache ("one level for the whole batch").
//
// Parameter gradients are a scatter-add. OpenCL 1.2 has no float atomics, and a compare-and-swap loop on
// the int view of a float is a locked instruction on a CPU: it serialises the cache misses that the
// out-of-order core would otherwise overlap, and its result depends on the order of the additions. Here each
// work-item *owns* a disjoint part of the table instead: the entries [lo, hi) of range r of level l, for
// (level, range) = (gid / N_RANGES, gid % N_RANGES). It walks the whole batch in sample order and adds only
// the contributions that fall into its range, with plain loads and stores. No atomics, no races, and every
// entry receives its additions in the same order (tile, corner, lane) whatever N_RANGES and the device are:
// the gradient is bit-for-bit reproducible. N_RANGES = 1 on CPUs (the levels alone keep the cores busy);
// GPUs use more ranges for more parallelism, at the price of recomputing the corners once per range.
//
// On a CPU the time goes into cache misses: at T = 2^19 a level's table is 4 MB (more than L2) and all of
// them together more than L3, so every pass brings each table back from memory. With PREFETCH (set for CPU
// devices) the kernels ask for lines ahead of use: the forward has each tile prefetch its share of the next
// level's table (sequential lines, so that table is cached when its level starts), and the backward
// prefetches the entries of the tile PREFETCH_TILES ahead before its read-modify-writes (by themselves those
// overlapped fewer misses than the forward's independent loads; the prefetches cut its time by a fifth). The
// backward also clears its own entries when it overwrites (`zero`), instead of a separate fill that sends the
// whole gradient out to memory and back.
// The forward loads an entry's 2 features with one 8-byte load (gather16x2): about 30% less forward time on
// PoCL (AVX-512, AMD EPYC) than two 4-byte loads per entry, which LLVM turned into AVX-512 gathers.
#include "enc_hashgrid.clh"

#ifndef PREFETCH
#define PREFETCH 0
#endif
#if PREFETCH && !defined(__clang__)
#undef PREFETCH
#define PREFETCH 0
#endif
// Prefetch only for tables larger than these (bytes): smaller ones stay cached, and the prefetches would
// cost more instructions than they save (measured with a 1 MiB L2: the backward gains from 4 MiB tables on).
#ifndef PREFETCH_FORWARD_MIN_BYTES
#define PREFETCH_FORWARD_MIN_BYTES (512u << 10)
#endif
#ifndef PREFETCH_BACKWARD_MIN_BYTES
#define PREFETCH_BACKWARD_MIN_BYTES (2u << 20)
#endif
#ifndef PREFETCH_TILES
#define PREFETCH_TILES 1
#endif
#ifndef N_RANGES
#define N_RANGES 1
#endif
// Cell and in-cell position of 16 samples at `level`.
inline void grid_cell(const float16* x, uint level, uint16* cell, float16* frac) {
  const float scale = level_scale[level];
#pragma unroll
  for (int d = 0; d < DIMS; ++d) {
    const float16 p = fma(fmin(fmax(x[d], 0.0f), 1.0f), (float16)scale, (float16)0.5f);
    const float16 f = floor(p);
    frac[d] = p - f;
    cell[d] = convert_uint16(f);
  }
}

// Table index of corner `c` (bit d of c: +1 along axis d).
inline uint16 grid_index(const uint16* cell, uint level, int c) {
  uint16 index = (uint16)0u;
  if (level_hashed[level]) {
#pragma unroll
    for (int d = 0; d < DIMS; ++d) index ^= (cell[d] + (uint)((c >> d) & 1)) * grid_prime[d];
    index &= (uint16)(level_size[level] - 1u);
  } else {
    uint stride = 1u;
#pragma unroll
    for (int d = 0; d < DIMS; ++d) {
      index += (cell[d] + (uint)((c >> d) & 1)) * stride;
      stride *= level_res[level];
    }
  }
  return index;
}

inline float16 grid_weight(const float16* frac, int c) {
  float16 w = (float16)1.0f;
#pragma unroll
  for (int d = 0; d < DIMS; ++d) w *= ((c >> d) & 1) ? frac[d] : 1.0f - frac[d];
  return w;
}

// Feature f of the entries of 16 samples, assembled in registers. (Scalar stores to a private array read
// back with vload16 would be simpler, but a wide load of narrow stores defeats store-to-load forwarding on
// x86 and stalls: that alone made the forward pass several times slower on PoCL.)
inline float16 gather16(__global const float* table, uint16 i, int f) {
  __global const float* p = table + f;
  return (float16)(p[i.s0 * FEATS], p[i.s1 * FEATS], p[i.s2 * FEATS], p[i.s3 * FEATS], p[i.s4 * FEATS], p[i.s5 * FEATS],
                   p[i.s6 * FEATS], p[i.s7 * FEATS], p[i.s8 * FEATS], p[i.s9 * FEATS], p[i.sa * FEATS], p[i.sb * FEATS],
                   p[i.sc * FEATS], p[i.sd * FEATS], p[i.se * FEATS], p[i.sf * FEATS]);
}

inline void gather16x2(__global const float* table, uint16 i, float16* f0, float16* f1) {
  const float2 a0 = vload2(i.s0, table), a1 = vload2(i.s1, table), a2 = vload2(i.s2, table), a3 = vload2(i.s3, table);
  const float2 a4 = vload2(i.s4, table), a5 = vload2(i.s5, table), a6 = vload2(i.s6, table), a7 = vload2(i.s7, table);
  const float2 a8 = vload2(i.s8, table), a9 = vload2(i.s9, table), aa = vload2(i.sa, table), ab = vload2(i.sb, table);
  const float2 ac = vload2(i.sc, table), ad = vload2(i.sd, table), ae = vload2(i.se, table), af = vload2(i.sf, table);
  const float8 lo = (float8)(a0, a1, a2, a3), mid = (float8)(a4, a5, a6, a7);
  const float8 hi = (float8)(a8, a9, aa, ab), top = (float8)(ac, ad, ae, af);
  const float16 p = (float16)(lo, mid), q = (float16)(hi, top);
  *f0 = (float16)(p.even, q.even);
  *f1 = (float16)(p.odd, q.odd);
}

inline void load_inputs(__global const float* in, size_t t, uint in_cols, uint in_col, float16* x) {
#pragma unroll
  for (int d = 0; d < DIMS; ++d) x[d] = tile_load(in, t, in_cols, in_col + d);
}

__kernel void hashgrid_forward(const uint n_tiles, __global const float* restrict params, const uint param_offset,
                               __global const float* restrict in, const uint in_cols, const uint in_col,
                               __global float* restrict out, const uint out_cols, const uint out_col) {
  const size_t gid = get_global_id(0);
  if (gid >= (size_t)n_tiles * N_LEVELS) return;
  const uint level = (uint)(gid / n_tiles);
  const size_t t = gid % n_tiles;
  __global const float* table = params + param_offset + level_offset[level];

  float16 x[DIMS], frac[DIMS];
  uint16 cell[DIMS];
  load_inputs(in, t, in_cols, in_col, x);
  grid_cell(x, level, cell, frac);
#if PREFETCH
  if (level + 1 < N_LEVELS && level_size[level + 1] * FEATS * 4u > PREFETCH_FORWARD_MIN_BYTES) {
    // This tile's share of the next level's table, so that it is in the cache when that level starts.
    __global const float* next = params + param_offset + level_offset[level + 1];
    const uint lines = (level_size[level + 1] * FEATS + 15u) / 16u;
    const uint a = (uint)(((ulong)lines * t) / n_tiles), b = (uint)(((ulong)lines * (t + 1)) / n_tiles);
    for (uint i = a; i < b; ++i) __builtin_prefetch(next + (size_t)i * 16u, 0, 3);
  }
#endif

  float16 acc[FEATS];
#pragma unroll
  for (int f = 0; f < FEATS; ++f) acc[f] = (float16)0.0f;
#pragma unroll
  for (int c = 0; c < N_CORNERS; ++c) {
    const uint16 ids = grid_index(cell, level, c);
    const float16 w = grid_weight(frac, c);
#if FEATS == 2
    float16 v0, v1;
    gather16x2(table, ids, &v0, &v1);
    acc[0] = fma(w, v0, acc[0]);
    acc[1] = fma(w, v1, acc[1]);
#else
#pragma unroll
    for (int f = 0; f < FEATS; ++f) acc[f] = fma(w, gather16(table, ids, f), acc[f]);
#endif
  }
#pragma unroll
  for (int f = 0; f < FEATS; ++f) tile_store(out, t, out_cols, out_col + level * FEATS + f, acc[f]);
}

// dL/d(table): see the file comment for the ownership scheme. `n` = logical batch size: padding rows
// contribute nothing, whatever their d_out holds. `zero` != 0: the gradient is overwritten, not accumulated.
__kernel void hashgrid_backward_params(const uint n_tiles, const uint n, __global const float* restrict in,
                                       const uint in_cols, const uint in_col, __global const float* restrict d_out,
                                       const uint out_cols, const uint out_col, __global float* restrict grads,
                                       const uint grad_offset, const uint zero) {
  const size_t gid = get_global_id(0);
  if (gid >= (size_t)N_LEVELS * N_RANGES) return;
  const uint level = (uint)(gid / N_RANGES);
  const uint range = (uint)(gid % N_RANGES);
  const uint lo = (uint)(((ulong)level_size[level] * range) / N_RANGES);
  const uint hi = (uint)(((ulong)level_size[level] * (range + 1)) / N_RANGES);
  __global float* table = grads + grad_offset + level_offset[level];
  const int16 lane = (int16)(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15);
#if PREFETCH
  const bool prefetch = level_size[level] * FEATS * 4u > PREFETCH_BACKWARD_MIN_BYTES;
#endif
  // zero: overwrite instead of accumulate. Clearing its own entries here, just before adding to them, leaves
  // them in the cache (a separate fill would write the whole gradient out to memory, to be read back by the
  // scattered additions).
  if (zero)
    for (size_t i = (size_t)lo * FEATS; i < (size_t)hi * FEATS; ++i) table[i] = 0.0f;

  for (size_t t = 0; t < n_tiles; ++t) {
    float16 x[DIMS], frac[DIMS], g[FEATS];
    uint16 cell[DIMS];
#if PREFETCH
    if (prefetch && t + PREFETCH_TILES < n_tiles) {
      load_inputs(in, t + PREFETCH_TILES, in_cols, in_col, x);
      grid_cell(x, level, cell, frac);
#pragma unroll
      for (int c = 0; c < N_CORNERS; ++c) {
        uint ids[RELIT_TILE];
        vstore16(grid_index(cell, level, c), 0, ids);
        for (int s = 0; s < RELIT_TILE; ++s) __builtin_prefetch(table + (size_t)ids[s] * FEATS, 1, 3);
      }
    }
#endif
    load_inputs(in, t, in_cols, in_col, x);
    grid_cell(x, level, cell, frac);
    const int16 valid = (int16)((int)t * RELIT_TILE) + lane < (int16)((int)n);
#pragma unroll
    for (int f = 0; f < FEATS; ++f)
      g[f] = select((float16)0.0f, tile_load(d_out, t, out_cols, out_col + level * FEATS + f), valid);
#pragma unroll
    for (int c = 0; c < N_CORNERS; ++c) {
      uint ids[RELIT_TILE];
      float wg[FEATS][RELIT_TILE];
      vstore16(grid_index(cell, level, c), 0, ids);
      const float16 w = grid_weight(frac, c);
#pragma unroll
      for (int f = 0; f < FEATS; ++f) vstore16(w * g[f], 0, wg[f]);
#pragma unroll
      for (int s = 0; s < RELIT_TILE; ++s) {
        const uint id = ids[s];
        if (N_RANGES > 1 && (id < lo || id >= hi)) continue;
        __global float* entry = table + (size_t)id * FEATS;
#pragma unroll
        for (int f = 0; f < FEATS; ++f) {
          // Not contracted with the product above into an fma: NVIDIA's compiler did so in one N_RANGES and not
          // in another (one ulp apart), and any number of ranges must give the same bits.
#pragma OPENCL FP_CONTRACT OFF
          entry[f] += wg[f][s];
        }
      }
    }
  }
}

// dL/dx = sum_levels sum_corners sum_f dL/dout_f * value_f * dw/dx; the clamp makes it 0 outside (0, 1).
__kernel void hashgrid_backward_input(const uint n_tiles, __global const float* restrict params,
                                      const uint param_offset, __global const float* restrict in, const uint in_cols,
                                      const uint in_col, __global const float* restrict d_out, const uint out_cols,
                                      const uint out_col, __global float* restrict d_in, const uint d_in_cols) {
  const size_t t = get_global_id(0);
  if (t >= n_tiles) return;
  float16 x[DIMS], gx[DIMS];
  load_inputs(in, t, in_cols, in_col, x);
#pragma unroll
  for (int d = 0; d < DIMS; ++d) gx[d] = (float16)0.0f;
  for (uint level = 0; level < N_LEVELS; ++level) {
    __global const float* table = params + param_offset + level_offset[level];
    float16 frac[DIMS], g[FEATS];
    uint16 cell[DIMS];
    grid_cell(x, level, cell, frac);
#pragma unroll
    for (int f = 0; f < FEATS; ++f) g[f] = tile_load(d_out, t, out_cols, out_col + level * FEATS + f);
#pragma unroll
    for (int c = 0; c < N_CORNERS; ++c) {
      const uint16 ids = grid_index(cell, level, c);
      float16 gv = (float16)0.0f;  // dL/dw_c
#pragma unroll
      for (int f = 0; f < FEATS; ++f) gv = fma(g[f], gather16(table, ids, f), gv);
#pragma unroll
      for (int d = 0; d < DIMS; ++d) {
        float16 dw = ((c >> d) & 1) ? (float16)1.0f : (float16)-1.0f;  // d w_c / d frac_d
#pragma unroll
        for (int e = 0; e < DIMS; ++e)
          if (e != d) dw *= ((c >> e) & 1) ? frac[e] : 1.0f - frac[e];
        gx[d] = fma((float16)level_scale[level] * dw, gv, gx[d]);
      }
    }
  }
#pragma unroll
  for (int d = 0; d < DIMS; ++d) {
    const int16 inside = x[d] > 0.0f && x[d] < 1.0f;
    tile_store(d_in, t, d_in_cols, in_col + d, select((float16)0.0f, gx[d], inside));
  }
}
