// peak.cl: calibrated FMA throughput of a device (the "% of peak" of the benchmarks).
//
// Each work-item runs PEAK_CHAINS independent accumulator chains a = fma(a, c, b) for `iters` steps, in
// float16 (512-bit, or two 256-bit halves) or float8 (256-bit) vectors. The chains start from lane- and
// item-varying values (splat data lets the compiler scalarise and fake a 2x peak), and every lane of every
// chain is summed into the output, in a fixed order the host repeats to verify the result. Every chain starts
// above 0 with b > 0, so none ever becomes subnormal (every FMA on a subnormal takes a microcode assist on
// Intel cores; relit::reference::peak_chain sets the chains up the same way on the host).
#ifndef PEAK_CHAINS
#define PEAK_CHAINS 12
#endif

#define PEAK_KERNEL(NAME, VEC, N, IOTA)                                                   \
  __kernel void NAME(const uint iters, const float c, __global float* restrict out) {     \
    const size_t gid = get_global_id(0);                                                  \
    const VEC iota = IOTA;                                                                \
    const float base = (float)(gid % 64u) * 0.001f + 0.001f;                              \
    VEC a[PEAK_CHAINS], b[PEAK_CHAINS];                                                   \
    _Pragma("unroll") for (uint i = 0; i < PEAK_CHAINS; ++i) {                            \
      a[i] = fma(iota, 0.01f, (VEC)(base + (float)i * 0.1f));                             \
      b[i] = fma(iota, 0.001f, (VEC)((float)i * 0.01f + 0.001f));                         \
    }                                                                                     \
    for (uint it = 0; it < iters; ++it) {                                                 \
      _Pragma("unroll") for (uint i = 0; i < PEAK_CHAINS; ++i) a[i] = fma(a[i], c, b[i]); \
    }                                                                                     \
    float s = 0.0f;                                                                       \
    _Pragma("unroll") for (uint i = 0; i < PEAK_CHAINS; ++i) {                            \
      float t[N];                                                                         \
      vstore##N(a[i], 0, t);                                                              \
      for (uint l = 0; l < N; ++l) s += t[l];                                             \
    }                                                                                     \
    out[gid] = s;                                                                         \
  }

PEAK_KERNEL(peak_fma_f16, float16, 16, ((float16)(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15)))
PEAK_KERNEL(peak_fma_f8, float8, 8, ((float8)(0, 1, 2, 3, 4, 5, 6, 7)))
