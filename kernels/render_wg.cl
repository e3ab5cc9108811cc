// render_wg.cl: the work-group variant of the renderer's lighting and compositing (render.cl has the SIMD
// variant, the sampling, the scattering "brdf" kernels and the definitions of every term): the same in-scattered
// radiance, compositing and backward passes, shaped for GPUs.
//
// One work-group per ray, RAY_ITEMS work-items (a power of two dividing N_SAMPLES); work-item i takes the ray's
// samples i, i + RAY_ITEMS, ..., so that consecutive work-items read consecutive samples of a column of the tiled
// property matrix (coalesced). What every sample of a ray, or of the batch, reads is loaded once per group:
//   - the ray record (one broadcast load per field);
//   - with STAGE_DIRS, the K indirect directions and their SH basis (K x (3 + N_SH) floats) and the N_ENV
//     environment directions and weights, staged in local memory: each is read by every sample, N_SAMPLES times
//     per ray (the host stages them where they fit the device's local memory);
//   - in closed-form mode (INDIRECT_MODE 1), the ray's view basis Y(-w_o).
//
// Compositing is a scan along the ray: the transmittance before sample i is T_i = exp(-tau_i) with tau_i the
// optical depth sum_{j<i} sigma_j delta_j (the same as the SIMD kernel's product of (1 - alpha_j) =
// exp(-sigma_j delta_j), in another rounding order). Each RAY_ITEMS-sample segment of the ray is scanned in
// local memory (Hillis-Steele, log2(RAY_ITEMS) steps) with the segments' totals carried in order; colours are
// summed by the same scan. The backward pass needs, per sample, the light that arrives from behind it,
// sum_{i>k} w_i c_i + T_N background: a second scan, run from the far end of the ray, gives it directly (the
// SIMD kernel subtracts a running prefix from the colour instead). Every sum has one fixed order, whatever
// the timing of the work-items: the results are bit-for-bit reproducible.
#include "layout.clh"

#include "render_config.clh"

#ifndef RAY_ITEMS
#define RAY_ITEMS 64
#endif
#ifndef STAGE_DIRS
#define STAGE_DIRS 1
#endif
#if N_SAMPLES % RAY_ITEMS != 0 || (RAY_ITEMS & (RAY_ITEMS - 1)) != 0
#error "RAY_ITEMS must be a power of two dividing N_SAMPLES"
#endif
#define SEGMENTS (N_SAMPLES / RAY_ITEMS)
#define INDIRECT_SUM (N_SH > 0 && INDIRECT_MODE == 0)
#define STAGED_INDIRECT (STAGE_DIRS && INDIRECT_SUM)
#define STAGED_ENV (STAGE_DIRS && N_ENV > 0)

// The HG phase and its derivative in g, as render.cl's hg_phase16 / hg_dphase16_dg, per sample.
inline float hg_phase1(float g, float mu) {
  const float d = fma(g, g, 1.0f) + 2.0f * g * mu;
  const float r = rsqrt(d);
  return INV_4PI * (1.0f - g * g) * r * r * r;
}
inline float hg_dphase1_dg(float g, float mu) {
  const float d = fma(g, g, 1.0f) + 2.0f * g * mu;
  const float r = rsqrt(d);
  const float r5 = r * r * r * r * r;
  return INV_4PI * r5 * (-2.0f * g * d - 3.0f * (1.0f - g * g) * (g + mu));
}

// Shared inputs, staged or read from global memory: direction k's component c, its basis value j, the
// environment direction / weight j's component c, the ray's view basis value j.
#if STAGED_INDIRECT
#define DIR(k, c) l_dirs[(k)*3 + (c)]
#define BASIS(k, j) l_basis[(k)*N_SH + (j)]
#else
#define DIR(k, c) TILED(dirs, 3, k, c)
#define BASIS(k, j) TILED(sh_basis, N_SH, k, j)
#endif
#if STAGED_ENV
#define ENV_DIR(j, c) l_env[(j)*6 + (c)]
#define ENV_WEIGHT(j, c) l_env[(j)*6 + 3 + (c)]
#else
#define ENV_DIR(j, c) TILED(env_dirs, 3, j, c)
#define ENV_WEIGHT(j, c) TILED(env_weights, 3, j, c)
#endif
#define VIEW_BASIS(j) l_view[j]

// Declares the group's local copies (at kernel scope, where OpenCL wants __local variables) and fills them.
#if STAGED_INDIRECT
#define DECLARE_INDIRECT            \
  __local float l_dirs[N_DIRS * 3]; \
  __local float l_basis[N_DIRS * N_SH];
