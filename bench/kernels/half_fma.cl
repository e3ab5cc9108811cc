// half_fma.cl: the device's rate of half-precision multiply-adds, beside kernels/peak.cl's float rate.
//
// Each work-item runs HALF_CHAINS independent chains a = a * c + b of HALF_LANES-lane half vectors for `iters`
// steps and writes the sum of every lane of every chain (in float, chain by chain, lane by lane). Where the
// device has cl_khr_fp16 the vectors are OpenCL's half16; elsewhere the program is written with Clang's
// _Float16 vectors (32 lanes, one 512-bit register), which Clang-based compilers such as PoCL's accept without
// the extension and lower either to native half instructions or to float conversions, whichever the compiler's
// target CPU has. Lane l of chain i of work-item g starts at (g % 8) * 64 + i * 32 + l (at most 863); with
// c = 1 and b = 1 every value stays an integer below 2048 for iters <= 1000, exact in half precision, so the
// host checks the result exactly on short runs (bench/bench_isa.cpp).
#define HALF_CHAINS 12

#ifdef cl_khr_fp16
#pragma OPENCL EXTENSION cl_khr_fp16 : enable
#define HALF_LANES 16
typedef half16 hvec;
typedef half hscalar;
#else
#define HALF_LANES 32
typedef _Float16 hvec __attribute__((ext_vector_type(32)));
typedef _Float16 hscalar;
#endif

__kernel void half_fma(const uint iters, const float c, const float b, __global float* restrict out) {
  const size_t gid = get_global_id(0);
  hvec a[HALF_CHAINS];
  const hvec cv = (hvec)((hscalar)c), bv = (hvec)((hscalar)b);
  for (uint i = 0; i < HALF_CHAINS; ++i)
    for (uint l = 0; l < HALF_LANES; ++l) a[i][l] = (hscalar)(float)((gid % 8u) * 64u + i * 32u + l);
  for (uint it = 0; it < iters; ++it) {
#pragma unroll
    for (uint i = 0; i < HALF_CHAINS; ++i) a[i] = a[i] * cv + bv;
  }
  float s = 0.0f;
  for (uint i = 0; i < HALF_CHAINS; ++i)
    for (uint l = 0; l < HALF_LANES; ++l) s += (float)a[i][l];
  out[gid] = s;
}

// The lanes per vector this build uses (1 work-item), so the host counts the multiply-adds right.
__kernel void half_lanes(__global uint* restrict out) { out[0] = HALF_LANES; }
