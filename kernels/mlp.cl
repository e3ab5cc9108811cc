// mlp.cl: the fully fused MLP (FullyFusedMLP): forward, backward (dL/dinput and the per-layer dL/dZ), the
// per-chunk weight-gradient partials and their fixed-order reduction, and a fused training step for small
// networks on CPUs (mlp_train_fused, at the end). Deterministic, no atomics.
//
// Batch layout (BatchMatrix, see relit/nn/batch.hpp): 16 consecutive samples of one feature are contiguous,
//
//   tile t:  [f0: s0 .. s15][f1: s0 .. s15] ... [f(cols-1): s0 .. s15]      (16 floats = one float16)
//
// so one work-item owns FWD_T tiles (16 samples each) and every value it handles is a float16 whose lanes
// are samples: PoCL maps it onto SIMD registers, a GPU treats it as 16 independent scalars.
//
// Register blocking (forward, dL/dinput): FWD_R outputs at a time for the FWD_T tiles, all inputs k
// streamed through:
//
//        acc[r][u] (float16, lanes = samples)  +=  W[j0 + r][k] (broadcast)  *  in[k] of tile u (float16)
//
//   per k: FWD_T float16 loads, FWD_R broadcasts, FWD_R * FWD_T FMAs (independent accumulator chains).
//   AVX2 and GPUs: FWD_T = 1, FWD_R = 4; AVX-512 (32 registers): FWD_T = 4, FWD_R = 6 (FullyFusedMLP::Blocking).
//
// The network's -D description, its parameter layout and the activations: mlp_common.clh.
//
// Everything is specialised with -D (set by FullyFusedMLP); the defaults make the file build alone.
#include "common.clh"
#include "mlp_common.clh"

#ifndef FWD_R
#define FWD_R 4
#endif
#ifndef FWD_T
#define FWD_T 1  // tiles (of 16 samples) per work-item in the forward and backward kernels
#endif
#ifndef BWD_R
#define BWD_R FWD_R  // register block of the backward kernel
#endif
#ifndef DW_VEC
#define DW_VEC 8  // samples per accumulator of the weight-gradient kernel: 8 or 16
#endif
#ifndef TRAIN_G
#define TRAIN_G (4 * FWD_T)  // tiles per group of the fused training kernel, a multiple of FWD_T
#endif
#ifndef DW_RJ
#define DW_RJ 4
#endif
#ifndef TRAIN_SAVED
#define TRAIN_SAVED 0
#endif
#if TRAIN_SAVED && DW_VEC != 1
#error "TRAIN_SAVED needs the outer-product weight gradients (DW_VEC 1)"
#endif
#ifndef DW_RK
#define DW_RK 2
#endif
// With the outer-product weight gradients (DW_VEC 1) the training forward saves its activations transposed
// (SAVE_T below; the widths are multiples of 16).
#define ACT_T (DW_VEC == 1)

MLP_DEFINE_ACTIVATIONS(float16, apply_act, act_grad)

#if defined(__clang__) && defined(__has_builtin)
#if __has_builtin(__builtin_nontemporal_store) && !defined(RELIT_NO_STREAM)
#define STREAM16(v, p) __builtin_nontemporal_store((v), (__global float16*)(p))
#endif
#endif
#ifndef STREAM16
#define STREAM16(v, p) vstore16((v), 0, (p))
#endif

// The saved ReLU masks: bit s of a mask word is set where sample s of its tile has h > 0. The separate backward
// kernel reads these 2 bytes per feature and tile instead of the saved activation's 64 (docs/networks.md): its
// ReLU mask then comes from a contiguous run per work-item, not from one activation row per feature.
// Layout: mask[(l * (padded / TILE) + tile) * WIDTH + feature] for the hidden layers l; MASK_ROW is a tile's row.
#define MASK_ROW(mask, l, tile) ((mask) + ((size_t)(l) * (padded / TILE) + (tile)) * WIDTH)
#define LANE_BITS (int16)(1, 2, 4, 8, 16, 32, 64, 128, 256, 512, 1024, 2048, 4096, 8192, 16384, 32768)

inline ushort lane_mask(const int16 c) {  // c: -1 or 0 per lane (a float16 comparison)
  const int16 b = c & LANE_BITS;
  const int8 t8 = b.lo | b.hi;
  const int4 t4 = t8.lo | t8.hi;
  const int2 t2 = t4.lo | t4.hi;
  return (ushort)(t2.x | t2.y);
}

inline float16 hidden_act(float16 z) {
#if HIDDEN_ACT == ACT_RELU
  return fmax(z, 0.0f);
#else
  return z;
#endif
}

// acc[r][u] += sum_k w[(j0 + r) * stride + k] * SRC(k, u), for r < NR and the FWD_T tiles u (compile-time
// constants, so the r and u loops unroll and acc[][] lives in registers). Per k: FWD_T activation loads, NR
// weight broadcasts, NR * FWD_T FMAs: with FWD_T = 2 every broadcast feeds two FMAs.
#define ACCUM(acc, NR, SRC, K, w, stride, j0)                                                           \
  for (uint k_ = 0; k_ < (uint)(K); ++k_) {                                                             \
    float16 x_[FWD_T];                                                                                  \
    _Pragma("unroll") for (uint u_ = 0; u_ < FWD_T; ++u_) x_[u_] = SRC(k_, u_);                         \
    _Pragma("unroll") for (uint r_ = 0; r_ < (NR); ++r_) {                                              \
      const float16 w_ = (float16)((w)[((j0) + r_) * (stride) + k_]);                                   \
      _Pragma("unroll") for (uint u_ = 0; u_ < FWD_T; ++u_) acc[r_][u_] = fma(w_, x_[u_], acc[r_][u_]); \
    }                                                                                                   \
  }

#define INIT_BIAS(acc, NR, w, stride, j0, K)                                                \
  _Pragma("unroll") for (uint r_ = 0; r_ < (NR); ++r_) {                                    \
    const float16 b_ = BIAS ? (float16)((w)[((j0) + r_) * (stride) + (K)]) : (float16)0.0f; \
    _Pragma("unroll") for (uint u_ = 0; u_ < FWD_T; ++u_) acc[r_][u_] = b_;                 \
  }

#define INIT_ZERO(acc, NR)                                                                                   \
  _Pragma("unroll") for (uint r_ = 0; r_ < (NR); ++r_) _Pragma("unroll") for (uint u_ = 0; u_ < FWD_T; ++u_) \
      acc[r_][u_] = (float16)0.0f;

// The FWD_T tiles of work-item `item`: FWD_T * item + u, clamped to the last tile. A work-item past the end
// of an odd tile count recomputes the last tile and writes the same values again (no branches, no reads
// past the end of the batch).
#define ITEM_TILES(tile, item, n_tiles) \
  size_t tile[FWD_T];                   \
  _Pragma("unroll") for (uint u_ = 0; u_ < FWD_T; ++u_) tile[u_] = min((item)*FWD_T + u_, (size_t)(n_tiles)-1);

// One stage of the 16 x 16 transpose: the perfect shuffle of the pairs (r[i], r[i + 8]). Element (vector v,
// lane l) moves to the position whose 8 bits (v, l) are those of (v, l) rotated left by one, so four stages
// swap v and l.
#define SHUFFLE_LO(a, b) \
  (float16)(a.s0, b.s0, a.s1, b.s1, a.s2, b.s2, a.s3, b.s3, a.s4, b.s4, a.s5, b.s5, a.s6, b.s6, a.s7, b.s7)
