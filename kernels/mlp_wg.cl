// mlp_wg.cl: the work-group variant of the fully fused MLP (FullyFusedMLP), written the way GPU code is
// (tiny-cuda-nn's fully fused MLP in shared memory, without tensor cores): forward (inference, and the
// training forward that saves the activations), backward (dZ of every layer and dL/dinput), the weight
// gradients as per-chunk partials and their fixed-order reduction. Deterministic, no atomics. The network's
// -D description, its parameter layout and the training workspace's rows: mlp_common.clh (shared with mlp.cl,
// the SIMD variant for CPUs). FullyFusedMLP chooses the variant and these parameters per device.
//
// Forward and backward: one work-group of WG_SIZE work-items owns a tile of WG_S samples (a multiple of 16:
// whole BatchMatrix tiles). The tile's activations stay in local memory across all layers, feature-major:
//
//   xs / hs / gs:  [f0: s0 .. s(WG_S-1)][f1: s0 ..] ...          one row of WG_S floats per feature
//
// A layer's product out[j][s] = sum_k W(j, k) in[k][s] is cut into register blocks of WG_RJ outputs x WG_RS
// samples; block b = (jb, sb) takes outputs jb*WG_RJ + r and samples sb + t*NSB (strided, so that the
// work-items of a warp read consecutive local words). Work-item i computes blocks i, i + WG_SIZE, ... (WG_NB
// of them, the accumulators WG_NB x WG_RJ x WG_RS floats in registers). The weights are staged through local
// memory WG_KT columns at a time, shared by the work-group:
//
//   for each k-slice [kc, kc + WG_KT):   barrier; wt[j][kk] = W(j, kc + kk) (all work-items); barrier;
//                                        acc[b][r][t] += wt[jb*WG_RJ + r][kk] * in[kc + kk][sample(sb, t)]
//
// A hidden layer writes its outputs over its inputs (hs): every block is finished in registers, then a barrier,
// then the stores. The output layer and dL/dinput (any width) run in chunks of WIDTH outputs straight to
// global memory.
//
// Weight gradients: dW_l = dZ_l^T in_l summed over the batch, a GEMM whose reduction runs over samples. A
// work-group owns a DW_T x DW_T tile of dW and a chunk of the batch; it stages DW_S samples of the tile's
// dZ and input rows in local memory at a time, each work-item accumulating a DW_R x DW_R register block over
// the whole chunk in a fixed order, then writing it to the chunk's partial slot. mlp_wg_reduce adds the chunks
// in order (bit-for-bit reproducible).
//
// Every work-item reaches every barrier (loops around barriers have fixed trip counts); local
// arrays are written before they are read; global reads and writes stay below n_valid (the batch rounded up
// to 16) or the batch.
#include "mlp_common.clh"

#ifndef WG_S
#define WG_S 64  // samples per work-group tile, a multiple of 16
#endif
#ifndef WG_SIZE
#define WG_SIZE 64  // work-items per work-group (forward, backward)
#endif
#ifndef WG_RJ
#define WG_RJ 4  // outputs per register block
#endif
#ifndef WG_RS
#define WG_RS 4  // samples per register block
#endif
#ifndef WG_KT
#define WG_KT 16  // weight columns staged in local memory at a time
#endif
#ifndef DW_T
#define DW_T 32  // dW tile: DW_T rows x DW_T columns per work-group
#endif
#ifndef DW_R
#define DW_R 4  // dW register block: DW_R x DW_R per work-item, (DW_T / DW_R)^2 work-items
#endif
#ifndef DW_S
#define DW_S 16  // samples staged in local memory at a time by the weight-gradient kernel
#endif

#define NSB ((WG_S + WG_RS - 1) / WG_RS)                   // sample blocks of a tile
#define JBLK ((WIDTH + WG_RJ - 1) / WG_RJ)                 // output blocks of a chunk of WIDTH outputs
#define WG_NB ((JBLK * NSB + WG_SIZE - 1) / WG_SIZE)       // blocks per work-item
#define WT_STRIDE (WG_KT + 1)                              // odd row stride of the staged weights
#define ACC(b, r, t) acc[((b)*WG_RJ + (r)) * WG_RS + (t)]  // the private accumulators
#define DW_N (DW_T / DW_R)                                 // work-items along each side of a dW tile
#define DW_WG (DW_N * DW_N)
#define DW_STRIDE (DW_S + 1)
#define N_OUT_CHUNKS ((N_OUT + WIDTH - 1) / WIDTH)  // chunks of WIDTH outputs of the output layer
#define N_IN_CHUNKS ((N_IN + WIDTH - 1) / WIDTH)    // and of dL/dx

