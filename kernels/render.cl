// render.cl: the neural volume renderer of docs/design.md §4.2 — stratified ray sampling, per-sample in-scattered
// radiance (point light + environment + SH indirect light), alpha compositing, and the backward passes of both.
//
// Samples are numbered s = ray * N_SAMPLES + i, so the 16 samples of a BatchMatrix tile all belong to one
// ray (N_SAMPLES is a multiple of 16). Per-sample kernels work on one tile per work-item with float16 lanes
// (one lane per sample: PoCL turns them into SIMD, GPUs see 16 coalesced loads); compositing is a short
// scalar scan per ray.
//
// Ray records and the tiled layout: layout.clh.
// Sample properties (BatchMatrix columns):
//   0 sigma  1-3 albedo  4 g  5 visibility (point light)  6.. SH coefficients, channel-major: c[ch * N_SH + j]
//   ENV_COL + j (= 6 + 3 N_SH + j): visibility toward environment direction j, j < N_ENV
//   SCATTERING_BRDF = 1 (solids): column 4 is the roughness r, and NORMAL_COL + 0..2 (= ENV_COL + N_ENV ..)
//   the raw normal; see "scattering brdf" below
// Radiance (BatchMatrix, 3 columns): a_i ⊙ S_i, the light each sample sends toward the camera per unit
// extinction-weighted density (with SCATTERING_BRDF: the BRDF-weighted light, one work-item per sample).
//
//   S_dir = p(w_o, w_l; g) V I / |p_l - x|^2
//   S_env = sum_j p(w_o, w_j; g) V_j weight_j,  weight_j = E(w_j) / (pdf(w_j) N_ENV)   (N_ENV > 0; RGB weights)
//   S_ind = (4 pi / K) sum_k p(w_o, w_k; g) max(0, sum_j c_j Y_j(w_k))          (INDIRECT_MODE 0)
//   S_ind = sum_lm g^l c_lm Y_lm(-w_o)                                          (INDIRECT_MODE 1)
// Mode 1 is the closed form of the HG convolution (Funk-Hecke; exact when the clamp is inactive): there
// `sh_basis` holds Y_j(-w_o) per ray (an n_rays x N_SH tiled matrix) and `dirs` is unused. The N_ENV
// environment directions and weights (N_ENV x 3 tiled each) are drawn once per iteration for the whole batch
// (environment.cl); with N_ENV = 0 the environment is compiled out and its arguments are unused.
// Directions point away from the sample (Zheng et al. 2021, appendix A); w_o = -d. HG with the paper's +2g convention.
#include "brdf.clh"
#include "common.clh"
#include "geometry.clh"
#include "layout.clh"

#include "render_config.clh"

// HG phase and its derivative in g, for mu = w_o . w_i (both pointing away from the sample).
inline float16 hg_phase16(float16 g, float16 mu) {
  const float16 d = fma(g, g, 1.0f) + 2.0f * g * mu;
  const float16 r = rsqrt(d);
  return INV_4PI * (1.0f - g * g) * r * r * r;
}
inline float16 hg_dphase16_dg(float16 g, float16 mu) {
  const float16 d = fma(g, g, 1.0f) + 2.0f * g * mu;
  const float16 r = rsqrt(d);
  const float16 r5 = r * r * r * r * r;
  return INV_4PI * r5 * (-2.0f * g * d - 3.0f * (1.0f - g * g) * (g + mu));
}

// mu = w_o . w_k for direction k of a tiled n x 3 matrix (indirect or environment directions).
inline float dir_cosine(float3 wo, __global const float* dirs, uint k) {
  return wo.x * TILED(dirs, 3, k, 0) + wo.y * TILED(dirs, 3, k, 1) + wo.z * TILED(dirs, 3, k, 2);
}

#if N_SH > 0
// Each channel's SH expansion sum_j c_j Y_j(w_k), before the max(0, .) clamp.
inline void sh_expand(const float16* c, __global const float* sh_basis, uint k, float16* lr, float16* lg, float16* lb) {
  float16 r = 0.0f, g = 0.0f, b = 0.0f;
  for (uint j = 0; j < N_SH; ++j) {
    const float y = TILED(sh_basis, N_SH, k, j);
    r = fma(c[j], y, r);
    g = fma(c[N_SH + j], y, g);
    b = fma(c[2 * N_SH + j], y, b);
  }
  *lr = r;
  *lg = g;
  *lb = b;
}