#define SHUFFLE_HI(a, b) \
  (float16)(a.s8, b.s8, a.s9, b.s9, a.sa, b.sa, a.sb, b.sb, a.sc, b.sc, a.sd, b.sd, a.se, b.se, a.sf, b.sf)

// The 16 float16s SRC (i_ = 0 .. 15; zero where VALID is false) transposed; STORE then stores row r_[i_] of the
// result. SRC is read for every i_, so it must be safe to read where VALID is false (clamped indices).
#define TRANSPOSED16(SRC, VALID, STORE)                       \
  {                                                           \
    float16 r_[16];                                           \
    _Pragma("unroll") for (uint i_ = 0; i_ < 16; ++i_) {      \
      const float16 x_ = (SRC);                               \
      r_[i_] = (VALID) ? x_ : (float16)0.0f;                  \
    }                                                         \
    transpose16(r_);                                          \
    _Pragma("unroll") for (uint i_ = 0; i_ < 16; ++i_) STORE; \
  }

inline void transpose16(float16* r) {
#pragma unroll
  for (uint stage = 0; stage < 4; ++stage) {
    float16 t[16];
#pragma unroll
    for (uint i = 0; i < 8; ++i) {
      t[2 * i] = SHUFFLE_LO(r[i], r[i + 8]);
      t[2 * i + 1] = SHUFFLE_HI(r[i], r[i + 8]);
    }
#pragma unroll
    for (uint i = 0; i < 16; ++i) r[i] = t[i];
  }
}

// Private and scratch arrays hold feature f of tile u at [f * HS + u]: HS = FWD_T in the forward and backward
// kernels, TRAIN_G in the fused training kernel (which runs the blocks on FWD_T of its TRAIN_G tiles at a time).
#define HS FWD_T

// The transposed training workspace (ACT_T): vector v of `act` holds 16 input columns of the weight gradients
// for every sample, [v][s][16] (vector v at act + v * padded * 16 floats): ACT_XV vectors of x (zero past
// N_IN), then WIDTH / 16 per hidden layer; no ones row (the bias gradients are dZ sums). These are the
// outer-product weight gradients' operands as they are (mlp_weight_grad_outer reads them directly).
// SAVE_T(v, t, SRC, VALID) transposes the 16 values SRC of tile t (SRC and VALID use i_, the column in the
// vector) and stores them to vector v.
#define ACT_XV ((N_IN + 15) / 16)
#define ACT_HV(l) (ACT_XV + (l) * (WIDTH / 16))  // the first vector of hidden layer l
// Vector v of a layer's inputs at sample s, as float16s: the a_n / 16 activation vectors from vector a_vec,
// then the x vectors from x_vec (layer 0 and skips).
#define SAVED_VEC(act, v, a_n, a_vec, x_vec, s) \
  ((__global const float16*)(act) +             \
   ((size_t)((v) < (a_n) / 16 ? (a_vec) + (v) : (x_vec) + (v) - (a_n) / 16) * padded + (s)))
#define SAVE_T(v, t, SRC, VALID) \
  TRANSPOSED16(SRC, VALID, STREAM16(r_[i_], act + ((size_t)(v)*padded + (t)*TILE + i_) * 16))

// ---------------------------------------------------------------------------------------------------------
// Forward. One work-item = FWD_T tiles of 16 samples; all layers in registers/private memory (per feature k
// the FWD_T tiles' float16 values are adjacent: h[k * FWD_T + u]). With save != 0 the training workspace
// `act` (feature-major: row f holds feature f of every sample, rows `padded` floats apart) receives the rows
// [x (N_IN), ones, h_0 (WIDTH), ..., h_(N_HIDDEN-1)], h_l after the activation, which the weight-gradient kernel
// streams row by row contiguously over the batch; with a ReLU the backward pass reads only the masks h_l > 0,
// saved into `mask` (above).
// ---------------------------------------------------------------------------------------------------------

#define SRC_X(k, u) vload16(0, xt[u] + (k)*TILE)
#define SRC_H(k, u) hin[(k)*HS + (u)]

// One hidden layer block of NR outputs starting at j0.
#define HIDDEN_BLOCK(NR, j0)                                                                               \
  {                                                                                                        \
    float16 acc[NR][FWD_T];                                                                                \
    INIT_BIAS(acc, NR, w, stride, j0, kin)                                                                 \
    if (l == 0) {                                                                                          \
      ACCUM(acc, NR, SRC_X, N_IN, w, stride, j0)                                                           \
    } else {                                                                                               \
      ACCUM(acc, NR, SRC_H, WIDTH, w, stride, j0)                                                          \
      if (skip) {                                                                                          \
        __global const float* ws_ = w + WIDTH;                                                             \
        ACCUM(acc, NR, SRC_X, N_IN, ws_, stride, j0)                                                       \
      }                                                                                                    \
    }                                                                                                      \
    _Pragma("unroll") for (uint r = 0; r < (NR); ++r) _Pragma("unroll") for (uint u = 0; u < FWD_T; ++u) { \
      const float16 y = hidden_act(acc[r][u]);                                                             \
      hout[((j0) + r) * HS + u] = y;                                                                       \
      if (save) {                                                                                          \
        if (!ACT_T) STREAM16(y, st + ((j0) + r) * (size_t)padded + tile[u] * TILE);                        \
        if (HIDDEN_ACT == ACT_RELU) MASK_ROW(mask, l, tile[u])[(j0) + r] = lane_mask(y > 0.0f);            \
      }                                                                                                    \
    }                                                                                                      \
  }

#define OUTPUT_BLOCK(NR, j0)                                                                             \
  {                                                                                                      \
    float16 acc[NR][FWD_T];                                                                              \
    INIT_BIAS(acc, NR, w, stride, j0, WIDTH)                                                             \
    ACCUM(acc, NR, SRC_H, WIDTH, w, stride, j0)                                                          \
    _Pragma("unroll") for (uint r = 0; r < (NR); ++r) _Pragma("unroll") for (uint u = 0; u < FWD_T; ++u) \
        vstore16(apply_act(acc[r][u], k_out_act[(j0) + r]), 0, yt[u] + ((j0) + r) * TILE);               \
  }

