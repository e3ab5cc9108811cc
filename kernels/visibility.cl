// visibility.cl: targets of the visibility network (DESIGN §4.3) — the transmittance of the learned density
// from each sample toward its ray's point light, or toward each of a set of directions shared by all samples
// (the environment's), by a midpoint-rule march through a cached density grid (a dense grid of sigma over
// [-1, 1]^3, refreshed from the property network every few iterations).
//
//   V(x, w) = exp(-sum_j sigma(x + t_j w) dt),  t_j = (j + 1/2) dt,  dt = d / MARCH_STEPS
// where d is the distance from x to where the shadow ray leaves the box (or to the light, if nearer).
#include "geometry.clh"

#ifndef N_SAMPLES
#define N_SAMPLES 64
#endif
#ifndef MARCH_STEPS
#define MARCH_STEPS 64
#endif
#define RAY_FLOATS 20

// exp(-optical depth) from x along unit w up to `max_distance` or the exit of the box, whichever is nearer.
inline float march_transmittance(__global const float* grid, int4 dims, float3 x, float3 w, float max_distance) {
  float t0, t1;
  float d = 0.0f;
  if (box_intersect(x, w, &t0, &t1)) d = fmin(t1, max_distance) - fmax(t0, 0.0f);
  float tau = 0.0f;
  if (d > 0.0f) {
    const float dt = d / MARCH_STEPS;
    const float start = fmax(t0, 0.0f);
    for (int j = 0; j < MARCH_STEPS; ++j) tau += grid_lookup(grid, dims, fma(start + (j + 0.5f) * dt, w, x));
    tau *= dt;
  }
  return exp(-tau);
}

inline float3 tiled_position(__global const float* positions, uint s) {
  const size_t tile = s / 16, lane = s % 16;
  return (float3)(positions[(tile * 3 + 0) * 16 + lane], positions[(tile * 3 + 1) * 16 + lane],
                  positions[(tile * 3 + 2) * 16 + lane]);
}

// One work-item per sample: V toward the light of the sample's ray (visibility: n x 1 tiled).
__kernel void march_to_light(const uint n, __global const float* restrict positions, __global const float* restrict rays,
                             __global const float* restrict grid, const int nx, const int ny, const int nz,
                             __global float* restrict visibility) {
  const uint s = get_global_id(0);
  if (s >= n) return;
  const float3 x = tiled_position(positions, s);
  __global const float* ray = rays + (size_t)(s / N_SAMPLES) * RAY_FLOATS;
  const float3 to_light = (float3)(ray[8], ray[9], ray[10]) - x;
  const float light_distance = length(to_light);
  visibility[s] = march_transmittance(grid, (int4)(nx, ny, nz, 0), x, to_light / light_distance, light_distance);
}

// V from every sample toward every one of n_dirs directions (dirs: n_dirs x 3 tiled), to the exit of the box:
// out is an n x n_dirs tiled matrix. Work-item o computes out's element o of the tiled layout (tile, direction,
// lane), so the 16 work-items of a direction and tile read 16 consecutive positions and write 16 consecutive
// values.
__kernel void march_directions(const uint n, const uint n_dirs, __global const float* restrict positions,
                               __global const float* restrict dirs, __global const float* restrict grid, const int nx,
                               const int ny, const int nz, __global float* restrict out) {
  const size_t o = get_global_id(0);
  const uint lane = o % 16, k = (o / 16) % n_dirs;
  const uint s = (uint)(o / (16 * (size_t)n_dirs)) * 16 + lane;
  if (s >= n) return;
  const size_t dbase = (size_t)(k / 16) * 48 + k % 16;
  const float3 w = (float3)(dirs[dbase], dirs[dbase + 16], dirs[dbase + 32]);
  out[o] = march_transmittance(grid, (int4)(nx, ny, nz, 0), tiled_position(positions, s), w, INFINITY);
}
