// pathtrace_probe.cl: kernels that expose the path tracer's building blocks to the tests (HG and BRDF
// sampling, environment sampling, delta and ratio tracking), so each can be checked against a host reference.
#include "pathtrace.clh"

// out[i] = (wi, pdf) for wo = wo_in, from the random stream (seed, i).
__kernel void probe_hg_sample(const uint n, const uint seed, const float4 wo_g, __global float4* out) {
  const size_t i = get_global_id(0);
  if (i >= n) return;
  Rng rng = rng_init(seed, (uint)i, 0u);
  const float u1 = rng_uniform(&rng), u2 = rng_uniform(&rng);
  const float3 wi = hg_sample(wo_g.xyz, wo_g.w, u1, u2);
  out[i] = (float4)(wi, hg_phase(dot(wo_g.xyz, wi), wo_g.w));
}

// out[i] = (wi, pdf) of the BRDF sampler, and f*cos in out_f[i].
__kernel void probe_brdf_sample(const uint n, const uint seed, const float4 wo_r, const float4 base,
                                __global float4* out, __global float4* out_f) {
  const size_t i = get_global_id(0);
  if (i >= n) return;
  Rng rng = rng_init(seed, (uint)i, 0u);
  const float u0 = rng_uniform(&rng), u1 = rng_uniform(&rng), u2 = rng_uniform(&rng);
  const float3 nrm = (float3)(0.0f, 0.0f, 1.0f);
  const float3 wi = brdf_sample(nrm, wo_r.xyz, wo_r.w, u0, u1, u2);
  out[i] = (float4)(wi, brdf_pdf(nrm, wo_r.xyz, wi, wo_r.w));
  out_f[i] = (float4)(brdf_eval(nrm, wo_r.xyz, wi, base.xyz, wo_r.w) * fmax(wi.z, 0.0f), 0.0f);
}

// out[i] = f(wo_i, wi_i) (RGB) for direction pairs (wo, wi) = (pairs[2i], pairs[2i+1]), normal +z; roughness in .w
// of the first direction of each pair.
__kernel void probe_brdf_eval(const uint n, __global const float4* pairs, const float4 base, __global float4* out) {
  const size_t i = get_global_id(0);
  if (i >= n) return;
  const float3 nrm = (float3)(0.0f, 0.0f, 1.0f);
  const float4 a = pairs[2 * i], b = pairs[2 * i + 1];
  out[i] = (float4)(brdf_eval(nrm, a.xyz, b.xyz, base.xyz, a.w), 0.0f);
}

// out[i] = f(wo, wi) max(0, n.wi) (RGB) for records rec[4i .. 4i+3] = (n, roughness), wo, wi, albedo: the
// BRDF the path tracer shades solids with, for comparison with the neural renderer's "brdf" mode.
__kernel void probe_brdf_cos(const uint n, __global const float4* rec, __global float4* out) {
  const size_t i = get_global_id(0);
  if (i >= n) return;
  const float3 nrm = rec[4 * i].xyz, wo = rec[4 * i + 1].xyz, wi = rec[4 * i + 2].xyz;
  out[i] = (float4)(brdf_eval(nrm, wo, wi, rec[4 * i + 3].xyz, rec[4 * i].w) * fmax(dot(nrm, wi), 0.0f), 0.0f);
}

// The directional albedo int f(wo, wi) n.wi dwi at albedo 1 (the white furnace of a surface), per case
// (wo.xyz, roughness), normal +z, as a deterministic quadrature over the path tracer's own sampler: the
// diffuse term over its cosine half and the specular term over its GGX half, each on a stratified m x m grid
// of (u1, u2) and divided by that half's own density, so each integrand is smooth in (u1, u2).
__kernel void probe_brdf_albedo(const uint n, __global const float4* cases, const uint m, __global float* out) {
  const size_t i = get_global_id(0);
  if (i >= n) return;
  const float3 nrm = (float3)(0.0f, 0.0f, 1.0f), wo = cases[i].xyz;
  const float r = cases[i].w, a2 = r * r * r * r;
  const BrdfView v = brdf_view(nrm, wo, r);
  float diffuse = 0.0f, spec = 0.0f;
  for (uint a = 0; a < m; ++a) {
    float row_d = 0.0f, row_s = 0.0f;  // rows summed apart keep the float sums accurate
    for (uint b = 0; b < m; ++b) {
      const float u1 = (a + 0.5f) / m, u2 = (b + 0.5f) / m;
      const float3 wd = brdf_sample(nrm, wo, r, 0.25f, u1, u2);  // cosine half: pdf n.wi / pi
      row_d += brdf_at(&v, wd, 0).diffuse * M_PI_F;
      const float3 ws = brdf_sample(nrm, wo, r, 0.75f, u1, u2);  // GGX half: pdf D n.h / (4 wo.h)
      if (ws.z > 0.0f) {
        const float3 h = normalize(wo + ws);
        const float pdf = ggx_d(h.z * h.z, ggx_sin2(nrm, h), a2) * h.z / (4.0f * dot(wo, h));
        row_s += brdf_at(&v, ws, 0).spec * ws.z / pdf;
      }
    }
    diffuse += row_d / ((float)m * (float)m);
    spec += row_s / ((float)m * (float)m);
  }
  out[i] = diffuse + spec;
}