// n_items = ceil(n_tiles / FWD_T) work-items.
__kernel void mlp_forward(const uint n_tiles, const uint padded, __global const float* restrict params,
                          const uint param_offset, __global const float* restrict x, __global float* restrict y,
                          __global float* restrict act, const uint save, __global ushort* restrict mask) {
  const size_t item = get_global_id(0);
  if (item * FWD_T >= n_tiles) return;
  ITEM_TILES(tile, item, n_tiles)
  __global const float* p = params + param_offset;
  __global const float* xt[FWD_T];
  __global float* yt[FWD_T];
#pragma unroll
  for (uint u = 0; u < FWD_T; ++u) {
    xt[u] = x + tile[u] * (size_t)(N_IN * TILE);
    yt[u] = y + tile[u] * (size_t)(N_OUT * TILE);
  }

  if (save) {  // the weight gradients' inputs of layer 0 (and skips): x and the bias column of ones
#if ACT_T
#pragma unroll
    for (uint u = 0; u < FWD_T; ++u)
      for (uint v = 0; v < ACT_XV; ++v)
        SAVE_T(v, tile[u], vload16(0, xt[u] + min(16 * v + i_, N_IN - 1u) * TILE), 16 * v + i_ < N_IN)
#else
#pragma unroll
    for (uint u = 0; u < FWD_T; ++u) {
      for (uint k = 0; k < N_IN; ++k)
        vstore16(vload16(0, xt[u] + k * TILE), 0, act + (size_t)k * padded + tile[u] * TILE);
      vstore16((float16)1.0f, 0, act + (size_t)N_IN * padded + tile[u] * TILE);
    }
#endif
  }
  float16 h[2][WIDTH * FWD_T];
  for (uint l = 0; l < N_HIDDEN; ++l) {
    const uint skip = (((uint)(SKIP_MASK)) >> l) & 1u;
    const uint kin = LAYER_IN(l);
    const uint stride = kin + BIAS;
    __global const float* w = p + layer_offset(l);
    __private float16* hin = h[(l + 1) & 1];
    __private float16* hout = h[l & 1];
    __global float* st = act + (size_t)(ACT_H0 + l * WIDTH) * padded;
    for (uint j0 = 0; j0 + FWD_R <= WIDTH; j0 += FWD_R) HIDDEN_BLOCK(FWD_R, j0)
#if WIDTH % FWD_R
    HIDDEN_BLOCK(WIDTH % FWD_R, WIDTH - WIDTH % FWD_R)
#endif
#if ACT_T
    if (save)
#pragma unroll
      for (uint u = 0; u < FWD_T; ++u)
        for (uint v = 0; v < WIDTH / 16; ++v) SAVE_T(ACT_HV(l) + v, tile[u], hout[(16 * v + i_) * HS + u], true)
#endif
  }
  {
    __private float16* hin = h[(N_HIDDEN + 1) & 1];
    const uint stride = LAYER_STRIDE(N_HIDDEN);
    __global const float* w = p + layer_offset(N_HIDDEN);
    for (uint j0 = 0; j0 + FWD_R <= N_OUT; j0 += FWD_R) OUTPUT_BLOCK(FWD_R, j0)
#if N_OUT % FWD_R
    OUTPUT_BLOCK(N_OUT % FWD_R, N_OUT - N_OUT % FWD_R)
#endif
  }
}

// ---------------------------------------------------------------------------------------------------------
// Backward through the activations: dZ_l = dL/d(pre-activation of layer l) for every layer, written to `dz`
// (feature-major like `act`: rows [dZ_0 (WIDTH), ..., dZ_(N_HIDDEN-1), dZ_out (N_OUT)]), and dL/dx into `dx`
// when want_dx. One work-item = FWD_T tiles, register blocks of BWD_R inputs. Lanes of samples >= batch get
// zero gradients, so the weight gradients never see the padding rows whatever d_output holds there.
// ---------------------------------------------------------------------------------------------------------

#define SRC_G(j, u) gin[(j)*HS + (u)]

// NR inputs k0.. of dL/dh_(l-1) = W_l^T dZ_l, masked by the activation derivative of h_(l-1), into gout.
// The product streams rows of the layer's transposed block wt ([n_in + bias][nout], mlp_transpose_params)
// as the forward pass streams rows of W: row k0 + r of W^T is contiguous, where column k0 + r of W would be
// a load from a different cache line for every output j.
// POS(k, u): int16, true in the lanes where h_(l-1) of input k in tile u is > 0 (used with a ReLU only);
// SAVE(k, u, g) stores the result elsewhere too.
#define BACK_MASKED_BLOCK(NR, k0, POS, SAVE)                                                               \
  {                                                                                                        \
    float16 acc[NR][FWD_T];                                                                                \
    INIT_ZERO(acc, NR)                                                                                     \
    ACCUM(acc, NR, SRC_G, nout, wt, nout, k0)                                                              \
    _Pragma("unroll") for (uint r = 0; r < (NR); ++r) _Pragma("unroll") for (uint u = 0; u < FWD_T; ++u) { \
      float16 g = acc[r][u];                                                                               \
      if (HIDDEN_ACT == ACT_RELU) g = select((float16)0.0f, g, POS((k0) + r, u));                          \
      gout[((k0) + r) * HS + u] = g;                                                                       \
      SAVE((k0) + r, u, g);                                                                                \
    }                                                                                                      \
  }

// The separate backward kernel: h_(l-1) > 0 from the saved masks, dZ stored for the weight gradients.
#define POS_SAVED(k, u) (((int16)(mk[u][k]) & LANE_BITS) != 0)
#define SAVE_DZ(k, u, g) STREAM16(g, dzt + (k) * (size_t)padded + tile[u] * TILE)
#define BACK_HIDDEN_BLOCK(NR, k0) BACK_MASKED_BLOCK(NR, k0, POS_SAVED, SAVE_DZ)
// A hidden layer's dZ in blocks of BWD_R rows (BLOCK: BACK_HIDDEN_BLOCK or the fused kernel's TRAIN_BACK_BLOCK),
// the last block shorter when BWD_R does not divide WIDTH.
#if WIDTH % BWD_R
#define BACK_ROWS(BLOCK)                                               \
  for (uint k0 = 0; k0 + BWD_R <= WIDTH; k0 += BWD_R) BLOCK(BWD_R, k0) \
  BLOCK(WIDTH % BWD_R, WIDTH - WIDTH % BWD_R)
#else
#define BACK_ROWS(BLOCK) \
  for (uint k0 = 0; k0 + BWD_R <= WIDTH; k0 += BWD_R) BLOCK(BWD_R, k0)
#endif
#define BACK_HIDDEN BACK_ROWS(BACK_HIDDEN_BLOCK)

// NR inputs k0.. of dL/dx from the input columns starting at column `xcol` of the layer (layer 0 or a skip),
// rows xcol.. of its transposed block wt.
#define BACK_INPUT_BLOCK(NR, k0)                                                                           \
  {                                                                                                        \
    float16 acc[NR][FWD_T];                                                                                \
    INIT_ZERO(acc, NR)                                                                                     \
    __global const float* wx_ = wt + xcol * nout;                                                          \
    ACCUM(acc, NR, SRC_G, nout, wx_, nout, k0)                                                             \
    /* all loads before the stores: a duplicated last tile (see ITEM_TILES) must not add twice */          \
    if (!first)                                                                                            \
      _Pragma("unroll") for (uint r = 0; r < (NR); ++r) _Pragma("unroll") for (uint u = 0; u < FWD_T; ++u) \
          acc[r][u] += vload16(0, dxt[u] + ((k0) + r) * TILE);                                             \
    _Pragma("unroll") for (uint r = 0; r < (NR); ++r) _Pragma("unroll") for (uint u = 0; u < FWD_T; ++u)   \
        vstore16(acc[r][u], 0, dxt[u] + ((k0) + r) * TILE);                                                \
  }

// BODY with `nout` (the outputs of layer l, the rows of its transposed block) a compile-time constant: N_OUT for
// the output layer, WIDTH below it. The blocks' weight rows are then constant offsets from one pointer, where
// a run-time row length took a register per row or a reload from the stack per row and k.
#define WITH_CONST_NOUT(l, BODY) \
  if ((l) == N_HIDDEN) {         \
    const uint nout = N_OUT;     \
    BODY                         \
  } else {                       \
    const uint nout = WIDTH;     \
    BODY                         \
  }