// The forward kernel's local rows: x stays beside h only when a skip layer reads it again; otherwise layer 0
// writes h over x (as every layer writes its outputs over its inputs), and the rows are shared.
#define X_ROWS ((SKIP_MASK) ? N_IN : 0)
#define H_ROWS ((SKIP_MASK) ? WIDTH : (N_IN > WIDTH ? N_IN : WIDTH))

MLP_DEFINE_ACTIVATIONS(float, apply_act1, act_grad1)

inline float hidden_act1(float z) { return HIDDEN_ACT == ACT_RELU ? fmax(z, 0.0f) : z; }

// Block b of this work-item (b < WG_NB): output block jb and sample block sb; `active` when it holds outputs
// below J.
#define BLOCK_OF(b, J)                         \
  const uint blk_ = lid + (b)*WG_SIZE;         \
  const uint jb = blk_ / NSB, sb = blk_ % NSB; \
  const bool active = jb * WG_RJ < (uint)(J)

// acc += W(j, k) in[k][s] over k < K for outputs j < J (J <= WIDTH), W(j, k) = w[j * sj + k * sk]: sk = 1 for
// a layer's product (rows of W), sj = 1 for the transposed product of the backward pass. `in` has K rows of
// WG_S samples, written before the call (the first barrier below publishes them). Every work-item of the
// group must call it with the same J, K, sj, sk.
inline void wg_accumulate(__private float* acc, const uint J, const uint K, __global const float* w, const uint sj,
                          const uint sk, __local const float* in, __local float* wt, const uint lid) {
  for (uint kc = 0; kc < K; kc += WG_KT) {
    const uint kn = min((uint)WG_KT, K - kc);
    barrier(CLK_LOCAL_MEM_FENCE);  // the previous readers of wt (and the writers of `in`) are done
    // Consecutive work-items read consecutive weights: along k for W's rows, along j for its columns.
    for (uint i = lid; i < J * kn; i += WG_SIZE) {
      const uint jj = sk == 1 ? i / kn : i % J, kk = sk == 1 ? i % kn : i / J;
      wt[jj * WT_STRIDE + kk] = w[(size_t)jj * sj + (size_t)(kc + kk) * sk];
    }
    barrier(CLK_LOCAL_MEM_FENCE);
#pragma unroll
    for (uint b = 0; b < WG_NB; ++b) {
      BLOCK_OF(b, J);
      if (!active) continue;
      for (uint kk = 0; kk < kn; ++kk) {
        __local const float* row = in + (kc + kk) * WG_S;
        float xv[WG_RS];
#pragma unroll
        for (uint t = 0; t < WG_RS; ++t) xv[t] = row[min(sb + t * NSB, (uint)WG_S - 1)];
#pragma unroll
        for (uint r = 0; r < WG_RJ; ++r) {
          const float wv = wt[min(jb * WG_RJ + r, J - 1) * WT_STRIDE + kk];
#pragma unroll
          for (uint t = 0; t < WG_RS; ++t) ACC(b, r, t) = fma(wv, xv[t], ACC(b, r, t));
        }
      }
    }
  }
}

// acc = the bias of outputs j < J of a layer whose row r starts at w + r * stride, bias in column n_in (0 without
// biases).
inline void wg_init_bias(__private float* acc, const uint J, __global const float* w, const uint stride,
                         const uint n_in, const uint lid) {
#pragma unroll
  for (uint b = 0; b < WG_NB; ++b) {
    BLOCK_OF(b, J);
#pragma unroll
    for (uint r = 0; r < WG_RJ; ++r) {
      const float v = BIAS && active ? w[min(jb * WG_RJ + r, J - 1) * stride + n_in] : 0.0f;
#pragma unroll
      for (uint t = 0; t < WG_RS; ++t) ACC(b, r, t) = v;
    }
  }
}

inline void wg_zero(__private float* acc) {
#pragma unroll
  for (uint i = 0; i < WG_NB * WG_RJ * WG_RS; ++i) acc[i] = 0.0f;
}