#define PROBE_SCENE_ARGS                                                                                             \
  __global const float *density, const int4 density_dims, const float density_scale, __global const float *majorant, \
      const int4 majorant_dims, __global const float4 *env, __global const float *env_pdf_uv,                        \
      __global const float *env_marginal, __global const float *env_conditional, const int4 env_dims

#define PROBE_SCENE_INIT                                                                         \
  PtScene s;                                                                                     \
  s.density = density;                                                                           \
  s.density_dims = density_dims;                                                                 \
  s.density_scale = density_scale;                                                               \
  s.majorant = majorant;                                                                         \
  s.majorant_dims = majorant_dims;                                                               \
  s.albedo = 0;                                                                                  \
  s.albedo_dims = (int4)(0);                                                                     \
  s.albedo_const = (float3)(1.0f);                                                               \
  s.g = 0.0f;                                                                                    \
  s.sdf = 0;                                                                                     \
  s.sdf_dims = (int4)(0);                                                                        \
  s.base_color = (float3)(0.0f);                                                                 \
  s.roughness = 1.0f;                                                                            \
  s.env = env_map(env, env_pdf_uv, env_marginal, env_conditional, env_dims.x, env_dims.y, 1.0f); \
  s.env_dims = env_dims;

// Environment sampling: out[i] = (direction, pdf reported by the sampler); pdf_at[i] = pdf evaluated at it.
__kernel void probe_env_sample(const uint n, const uint seed, PROBE_SCENE_ARGS, __global float4* out,
                               __global float* pdf_at) {
  const size_t i = get_global_id(0);
  if (i >= n) return;
  PROBE_SCENE_INIT
  Rng rng = rng_init(seed, (uint)i, 0u);
  const float u1 = rng_uniform(&rng), u2 = rng_uniform(&rng);
  float pdf;
  const float3 d = env_sample(&s.env, u1, u2, &pdf);
  out[i] = (float4)(d, pdf);
  pdf_at[i] = env_pdf(&s.env, d);
}

// Transmittance estimates along ray r (origin rays[2r], direction rays[2r+1], t in [rays[2r].w, rays[2r+1].w])
// averaged over `samples` runs of ratio tracking (out[r].x) and of delta tracking (out[r].y: fraction with no
// collision), with their second moments in .z and .w.
__kernel void probe_transmittance(const uint n, const uint seed, const uint samples, __global const float4* rays,
                                  PROBE_SCENE_ARGS, __global float4* out) {
  const size_t r = get_global_id(0);
  if (r >= n) return;
  PROBE_SCENE_INIT
  const float3 o = rays[2 * r].xyz, d = rays[2 * r + 1].xyz;
  const float t0 = rays[2 * r].w, t1 = rays[2 * r + 1].w;
  float ratio = 0.0f, ratio2 = 0.0f, delta = 0.0f;
  for (uint k = 0; k < samples; ++k) {
    Rng rng = rng_init(seed, (uint)r, k);
    const float tr = pt_ratio_track(&s, o, d, t0, t1, &rng);
    ratio += tr;
    ratio2 += tr * tr;
    delta += isinf(pt_delta_track(&s, o, d, t0, t1, &rng)) ? 1.0f : 0.0f;
  }
  out[r] = (float4)(ratio / samples, delta / samples, ratio2 / samples, delta / samples);
}
