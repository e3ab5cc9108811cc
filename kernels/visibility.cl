// visibility.cl: targets of the visibility network (DESIGN §4.3) — the transmittance of the learned density
// from each sample toward its ray's point light, by a midpoint-rule march through a cached density grid
// (a dense grid of sigma over [-1, 1]^3, refreshed from the property network every few iterations).
//
//   V(x) = exp(-sum_j sigma(x + t_j w_l) dt),  t_j = (j + 1/2) dt,  dt = d / MARCH_STEPS
// where d is the distance from x to where the shadow ray leaves the box (or to the light, if nearer).
#include "geometry.clh"

#ifndef N_SAMPLES
#define N_SAMPLES 64
#endif
#ifndef MARCH_STEPS
#define MARCH_STEPS 64
#endif
#define RAY_FLOATS 20

__kernel void march_to_light(const uint n, __global const float* restrict positions, __global const float* restrict rays,
                             __global const float* restrict grid, const int nx, const int ny, const int nz,
                             __global float* restrict visibility) {
  const uint s = get_global_id(0);
  if (s >= n) return;
  const size_t tile = s / 16, lane = s % 16;
  const float3 x = (float3)(positions[(tile * 3 + 0) * 16 + lane], positions[(tile * 3 + 1) * 16 + lane],
                            positions[(tile * 3 + 2) * 16 + lane]);
  __global const float* ray = rays + (size_t)(s / N_SAMPLES) * RAY_FLOATS;
  const float3 to_light = (float3)(ray[8], ray[9], ray[10]) - x;
  const float light_distance = length(to_light);
  const float3 w = to_light / light_distance;
  float t0, t1;
  float d = 0.0f;
  if (box_intersect(x, w, &t0, &t1)) d = fmin(t1, light_distance) - fmax(t0, 0.0f);
  float tau = 0.0f;
  if (d > 0.0f) {
    const int4 dims = (int4)(nx, ny, nz, 0);
    const float dt = d / MARCH_STEPS;
    const float start = fmax(t0, 0.0f);
    for (int j = 0; j < MARCH_STEPS; ++j) tau += grid_lookup(grid, dims, fma(start + (j + 0.5f) * dt, w, x));
    tau *= dt;
  }
  visibility[tile * 16 + lane] = exp(-tau);
}