// Closed form: per channel sum_l g^l sum_m c_lm Y_lm(-w_o) with Y of the tile's ray, and, for the backward
// pass, the derivative in g (sum_l l g^(l-1) ...).
inline void sh_closed_form(const float16* c, __global const float* view_basis, uint ray, float16 g, float16* s,
                           float16* ds_dg) {
  for (int ch = 0; ch < 3; ++ch) {
    float16 sum = 0.0f, dsum = 0.0f, gl = 1.0f, dgl = 0.0f;  // g^l and its derivative l g^(l-1)
    for (uint l = 0, j = 0; j < N_SH; ++l) {
      float16 band = 0.0f;
      for (uint m = 0; m < 2 * l + 1; ++m, ++j) band = fma(c[ch * N_SH + j], TILED(view_basis, N_SH, ray, j), band);
      sum = fma(gl, band, sum);
      dsum = fma(dgl, band, dsum);
      dgl = fma(dgl, g, gl);  // d(g^(l+1)) = g d(g^l) + g^l
      gl *= g;
    }
    s[ch] = sum;
    ds_dg[ch] = dsum;
  }
}
#endif

// ---- sampling ---------------------------------------------------------------------------------------------

// Intersects each ray with the box [-1, 1]^3, writes t_near/t_far into the ray record (0, 0 on a miss), and
// places N_SAMPLES stratified samples: t_i = t_near + (i + u_i) (t_far - t_near) / N, u_i = 1/2 or jittered by
// (seed, ray, i). delta_i spans the midpoints to the neighbouring samples. positions: BatchMatrix, 3 columns.
// Ray r is ray ray_first + ray_stride r of the global batch (its rank's share, relit/parallel.hpp): the jitter
// follows the global index, so a batch split over ranks is jittered as in one process.
__kernel void sample_rays(const uint n_rays, const uint jitter, const uint seed, __global float* restrict rays,
                          __global float* restrict t_out, __global float* restrict delta_out,
                          __global float* restrict positions, const uint ray_first, const uint ray_stride) {
  const uint r = get_global_id(0);
  if (r >= n_rays) return;
  __global float* ray = RAY_RECORD(rays, r);
  const float3 o = ray_origin(ray);
  const float3 d = ray_direction(ray);
  float tn, tf;
  if (box_intersect(o, d, &tn, &tf) && tf > fmax(tn, 0.0f))
    tn = fmax(tn, 0.0f);
  else
    tn = tf = 0.0f;
  ray_set_t_range(ray, tn, tf);
  const float step = (tf - tn) / N_SAMPLES;
  // Each sample stands for the interval between the midpoints to its neighbours (t_near and t_far at the
  // ends), so the deltas tile [t_near, t_far] exactly: a homogeneous medium transmits exp(-sigma d).
  float t_prev = 0.0f, lower = tn;
  for (uint i = 0; i < N_SAMPLES; ++i) {
    const float u = jitter ? relit_uniform(relit_hash2(seed, (ray_first + ray_stride * r) * N_SAMPLES + i)) : 0.5f;
    const float t = fma((float)i + u, step, tn);
    const size_t s = (size_t)r * N_SAMPLES + i;
    t_out[s] = t;
    if (i > 0) {
      const float mid = 0.5f * (t_prev + t);
      delta_out[s - 1] = mid - lower;
      lower = mid;
    }
    t_prev = t;
    const float3 x = fma(t, d, o);
    store_tiled3(positions, 3, s, 0, x);
  }
  delta_out[(size_t)r * N_SAMPLES + N_SAMPLES - 1] = tf - lower;
}

// ---- per-sample radiance ----------------------------------------------------------------------------------

// Everything a tile's samples share or need, for forward and backward.
typedef struct {
  float3 wo;  // toward the camera
  float16 g, vis;
  float16 mu_l;    // w_o . w_l per sample
  float16 direct;  // V I / r^2 without the colour: multiplies intensity.rgb
  float16 inv_r2;  // 1 / r^2
  float3 intensity;
} TileLight;