// For every (output j < J, sample s < WG_S) this work-item holds: `v` = its accumulator, then BODY.
#define FOR_EACH_RESULT(J, BODY)                                   \
  _Pragma("unroll") for (uint b = 0; b < WG_NB; ++b) {             \
    BLOCK_OF(b, J);                                                \
    if (!active) continue;                                         \
    _Pragma("unroll") for (uint r = 0; r < WG_RJ; ++r) {           \
      const uint j = jb * WG_RJ + r;                               \
      if (j >= (uint)(J)) continue;                                \
      _Pragma("unroll") for (uint t = 0; t < WG_RS; ++t) {         \
        const uint s = sb + t * NSB;                               \
        if (s >= WG_S) continue;                                   \
        const size_t g = s_base + s; /* the sample in the batch */ \
        float v = ACC(b, r, t);                                    \
        BODY                                                       \
      }                                                            \
    }                                                              \
  }

// ---------------------------------------------------------------------------------------------------------
// Forward: one work-group per tile of WG_S samples; n_valid = the batch rounded up to 16 (samples past it are
// neither read nor written). With save != 0 the training workspace `act` receives the rows [x, ones, h_0, ...]
// as the SIMD kernel writes them (mlp_common.clh), for the backward and weight-gradient kernels.
//
// One flat loop of passes (layer, chunk of WIDTH outputs): a pass that does not apply (an output chunk past
// N_OUT, a layer without skip's x segment) runs its product over zero columns, so that every work-item runs
// the same barriers. (Earlier forms of these kernels, with loops around barriers nested in a loop over the
// layers whose trip counts changed from layer to layer, ran wrongly under PoCL 3.1 -- dL/dx changing from run
// to run, writes past the end of dz -- although every work-item took the same path; the flat form runs
// correctly there. The cause was not isolated.)
// ---------------------------------------------------------------------------------------------------------
__kernel __attribute__((reqd_work_group_size(WG_SIZE, 1, 1))) void mlp_wg_forward(
    const uint n_valid, const uint padded, __global const float* restrict params, const uint param_offset,
    __global const float* restrict x, __global float* restrict y, __global float* restrict act, const uint save) {
  __local float rows[X_ROWS * WG_S + H_ROWS * WG_S];
  __local float wt[WIDTH * WT_STRIDE];
  __local float* xs = rows;
  __local float* hs = rows + X_ROWS * WG_S;
  const uint lid = get_local_id(0);
  const size_t s_base = get_group_id(0) * (size_t)WG_S;
  __global const float* p = params + param_offset;

  for (uint i = lid; i < N_IN * WG_S; i += WG_SIZE) {
    const uint k = i / WG_S, s = i % WG_S;
    const size_t g = s_base + s;
    const float v = g < n_valid ? x[TILED_AT(N_IN, g, k)] : 0.0f;
    xs[i] = v;
    if (save && g < n_valid) act[(size_t)k * padded + g] = v;
  }
  if (save)  // the bias column of the weight gradients
    for (uint s = lid; s < WG_S; s += WG_SIZE)
      if (s_base + s < n_valid) act[(size_t)N_IN * padded + s_base + s] = 1.0f;

  float acc[WG_NB * WG_RJ * WG_RS];
  for (uint pass = 0; pass < (N_HIDDEN + 1) * N_OUT_CHUNKS; ++pass) {
    const uint l = pass / N_OUT_CHUNKS, oc = (pass % N_OUT_CHUNKS) * WIDTH;  // layer, first output of the chunk
    const uint nout = LAYER_OUT(l), stride = LAYER_STRIDE(l);
    const bool on = oc < nout;  // hidden layers have one chunk
    const uint J = on ? min((uint)WIDTH, nout - oc) : 1;
    __global const float* w = p + layer_offset(l) + (on ? oc : 0) * stride;
    wg_init_bias(acc, J, w, stride, LAYER_IN(l), lid);
    // Layer 0 reads x; a hidden layer h, then x when it is a skip layer (its input is [h, x]).
    wg_accumulate(acc, J, on ? (l == 0 ? N_IN : WIDTH) : 0, w, stride, 1, l == 0 ? xs : hs, wt, lid);
    wg_accumulate(acc, J, on && l > 0 && LAYER_SKIP(l) ? N_IN : 0, w + WIDTH, stride, 1, xs, wt, lid);
    barrier(CLK_LOCAL_MEM_FENCE);  // every read of hs for this layer is done: overwrite it
    __global float* st = act + (size_t)(ACT_H0 + min(l, N_HIDDEN - 1u) * WIDTH) * padded;  // used when l < N_HIDDEN
    if (on)
      FOR_EACH_RESULT(J, {
        if (l < N_HIDDEN) {
          v = hidden_act1(v);
          hs[j * WG_S + s] = v;
          if (save && g < n_valid) st[(size_t)j * padded + g] = v;
        } else if (g < n_valid) {
          y[TILED_AT(N_OUT, g, oc + j)] = apply_act1(v, k_out_act[oc + j]);
        }
      })
  }
}