#define BACK_INPUT(first_)                                                         \
  {                                                                                \
    const uint first = (first_);                                                   \
    for (uint k0 = 0; k0 + BWD_R <= N_IN; k0 += BWD_R) BACK_INPUT_BLOCK(BWD_R, k0) \
    BACK_INPUT_TAIL                                                                \
  }
#if N_IN % BWD_R
#define BACK_INPUT_TAIL BACK_INPUT_BLOCK(N_IN % BWD_R, N_IN - N_IN % BWD_R)
#else
#define BACK_INPUT_TAIL
#endif

// The parameters with every layer's [n_out][n_in + bias] block transposed to [n_in + bias][n_out], at the
// same offsets, for the backward passes (BACK_MASKED_BLOCK). One work-item per output row of a layer: ids
// l * GMAX + j.
__kernel void mlp_transpose_params(__global const float* restrict params, const uint param_offset,
                                   __global float* restrict wt) {
  const uint id = get_global_id(0), l = id / GMAX, j = id % GMAX;
  if (l > N_HIDDEN || j >= LAYER_OUT(l)) return;
  const uint nout = LAYER_OUT(l), stride = LAYER_STRIDE(l), off = layer_offset(l);
  __global const float* row = params + param_offset + off + j * stride;
  for (uint k = 0; k < stride; ++k) wt[off + k * nout + j] = row[k];
}

// n_items = ceil(n_tiles / FWD_T) work-items.
__kernel void mlp_backward(const uint n_tiles, const uint padded, const uint batch,
                           __global const float* restrict wt_params, __global const float* restrict y,
                           __global const float* restrict dy, __global const ushort* restrict mask,
                           __global float* restrict dz, __global float* restrict dx, const uint want_dx) {
  const size_t item = get_global_id(0);
  if (item * FWD_T >= n_tiles) return;
  ITEM_TILES(tile, item, n_tiles)
  const int16 lane = (int16)(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15);

  float16 g[2][GMAX * FWD_T];
#pragma unroll
  for (uint u = 0; u < FWD_T; ++u) {  // dZ of the output layer.
    const int16 valid = (int16)((int)(tile[u] * TILE)) + lane < (int16)((int)batch);
    __global const float* yt = y + tile[u] * (size_t)(N_OUT * TILE);
    __global const float* dyt = dy + tile[u] * (size_t)(N_OUT * TILE);
    __global float* dzt = dz + (size_t)N_HIDDEN * padded * WIDTH + tile[u] * TILE;
    for (uint j = 0; j < N_OUT; ++j) {
      const float16 d = vload16(0, dyt + j * TILE) * act_grad(vload16(0, yt + j * TILE), k_out_act[j]);
      const float16 dm = select((float16)0.0f, d, valid);
      g[N_HIDDEN & 1][j * FWD_T + u] = dm;
      vstore16(dm, 0, dzt + j * (size_t)padded);
    }
  }
  __global float* dxt[FWD_T];
#pragma unroll
  for (uint u = 0; u < FWD_T; ++u) dxt[u] = dx + tile[u] * (size_t)(N_IN * TILE);
  for (uint l = N_HIDDEN; l >= 1; --l) {
    __global const float* wt = wt_params + layer_offset(l);
    __private const float16* gin = g[l & 1];
    __private float16* gout = g[(l + 1) & 1];
    __global const ushort* mk[FWD_T];
#pragma unroll
    for (uint u = 0; u < FWD_T; ++u) mk[u] = MASK_ROW(mask, l - 1, tile[u]);
    __global float* dzt = dz + (size_t)(l - 1) * WIDTH * padded;
    if (want_dx && ((((uint)(SKIP_MASK)) >> l) & 1u)) {
      const uint xcol = WIDTH;
      WITH_CONST_NOUT(l, BACK_INPUT(l == TOP_SKIP))
    }
    WITH_CONST_NOUT(l, BACK_HIDDEN)
  }
  if (want_dx) {
    const uint nout = WIDTH, xcol = 0;
    __global const float* wt = wt_params;
    __private const float16* gin = g[0];
    BACK_INPUT(TOP_SKIP == 0)
  }
}

// ---------------------------------------------------------------------------------------------------------
// Weight gradients of one layer: partial[c][layer_off + j * n_in + k] = sum over the samples of chunk c of
// dZ[j][s] * in[k][s]. The training workspace is feature-major (row f holds feature f of every sample, rows
// `padded` floats apart), so every operand is a contiguous stream over the batch:
//   dz rows j:  dz + (dz_row + j) * padded
//   in rows k:  act + (a_row + k) * padded for k < a_n (the layer's input activations), then
//               act + (x_row + k - a_n) * padded for the x_n remaining columns (x rows and/or the ones row).
//
// One work-item = one chunk x DW_ROWS rows of dW. It walks its chunk in sub-chunks of `sub` samples (sized by
// the host so the sub-chunk's input rows stay in cache); per sub-chunk it computes every DW_RJ x DW_RK
// register block of its rows: accumulators of DW_VEC (8 or 16) floats whose lanes are samples,
//
//   acc[i][r] += dz[j0 + i][s ..] * in[k0 + r][s ..]                  (DW_RJ + DW_RK loads, DW_RJ*DW_RK FMAs)
//
// and adds the lane sums into its partial rows. Partial sums go to per-chunk slots: no atomics, and the
// reduction below adds chunks in a fixed order (bit-for-bit reproducible).
// ---------------------------------------------------------------------------------------------------------
#ifndef DW_ROWS
#define DW_ROWS (4 * DW_RJ)
#endif

// Sum of the 16 lanes, in a fixed order (pairwise halves).
#define sum16 relit_sum16

// The weight-gradient kernels' work-item: chunk c of the batch (samples s0 .. s1) and the region of dW rows
// jr0 .. jr1, its partial rows `out` and the layer's dZ rows `dzl`; past the last work-item it returns.
#define DW_WORK_ITEM                                                           \
  const uint regions = (n_out + DW_ROWS - 1) / DW_ROWS;                        \
  const size_t gid = get_global_id(0);                                         \
  if (gid >= (size_t)n_chunks * regions) return;                               \
  const uint c = gid / regions;                                                \
  const uint jr0 = (gid % regions) * DW_ROWS, jr1 = min(jr0 + DW_ROWS, n_out); \
  const uint s0 = c * chunk_len, s1 = min(s0 + chunk_len, n_samples);          \
  __global float* out = partial + (size_t)c * partial_stride + layer_off;      \
  __global const float* dzl = dz + (size_t)dz_row * padded;

#if DW_VEC != 1  // the lane form (DW_VEC 1: mlp_weight_grad_outer below)
// The accumulators: DW_VEC samples (float8: one 256-bit register, float16: one 512-bit register).
#if DW_VEC == 16
typedef float16 dw_vec;
#define DW_LOAD(p) vload16(0, (p))
#define dw_sum sum16
#else
typedef float8 dw_vec;
#define DW_LOAD(p) vload8(0, (p))
#define dw_sum relit_sum8
#endif

