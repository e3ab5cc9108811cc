// fill_uniform.cl: a uniform fill from common.clh's counter-based random numbers, for the tests.
#include "common.clh"

// x[i] = uniform random in [lo, hi), from (seed, i): reproducible, independent of the launch shape.
__kernel void fill_uniform_f32(const uint n, const uint seed, const float lo, const float hi,
                               __global float* restrict x) {
  const size_t i = get_global_id(0);
  if (i >= n) return;
  x[i] = fma(hi - lo, relit_uniform(relit_hash2(seed, (uint)i)), lo);
}