#define STAGE_INDIRECT                                                                         \
  for (uint q = lid; q < N_DIRS * 3; q += RAY_ITEMS) l_dirs[q] = TILED(dirs, 3, q / 3, q % 3); \
  for (uint q = lid; q < N_DIRS * N_SH; q += RAY_ITEMS) l_basis[q] = TILED(sh_basis, N_SH, q / N_SH, q % N_SH);
#else
#define DECLARE_INDIRECT
#define STAGE_INDIRECT
#endif
#if STAGED_ENV
#define DECLARE_ENV __local float l_env[N_ENV * 6];
#define STAGE_ENV                                   \
  for (uint q = lid; q < N_ENV * 6; q += RAY_ITEMS) \
    l_env[q] = (q % 6) < 3 ? TILED(env_dirs, 3, q / 6, q % 6) : TILED(env_weights, 3, q / 6, q % 6 - 3);
#else
#define DECLARE_ENV
#define STAGE_ENV
#endif
#if N_SH > 0 && INDIRECT_MODE == 1
#define DECLARE_VIEW __local float l_view[N_SH];
#define STAGE_VIEW \
  for (uint q = lid; q < N_SH; q += RAY_ITEMS) l_view[q] = TILED(sh_basis, N_SH, ray_index, q);
#else
#define DECLARE_VIEW
#define STAGE_VIEW
#endif
#define STAGE_SHARED_INPUTS \
  STAGE_INDIRECT            \
  STAGE_ENV                 \
  STAGE_VIEW                \
  barrier(CLK_LOCAL_MEM_FENCE);

// What one sample needs of its ray and its point light (render.cl's TileLight, per sample).
typedef struct {
  float3 wo;              // toward the camera
  float g, mu_l, direct;  // HG asymmetry, w_o . w_l, V / |p_l - x|^2
  float inv_r2;           // 1 / |p_l - x|^2
  float3 intensity;       // the light's RGB intensity
} SampleLight;

inline SampleLight sample_light(__global const float* ray, __global const float* t, __global const float* props,
                                size_t s) {
  SampleLight L;
  const float3 o = ray_origin(ray), d = ray_direction(ray);
  L.intensity = ray_light_intensity(ray);
  L.wo = -d;
  const float ts = t[s];
  const float lx = ray[RELIT_RAY_LIGHT_POSITION] - fma(ts, d.x, o.x);
  const float ly = ray[RELIT_RAY_LIGHT_POSITION + 1] - fma(ts, d.y, o.y);
  const float lz = ray[RELIT_RAY_LIGHT_POSITION + 2] - fma(ts, d.z, o.z);
  const float r2 = fma(lx, lx, fma(ly, ly, lz * lz));
  L.mu_l = (L.wo.x * lx + L.wo.y * ly + L.wo.z * lz) * rsqrt(r2);
  L.g = TILED(props, PROP_COLS, s, 4);
  L.inv_r2 = 1.0f / r2;
  L.direct = TILED(props, PROP_COLS, s, 5) * L.inv_r2;
  return L;
}