// ---------------------------------------------------------------------------------------------------------
// Backward: dZ of every layer into `dz` (the workspace rows, mlp_common.clh) and, when want_dx, dL/dx into
// `dx` (layer 0 and every skip layer). Samples >= batch get zero gradients whatever d_output holds there.
//
// Per layer l (from the output layer down) products of W_l^T with dZ_l (in gs), in one flat loop of passes as
// in the forward kernel: N_IN_CHUNKS passes of dL/dx from the x columns of layer 0 or a skip layer (the first
// contribution stores, the others add; the block mapping depends only on the work-item and the chunk, so each
// dx element is read and written by one work-item), then dZ_(l-1), masked by the ReLU derivative of the saved
// h_(l-1), written over dZ_l in gs and to the workspace. A pass that does not apply runs over zero columns.
// ---------------------------------------------------------------------------------------------------------
__kernel __attribute__((reqd_work_group_size(WG_SIZE, 1, 1))) void mlp_wg_backward(
    const uint n_valid, const uint padded, const uint batch, __global const float* restrict params,
    const uint param_offset, __global const float* restrict y, __global const float* restrict dy,
    __global const float* restrict act, __global float* restrict dz, __global float* restrict dx, const uint want_dx) {
  __local float gs[GMAX * WG_S];
  __local float wt[WIDTH * WT_STRIDE];
  const uint lid = get_local_id(0);
  const size_t s_base = get_group_id(0) * (size_t)WG_S;
  __global const float* p = params + param_offset;

  for (uint i = lid; i < N_OUT * WG_S; i += WG_SIZE) {  // dZ of the output layer
    const uint j = i / WG_S, s = i % WG_S;
    const size_t g = s_base + s;
    float d = 0.0f;
    if (g < batch) d = dy[TILED_AT(N_OUT, g, j)] * act_grad1(y[TILED_AT(N_OUT, g, j)], k_out_act[j]);
    gs[i] = d;
    if (g < n_valid) dz[(size_t)(N_HIDDEN * WIDTH + j) * padded + g] = d;
  }

  float acc[WG_NB * WG_RJ * WG_RS];
  for (uint pass = 0; pass < (N_HIDDEN + 1) * (N_IN_CHUNKS + 1); ++pass) {
    const uint l = N_HIDDEN - pass / (N_IN_CHUNKS + 1), q = pass % (N_IN_CHUNKS + 1);
    const bool dx_step = q < N_IN_CHUNKS;  // else the dZ_(l-1) step
    const bool on = dx_step ? want_dx && (l == 0 || LAYER_SKIP(l)) : l > 0;
    const uint oc = dx_step ? q * WIDTH : 0;  // first output of the chunk
    const uint J = dx_step ? min((uint)WIDTH, N_IN - oc) : WIDTH;
    const uint nout = LAYER_OUT(l), stride = LAYER_STRIDE(l);
    const uint col = dx_step && l > 0 ? WIDTH : 0;  // the x columns of a skip layer follow h's
    wg_zero(acc);
    wg_accumulate(acc, J, on ? nout : 0, p + layer_offset(l) + col + oc, 1, stride, gs, wt, lid);
    barrier(CLK_LOCAL_MEM_FENCE);          // every read of gs for this product is done
    const uint first = l == TOP_SKIP;      // the first dL/dx contribution
    const uint below = l > 0 ? l - 1 : 0;  // used when l > 0
    __global const float* at = act + (size_t)(ACT_H0 + below * WIDTH) * padded;  // h_(l-1)
    __global float* dzt = dz + (size_t)below * WIDTH * padded;
    if (on)
      FOR_EACH_RESULT(J, {
        if (dx_step) {
          if (g < n_valid) {
            __global float* o = dx + TILED_AT(N_IN, g, oc + j);
            if (first)  // no read of dx before its first write
              *o = v;
            else
              *o += v;
          }
        } else {
          if (HIDDEN_ACT == ACT_RELU && !(g < n_valid && at[(size_t)j * padded + g] > 0.0f)) v = 0.0f;
          gs[j * WG_S + s] = v;
          if (g < n_valid) dzt[(size_t)j * padded + g] = v;
        }
      })
  }
}