inline TileLight tile_light(__global const float* ray, __global const float* t, __global const float* props,
                            uint tile) {
  TileLight L;
  const float3 o = ray_origin(ray);
  const float3 d = ray_direction(ray);
  const float3 lp = ray_light_position(ray);
  L.intensity = ray_light_intensity(ray);
  L.wo = -d;
  const float16 ts = tile_load(t, tile, 1, 0);  // per-sample vectors are 1-column tiled matrices
  // Vector from each sample to the light, per lane.
  const float16 lx = lp.x - fma(ts, (float16)(d.x), (float16)(o.x));
  const float16 ly = lp.y - fma(ts, (float16)(d.y), (float16)(o.y));
  const float16 lz = lp.z - fma(ts, (float16)(d.z), (float16)(o.z));
  const float16 r2 = fma(lx, lx, fma(ly, ly, lz * lz));
  const float16 inv_r = rsqrt(r2);
  L.mu_l = (L.wo.x * lx + L.wo.y * ly + L.wo.z * lz) * inv_r;
  L.g = tile_load(props, tile, PROP_COLS, 4);
  L.vis = tile_load(props, tile, PROP_COLS, 5);
  L.inv_r2 = 1.0f / r2;
  L.direct = L.vis * L.inv_r2;
  return L;
}

// radiance = albedo ⊙ (S_dir + S_env + S_ind) for the 16 samples of each tile.
__kernel void render_radiance(const uint n_tiles, __global const float* restrict rays, __global const float* restrict t,
                              __global const float* restrict props, __global const float* restrict dirs,
                              __global const float* restrict sh_basis, __global const float* restrict env_dirs,
                              __global const float* restrict env_weights, __global float* restrict radiance) {
  const uint tile = get_global_id(0);
  if (tile >= n_tiles) return;
  const uint ray_index = tile / (N_SAMPLES / RELIT_TILE);
  const TileLight L = tile_light(RAY_RECORD(rays, ray_index), t, props, tile);
  const float16 p_l = hg_phase16(L.g, L.mu_l) * L.direct;
  float16 s_r = p_l * L.intensity.x, s_g = p_l * L.intensity.y, s_b = p_l * L.intensity.z;
#if N_ENV > 0
  for (uint j = 0; j < N_ENV; ++j) {
    const float16 pv =
        hg_phase16(L.g, (float16)(dir_cosine(L.wo, env_dirs, j))) * tile_load(props, tile, PROP_COLS, ENV_COL + j);
    s_r = fma(pv, TILED(env_weights, 3, j, 0), s_r);
    s_g = fma(pv, TILED(env_weights, 3, j, 1), s_g);
    s_b = fma(pv, TILED(env_weights, 3, j, 2), s_b);
  }
#endif
#if N_SH > 0 && INDIRECT_MODE == 1
  float16 c[3 * N_SH], ind[3], unused[3];
  for (uint j = 0; j < 3 * N_SH; ++j) c[j] = tile_load(props, tile, PROP_COLS, 6 + j);
  sh_closed_form(c, sh_basis, ray_index, L.g, ind, unused);
  s_r += ind[0];
  s_g += ind[1];
  s_b += ind[2];
#elif N_SH > 0
  float16 c[3 * N_SH];
  for (uint j = 0; j < 3 * N_SH; ++j) c[j] = tile_load(props, tile, PROP_COLS, 6 + j);
  float16 i_r = 0.0f, i_g = 0.0f, i_b = 0.0f;
  for (uint k = 0; k < N_DIRS; ++k) {
    const float mu = dir_cosine(L.wo, dirs, k);
    const float16 p = hg_phase16(L.g, (float16)(mu));
    float16 lr, lg, lb;
    sh_expand(c, sh_basis, k, &lr, &lg, &lb);
    i_r = fma(p, fmax(lr, 0.0f), i_r);
    i_g = fma(p, fmax(lg, 0.0f), i_g);
    i_b = fma(p, fmax(lb, 0.0f), i_b);
  }
  const float w = 4.0f * M_PI_F / N_DIRS;
  s_r = fma(i_r, w, s_r);
  s_g = fma(i_g, w, s_g);
  s_b = fma(i_b, w, s_b);
#endif
  tile_store(radiance, tile, 3, 0, tile_load(props, tile, PROP_COLS, 1) * s_r);
  tile_store(radiance, tile, 3, 1, tile_load(props, tile, PROP_COLS, 2) * s_g);
  tile_store(radiance, tile, 3, 2, tile_load(props, tile, PROP_COLS, 3) * s_b);
}

