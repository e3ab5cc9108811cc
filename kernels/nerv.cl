// nerv.cl: NeRV's one-bounce indirect light adapted to participating media (Zheng et al. 2021, appendix D;
// docs/design.md §4.5).
//
// Per camera ray r, after the direct-light pass (render.cl) has composited its samples:
//   W_r   = sum_i w_i a_i                        the albedo the ray sees, w_i = T_i (1 - exp(-sigma_i delta_i))
//   x_t   = o + t_bar d,  t_bar = sum_i w_i t_i / sum_i w_i     the expected termination point
// For the K directions w_k shared by the batch, the visibility MLP gives V_k = V(x_t, w_k) and the expected
// termination depth D_k = D(x_t, w_k); the bounce lands at x'_k = x_t + D_k w_k, where the property MLP gives
// a'_k, g'_k and the visibility MLP V'_k toward the point light (and V'_kj toward the N_e environment
// directions w_j, with weights E(w_j) / (pdf N_e), on 'env+point' data). The light single-scattered at x'_k
// back toward x_t, times the share 1 - V_k of the bounce ray that terminates, is
//   L_k   = (1 - V_k) a'_k ⊙ [p(-w_k, w_l'; g'_k) V'_k I / |p_l - x'_k|^2 + sum_j p(-w_k, w_j; g'_k) V'_kj weight_j]
// and comes back to the camera through the phase at x_t (g_t from the property MLP at x_t):
//   E_r   = (4 pi / K) sum_k p(-d, w_k; g_t) L_k,          colour_r += W_r ⊙ E_r.
// Directions point away from the scattering point, as in render.cl (HG with +2g). Gradients reach the
// albedo and density along the ray (through W) and the albedo and g at x'_k and x_t; V, D and x_t are
// constants for the render loss (V and D belong to ψ; no gradient through the sample placement).
//
// Layouts: tiled matrices (16-sample tiles) as render.cl; per-ray vectors as float4 rows.
#include "geometry.clh"
#include "layout.clh"
#include "phase.clh"

// d p(mu; g) / dg for p = (1/4pi) (1 - g^2) / (1 + g^2 + 2 g mu)^(3/2).
inline float hg_dphase_dg(float cos_owi, float g) {
  const float d = fmax(1.0f + g * g + 2.0f * g * cos_owi, 1e-12f);
  const float r = rsqrt(d);
  return RELIT_INV_4PI * r * r * r * r * r * (-2.0f * g * d - 3.0f * (1.0f - g * g) * (g + cos_owi));
}

// W_r (xyz) and sum_i w_i (w), and x_t (xyz; w = 1 when the ray terminates at all; kept as it is when
// keep_x_t is set, which the tests use to check the gradient the render loss gets).
__kernel void nerv_termination(const uint n_rays, const uint spr, __global const float* restrict rays,
                               __global const float* restrict t, __global const float* restrict delta,
                               __global const float* restrict props, const uint prop_cols,
                               __global float4* restrict albedo_sum, __global float4* restrict x_t,
                               const uint keep_x_t) {
  const uint r = get_global_id(0);
  if (r >= n_rays) return;
  __global const float* ray = RAY_RECORD(rays, r);
  float T = 1.0f, wsum = 0.0f, wt = 0.0f;
  float3 W = (float3)(0.0f);
  for (uint i = 0; i < spr; ++i) {
    const uint s = r * spr + i;
    const float alpha = 1.0f - exp(-props[TILED_AT(prop_cols, s, 0)] * delta[s]);
    const float w = T * alpha;
    W = fma(w, tiled3(props, prop_cols, s, 1), W);
    wsum += w;
    wt = fma(w, t[s], wt);
    T *= 1.0f - alpha;
  }
  albedo_sum[r] = (float4)(W, wsum);
  if (keep_x_t) return;
  const float3 o = ray_origin(ray), d = ray_direction(ray);
  const float tb = wsum > 1e-6f ? wt / wsum : 0.5f * (ray_t_near(ray) + ray_t_far(ray));
  x_t[r] = (float4)(fma(tb, d, o), wsum > 1e-6f ? 1.0f : 0.0f);
}