__kernel void mlp_weight_grad_partial(const uint n_samples, const uint chunk_len, const uint n_chunks, const uint sub,
                                      const uint padded, __global const float* restrict dz, const uint dz_row,
                                      const uint n_out, __global const float* restrict act, const uint a_row,
                                      const uint a_n, const uint x_row, const uint x_n,
                                      __global float* restrict partial, const uint partial_stride,
                                      const uint layer_off) {
  const uint n_in = a_n + x_n;
  DW_WORK_ITEM

  for (uint ss = s0; ss < s1; ss += sub) {
    const uint se = min(ss + sub, s1);
    const bool first = ss == s0;
    for (uint j0 = jr0; j0 < jr1; j0 += DW_RJ) {
      // Rows and columns past the end repeat the last one: no branches in the inner loop; those results are
      // not stored.
      __global const float* dzp[DW_RJ];
#pragma unroll
      for (uint i = 0; i < DW_RJ; ++i) dzp[i] = dzl + (size_t)min(j0 + i, jr1 - 1) * padded;
      for (uint k0 = 0; k0 < n_in; k0 += DW_RK) {
        __global const float* inp[DW_RK];
#pragma unroll
        for (uint r = 0; r < DW_RK; ++r) {
          const uint k = min(k0 + r, n_in - 1);
          inp[r] = act + (size_t)(k < a_n ? a_row + k : x_row + (k - a_n)) * padded;
        }
        dw_vec acc[DW_RJ][DW_RK];
#pragma unroll
        for (uint i = 0; i < DW_RJ; ++i)
#pragma unroll
          for (uint r = 0; r < DW_RK; ++r) acc[i][r] = (dw_vec)0.0f;
        for (uint s = ss; s < se; s += DW_VEC) {
          dw_vec xv[DW_RK];
#pragma unroll
          for (uint r = 0; r < DW_RK; ++r) xv[r] = DW_LOAD(inp[r] + s);
#pragma unroll
          for (uint i = 0; i < DW_RJ; ++i) {
            const dw_vec d = DW_LOAD(dzp[i] + s);
#pragma unroll
            for (uint r = 0; r < DW_RK; ++r) acc[i][r] = fma(d, xv[r], acc[i][r]);
          }
        }
#pragma unroll
        for (uint i = 0; i < DW_RJ; ++i)
#pragma unroll
          for (uint r = 0; r < DW_RK; ++r) {
            if (j0 + i < jr1 && k0 + r < n_in) {
              const float v = dw_sum(acc[i][r]);
              __global float* o = out + (j0 + i) * n_in + k0 + r;
              *o = first ? v : *o + v;
            }
          }
      }
    }
  }
}
#endif

#if DW_VEC == 1
// ---------------------------------------------------------------------------------------------------------
// Weight gradients of one layer, outer-product form (DW_VEC == 1): the partials of mlp_weight_grad_partial,
// from accumulators whose 16 lanes are 16 dW columns (inputs) of one row, one sample per FMA:
//
//   acc[i][r] += dz[j0 + i][s] (broadcast)  *  in^T[s][16 (v0 + r) .. + 15]      (DW_RK loads, DW_RJ broadcasts)
//
// A block's accumulators are dW entries, not lane partial sums: no horizontal sums, so the samples can be
// walked in short blocks of `sub`, whose DW_RJ dZ row pieces stay in L1 while every column block reuses
// them, and the accumulators are added to the work-item's copy of its dW rows (`cbuf`, rows padded to
// NV x 16 floats) after each block. The lane form must keep its blocks long to amortise its horizontal sums,
// and its DW_RJ dZ rows of a sub-chunk (32 KiB at 8 rows of 1 KiB samples) then compete for L1 with the
// input rows it streams. The input vectors are `act` as the training forward pass saved it (SAVE_T), already
// transposed:
//
//   act [v][s][0..15] = in[16 v + 0 .. 16 v + 15][s]      (NV = ceil(n_dw / 16) column vectors, zero past n_dw,
//                                                         the inputs without the ones row of the bias)
//
// (Transposing feature-major rows here, block by block, cost 12-20 % of this kernel's time, its loads missing
// to memory; the forward pass transposes values it holds in registers.) The chunk's last block writes the
// work-item's dW rows into its partial slot.
//
// scratch (per work-item, scratch_stride floats apart, 64-byte aligned):
//   cbuf  DW_ROWS x cstride   the work-item's dW rows without the bias column, cstride = NV x 16 (a multiple
//                             of 16)
//   bacc  DW_ROWS float16s    the bias gradients' accumulators (BIAS_SUMS)
// ---------------------------------------------------------------------------------------------------------

// One tile of 16 samples of the inputs 16 v .. 16 v + 15 of a layer, transposed into dst[0 .. 15] (sample i's
// 16 inputs as one float16; the fused training kernel's dW blocks). Input k is row a_row + k of its source for
// k < a_n, else row x_row + k - a_n; SRC(row) loads the tile's float16 of a row; inputs past n_in are zero.
inline uint pack_row(const uint k, const uint a_n, const uint a_row, const uint x_row) {
  return k < a_n ? a_row + k : x_row + (k - a_n);
}
#define PACK_TILE(dst, v, n_in, a_n, a_row, x_row, SRC)                                                  \
  TRANSPOSED16(SRC(pack_row(min((v)*16 + i_, (n_in)-1), (a_n), (a_row), (x_row))), (v)*16 + i_ < (n_in), \
               (dst)[i_] = r_[i_])

// The DW_RJ x NRK block of column vectors v0.. of the dW rows at cb (row i at cb + i * cs) over n samples:
// input vector v's samples at VEC(v) (float16s), dZ row i at dzp[i]; `first` starts the accumulators from
// zero instead of the stored rows.
#define OUTER_BLOCK(NRK, v0, cb, cs, VEC, n, first)                                                                   \
  {                                                                                                                   \
    __global float* cb_ = (cb) + (v0)*16;                                                                             \
    __global const float16* px_[NRK];                                                                                 \
    _Pragma("unroll") for (uint r = 0; r < (NRK); ++r) px_[r] = VEC((v0) + r);                                        \
    float16 acc[DW_RJ][NRK];                                                                                          \
    _Pragma("unroll") for (uint i = 0; i < DW_RJ; ++i) _Pragma("unroll") for (uint r = 0; r < (NRK); ++r) acc[i][r] = \
        (first) ? (float16)0.0f : vload16(0, cb_ + i * (cs) + r * 16);                                                \
    for (uint s = 0; s < (n); ++s) {                                                                                  \
      float16 xv[NRK];                                                                                                \
      _Pragma("unroll") for (uint r = 0; r < (NRK); ++r) xv[r] = px_[r][s];                                           \
      _Pragma("unroll") for (uint i = 0; i < DW_RJ; ++i) {                                                            \
        const float16 d = (float16)(dzp[i][s]);                                                                       \
        _Pragma("unroll") for (uint r = 0; r < (NRK); ++r) acc[i][r] = fma(d, xv[r], acc[i][r]);                      \
      }                                                                                                               \
    }                                                                                                                 \
    _Pragma("unroll") for (uint i = 0; i < DW_RJ; ++i) _Pragma("unroll") for (uint r = 0; r < (NRK); ++r)             \
        vstore16(acc[i][r], 0, cb_ + i * (cs) + r * 16);                                                              \
  }

// The n_rows x n_cols dW rows at src (src_stride floats apart) into the partial slot's rows at dst (dst_stride
// floats apart); with a bias, the bias gradients' lane sums from bacc into the column after them.
inline void copy_dw_rows(__global float* restrict dst, const uint dst_stride, __global const float* restrict src,
                         const uint n_rows, const uint n_cols, const uint src_stride,
                         __global const float16* restrict bacc) {
  for (uint j = 0; j < n_rows; ++j) {
    for (uint k = 0; k < n_cols; ++k) dst[j * dst_stride + k] = src[(size_t)j * src_stride + k];
    if (BIAS) dst[j * dst_stride + n_cols] = relit_sum16(bacc[j]);
  }
}