// Given dL/d(radiance): dL/d(albedo), dL/dg and dL/d(SH coefficients) into d_props (columns 1..4 and 6..);
// sigma's column is written by the compositing backward, the visibility columns (point light and
// environment) get zero: the render loss must not reach the visibility network (gradient isolation); with
// VISIBILITY_GRADIENT the point light's column gets dL/dV (for the shadow gradient, not for the network).
__kernel void render_radiance_backward(const uint n_tiles, __global const float* restrict rays,
                                       __global const float* restrict t, __global const float* restrict props,
                                       __global const float* restrict dirs, __global const float* restrict sh_basis,
                                       __global const float* restrict env_dirs,
                                       __global const float* restrict env_weights,
                                       __global const float* restrict d_radiance, __global float* restrict d_props) {
  const uint tile = get_global_id(0);
  if (tile >= n_tiles) return;
  const uint ray_index = tile / (N_SAMPLES / RELIT_TILE);
  const TileLight L = tile_light(RAY_RECORD(rays, ray_index), t, props, tile);
  const float16 ar = tile_load(props, tile, PROP_COLS, 1), ag = tile_load(props, tile, PROP_COLS, 2),
                ab = tile_load(props, tile, PROP_COLS, 3);
  const float16 dr = tile_load(d_radiance, tile, 3, 0), dg = tile_load(d_radiance, tile, 3, 1),
                db = tile_load(d_radiance, tile, 3, 2);
  // Upstream gradient per channel on S (radiance = a ⊙ S).
  const float16 er = dr * ar, eg = dg * ag, eb = db * ab;
  const float16 dir_common = L.direct;
  const float16 p_l = hg_phase16(L.g, L.mu_l) * dir_common;
  float16 s_r = p_l * L.intensity.x, s_g = p_l * L.intensity.y, s_b = p_l * L.intensity.z;
  float16 d_g =
      hg_dphase16_dg(L.g, L.mu_l) * dir_common * (er * L.intensity.x + eg * L.intensity.y + eb * L.intensity.z);
#if N_ENV > 0
  for (uint j = 0; j < N_ENV; ++j) {
    const float16 mu = (float16)(dir_cosine(L.wo, env_dirs, j));
    const float16 v = tile_load(props, tile, PROP_COLS, ENV_COL + j);
    const float wr = TILED(env_weights, 3, j, 0), wg = TILED(env_weights, 3, j, 1), wb = TILED(env_weights, 3, j, 2);
    const float16 pv = hg_phase16(L.g, mu) * v;
    s_r = fma(pv, wr, s_r);
    s_g = fma(pv, wg, s_g);
    s_b = fma(pv, wb, s_b);
    d_g = fma(hg_dphase16_dg(L.g, mu) * v, fma(er, wr, fma(eg, wg, eb * wb)), d_g);
    tile_store(d_props, tile, PROP_COLS, ENV_COL + j, (float16)(0.0f));
  }
#endif
#if N_SH > 0 && INDIRECT_MODE == 1
  float16 c[3 * N_SH], ind[3], dind[3];
  for (uint j = 0; j < 3 * N_SH; ++j) c[j] = tile_load(props, tile, PROP_COLS, 6 + j);
  sh_closed_form(c, sh_basis, ray_index, L.g, ind, dind);
  s_r += ind[0];
  s_g += ind[1];
  s_b += ind[2];
  d_g = fma(er, dind[0], fma(eg, dind[1], fma(eb, dind[2], d_g)));
  {
    const float16 e[3] = {er, eg, eb};
    for (int ch = 0; ch < 3; ++ch) {
      float16 gl = 1.0f;
      for (uint l = 0, j = 0; j < N_SH; ++l, gl *= L.g)
        for (uint m = 0; m < 2 * l + 1; ++m, ++j)
          tile_store(d_props, tile, PROP_COLS, 6 + ch * N_SH + j, e[ch] * gl * TILED(sh_basis, N_SH, ray_index, j));
    }
  }
#elif N_SH > 0
  float16 c[3 * N_SH];
  float16 dc[3 * N_SH];
  for (uint j = 0; j < 3 * N_SH; ++j) {
    c[j] = tile_load(props, tile, PROP_COLS, 6 + j);
    dc[j] = 0.0f;
  }
  const float w = 4.0f * M_PI_F / N_DIRS;
  float16 i_r = 0.0f, i_g = 0.0f, i_b = 0.0f;
  for (uint k = 0; k < N_DIRS; ++k) {
    const float mu = dir_cosine(L.wo, dirs, k);
    const float16 p = hg_phase16(L.g, (float16)(mu));
    const float16 dp = hg_dphase16_dg(L.g, (float16)(mu));
    float16 lr, lg, lb;
    sh_expand(c, sh_basis, k, &lr, &lg, &lb);
    const float16 pr = fmax(lr, 0.0f), pg = fmax(lg, 0.0f), pb = fmax(lb, 0.0f);
    i_r = fma(p, pr, i_r);
    i_g = fma(p, pg, i_g);
    i_b = fma(p, pb, i_b);
    d_g = fma(dp * w, er * pr + eg * pg + eb * pb, d_g);
    // d/dc_j of max(0, L_k): Y_j where L_k > 0.
    const float16 zero = 0.0f;
    const float16 gr = select(zero, p * er * w, lr > 0.0f), gg = select(zero, p * eg * w, lg > 0.0f),
                  gb = select(zero, p * eb * w, lb > 0.0f);
    for (uint j = 0; j < N_SH; ++j) {
      const float y = TILED(sh_basis, N_SH, k, j);
      dc[j] = fma(gr, y, dc[j]);
      dc[N_SH + j] = fma(gg, y, dc[N_SH + j]);
      dc[2 * N_SH + j] = fma(gb, y, dc[2 * N_SH + j]);
    }
  }
  s_r = fma(i_r, w, s_r);
  s_g = fma(i_g, w, s_g);
  s_b = fma(i_b, w, s_b);
  for (uint j = 0; j < 3 * N_SH; ++j) tile_store(d_props, tile, PROP_COLS, 6 + j, dc[j]);
#endif
  tile_store(d_props, tile, PROP_COLS, 1, dr * s_r);
  tile_store(d_props, tile, PROP_COLS, 2, dg * s_g);
  tile_store(d_props, tile, PROP_COLS, 3, db * s_b);
  tile_store(d_props, tile, PROP_COLS, 4, d_g);
#if VISIBILITY_GRADIENT
  // dS_dir/dV = p(w_o, w_l) I / r^2 per channel.
  const float16 d_vis =
      hg_phase16(L.g, L.mu_l) * L.inv_r2 * (er * L.intensity.x + eg * L.intensity.y + eb * L.intensity.z);
  tile_store(d_props, tile, PROP_COLS, 5, d_vis);
#else
  tile_store(d_props, tile, PROP_COLS, 5, (float16)(0.0f));
#endif
}

