// method.cl: the glue kernels of the "Ours" model (docs/design.md §4.3) — network inputs that depend on the light,
// moves between the renderer's per-ray rows and the nn family's tiled matrices, density-grid refresh, and the
// NaN/Inf guard of a training step.
//
// Ray records and the tiled layout (TILED_AT: element (s, f) of a matrix with `cols` columns): layout.clh.
#include "common.clh"
#include "geometry.clh"
#include "layout.clh"

// For sample s of ray s / samples_per_ray at world position x in [-1, 1]^3 (positions: n x 3):
//   net_pos[:, 0..3]            = (x + 1) / 2               (networks see the box as [0, 1]^3)
//   light_in[:, light_col..+3]  = light_scale * p_l          (the indirect head's conditioning input)
//   vis_in[:, 0..3] = (x + 1) / 2,  vis_in[:, 3..6] = w_l = (p_l - x)/|p_l - x|   (the visibility net's input)
__kernel void light_inputs(const uint n, const uint samples_per_ray, __global const float* restrict rays,
                           __global const float* restrict positions, const float light_scale,
                           __global float* restrict net_pos, __global float* restrict light_in, const uint light_cols,
                           const uint light_col, __global float* restrict vis_in) {
  const uint s = get_global_id(0);
  if (s >= n) return;
  const float3 p = ray_light_position(RAY_RECORD(rays, s / samples_per_ray));
  const float3 x = tiled3(positions, 3, s, 0);
  const float3 w = normalize(p - x);
  const float3 u = fma(x, 0.5f, 0.5f);
  store_tiled3(net_pos, 3, s, 0, u);
  if (light_cols) store_tiled3(light_in, light_cols, s, light_col, light_scale * p);
  store_tiled3(vis_in, 6, s, 0, u);
  store_tiled3(vis_in, 6, s, 3, w);
}

// Row-major (n x cols, rows contiguous) <-> tiled n x cols.
__kernel void rows_to_tiled(const uint n, const uint cols, __global const float* restrict src,
                            __global float* restrict dst) {
  const uint s = get_global_id(0);
  if (s >= n) return;
  for (uint f = 0; f < cols; ++f) dst[TILED_AT(cols, s, f)] = src[(size_t)s * cols + f];
}
__kernel void tiled_to_rows(const uint n, const uint cols, __global const float* restrict src,
                            __global float* restrict dst) {
  const uint s = get_global_id(0);
  if (s >= n) return;
  for (uint f = 0; f < cols; ++f) dst[(size_t)s * cols + f] = src[TILED_AT(cols, s, f)];
}

// Network positions ([0, 1]^3) of voxel centres first .. first + n of an nx x ny x nz grid over the box
// (x fastest), n x 3 tiled.
__kernel void grid_positions(const uint n, const uint first, const int nx, const int ny, const int nz,
                             __global float* restrict out) {
  const uint s = get_global_id(0);
  if (s >= n) return;
  const uint v = first + s;
  const int ix = v % nx, iy = (v / nx) % ny, iz = v / (nx * ny);
  out[TILED_AT(3, s, 0)] = (ix + 0.5f) / nx;
  out[TILED_AT(3, s, 1)] = (iy + 0.5f) / ny;
  out[TILED_AT(3, s, 2)] = (iz + 0.5f) / nz;
}

// dst[offset + s] = src[s, col] for s < n (one column of a tiled matrix into a flat array).
__kernel void column_to_flat(const uint n, const uint cols, const uint col, __global const float* restrict src,
                             __global float* restrict dst, const uint offset) {
  const uint s = get_global_id(0);
  if (s >= n) return;
  dst[offset + s] = src[TILED_AT(cols, s, col)];
}

// guard[0] = a[0] + b[0] (the step's losses); when it is not finite the optimisers skip the step (they read
// guard[0]) and skipped[0] counts it. One work-item.
__kernel void step_guard(__global const float* restrict a, __global const float* restrict b,
                         __global float* restrict guard, __global uint* restrict skipped) {
  if (get_global_id(0) != 0) return;
  const float total = a[0] + b[0];
  guard[0] = total;
  if (!isfinite(total)) skipped[0] += 1;
}