// The bias gradients of a layer are the sums of its dZ rows: added into float16 accumulators (lanes = a
// sample's position in its tile), n_vec vectors of dZ row j at d + j * row_stride, in place of a column of
// ones in the outer products (whose 16-column vector would cost DW_RJ FMAs per sample for that one column).
#define BIAS_SUMS(bacc, n_rows, d, row_stride, n_vec, first)                       \
  if (BIAS)                                                                        \
    for (uint j_ = 0; j_ < (n_rows); ++j_) {                                       \
      float16 b_ = (first) ? (float16)0.0f : (bacc)[j_];                           \
      for (uint t_ = 0; t_ < (n_vec); ++t_) b_ += DZ_VEC((d), j_, row_stride, t_); \
      (bacc)[j_] = b_;                                                             \
    }

// All nv column vectors of the DW_RJ rows at cb: blocks of DW_RK, then the last ones.
#if DW_RK > 3
#define OUTER_LAST_3(...) \
  case 3:                 \
    OUTER_BLOCK(3, __VA_ARGS__) break;
#else
#define OUTER_LAST_3(...)
#endif
#if DW_RK > 2
#define OUTER_LAST_2(...) \
  case 2:                 \
    OUTER_BLOCK(2, __VA_ARGS__) break;
#else
#define OUTER_LAST_2(...)
#endif
#define OUTER_ROW(cb, cs, VEC, n, first)                                                \
  {                                                                                     \
    uint v0 = 0;                                                                        \
    for (; v0 + DW_RK <= nv; v0 += DW_RK) OUTER_BLOCK(DW_RK, v0, cb, cs, VEC, n, first) \
    switch (nv - v0) {                                                                  \
      OUTER_LAST_3(v0, cb, cs, VEC, n, first)                                           \
      OUTER_LAST_2(v0, cb, cs, VEC, n, first)                                           \
      case 1: OUTER_BLOCK(1, v0, cb, cs, VEC, n, first) break;                          \
      default: break;                                                                   \
    }                                                                                   \
  }

__kernel void mlp_weight_grad_outer(const uint n_samples, const uint chunk_len, const uint n_chunks, const uint sub,
                                    const uint padded, __global const float* restrict dz, const uint dz_row,
                                    const uint n_out, __global const float* restrict act, const uint a_row,
                                    const uint a_n, const uint x_row, const uint x_n, __global float* restrict partial,
                                    const uint partial_stride, const uint layer_off, __global float* restrict scratch,
                                    const uint scratch_stride) {
  // The outer products cover the n_dw inputs without the bias column (the ones row), whose gradients are the
  // dZ rows' sums (BIAS_SUMS), kept in bacc.
  const uint n_in = a_n + x_n, n_dw = n_in - BIAS, nv = (n_dw + 15) / 16, cstride = nv * 16;
  DW_WORK_ITEM
  __global float* cbuf = scratch + gid * scratch_stride;
  __global float16* bacc = (__global float16*)(cbuf + (size_t)DW_ROWS * cstride);

  for (uint ss = s0; ss < s1; ss += sub) {
    const uint len = min(sub, s1 - ss);  // a multiple of 16, like chunk_len and n_samples
    const bool first = ss == s0;
    // The block's input vectors as the forward pass saved them (SAVE_T; a_row and x_row count vectors).
#define ACT_VEC(v) SAVED_VEC(act, v, a_n, a_row, x_row, ss)
    for (uint j0 = jr0; j0 < jr1; j0 += DW_RJ) {
      // Rows past the end repeat the last one; cbuf has room for them (DW_ROWS is a multiple of DW_RJ) and they
      // are never written out.
      __global const float* dzp[DW_RJ];
#pragma unroll
      for (uint i = 0; i < DW_RJ; ++i) dzp[i] = dzl + (size_t)min(j0 + i, jr1 - 1) * padded + ss;
      OUTER_ROW(cbuf + (size_t)(j0 - jr0) * cstride, cstride, ACT_VEC, len, first)
    }
#define DZ_VEC(d, j, row_stride, t) vload16(0, (d) + (size_t)(j) * (row_stride) + 16 * (t))
    BIAS_SUMS(bacc, jr1 - jr0, dzl + (size_t)jr0 * padded + ss, padded, len / 16, first)
#undef DZ_VEC
  }
  copy_dw_rows(out + jr0 * n_in, n_in, cbuf, jr1 - jr0, n_dw, cstride, bacc);
}
#endif

// grads[i] (+)= sum_c partial[c * partial_stride + i], chunks added in order; 8 parameters per work-item.
__kernel void mlp_reduce_chunks(const uint n, const uint n_chunks, __global const float* restrict partial,
                                const uint partial_stride, __global float* restrict grads, const uint grad_offset,
                                const uint accumulate) {
  const size_t i = get_global_id(0) * 8;
  if (i >= n) return;
  __global float* g = grads + grad_offset;
  if (i + 8 <= n) {
    float8 s = vload8(0, partial + i);
    for (uint c = 1; c < n_chunks; ++c) s += vload8(0, partial + (size_t)c * partial_stride + i);
    if (accumulate) s += vload8(0, g + i);
    vstore8(s, 0, g + i);
  } else {
    for (size_t k = i; k < n; ++k) {
      float s = partial[k];
      for (uint c = 1; c < n_chunks; ++c) s += partial[(size_t)c * partial_stride + k];
      g[k] = accumulate ? g[k] + s : s;
    }
  }
}

// ---------------------------------------------------------------------------------------------------------
// Fused training step for small networks (CPUs): one work-item = one chunk of the batch, walked TRAIN_G tiles
// at a time. Per group it recomputes the forward pass into its scratch rows, back-propagates dZ through the
// layers (dL/dx on the way), and adds every layer's dZ x input products into float16 accumulators, one per
// parameter (lanes = the samples' position in their tile). Outside its scratch, which stays in the core's L2
// cache (the host picks this kernel only while the accumulators, 64 bytes per parameter, are small), nothing
// but x, y, dy and dx is read or written; the separate kernels above write and re-read the saved activations
// and every dZ, and on a CPU they are bound by that memory traffic. The forward and backward blocks run on
// FWD_T tiles at a time; the weight-gradient blocks on all TRAIN_G tiles, so that each accumulator load and
// store feeds TRAIN_G FMAs; the chunk's first group starts them from zero, its last one writes their lane sums
// to the work-item's partial slot instead of storing them;
// mlp_reduce_chunks adds the chunks in a fixed order (deterministic, no atomics).
//
// With DW_VEC == 1 the weight-gradient blocks take the outer-product form of mlp_weight_grad_outer instead:
// per layer the group's input rows are transposed into pk and DW_RJ x DW_RK blocks accumulate float dW rows
// (cacc, 4 bytes per parameter instead of 64, so larger networks fit the cache), which the chunk's last group
// copies to the partial slot.
//
// With TRAIN_SAVED (DW_VEC == 1 only) nothing is recomputed: the training forward saved the activations
// transposed (SAVE_T) and the ReLU masks, as for the separate kernels; the dW blocks read the group's input
// vectors there (saved_act, saved_padded samples per vector) and the backward blocks the masks (saved_mask).
// Only dZ stays in the scratch: the separate kernels' dZ traffic is saved, and so is the recomputed forward
// pass, for the saved activations' traffic.
//
// scratch (per work-item, scratch_stride floats apart, 64-byte aligned):
//   acc   acc16 float16s             the accumulators: one per parameter i (the parameters' layout), or with
//                                    DW_VEC == 1 cacc (fused_outer_offset) and pk
//   rows  N_ROWS x TRAIN_G float16   like `act`: x (N_IN), ones, h_0 .. h_(N_HIDDEN-1)
//   g     2 x GROWS x TRAIN_G float16 dZ of the current layer and of the one below (GROWS: GMAX rounded up
//                                    to a multiple of DW_RJ, so that a dW block's rows past nout are there)
//   sink  N_IN x TILE floats         dL/dx of repeated tiles (past the chunk's end) goes here
// ---------------------------------------------------------------------------------------------------------
#undef HS
#define HS TRAIN_G
#define N_ROWS (ACT_H0 + N_HIDDEN * WIDTH)
#define GROWS ((GMAX + DW_RJ - 1) / DW_RJ * DW_RJ)