// ---- per-sample radiance, scattering "brdf" (solids, docs/design.md §4.4) -------------------------------------------
//
// The light a surface sample sends toward the camera: each light term adds f(w_o, w_i) max(0, n.w_i) L(w_i)
// with f = a * diffuse + spec the BRDF of brdf.clh (the path tracer's), n = n_raw / |n_raw|:
//   point light   L = V I / |p_l - x|^2
//   environment   L_j = V_j weight_j                                      (N_ENV > 0)
//   indirect      L_k = (4 pi / K) max(0, sum_j c_j Y_j(w_k))              (the K-direction sum; no closed form)
// so radiance = a ⊙ sum diffuse cos L + sum spec cos L (the specular part is not scaled by the albedo).
// One work-item per sample, scalar: the BRDF is written for one direction pair, as the path tracer needs it.
// These kernels are compiled in either mode; the renderer launches them with SCATTERING_BRDF = 1 only.

typedef struct {
  BrdfView brdf;  // unit normal n, w_o, roughness and what the BRDF derives from them once per sample
  float3 wl, albedo;
  float3 direct;  // V I / |p_l - x|^2
  float3 light;   // I / |p_l - x|^2: d(direct)/dV
  float inv_len;  // 1 / |n_raw| (0 for a zero normal, which scatters nothing)
} SurfacePoint;

inline SurfacePoint surface_point(__global const float* ray, __global const float* t, __global const float* props,
                                  uint s) {
  SurfacePoint p;
  const float3 o = ray_origin(ray);
  const float3 d = ray_direction(ray);
  const float3 to_light = ray_light_position(ray) - fma((float3)(t[s]), d, o);
  const float r2 = dot(to_light, to_light);
  p.wl = to_light * rsqrt(r2);
  p.light = ray_light_intensity(ray) / r2;
  p.direct = p.light * TILED(props, PROP_COLS, s, 5);
  const float3 m = tiled3(props, PROP_COLS, s, NORMAL_COL);
  const float len2 = dot(m, m);
  p.inv_len = len2 > 0.0f ? rsqrt(len2) : 0.0f;
  p.brdf = brdf_view(m * p.inv_len, -d, TILED(props, PROP_COLS, s, 4));
  p.albedo = tiled3(props, PROP_COLS, s, 1);
  return p;
}

