// util.cl: small element-wise kernels used across the library (and as the smoke test of a device).
#include "common.clh"

// y[i] = a * x[i] + y[i]
__kernel void axpy_f32(const uint n, const float a, __global const float* restrict x, __global float* restrict y) {
  const size_t i = get_global_id(0);
  if (i >= n) return;
  y[i] = fma(a, x[i], y[i]);
}

// x[i] = uniform random in [lo, hi), from (seed, i): reproducible, independent of the launch shape.
__kernel void fill_uniform_f32(const uint n, const uint seed, const float lo, const float hi,
                               __global float* restrict x) {
  const size_t i = get_global_id(0);
  if (i >= n) return;
  x[i] = fma(hi - lo, relit_uniform(relit_hash2(seed, (uint)i)), lo);
}