// The fused training kernel: h_(l-1) from the scratch rows (hprev), dZ kept in gout only.
#define POS_SCRATCH(k, u) (hprev[(k)*HS + (u)] > 0.0f)
#define SAVE_NONE(k, u, g)
#if TRAIN_SAVED
#define TRAIN_BACK_BLOCK(NR, k0) BACK_MASKED_BLOCK(NR, k0, POS_SAVED, SAVE_NONE)
#else
#define TRAIN_BACK_BLOCK(NR, k0) BACK_MASKED_BLOCK(NR, k0, POS_SCRATCH, SAVE_NONE)
#endif
#define TRAIN_BACK BACK_ROWS(TRAIN_BACK_BLOCK)

// The FWD_T tiles of sub-group s of the group starting at tile tb: tile indices (clamped to the chunk), x
// and dL/dx pointers (the sink for tiles past the chunk's end).
#define SUB_TILES(s)                                                   \
  size_t tile[FWD_T];                                                  \
  __global const float* xt[FWD_T];                                     \
  __global float* dxt[FWD_T];                                          \
  _Pragma("unroll") for (uint u = 0; u < FWD_T; ++u) {                 \
    const size_t t_ = tb + (s)*FWD_T + u;                              \
    tile[u] = min(t_, t_end - 1);                                      \
    xt[u] = x + tile[u] * (size_t)(N_IN * TILE);                       \
    dxt[u] = t_ < t_end ? dx + tile[u] * (size_t)(N_IN * TILE) : sink; \
  }

#if DW_VEC == 1
// The outer-product weight gradients of the fused kernel: per layer, its rows padded to a multiple of DW_RJ,
// each of round_up(n_in, 16) floats (the bias column apart), then with a bias its LAYER_OUT(l) float16 bias
// accumulators (BIAS_SUMS), at fused_outer_offset(l) in the work-item's cacc; the layer's input rows of the
// group transposed in pk ([v][s]: the 16 inputs 16 v .. of sample s of the group as a float16).
inline uint fused_outer_offset(const uint l) {
  uint off = 0;
  for (uint m = 0; m < l; ++m)
    off += (LAYER_OUT(m) + DW_RJ - 1) / DW_RJ * DW_RJ * ((LAYER_IN(m) + 15) / 16 * 16) + BIAS * LAYER_OUT(m) * 16;
  return off;
}

#endif