inline float3 tiled_dir(__global const float* dirs, uint k) { return tiled3(dirs, 3, k, 0); }

#if N_SH > 0
// sum_j c_j Y_j(w_k) per channel, before the clamp.
inline float3 sh_expand3(const float* c, __global const float* sh_basis, uint k) {
  float3 l = 0.0f;
  for (uint j = 0; j < N_SH; ++j) {
    const float y = TILED(sh_basis, N_SH, k, j);
    l = fma((float3)(c[j], c[N_SH + j], c[2 * N_SH + j]), (float3)(y), l);
  }
  return l;
}
#endif

__kernel void render_radiance_brdf(const uint n, __global const float* restrict rays, __global const float* restrict t,
                                   __global const float* restrict props, __global const float* restrict dirs,
                                   __global const float* restrict sh_basis, __global const float* restrict env_dirs,
                                   __global const float* restrict env_weights, __global float* restrict radiance) {
  const uint s = get_global_id(0);
  if (s >= n) return;
  const SurfacePoint p = surface_point(RAY_RECORD(rays, s / N_SAMPLES), t, props, s);
  float3 diffuse = 0.0f, spec = 0.0f;  // sum of diffuse cos L, of spec cos L
  BrdfTerms b = brdf_at(&p.brdf, p.wl, 0);
  float c_i = fmax(dot(p.brdf.n, p.wl), 0.0f);
  diffuse = b.diffuse * c_i * p.direct;
  spec = b.spec * c_i * p.direct;
#if N_ENV > 0
  for (uint j = 0; j < N_ENV; ++j) {
    const float3 w = tiled_dir(env_dirs, j);
    b = brdf_at(&p.brdf, w, 0);
    if (b.diffuse == 0.0f && b.spec == 0.0f) continue;  // below the surface
    const float3 L = TILED(props, PROP_COLS, s, ENV_COL + j) * tiled_dir(env_weights, j);
    c_i = dot(p.brdf.n, w);
    diffuse = fma((float3)(b.diffuse * c_i), L, diffuse);
    spec = fma((float3)(b.spec * c_i), L, spec);
  }
#endif
#if N_SH > 0
  float c[3 * N_SH];
  for (uint j = 0; j < 3 * N_SH; ++j) c[j] = TILED(props, PROP_COLS, s, 6 + j);
  const float w_k = 4.0f * M_PI_F / N_DIRS;
  for (uint k = 0; k < N_DIRS; ++k) {
    const float3 w = tiled_dir(dirs, k);
    b = brdf_at(&p.brdf, w, 0);
    if (b.diffuse == 0.0f && b.spec == 0.0f) continue;
    const float3 L = w_k * fmax(sh_expand3(c, sh_basis, k), 0.0f);
    c_i = dot(p.brdf.n, w);
    diffuse = fma((float3)(b.diffuse * c_i), L, diffuse);
    spec = fma((float3)(b.spec * c_i), L, spec);
  }
#endif
  const float3 rad = fma(p.albedo, diffuse, spec);
  store_tiled3(radiance, 3, s, 0, rad);
}

// One light term's share of the backward pass: e = dL/d(radiance), L the term's incident light. Adds the
// albedo's factor (diffuse cos L) and the gradients in r and in the unit normal; returns dL/dL per channel,
// e ⊙ (a diffuse + spec) cos, for the indirect terms' SH coefficients.
inline float3 brdf_term_backward(const SurfacePoint* p, float3 w, float3 L, float3 e, float3* diffuse, float* d_r,
                                 float3* d_n) {
  BrdfGrad g;
  const BrdfTerms b = brdf_at(&p->brdf, w, &g);
  if (b.diffuse == 0.0f && b.spec == 0.0f) return (float3)(0.0f);  // below the surface: zero nearby too
  const float c = dot(p->brdf.n, w);
  *diffuse = fma((float3)(b.diffuse * c), L, *diffuse);
  const float e_d = dot(e * p->albedo, L), e_s = dot(e, L);  // upstream weights of diffuse cos, spec cos
  *d_r += c * (e_d * g.d_diffuse_dr + e_s * g.d_spec_dr);
  *d_n += e_d * fma((float3)(c), g.d_diffuse_dn, b.diffuse * w) + e_s * fma((float3)(c), g.d_spec_dn, b.spec * w);
  return e * fma(p->albedo, (float3)(b.diffuse), (float3)(b.spec)) * c;
}