// Rows q N_e + j of the visibility MLP's input from the bounce points toward the environment directions.
__kernel void nerv_bounce_env_queries(const uint nq, const uint n_env, __global const float4* restrict x_b,
                                      __global const float* restrict env_dirs, __global float* restrict vis_in) {
  const uint i = get_global_id(0);
  if (i >= nq * n_env) return;
  store_tiled3(vis_in, 6, i, 0, fma(x_b[i / n_env].xyz, 0.5f, 0.5f));
  store_tiled3(vis_in, 6, i, 3, tiled3(env_dirs, 3, i % n_env, 0));
}

// Rows q = r K + k of the visibility MLP's input toward the bounce directions: [(x_t + 1) / 2, w_k].
__kernel void nerv_bounce_queries(const uint n_rays, const uint K, __global const float4* restrict x_t,
                                  __global const float* restrict dirs, __global float* restrict vis_in) {
  const uint q = get_global_id(0);
  if (q >= n_rays * K) return;
  store_tiled3(vis_in, 6, q, 0, fma(x_t[q / K].xyz, 0.5f, 0.5f));
  store_tiled3(vis_in, 6, q, 3, tiled3(dirs, 3, q % K, 0));
}

// The bounce points x'_q = clamp(x_t + D_q w_k) (xyz; w: 1 - V_q), the property MLP's inputs (rows q < n_rays K:
// x'_q, rows n_rays K + r: x_t of ray r) and the visibility MLP's inputs from x'_q toward the ray's light.
__kernel void nerv_bounce_points(const uint n_rays, const uint K, __global const float* restrict rays,
                                 __global const float4* restrict x_t, __global const float* restrict dirs,
                                 __global const float* restrict vd, const uint vd_cols, __global float4* restrict x_b,
                                 __global float* restrict net_pos, __global float* restrict light_in) {
  const uint q = get_global_id(0);
  const uint nq = n_rays * K;
  if (q >= nq + n_rays) return;
  if (q >= nq) {  // x_t of ray q - nq
    store_tiled3(net_pos, 3, q, 0, fma(x_t[q - nq].xyz, 0.5f, 0.5f));
    return;
  }
  __global const float* ray = RAY_RECORD(rays, q / K);
  const float3 w = tiled3(dirs, 3, q % K, 0);
  const float V = vd[TILED_AT(vd_cols, q, 0)], D = vd[TILED_AT(vd_cols, q, 1)];
  const float3 x = clamp(fma(D, w, x_t[q / K].xyz), -1.0f, 1.0f);
  x_b[q] = (float4)(x, 1.0f - V);
  const float3 u = fma(x, 0.5f, 0.5f);
  store_tiled3(net_pos, 3, q, 0, u);
  store_tiled3(light_in, 6, q, 0, u);
  store_tiled3(light_in, 6, q, 3, normalize(ray_light_position(ray) - x));
}

// The light bounce q sends toward x_t per unit albedo a'_q (the bracket of L_k times 1 - V_q), and its
// derivative in g'_q through *dS. Environment: n_env directions and RGB weights (tiled n_env x 3) and the
// visibility MLP's outputs at rows q n_env + j of env_vd (vd_cols columns, V first).
inline float3 bounce_light(__global const float* ray, float4 xb, float3 w, float g, float vis_l, uint q, uint n_env,
                           __global const float* env_dirs, __global const float* env_weights,
                           __global const float* env_vd, uint vd_cols, float3* dS) {
  const float3 to_l = ray_light_position(ray) - xb.xyz;
  const float r2 = fmax(dot(to_l, to_l), 1e-8f);
  const float mu = dot(-w, to_l * rsqrt(r2));
  const float3 I = ray_light_intensity(ray) * (vis_l / r2);
  float3 S = hg_phase(mu, g) * I, dS_dg = hg_dphase_dg(mu, g) * I;
  for (uint j = 0; j < n_env; ++j) {
    const float mu_j = dot(-w, tiled3(env_dirs, 3, j, 0));
    const float3 e = tiled3(env_weights, 3, j, 0) * env_vd[TILED_AT(vd_cols, q * n_env + j, 0)];
    S = fma(hg_phase(mu_j, g), e, S);
    dS_dg = fma(hg_dphase_dg(mu_j, g), e, dS_dg);
  }
  *dS = dS_dg * xb.w;
  return S * xb.w;
}