// The visibility net's queries toward the N_e environment directions, sample-major: row r = s N_e + j of `out`
// (6 columns, rows from `row0` on) = [net_pos(s), w_j] for samples s < n. dirs: N_e x 3 tiled, unit.
__kernel void env_visibility_inputs(const uint n, const uint n_env, __global const float* restrict net_pos,
                                    __global const float* restrict dirs, __global float* restrict out,
                                    const uint row0) {
  const uint r = get_global_id(0);
  if (r >= n * n_env) return;
  const uint s = r / n_env, j = r % n_env;
  const uint o = row0 + r;
  for (uint c = 0; c < 3; ++c) {
    out[TILED_AT(6, o, c)] = net_pos[TILED_AT(3, s, c)];
    out[TILED_AT(6, o, 3 + c)] = dirs[TILED_AT(3, j, c)];
  }
}

// Sample-major rows (a one-column tiled matrix is flat: row r at r) <-> N_e columns of a tiled matrix:
// dst[s, col + j] = src[s N_e + j, 0]  (rows_to_columns; src has src_cols columns, V first)   and
// dst[row0 + s N_e + j] = src[s, j]  (columns_to_rows).
__kernel void env_rows_to_columns(const uint n, const uint n_env, __global const float* restrict src,
                                  const uint src_cols, __global float* restrict dst, const uint dst_cols,
                                  const uint col) {
  const uint r = get_global_id(0);
  if (r >= n * n_env) return;
  dst[TILED_AT(dst_cols, r / n_env, col + r % n_env)] = src[TILED_AT(src_cols, r, 0)];
}
__kernel void env_columns_to_rows(const uint n, const uint n_env, __global const float* restrict src,
                                  __global float* restrict dst, const uint row0) {
  const uint r = get_global_id(0);
  if (r >= n * n_env) return;
  dst[row0 + r] = src[TILED_AT(n_env, r / n_env, r % n_env)];
}

// The shadow gradient (MediumModel::add_shadow_gradient, docs/baselines.md): sample s's V toward the point light
// is exp(-∫ σ dl) over the part of its shadow ray, from x_s toward p_l, that lies in the box, so the render
// loss's dL/dV_s (column 5 of d_props) gives dL/dσ(y) = -dL/dV_s V_s at every point y of that segment, of length
// len_s. `points` points y_sj at uniform random distances on it (counter-based: seed, the global sample index,
// j) estimate the line integral: row q = s points + j of `out` (net positions, [0, 1]^3) is y_sj, and row q of
// `d_out` (the property net's outputs, `cols` columns) is -dL/dV_s V_s len_s scale / points in column 0 (σ),
// zero elsewhere. Rows n .. padded are padding: centre position, zero gradient. One work-item per row.
__kernel void shadow_points(const uint n, const uint padded, const uint samples_per_ray, const uint points,
                            const uint seed, const uint ray_first, const uint ray_stride, const float scale,
                            __global const float* restrict rays, __global const float* restrict positions,
                            __global const float* restrict props, const uint prop_cols,
                            __global const float* restrict d_props, __global float* restrict out,
                            __global float* restrict d_out, const uint cols) {
  const uint q = get_global_id(0);
  if (q >= padded) return;
  float3 y = (float3)(0.0f);
  float grad = 0.0f;
  if (q < n) {
    const uint s = q / points, j = q % points;
    const uint ray = s / samples_per_ray;
    const float3 x = tiled3(positions, 3, s, 0);
    const float3 to_light = ray_light_position(RAY_RECORD(rays, ray)) - x;
    const float dist = length(to_light);
    const float3 w = to_light / dist;
    float t0, t1, start = 0.0f, len = 0.0f;
    if (box_intersect(x, w, &t0, &t1)) {
      start = fmax(t0, 0.0f);
      len = fmax(fmin(t1, dist) - start, 0.0f);
    }
    const uint global_sample = (ray_first + ray_stride * ray) * samples_per_ray + s % samples_per_ray;
    const float u = relit_uniform(relit_hash2(relit_hash2(seed, global_sample), j));
    y = fma((float3)(fma(u, len, start)), w, x);
    grad = -TILED(d_props, prop_cols, s, 5) * TILED(props, prop_cols, s, 5) * len * (scale / points);
  }
  store_tiled3(out, 3, q, 0, fma(y, 0.5f, 0.5f));
  d_out[TILED_AT(cols, q, 0)] = grad;
  for (uint f = 1; f < cols; ++f) d_out[TILED_AT(cols, q, f)] = 0.0f;
}