// Given dL/d(radiance): dL/d(albedo), dL/dr, dL/d(SH coefficients) and dL/d(n_raw) into d_props; sigma's
// column is written by the compositing backward; every visibility column gets zero (gradient isolation), but
// the point light's gets dL/dV with VISIBILITY_GRADIENT.
__kernel void render_radiance_brdf_backward(
    const uint n, __global const float* restrict rays, __global const float* restrict t,
    __global const float* restrict props, __global const float* restrict dirs, __global const float* restrict sh_basis,
    __global const float* restrict env_dirs, __global const float* restrict env_weights,
    __global const float* restrict d_radiance, __global float* restrict d_props) {
  const uint s = get_global_id(0);
  if (s >= n) return;
  const SurfacePoint p = surface_point(RAY_RECORD(rays, s / N_SAMPLES), t, props, s);
  const float3 e = tiled3(d_radiance, 3, s, 0);
  float3 diffuse = 0.0f, d_n = 0.0f;
  float d_r = 0.0f;
  const float3 d_direct = brdf_term_backward(&p, p.wl, p.direct, e, &diffuse, &d_r, &d_n);
#if N_ENV > 0
  for (uint j = 0; j < N_ENV; ++j) {
    const float3 L = TILED(props, PROP_COLS, s, ENV_COL + j) * tiled_dir(env_weights, j);
    brdf_term_backward(&p, tiled_dir(env_dirs, j), L, e, &diffuse, &d_r, &d_n);
    TILED(d_props, PROP_COLS, s, ENV_COL + j) = 0.0f;
  }
#endif
#if N_SH > 0
  float c[3 * N_SH], dc[3 * N_SH];
  for (uint j = 0; j < 3 * N_SH; ++j) {
    c[j] = TILED(props, PROP_COLS, s, 6 + j);
    dc[j] = 0.0f;
  }
  const float w_k = 4.0f * M_PI_F / N_DIRS;
  for (uint k = 0; k < N_DIRS; ++k) {
    const float3 w = tiled_dir(dirs, k);
    if (dot(p.brdf.n, w) <= 0.0f || p.brdf.n_v <= 0.0f) continue;  // below the surface: no light, no gradient
    const float3 lk = sh_expand3(c, sh_basis, k);
    const float3 L = w_k * fmax(lk, 0.0f);
    const float3 dl = brdf_term_backward(&p, w, L, e, &diffuse, &d_r, &d_n);
    // d/dc_j of w_k max(0, l_k): w_k Y_j where l_k > 0.
    const float3 g = w_k * select((float3)(0.0f), dl, isgreater(lk, (float3)(0.0f)));
    if (g.x == 0.0f && g.y == 0.0f && g.z == 0.0f) continue;
    for (uint j = 0; j < N_SH; ++j) {
      const float y = TILED(sh_basis, N_SH, k, j);
      dc[j] = fma(g.x, y, dc[j]);
      dc[N_SH + j] = fma(g.y, y, dc[N_SH + j]);
      dc[2 * N_SH + j] = fma(g.z, y, dc[2 * N_SH + j]);
    }
  }
  for (uint j = 0; j < 3 * N_SH; ++j) TILED(d_props, PROP_COLS, s, 6 + j) = dc[j];
#endif
  const float3 d_albedo = e * diffuse;
  store_tiled3(d_props, PROP_COLS, s, 1, d_albedo);
  TILED(d_props, PROP_COLS, s, 4) = d_r;
  TILED(d_props, PROP_COLS, s, 5) = VISIBILITY_GRADIENT ? dot(d_direct, p.light) : 0.0f;
  // Through n = n_raw / |n_raw|: (I - n n^T) / |n_raw|.
  const float3 d_m = (d_n - p.brdf.n * dot(p.brdf.n, d_n)) * p.inv_len;
  store_tiled3(d_props, PROP_COLS, s, NORMAL_COL, d_m);
}

// ---- compositing ------------------------------------------------------------------------------------------

