// util.cl: small element-wise kernels (the example of the documentation and the smoke test of a device).
#include "common.clh"

// y[i] = a * x[i] + y[i]
__kernel void axpy_f32(const uint n, const float a, __global const float* restrict x, __global float* restrict y) {
  const size_t i = get_global_id(0);
  if (i >= n) return;
  y[i] = fma(a, x[i], y[i]);
}
