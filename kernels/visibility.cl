// visibility.cl: targets of the visibility network (docs/design.md §4.3) — the transmittance of the learned density
// from each sample toward its ray's point light, or toward each of a set of directions shared by all samples
// (the environment's), by a midpoint-rule march through a cached density grid (a dense grid of sigma over
// [-1, 1]^3, refreshed from the property network every few iterations).
//
//   V(x, w) = exp(-sum_j sigma(x + t_j w) dt),  t_j = (j + 1/2) dt,  dt = d / MARCH_STEPS
// where d is the distance from x to where the shadow ray leaves the box (or to the light, if nearer).
#ifndef N_SAMPLES
#define N_SAMPLES 64
#endif
#ifndef MARCH_STEPS
#define MARCH_STEPS 64
#endif
#include "layout.clh"

// Trilinear lookup (as grid_lookup) at 16 points at once: the coordinate math runs on float16 lanes, the 8
// corner values are gathered lane by lane.
inline float16 gather16(__global const float* g, int16 i) {
  return (float16)(g[i.s0], g[i.s1], g[i.s2], g[i.s3], g[i.s4], g[i.s5], g[i.s6], g[i.s7], g[i.s8], g[i.s9], g[i.sa],
                   g[i.sb], g[i.sc], g[i.sd], g[i.se], g[i.sf]);
}

inline void grid_axis16(float16 p, int n, int16* lo, int16* hi, float16* f) {
  const float nf = (float)n;
  const float16 u = clamp(fma(p + 1.0f, 0.5f * nf, -0.5f), 0.0f, nf - 1.0f);
  // The bound as a vector, not min(int16, int): Oclgrind 21.10 fills lanes 4-15 of that overload with garbage.
  const int16 last = (int16)(n - 1);
  *lo = min(convert_int16(floor(u)), last);
  *hi = min(*lo + 1, last);
  *f = u - convert_float16(*lo);
}

inline float16 grid_lookup16(__global const float* g, int4 n, float16 x, float16 y, float16 z) {
  int16 x0, x1, y0, y1, z0, z1;
  float16 fx, fy, fz;
  grid_axis16(x, n.x, &x0, &x1, &fx);
  grid_axis16(y, n.y, &y0, &y1, &fy);
  grid_axis16(z, n.z, &z0, &z1, &fz);
  const int16 r00 = (z0 * n.y + y0) * n.x, r10 = (z0 * n.y + y1) * n.x, r01 = (z1 * n.y + y0) * n.x,
              r11 = (z1 * n.y + y1) * n.x;
  const float16 c00 = mix(gather16(g, r00 + x0), gather16(g, r00 + x1), fx);
  const float16 c10 = mix(gather16(g, r10 + x0), gather16(g, r10 + x1), fx);
  const float16 c01 = mix(gather16(g, r01 + x0), gather16(g, r01 + x1), fx);
  const float16 c11 = mix(gather16(g, r11 + x0), gather16(g, r11 + x1), fx);
  return mix(mix(c00, c10, fy), mix(c01, c11, fy), fz);
}

// Optical depth of 16 samples (float16 lanes) along their unit directions w, from where each lane's ray is
// inside the box up to its exit or `max_distance`, whichever is nearer (slab test per lane, as box_intersect;
// a lane whose ray misses the box gets 0).
inline float16 march_depth16(__global const float* grid, int4 dims, float16 px, float16 py, float16 pz, float16 wx,
                             float16 wy, float16 wz, float16 max_distance) {
  const float16 ix = 1.0f / wx, iy = 1.0f / wy, iz = 1.0f / wz;
  const float16 ax = (-1.0f - px) * ix, bx = (1.0f - px) * ix;
  const float16 ay = (-1.0f - py) * iy, by = (1.0f - py) * iy;
  const float16 az = (-1.0f - pz) * iz, bz = (1.0f - pz) * iz;
  const float16 t0 = fmax(fmax(fmin(ax, bx), fmin(ay, by)), fmin(az, bz));
  const float16 t1 = fmin(fmin(fmax(ax, bx), fmax(ay, by)), fmax(az, bz));
  const float16 start = fmax(t0, 0.0f);
  const float16 dt = fmax(fmin(t1, max_distance) - start, 0.0f) * (1.0f / MARCH_STEPS);
  float16 tau = 0.0f;
  for (int j = 0; j < MARCH_STEPS; ++j) {
    const float16 tj = fma((float16)(j + 0.5f), dt, start);
    tau += grid_lookup16(grid, dims, fma(tj, wx, px), fma(tj, wy, py), fma(tj, wz, pz));
  }
  return tau * dt;
}

inline void load_positions16(__global const float* positions, uint tile, float16* px, float16* py, float16* pz) {
  *px = tile_load(positions, tile, 3, 0);
  *py = tile_load(positions, tile, 3, 1);
  *pz = tile_load(positions, tile, 3, 2);
}

// One work-item per tile of 16 samples (the samples of a tile belong to one ray: N_SAMPLES % 16 == 0), one
// float16 lane per sample: V toward the ray's light into column 0 of `visibility` (n x cols tiled; the other
// columns untouched), or with depth_scale k != 1 exp(-k tau), tau the optical depth (the SH head's input).
__kernel void march_to_light(const uint n_tiles, __global const float* restrict positions,
                             __global const float* restrict rays, __global const float* restrict grid, const int nx,
                             const int ny, const int nz, const float depth_scale, __global float* restrict visibility,
                             const uint cols) {
  const uint tile = get_global_id(0);
  if (tile >= n_tiles) return;
  float16 px, py, pz;
  load_positions16(positions, tile, &px, &py, &pz);
  const float3 lp = ray_light_position(RAY_RECORD(rays, (tile * RELIT_TILE) / N_SAMPLES));
  const float16 lx = lp.x - px, ly = lp.y - py, lz = lp.z - pz;
  const float16 light_distance = sqrt(fma(lx, lx, fma(ly, ly, lz * lz)));
  const float16 tau = march_depth16(grid, (int4)(nx, ny, nz, 0), px, py, pz, lx / light_distance, ly / light_distance,
                                    lz / light_distance, light_distance);
  tile_store(visibility, tile, cols, 0, exp(-depth_scale * tau));
}

// V from every sample toward every one of n_dirs directions (dirs: n_dirs x 3 tiled), to the exit of the box:
// out is an n x n_dirs tiled matrix. One work-item per (tile of 16 samples, direction): the direction is
// shared, the 16 samples are float16 lanes, and the result is one contiguous 16-float column of a tile
// (padding rows of the last tile included, computed from their zero positions).
__kernel void march_directions(const uint n_tiles, const uint n_dirs, __global const float* restrict positions,
                               __global const float* restrict dirs, __global const float* restrict grid, const int nx,
                               const int ny, const int nz, __global float* restrict out) {
  const uint item = get_global_id(0);
  if (item >= n_tiles * n_dirs) return;
  const uint tile = item / n_dirs, k = item % n_dirs;
  const float3 w = tiled3(dirs, 3, k, 0);
  float16 px, py, pz;
  load_positions16(positions, tile, &px, &py, &pz);
  const float16 tau = march_depth16(grid, (int4)(nx, ny, nz, 0), px, py, pz, (float16)w.x, (float16)w.y, (float16)w.z,
                                    (float16)INFINITY);
  tile_store(out, tile, n_dirs, k, exp(-tau));
}