__kernel void mlp_train_fused(const uint n_tiles, const uint batch, const uint chunk_tiles, const uint acc16,
                              __global const float* restrict params, const uint param_offset,
                              __global const float* restrict wt_params, __global const float* restrict x,
                              __global const float* restrict y, __global const float* restrict dy,
                              __global float* restrict dx, const uint want_dx, __global float* restrict scratch,
                              const uint scratch_stride, __global float* restrict partial, const uint partial_stride,
                              __global const float* restrict saved_act, __global const ushort* restrict saved_mask,
                              const uint saved_padded) {
  const size_t c = get_global_id(0);
  const size_t t_begin = c * chunk_tiles;
  if (t_begin >= n_tiles) return;
  const size_t t_end = min(t_begin + chunk_tiles, (size_t)n_tiles);
  __global const float* p = params + param_offset;
  __global float16* accv = (__global float16*)(scratch + c * scratch_stride);
  __global float16* rows = accv + acc16;
#if DW_VEC == 1
  __global float* cacc = (__global float*)accv;
#if !TRAIN_SAVED
  __global float16* pk = accv + fused_outer_offset(N_HIDDEN + 1) / 16;
#endif
#endif
  __global float16* gbuf = rows + N_ROWS * TRAIN_G;
  __global float* sink = (__global float*)(gbuf + 2 * GROWS * TRAIN_G);
  const int16 lane = (int16)(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15);
  __global float* out = partial + c * (size_t)partial_stride;
#if !TRAIN_SAVED
  for (uint u = 0; u < TRAIN_G; ++u) rows[N_IN * TRAIN_G + u] = (float16)1.0f;
#endif
  // Finite values in the dZ rows a dW block reads past nout (the other layers' dZ later on).
  for (uint i = 0; i < 2 * GROWS * TRAIN_G; ++i) gbuf[i] = (float16)0.0f;
#if TRAIN_SAVED
  const uint padded = saved_padded;  // MASK_ROW's
  __global const ushort* mask = saved_mask;
#else
  const uint save = 0, padded = 0;  // the forward blocks keep their activations in the scratch only
  __global float* st = 0;
  __global ushort* mask = 0;
#endif

  for (size_t tb = t_begin; tb < t_end; tb += TRAIN_G) {
    // The chunk's first group starts the accumulators from zero, its last one writes their lane sums to the
    // partial slot in place of storing them (no separate passes over the accumulators).
    const bool first_group = tb == t_begin, last_group = tb + TRAIN_G >= t_end;
#if !TRAIN_SAVED
    // Forward through the hidden layers (the output y is the caller's, from forward()).
    for (uint sg = 0; sg < TRAIN_G / FWD_T; ++sg) {
      SUB_TILES(sg)
      for (uint k = 0; k < N_IN; ++k)
#pragma unroll
        for (uint u = 0; u < FWD_T; ++u) rows[k * HS + sg * FWD_T + u] = vload16(0, xt[u] + k * TILE);
      for (uint l = 0; l < N_HIDDEN; ++l) {
        const uint skip = (((uint)(SKIP_MASK)) >> l) & 1u;
        const uint kin = LAYER_IN(l);
        const uint stride = kin + BIAS;
        __global const float* w = p + layer_offset(l);
        __global const float16* hin = rows + (l == 0 ? 0 : ACT_H0 + (l - 1) * WIDTH) * HS + sg * FWD_T;
        __global float16* hout = rows + (ACT_H0 + l * WIDTH) * HS + sg * FWD_T;
        for (uint j0 = 0; j0 + FWD_R <= WIDTH; j0 += FWD_R) HIDDEN_BLOCK(FWD_R, j0)
#if WIDTH % FWD_R
        HIDDEN_BLOCK(WIDTH % FWD_R, WIDTH - WIDTH % FWD_R)
#endif
      }
    }
#endif

    // dZ of the output layer; zero for samples past the batch and for tiles past the chunk's end.
    {
      __global float16* gout = gbuf + (N_HIDDEN & 1) * GROWS * HS;
      for (uint u = 0; u < TRAIN_G; ++u) {
        const size_t t_ = tb + u, tu = min(t_, t_end - 1);
        const int16 valid = ((int16)((int)(tu * TILE)) + lane < (int16)((int)batch)) & (int16)(t_ < t_end ? -1 : 0);
        __global const float* yt = y + tu * (size_t)(N_OUT * TILE);
        __global const float* dyt = dy + tu * (size_t)(N_OUT * TILE);
        for (uint j = 0; j < N_OUT; ++j) {
          const float16 d = vload16(0, dyt + j * TILE) * act_grad(vload16(0, yt + j * TILE), k_out_act[j]);
          gout[j * HS + u] = select((float16)0.0f, d, valid);
        }
      }
    }

    for (uint l = N_HIDDEN;; --l) {
      const uint nout = LAYER_OUT(l);
      const uint stride = LAYER_STRIDE(l);
      const uint lskip = l > 0 && ((((uint)(SKIP_MASK)) >> l) & 1u);
      __global const float* wt = wt_params + layer_offset(l);
      // Input rows of layer l in the scratch: a_n activation rows from a_row, then from x_row (x and/or ones).
      const uint a_row = l == 0 ? 0 : ACT_H0 + (l - 1) * WIDTH, a_n = l == 0 ? 0 : WIDTH;
      const uint x_row = l == 0 || lskip ? 0 : N_IN;
#if DW_VEC == 1
      {  // dW_l += dZ_l x input_l over the group's samples, in the outer-product form (mlp_weight_grad_outer):
         // the group's input rows transposed into pk, then DW_RJ x DW_RK blocks of the float dW rows in cacc.
        __global const float16* gin = gbuf + (l & 1) * GROWS * HS;
        const uint n_dw = stride - BIAS, nv = (n_dw + 15) / 16, cs = nv * 16;
        __global float* cb_l = cacc + fused_outer_offset(l);
        __global float16* bacc = (__global float16*)(cb_l + (size_t)(nout + DW_RJ - 1) / DW_RJ * DW_RJ * cs);
#if TRAIN_SAVED
        // The input vectors as the training forward saved them (SAVE_T, as mlp_weight_grad_outer reads them):
        // the group's samples are consecutive; only the chunk's tiles are read (the last group may be short).
        const uint n_group = (uint)min((size_t)TRAIN_G, t_end - tb) * TILE;
#define PK_VEC(v) SAVED_VEC(saved_act, v, a_n, l == 0 ? 0 : ACT_HV(l - 1), 0, tb * TILE)
#else
        const uint n_group = TRAIN_G * TILE;
#define SRC_ROWS(row) rows[(row)*HS + u]
        for (uint v = 0; v < nv; ++v)
          for (uint u = 0; u < TRAIN_G; ++u)
            PACK_TILE(pk + (size_t)v * TRAIN_G * TILE + u * TILE, v, n_dw, a_n, a_row, x_row, SRC_ROWS)
#define PK_VEC(v) (pk + (size_t)(v)*TRAIN_G * TILE)
#endif
        for (uint j0 = 0; j0 < nout; j0 += DW_RJ) {
          // dZ row j0 + i over the group's samples, HS float16s apart: constant offsets from one pointer (rows
          // past nout hold whatever is there; their dW rows are not written out).
          __global const float* dzp[DW_RJ];
#pragma unroll
          for (uint i = 0; i < DW_RJ; ++i) dzp[i] = (__global const float*)(gin + (j0 + i) * HS);
          OUTER_ROW(cb_l + (size_t)j0 * cs, cs, PK_VEC, n_group, first_group)
        }
#define DZ_VEC(d, j, row_stride, t) (d)[(j) * (row_stride) + (t)]
        BIAS_SUMS(bacc, nout, gin, HS, TRAIN_G, first_group)
#undef DZ_VEC
        if (last_group) copy_dw_rows(out + layer_offset(l), stride, cb_l, nout, n_dw, cs, bacc);
      }
#else
      {  // dW_l += dZ_l x input_l over the group's TRAIN_G tiles, DW_RJ x DW_RK blocks.
        __global const float16* gin = gbuf + (l & 1) * GROWS * HS;
        __global float16* acc_l = accv + layer_offset(l);
        __global float* out_l = out + layer_offset(l);
        for (uint j0 = 0; j0 < nout; j0 += DW_RJ)
          for (uint k0 = 0; k0 < stride; k0 += DW_RK) {
            // Rows and columns past the end repeat the last one; their sums are not stored.
            __global const float16* dp[DW_RJ];
            __global const float16* ip[DW_RK];
            float16 a[DW_RJ][DW_RK];
#pragma unroll
            for (uint i = 0; i < DW_RJ; ++i) dp[i] = gin + min(j0 + i, nout - 1) * HS;
#pragma unroll
            for (uint r = 0; r < DW_RK; ++r) {
              const uint k = min(k0 + r, stride - 1);
              ip[r] = rows + (k < a_n ? a_row + k : x_row + (k - a_n)) * HS;
            }
#pragma unroll
            for (uint i = 0; i < DW_RJ; ++i)
#pragma unroll
              for (uint r = 0; r < DW_RK; ++r)
                a[i][r] = first_group ? (float16)0.0f : acc_l[min(j0 + i, nout - 1) * stride + min(k0 + r, stride - 1)];
            for (uint u = 0; u < TRAIN_G; ++u) {
              float16 v[DW_RK];
#pragma unroll
              for (uint r = 0; r < DW_RK; ++r) v[r] = ip[r][u];
#pragma unroll
              for (uint i = 0; i < DW_RJ; ++i) {
                const float16 d = dp[i][u];
#pragma unroll
                for (uint r = 0; r < DW_RK; ++r) a[i][r] = fma(d, v[r], a[i][r]);
              }
            }
#pragma unroll
            for (uint i = 0; i < DW_RJ; ++i)
#pragma unroll
              for (uint r = 0; r < DW_RK; ++r)
                if (j0 + i < nout && k0 + r < stride) {
                  const uint at = (j0 + i) * stride + k0 + r;
                  if (last_group)
                    out_l[at] = sum16(a[i][r]);
                  else
                    acc_l[at] = a[i][r];
                }
          }
      }
#endif
      // dL/dx (layer 0 and skips) and dZ of layer l - 1, FWD_T tiles at a time.
      for (uint sg = 0; sg < TRAIN_G / FWD_T; ++sg) {
        SUB_TILES(sg)
        __global const float16* gin = gbuf + (l & 1) * GROWS * HS + sg * FWD_T;
        if (want_dx && (l == 0 || lskip)) {
          const uint xcol = l == 0 ? 0 : WIDTH;
          WITH_CONST_NOUT(l, BACK_INPUT(l == TOP_SKIP))
        }
        if (l > 0) {
          __global float16* gout = gbuf + ((l + 1) & 1) * GROWS * HS + sg * FWD_T;
#if TRAIN_SAVED
          __global const ushort* mk[FWD_T];
#pragma unroll
          for (uint u = 0; u < FWD_T; ++u) mk[u] = MASK_ROW(mask, l - 1, tile[u]);
#else
          __global const float16* hprev = rows + a_row * HS + sg * FWD_T;
#endif
          WITH_CONST_NOUT(l, TRAIN_BACK)
        }
      }
      if (l == 0) break;
    }
  }
}
