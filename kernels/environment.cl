// environment.cl: the environment light of the neural renderer (docs/design.md §4.2) — the N_e importance-sampled
// directions of an iteration with their Monte Carlo weights, shared by the whole batch, and the background
// radiance L_bg(d) of camera rays. The map's layout and sampler are in environment.clh.
//
//   S_env(x) = sum_j p(w_o, w_j; g) V(x, w_j) weight_j,   weight_j = E(w_j) / (pdf(w_j) N_e)   (RGB)
#include "common.clh"
#include "environment.clh"
#include "layout.clh"

// Direction j of `iteration` (n x 3 tiled) and its weight (n x 3 tiled), counter-based from (seed, iteration, j).
// The row coordinate u1 is stratified over the n draws, (j + xi) / n: the set of draws covers the map's rows
// in proportion to their probability however few there are (a sun is neither missed nor hit by every
// draw), and sum_j E / (pdf n) stays an unbiased estimate of the integral of E. u2 is uniform.
__kernel void env_draw(const uint n, const uint seed, const uint iteration, __global const float4* restrict texels,
                       __global const float* restrict pdf_uv, __global const float* restrict marginal,
                       __global const float* restrict conditional, const int width, const int height, const float scale,
                       __global float* restrict dirs, __global float* restrict weights) {
  const uint j = get_global_id(0);
  if (j >= n) return;
  const EnvMap e = env_map(texels, pdf_uv, marginal, conditional, width, height, scale);
  const uint h = relit_hash2(relit_hash2(seed ^ 0x2545f491u, iteration), j);
  const float u1 = fmin(((float)j + relit_uniform(h)) / (float)n, 0x1.fffffep-1f);
  const float u2 = relit_uniform(relit_hash(h ^ 0x68e31da4u));
  float pdf;
  const float3 d = env_sample(&e, u1, u2, &pdf);
  const float3 w = pdf > 0.0f ? env_radiance(&e, d) / (pdf * (float)n) : (float3)(0.0f);
  store_tiled3(dirs, 3, j, 0, d);
  store_tiled3(weights, 3, j, 0, w);
}

// The background of each ray record: the environment's radiance toward the ray's
// direction when the environment is visible to the camera, else zero.
__kernel void env_background(const uint n_rays, const uint visible, __global const float4* restrict texels,
                             const int width, const int height, const float scale, __global float* restrict rays) {
  const uint r = get_global_id(0);
  if (r >= n_rays) return;
  __global float* ray = RAY_RECORD(rays, r);
  float3 bg = (float3)(0.0f);
  if (visible) {
    const EnvMap e = env_map(texels, 0, 0, 0, width, height, scale);
    bg = env_radiance(&e, ray_direction(ray));
  }
  ray_set_background(ray, bg);
}