// colour_r = direct_r + W_r ⊙ E_r (n_rays x 3 rows; the renderer's backward pass needs its own colour, the
// direct one, unchanged); E_r into `indirect` (float4 rows, for the backward pass).
// bprops: the property MLP's outputs at the bounce points and x_t (sigma, albedo, tanh g, ...), g = g_scale tanh.
__kernel void nerv_indirect(const uint n_rays, const uint K, __global const float* restrict rays,
                            __global const float* restrict dirs, __global const float4* restrict x_b,
                            __global const float* restrict bprops, const uint bcols, const float g_scale,
                            __global const float* restrict light_vis, const uint lv_cols, const uint n_env,
                            __global const float* restrict env_dirs, __global const float* restrict env_weights,
                            __global const float* restrict env_vd, __global const float4* restrict albedo_sum,
                            __global const float* restrict direct, __global float* restrict color,
                            __global float4* restrict indirect) {
  const uint r = get_global_id(0);
  if (r >= n_rays) return;
  __global const float* ray = RAY_RECORD(rays, r);
  const float3 d = ray_direction(ray);
  const uint nq = n_rays * K;
  const float g_t = g_scale * bprops[TILED_AT(bcols, nq + r, 4)];
  float3 E = (float3)(0.0f);
  for (uint k = 0; k < K; ++k) {
    const uint q = r * K + k;
    const float3 w = tiled3(dirs, 3, k, 0);
    float3 dS;
    const float3 S =
        bounce_light(ray, x_b[q], w, g_scale * bprops[TILED_AT(bcols, q, 4)], light_vis[TILED_AT(lv_cols, q, 0)], q,
                     n_env, env_dirs, env_weights, env_vd, lv_cols, &dS);
    E = fma(hg_phase(dot(-d, w), g_t) * tiled3(bprops, bcols, q, 1), S, E);
  }
  E *= 4.0f * M_PI_F / K;
  indirect[r] = (float4)(E, 0.0f);
  const float3 W = albedo_sum[r].xyz;
  color[3 * r + 0] = fma(W.x, E.x, direct[3 * r + 0]);
  color[3 * r + 1] = fma(W.y, E.y, direct[3 * r + 1]);
  color[3 * r + 2] = fma(W.z, E.z, direct[3 * r + 2]);
}

// Backward of nerv_indirect given dL/dcolour (rows): dL/d(albedo, g) at the bounce points and dL/dg at x_t
// into d_bprops (tiled as bprops; the other columns zero; g through g_scale), and E ⊙ dL/dcolour per ray into
// `dw` for nerv_samples_backward.
__kernel void nerv_indirect_backward(const uint n_rays, const uint K, __global const float* restrict rays,
                                     __global const float* restrict dirs, __global const float4* restrict x_b,
                                     __global const float* restrict bprops, const uint bcols, const float g_scale,
                                     __global const float* restrict light_vis, const uint lv_cols, const uint n_env,
                                     __global const float* restrict env_dirs,
                                     __global const float* restrict env_weights, __global const float* restrict env_vd,
                                     __global const float4* restrict albedo_sum,
                                     __global const float4* restrict indirect, __global const float* restrict d_color,
                                     __global float* restrict d_bprops, __global float4* restrict dw) {
  const uint r = get_global_id(0);
  if (r >= n_rays) return;
  __global const float* ray = RAY_RECORD(rays, r);
  const float3 d = ray_direction(ray);
  const float3 dc = (float3)(d_color[3 * r], d_color[3 * r + 1], d_color[3 * r + 2]);
  dw[r] = (float4)(indirect[r].xyz * dc, 0.0f);
  const float3 dE = albedo_sum[r].xyz * dc * (4.0f * M_PI_F / K);
  const uint nq = n_rays * K;
  const float g_t = g_scale * bprops[TILED_AT(bcols, nq + r, 4)];
  float dg_t = 0.0f;
  for (uint k = 0; k < K; ++k) {
    const uint q = r * K + k;
    const float3 w = tiled3(dirs, 3, k, 0);
    const float mu_t = dot(-d, w);
    const float g = g_scale * bprops[TILED_AT(bcols, q, 4)];
    float3 dS;
    const float3 S = bounce_light(ray, x_b[q], w, g, light_vis[TILED_AT(lv_cols, q, 0)], q, n_env, env_dirs,
                                  env_weights, env_vd, lv_cols, &dS);
    const float3 a = tiled3(bprops, bcols, q, 1);
    const float pt = hg_phase(mu_t, g_t);
    const float3 da = pt * S * dE;  // dL/da'_q
    d_bprops[TILED_AT(bcols, q, 0)] = 0.0f;
    d_bprops[TILED_AT(bcols, q, 1)] = da.x;
    d_bprops[TILED_AT(bcols, q, 2)] = da.y;
    d_bprops[TILED_AT(bcols, q, 3)] = da.z;
    d_bprops[TILED_AT(bcols, q, 4)] = g_scale * pt * dot(a * dS, dE);
    for (uint c = 5; c < bcols; ++c) d_bprops[TILED_AT(bcols, q, c)] = 0.0f;
    dg_t += hg_dphase_dg(mu_t, g_t) * dot(a * S, dE);
  }
  for (uint c = 0; c < bcols; ++c) d_bprops[TILED_AT(bcols, nq + r, c)] = 0.0f;
  d_bprops[TILED_AT(bcols, nq + r, 4)] = g_scale * dg_t;
}