// radiance = albedo ⊙ (S_dir + S_env + S_ind), one group per ray.
__kernel __attribute__((reqd_work_group_size(RAY_ITEMS, 1, 1))) void render_wg_radiance(
    const uint n_rays, __global const float* restrict rays, __global const float* restrict t,
    __global const float* restrict props, __global const float* restrict dirs, __global const float* restrict sh_basis,
    __global const float* restrict env_dirs, __global const float* restrict env_weights,
    __global float* restrict radiance) {
  DECLARE_INDIRECT
  DECLARE_ENV
  DECLARE_VIEW
  const uint ray_index = get_group_id(0), lid = get_local_id(0);
  STAGE_SHARED_INPUTS
  if (ray_index >= n_rays) return;  // after the barrier; the host launches exactly n_rays groups
  __global const float* ray = RAY_RECORD(rays, ray_index);
  for (uint i = lid; i < N_SAMPLES; i += RAY_ITEMS) {
    const size_t s = (size_t)ray_index * N_SAMPLES + i;
    const SampleLight L = sample_light(ray, t, props, s);
    float3 S = hg_phase1(L.g, L.mu_l) * L.direct * L.intensity;
#if N_ENV > 0
    for (uint j = 0; j < N_ENV; ++j) {
      const float mu = L.wo.x * ENV_DIR(j, 0) + L.wo.y * ENV_DIR(j, 1) + L.wo.z * ENV_DIR(j, 2);
      const float pv = hg_phase1(L.g, mu) * TILED(props, PROP_COLS, s, ENV_COL + j);
      S = fma((float3)(pv), (float3)(ENV_WEIGHT(j, 0), ENV_WEIGHT(j, 1), ENV_WEIGHT(j, 2)), S);
    }
#endif
#if N_SH > 0 && INDIRECT_MODE == 1
    // sum_l g^l sum_m c_lm Y_lm(-w_o) per channel.
    for (int ch = 0; ch < 3; ++ch) {
      float sum = 0.0f, gl = 1.0f;
      for (uint l = 0, j = 0; j < N_SH; ++l, gl *= L.g) {
        float band = 0.0f;
        for (uint m = 0; m < 2 * l + 1; ++m, ++j)
          band = fma(TILED(props, PROP_COLS, s, 6 + ch * N_SH + j), VIEW_BASIS(j), band);
        sum = fma(gl, band, sum);
      }
      if (ch == 0) S.x += sum;
      if (ch == 1) S.y += sum;
      if (ch == 2) S.z += sum;
    }
#elif N_SH > 0
    float c[3 * N_SH];
    for (uint j = 0; j < 3 * N_SH; ++j) c[j] = TILED(props, PROP_COLS, s, 6 + j);
    float3 ind = 0.0f;
    for (uint k = 0; k < N_DIRS; ++k) {
      const float p = hg_phase1(L.g, L.wo.x * DIR(k, 0) + L.wo.y * DIR(k, 1) + L.wo.z * DIR(k, 2));
      float3 l = 0.0f;
      for (uint j = 0; j < N_SH; ++j) l = fma((float3)(c[j], c[N_SH + j], c[2 * N_SH + j]), (float3)(BASIS(k, j)), l);
      ind = fma((float3)(p), fmax(l, 0.0f), ind);
    }
    S = fma(ind, (float3)(4.0f * M_PI_F / N_DIRS), S);
#endif
    store_tiled3(radiance, 3, s, 0, tiled3(props, PROP_COLS, s, 1) * S);
  }
}

