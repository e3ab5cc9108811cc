// pathtrace.cl: the reference path tracer's render kernel (see pathtrace.clh for the estimators).
//
// One work-item per pixel of a tile (pixels pixel_begin .. pixel_begin + n - 1 in row-major order); each
// traces samples sample_begin .. sample_begin + sample_count - 1 and adds their sum and sum of squares to
// accum / accum_sq (float4: RGB + alpha). Sample s of pixel p always uses the random stream (seed, p, s), so
// the image does not depend on how it was cut into tiles and passes.
#include "pathtrace.clh"

__kernel void pathtrace_render(const uint n, const uint pixel_begin, const uint sample_begin, const uint sample_count,
                               const uint seed, const uint width, const float4 cam_row0, const float4 cam_row1,
                               const float4 cam_row2, const float4 cam_params, const uint max_bounces,
                               const uint rr_depth, __global const float* density, const int4 density_dims,
                               const float density_scale, __global const float* majorant, const int4 majorant_dims,
                               __global const float4* albedo, const int4 albedo_dims, const float4 albedo_g,
                               __global const float* sdf, const int4 sdf_dims, const float4 material,
                               __global const float4* lights, const uint n_lights, __global const float4* env,
                               __global const float* env_pdf_uv, __global const float* env_marginal,
                               __global const float* env_conditional, const int4 env_dims, const float env_scale,
                               __global float4* accum, __global float4* accum_sq) {
  const size_t gid = get_global_id(0);
  if (gid >= n) return;
  const uint pixel = pixel_begin + (uint)gid;

  PtScene s;
  s.density = density;
  s.density_dims = density_dims;
  s.density_scale = density_scale;
  s.majorant = majorant;
  s.majorant_dims = majorant_dims;
  s.albedo = albedo_dims.w ? albedo : 0;
  s.albedo_dims = albedo_dims;
  s.albedo_const = albedo_g.xyz;
  s.g = albedo_g.w;
  s.sdf = sdf;
  s.sdf_dims = sdf_dims;
  s.base_color = material.xyz;
  s.roughness = material.w;
  s.env = env_map(env, env_pdf_uv, env_marginal, env_conditional, env_dims.x, env_dims.y, env_scale);
  s.env_dims = env_dims;

  const float px = (float)(pixel % width), py = (float)(pixel / width);
  const float focal = cam_params.x, w = cam_params.y, h = cam_params.z;
  const float3 origin = (float3)(cam_row0.w, cam_row1.w, cam_row2.w);
  float4 sum = (float4)(0.0f), sum_sq = (float4)(0.0f);
  for (uint k = 0; k < sample_count; ++k) {
    Rng rng = rng_init(seed, pixel, sample_begin + k);
    const float jx = rng_uniform(&rng), jy = rng_uniform(&rng);  // box filter over the pixel
    const float3 dc = (float3)((px + jx - 0.5f * w) / focal, -(py + jy - 0.5f * h) / focal, -1.0f);
    const float3 d = normalize((float3)(dot(cam_row0.xyz, dc), dot(cam_row1.xyz, dc), dot(cam_row2.xyz, dc)));
    const float4 v = pt_trace(&s, origin, d, lights, n_lights, max_bounces, rr_depth, &rng);
    sum += v;
    sum_sq = fma(v, v, sum_sq);
  }
  accum[pixel] += sum;
  accum_sq[pixel] += sum_sq;
}