// dL/d(albedo_i) and dL/d(sigma_i) of W_r ⊙ E_r given dw_r = E_r ⊙ dL/dcolour_r, added to d_props:
//   d a_i += w_i dw,   d sigma_i += delta_i (T_{i+1} (a_i . dw) - sum_{j > i} w_j (a_j . dw)).
__kernel void nerv_samples_backward(const uint n_rays, const uint spr, __global const float* restrict delta,
                                    __global const float* restrict props, const uint prop_cols,
                                    __global const float4* restrict dw, __global float* restrict d_props) {
  const uint r = get_global_id(0);
  if (r >= n_rays) return;
  const float3 g = dw[r].xyz;
  float T = 1.0f, total = 0.0f;
  for (uint i = 0; i < spr; ++i) {
    const uint s = r * spr + i;
    const float alpha = 1.0f - exp(-props[TILED_AT(prop_cols, s, 0)] * delta[s]);
    total = fma(T * alpha, dot(tiled3(props, prop_cols, s, 1), g), total);
    T *= 1.0f - alpha;
  }
  T = 1.0f;
  float prefix = 0.0f;
  for (uint i = 0; i < spr; ++i) {
    const uint s = r * spr + i;
    const float alpha = 1.0f - exp(-props[TILED_AT(prop_cols, s, 0)] * delta[s]);
    const float w = T * alpha;
    const float3 a = tiled3(props, prop_cols, s, 1);
    const float ag = dot(a, g);
    prefix = fma(w, ag, prefix);
    T *= 1.0f - alpha;
    d_props[TILED_AT(prop_cols, s, 0)] += delta[s] * (T * ag - (total - prefix));
    d_props[TILED_AT(prop_cols, s, 1)] += w * g.x;
    d_props[TILED_AT(prop_cols, s, 2)] += w * g.y;
    d_props[TILED_AT(prop_cols, s, 3)] += w * g.z;
  }
}

// Visibility-MLP targets by marching the density grid from x = 2 u - 1 along w (rows of `in`: [u, w], 6
// columns): V = exp(-optical depth to the box exit) and D = the expected termination depth along the ray,
// sum_j w_j t_j / sum_j w_j (the exit distance when nothing terminates). Output: tiled, 2 columns.
__kernel void nerv_march_targets(const uint n, __global const float* restrict in, __global const float* restrict grid,
                                 const int nx, const int ny, const int nz, const uint steps,
                                 __global float* restrict out, const uint row0) {
  const uint s = get_global_id(0);
  if (s >= n) return;
  const uint row = row0 + s;
  const float3 x = fma(tiled3(in, 6, row, 0), 2.0f, -1.0f);
  const float3 w = normalize(tiled3(in, 6, row, 3));
  const int4 dims = (int4)(nx, ny, nz, 0);
  float t0, t1, len = 0.0f;
  if (box_intersect(x, w, &t0, &t1)) len = t1 - fmax(t0, 0.0f);
  float T = 1.0f, wt = 0.0f, ws = 0.0f;
  if (len > 0.0f) {
    const float dt = len / steps, start = fmax(t0, 0.0f);
    for (uint j = 0; j < steps; ++j) {
      const float tj = start + (j + 0.5f) * dt;
      const float alpha = 1.0f - exp(-grid_lookup(grid, dims, fma(tj, w, x)) * dt);
      wt = fma(T * alpha, tj, wt);
      ws += T * alpha;
      T *= 1.0f - alpha;
    }
  }
  out[TILED_AT(2, row, 0)] = T;
  out[TILED_AT(2, row, 1)] = ws > 1e-6f ? wt / ws : len;
}