// ---------------------------------------------------------------------------------------------------------
// Weight gradients of one layer: partial[c][layer_off + j * n_in + k] = sum over the samples of chunk c of
// dZ[j][s] * in[k][s], from the workspace rows (mlp_common.clh):
//   dz rows j:  dz + (dz_row + j) * padded
//   in rows k:  act + (a_row + k) * padded for k < a_n (the layer's input activations), then
//               act + (x_row + k - a_n) * padded for the x_n remaining columns (x rows and/or the ones row).
// Work-group g: chunk g / (tj * tk), dW tile (g % (tj * tk)) of tj x tk tiles of DW_T x DW_T. Work-item
// (wj, wk) holds rows wj + r * DW_N and columns wk + q * DW_N of the tile (strided: conflict-free local reads).
// ---------------------------------------------------------------------------------------------------------
__kernel __attribute__((reqd_work_group_size(DW_WG, 1, 1))) void mlp_wg_weight_grad(
    const uint n_samples, const uint chunk_len, const uint padded, __global const float* restrict dz, const uint dz_row,
    const uint n_out, __global const float* restrict act, const uint a_row, const uint a_n, const uint x_row,
    const uint x_n, __global float* restrict partial, const uint partial_stride, const uint layer_off) {
  __local float ds[DW_T * DW_STRIDE];
  __local float is[DW_T * DW_STRIDE];
  const uint n_in = a_n + x_n;
  const uint tj = (n_out + DW_T - 1) / DW_T, tk = (n_in + DW_T - 1) / DW_T;
  const uint grp = get_group_id(0), lid = get_local_id(0);
  const uint c = grp / (tj * tk), tile = grp % (tj * tk);
  const uint j0 = (tile / tk) * DW_T, k0 = (tile % tk) * DW_T;
  const uint wj = lid % DW_N, wk = lid / DW_N;
  const uint s0 = c * chunk_len, s1 = min(s0 + chunk_len, n_samples);

  float a[DW_R][DW_R];
#pragma unroll
  for (uint r = 0; r < DW_R; ++r)
#pragma unroll
    for (uint q = 0; q < DW_R; ++q) a[r][q] = 0.0f;
  for (uint ss = s0; ss < s1; ss += DW_S) {
    barrier(CLK_LOCAL_MEM_FENCE);  // the previous step's readers are done
    for (uint i = lid; i < DW_T * DW_S; i += DW_WG) {
      const uint row = i / DW_S, t = i % DW_S;
      const uint s = ss + t, j = j0 + row, k = k0 + row;
      ds[row * DW_STRIDE + t] = j < n_out && s < s1 ? dz[(size_t)(dz_row + j) * padded + s] : 0.0f;
      is[row * DW_STRIDE + t] =
          k < n_in && s < s1 ? act[(size_t)(k < a_n ? a_row + k : x_row + (k - a_n)) * padded + s] : 0.0f;
    }
    barrier(CLK_LOCAL_MEM_FENCE);
    for (uint t = 0; t < DW_S; ++t) {
      float dv[DW_R], iv[DW_R];
#pragma unroll
      for (uint r = 0; r < DW_R; ++r) dv[r] = ds[(wj + r * DW_N) * DW_STRIDE + t];
#pragma unroll
      for (uint q = 0; q < DW_R; ++q) iv[q] = is[(wk + q * DW_N) * DW_STRIDE + t];
#pragma unroll
      for (uint r = 0; r < DW_R; ++r)
#pragma unroll
        for (uint q = 0; q < DW_R; ++q) a[r][q] = fma(dv[r], iv[q], a[r][q]);
    }
  }
  __global float* out = partial + (size_t)c * partial_stride + layer_off;
#pragma unroll
  for (uint r = 0; r < DW_R; ++r)
#pragma unroll
    for (uint q = 0; q < DW_R; ++q) {
      const uint j = j0 + wj + r * DW_N, k = k0 + wk + q * DW_N;
      if (j < n_out && k < n_in) out[j * n_in + k] = a[r][q];
    }
}

// grads[i] (+)= sum_c partial[c * partial_stride + i], chunks added in order; one parameter per work-item
// (consecutive work-items read consecutive words of each chunk).
__kernel void mlp_wg_reduce(const uint n, const uint n_chunks, __global const float* restrict partial,
                            const uint partial_stride, __global float* restrict grads, const uint grad_offset,
                            const uint accumulate) {
  const size_t i = get_global_id(0);
  if (i >= n) return;
  float s = partial[i];
  for (uint c = 1; c < n_chunks; ++c) s += partial[(size_t)c * partial_stride + i];
  __global float* g = grads + grad_offset + i;
  *g = accumulate ? *g + s : s;
}