// Given dL/d(radiance): dL/d(albedo), dL/dg and dL/d(SH coefficients) into d_props; zero for every visibility
// column (gradient isolation, as render.cl's render_radiance_backward); sigma's column is the compositing's.
__kernel __attribute__((reqd_work_group_size(RAY_ITEMS, 1, 1))) void render_wg_radiance_backward(
    const uint n_rays, __global const float* restrict rays, __global const float* restrict t,
    __global const float* restrict props, __global const float* restrict dirs, __global const float* restrict sh_basis,
    __global const float* restrict env_dirs, __global const float* restrict env_weights,
    __global const float* restrict d_radiance, __global float* restrict d_props) {
  DECLARE_INDIRECT
  DECLARE_ENV
  DECLARE_VIEW
  const uint ray_index = get_group_id(0), lid = get_local_id(0);
  STAGE_SHARED_INPUTS
  if (ray_index >= n_rays) return;
  __global const float* ray = RAY_RECORD(rays, ray_index);
  for (uint i = lid; i < N_SAMPLES; i += RAY_ITEMS) {
    const size_t s = (size_t)ray_index * N_SAMPLES + i;
    const SampleLight L = sample_light(ray, t, props, s);
    const float3 a = tiled3(props, PROP_COLS, s, 1), dr = tiled3(d_radiance, 3, s, 0);
    const float3 e = dr * a;  // upstream gradient on S (radiance = a ⊙ S)
    float3 S = hg_phase1(L.g, L.mu_l) * L.direct * L.intensity;
    float d_g = hg_dphase1_dg(L.g, L.mu_l) * L.direct * dot(e, L.intensity);
#if N_ENV > 0
    for (uint j = 0; j < N_ENV; ++j) {
      const float mu = L.wo.x * ENV_DIR(j, 0) + L.wo.y * ENV_DIR(j, 1) + L.wo.z * ENV_DIR(j, 2);
      const float v = TILED(props, PROP_COLS, s, ENV_COL + j);
      const float3 w = (float3)(ENV_WEIGHT(j, 0), ENV_WEIGHT(j, 1), ENV_WEIGHT(j, 2));
      S = fma((float3)(hg_phase1(L.g, mu) * v), w, S);
      d_g = fma(hg_dphase1_dg(L.g, mu) * v, dot(e, w), d_g);
      TILED(d_props, PROP_COLS, s, ENV_COL + j) = 0.0f;
    }
#endif
#if N_SH > 0 && INDIRECT_MODE == 1
    {
      const float ec[3] = {e.x, e.y, e.z};
      for (int ch = 0; ch < 3; ++ch) {
        float sum = 0.0f, dsum = 0.0f, gl = 1.0f, dgl = 0.0f;  // g^l and l g^(l-1)
        for (uint l = 0, j = 0; j < N_SH; ++l) {
          float band = 0.0f;
          for (uint m = 0; m < 2 * l + 1; ++m, ++j) {
            band = fma(TILED(props, PROP_COLS, s, 6 + ch * N_SH + j), VIEW_BASIS(j), band);
            TILED(d_props, PROP_COLS, s, 6 + ch * N_SH + j) = ec[ch] * gl * VIEW_BASIS(j);
          }
          sum = fma(gl, band, sum);
          dsum = fma(dgl, band, dsum);
          dgl = fma(dgl, L.g, gl);
          gl *= L.g;
        }
        d_g = fma(ec[ch], dsum, d_g);
        if (ch == 0) S.x += sum;
        if (ch == 1) S.y += sum;
        if (ch == 2) S.z += sum;
      }
    }
#elif N_SH > 0
    float c[3 * N_SH], dc[3 * N_SH];
    for (uint j = 0; j < 3 * N_SH; ++j) {
      c[j] = TILED(props, PROP_COLS, s, 6 + j);
      dc[j] = 0.0f;
    }
    const float w = 4.0f * M_PI_F / N_DIRS;
    float3 ind = 0.0f;
    for (uint k = 0; k < N_DIRS; ++k) {
      const float mu = L.wo.x * DIR(k, 0) + L.wo.y * DIR(k, 1) + L.wo.z * DIR(k, 2);
      const float p = hg_phase1(L.g, mu), dp = hg_dphase1_dg(L.g, mu);
      float3 l = 0.0f;
      for (uint j = 0; j < N_SH; ++j) l = fma((float3)(c[j], c[N_SH + j], c[2 * N_SH + j]), (float3)(BASIS(k, j)), l);
      const float3 pl = fmax(l, 0.0f);
      ind = fma((float3)(p), pl, ind);
      d_g = fma(dp * w, dot(e, pl), d_g);
      // d/dc_j of max(0, l_k): Y_j where l_k > 0.
      const float3 gk = select((float3)(0.0f), p * e * w, isgreater(l, (float3)(0.0f)));
      for (uint j = 0; j < N_SH; ++j) {
        const float y = BASIS(k, j);
        dc[j] = fma(gk.x, y, dc[j]);
        dc[N_SH + j] = fma(gk.y, y, dc[N_SH + j]);
        dc[2 * N_SH + j] = fma(gk.z, y, dc[2 * N_SH + j]);
      }
    }
    S = fma(ind, (float3)(w), S);
    for (uint j = 0; j < 3 * N_SH; ++j) TILED(d_props, PROP_COLS, s, 6 + j) = dc[j];
#endif
    store_tiled3(d_props, PROP_COLS, s, 1, dr * S);
    TILED(d_props, PROP_COLS, s, 4) = d_g;
    // dL/dV toward the point light with VISIBILITY_GRADIENT (render.cl: the shadow gradient), else zero.
    TILED(d_props, PROP_COLS, s, 5) =
        VISIBILITY_GRADIENT ? hg_phase1(L.g, L.mu_l) * L.inv_r2 * dot(e, L.intensity) : 0.0f;
  }
}

// ---- compositing --------------------------------------------------------------------------------------------

// Inclusive scan of `v` over the group in the order of `slot` (a permutation of the local ids): on return
// *before = the sum over the slots below, *total = the sum over all. Hillis-Steele in local memory: the same
// additions in the same order on every run.
inline void group_scan(float4 v, uint slot, __local float4* buf, float4* before, float4* total) {
  buf[slot] = v;
  barrier(CLK_LOCAL_MEM_FENCE);
  for (uint offset = 1; offset < RAY_ITEMS; offset <<= 1) {
    const float4 add = slot >= offset ? buf[slot - offset] : (float4)(0.0f);
    barrier(CLK_LOCAL_MEM_FENCE);
    v += add;
    buf[slot] = v;
    barrier(CLK_LOCAL_MEM_FENCE);
  }
  *before = slot > 0 ? buf[slot - 1] : (float4)(0.0f);
  *total = buf[RAY_ITEMS - 1];
  barrier(CLK_LOCAL_MEM_FENCE);  // before the next scan overwrites buf
}