// color = sum_i T_i alpha_i radiance_i + T_N background, alpha_i = 1 - exp(-sigma_i delta_i).
// Also writes the final transmittance per ray (alpha = 1 - T_N is the pixel's opacity).
__kernel void composite(const uint n_rays, __global const float* restrict rays, __global const float* restrict delta,
                        __global const float* restrict props, __global const float* restrict radiance,
                        __global float* restrict color, __global float* restrict transmittance) {
  const uint r = get_global_id(0);
  if (r >= n_rays) return;
  float T = 1.0f;
  float3 c = 0.0f;
  for (uint i = 0; i < N_SAMPLES; ++i) {
    const size_t s = (size_t)r * N_SAMPLES + i;
    const float alpha = 1.0f - exp(-TILED(props, PROP_COLS, s, 0) * delta[s]);
    const float w = T * alpha;
    c = fma((float3)(w), tiled3(radiance, 3, s, 0), c);
    T *= 1.0f - alpha;
  }
  c = fma((float3)(T), ray_background(RAY_RECORD(rays, r)), c);
  vstore3(c, r, color);
  transmittance[r] = T;
}

// Given dL/dcolor: dL/dsigma_i into d_props column 0 and dL/dradiance_i = w_i dL/dcolor.
//   dC/dsigma_k = delta_k ( T_k (1 - alpha_k) c_k - sum_{i>k} w_i c_i - T_N bg )
// The suffix sum is the total colour minus the running prefix, so one forward sweep suffices.
__kernel void composite_backward(const uint n_rays, __global const float* restrict rays,
                                 __global const float* restrict delta, __global const float* restrict props,
                                 __global const float* restrict radiance, __global const float* restrict color,
                                 __global const float* restrict d_color, __global float* restrict d_props,
                                 __global float* restrict d_radiance) {
  const uint r = get_global_id(0);
  if (r >= n_rays) return;
  const float3 C = vload3(r, color);
  const float3 dC = vload3(r, d_color);
  float T = 1.0f;
  float3 prefix = 0.0f;
  for (uint i = 0; i < N_SAMPLES; ++i) {
    const size_t s = (size_t)r * N_SAMPLES + i;
    const float d = delta[s];
    const float alpha = 1.0f - exp(-TILED(props, PROP_COLS, s, 0) * d);
    const float w = T * alpha;
    const float3 ci = tiled3(radiance, 3, s, 0);
    prefix = fma((float3)(w), ci, prefix);
    const float3 suffix = C - prefix;  // sum_{i>k} w_i c_i + T_N bg
    const float3 dsigma3 = d * (T * (1.0f - alpha) * ci - suffix);
    TILED(d_props, PROP_COLS, s, 0) = dot(dsigma3, dC);
    store_tiled3(d_radiance, 3, s, 0, w * dC);
    T *= 1.0f - alpha;
  }
}

// -w_o = d of each ray, as an n_rays x 3 tiled matrix: the SH encoding turns it into Y(-w_o) for mode 1.
__kernel void view_directions(const uint n_rays, __global const float* restrict rays, __global float* restrict out) {
  const uint r = get_global_id(0);
  if (r >= n_rays) return;
  store_tiled3(out, 3, r, 0, ray_direction(RAY_RECORD(rays, r)));
}

// Channel-major RGB blocks of `per_channel` columns, scaled per sample by its ray's light intensity:
// dst[ch * per_channel + j] = I_ch(ray(s)) * src[ch * per_channel + j]. Indirect light is linear in the light's
// intensity, so the SH head predicts light per unit intensity (docs/design.md §4.3). `scale` multiplies every value
// (the model's intensity normalisation). One work-item per tile: its 16 samples belong to one ray.
__kernel void scale_rgb_by_ray_intensity(const uint n_tiles, const uint per_channel, const float scale,
                                         __global const float* restrict rays, __global const float* restrict src,
                                         const uint src_cols, const uint src_col, __global float* restrict dst,
                                         const uint dst_cols, const uint dst_col) {
  const size_t t = get_global_id(0);
  if (t >= n_tiles) return;
  __global const float* ray = RAY_RECORD(rays, (t * RELIT_TILE) / N_SAMPLES);
  for (uint ch = 0; ch < 3; ++ch) {
    const float intensity = scale * ray[RELIT_RAY_LIGHT_INTENSITY + ch];
    for (uint j = 0; j < per_channel; ++j) {
      const uint c = ch * per_channel + j;
      tile_store(dst, t, dst_cols, dst_col + c, intensity * tile_load(src, t, src_cols, src_col + c));
    }
  }
}