inline float optical_depth(__global const float* props, __global const float* delta, size_t s) {
  return TILED(props, PROP_COLS, s, 0) * delta[s];
}

// color = sum_i T_i alpha_i radiance_i + T_N background and the final transmittance T_N, one group per ray.
__kernel __attribute__((reqd_work_group_size(RAY_ITEMS, 1, 1))) void render_wg_composite(
    const uint n_rays, __global const float* restrict rays, __global const float* restrict delta,
    __global const float* restrict props, __global const float* restrict radiance, __global float* restrict color,
    __global float* restrict transmittance) {
  __local float4 buf[RAY_ITEMS];
  const uint r = get_group_id(0), lid = get_local_id(0);
  if (r >= n_rays) return;  // uniform over the group
  float tau = 0.0f;         // optical depth before the segment
  float3 c = 0.0f;          // this work-item's samples' share of the colour
  for (uint seg = 0; seg < SEGMENTS; ++seg) {
    const size_t s = (size_t)r * N_SAMPLES + seg * RAY_ITEMS + lid;
    const float od = optical_depth(props, delta, s);
    float4 before, total;
    group_scan((float4)(od, 0.0f, 0.0f, 0.0f), lid, buf, &before, &total);
    const float w = exp(-(tau + before.x)) * (1.0f - exp(-od));
    c = fma((float3)(w), tiled3(radiance, 3, s, 0), c);
    tau += total.x;
  }
  float4 before, sum;
  group_scan((float4)(c, 0.0f), lid, buf, &before, &sum);
  if (lid == 0) {
    const float T = exp(-tau);
    vstore3(fma((float3)(T), ray_background(RAY_RECORD(rays, r)), sum.xyz), r, color);
    transmittance[r] = T;
  }
}

// Given dL/dcolor: dL/dsigma_k = delta_k (T_k (1 - alpha_k) c_k - behind_k) . dL/dcolor into d_props column 0,
// behind_k = sum_{i>k} w_i c_i + T_N background, and dL/dradiance_k = w_k dL/dcolor. A first sweep along the ray
// scans the optical depths (each work-item keeps those of its samples), a second from the far end scans
// w_i c_i into behind_k. `color` is unused (the argument list is the SIMD kernel's, which needs it).
__kernel __attribute__((reqd_work_group_size(RAY_ITEMS, 1, 1))) void render_wg_composite_backward(
    const uint n_rays, __global const float* restrict rays, __global const float* restrict delta,
    __global const float* restrict props, __global const float* restrict radiance, __global const float* restrict color,
    __global const float* restrict d_color, __global float* restrict d_props, __global float* restrict d_radiance) {
  __local float4 buf[RAY_ITEMS];
  const uint r = get_group_id(0), lid = get_local_id(0);
  if (r >= n_rays) return;  // uniform over the group
  float od[SEGMENTS], tau_before[SEGMENTS];
  float tau = 0.0f;
  for (uint seg = 0; seg < SEGMENTS; ++seg) {
    const size_t s = (size_t)r * N_SAMPLES + seg * RAY_ITEMS + lid;
    od[seg] = optical_depth(props, delta, s);
    float4 before, total;
    group_scan((float4)(od[seg], 0.0f, 0.0f, 0.0f), lid, buf, &before, &total);
    tau_before[seg] = tau + before.x;
    tau += total.x;
  }
  const float3 dC = vload3(r, d_color);
  float3 behind = exp(-tau) * ray_background(RAY_RECORD(rays, r));  // past the last segment
  const uint slot = RAY_ITEMS - 1 - lid;                            // the far end first
  for (uint seg = SEGMENTS; seg-- > 0;) {
    const size_t s = (size_t)r * N_SAMPLES + seg * RAY_ITEMS + lid;
    const float T = exp(-tau_before[seg]), transmitted = exp(-od[seg]);
    const float w = T * (1.0f - transmitted);
    const float3 ci = tiled3(radiance, 3, s, 0);
    float4 later, total;
    group_scan((float4)(w * ci, 0.0f), slot, buf, &later, &total);
    const float3 dsigma3 = delta[s] * (T * transmitted * ci - (behind + later.xyz));
    TILED(d_props, PROP_COLS, s, 0) = dot(dsigma3, dC);
    store_tiled3(d_radiance, 3, s, 0, w * dC);
    behind += total.xyz;
  }
}
