// EnvironmentSamples: the environment light of the neural renderer (docs/design.md §4.2, kernels/environment.cl).
//
//   S_env(x) = (1/N_e) sum_j p(w_o, w_j; g) V(x, w_j) E(w_j) / pdf(w_j)
//
// The N_e directions w_j are importance-sampled from the environment map on the device, drawn anew per
// iteration from (seed, iteration) and shared by the whole batch (as IndirectBasis's K directions), so each
// sample of the batch needs only N_e visibility values and phase evaluations. The weights E(w_j) / (pdf(w_j)
// N_e) are RGB. The map's importance tables are uploaded once, at construction.
//
//   render::EnvironmentSamples env(device, *scene.environment, 32);
//   env.draw(seed, iteration);                 // enqueued only
//   env.fill_background(rays, n_rays);         // L_bg(d) into the ray records, if the map is visible
//   renderer.forward(..., &env);
#pragma once

#include <relit/cl/buffer.hpp>
#include <relit/nn/batch.hpp>
#include <relit/scene/light.hpp>

#include <cstdint>

namespace relit::render {

class EnvironmentSamples {
 public:
  /// `n_env_dirs` (N_e) in [1, 1024]; the environment must have an image.
  EnvironmentSamples(const Device& device, const EnvironmentLight& light, std::uint32_t n_env_dirs);

  /// Draws the N_e directions of `iteration` and their weights; enqueued only. The row coordinate of the
  /// sampler is stratified over the N_e draws (each draw alone is not distributed as the map's pdf, the set
  /// is, and the estimate stays unbiased).
  void draw(std::uint32_t seed, std::uint32_t iteration);

  /// Writes L_bg(d), the environment's radiance toward each ray's direction, into the background slots of the
  /// ray records (floats 16..18) when the environment is visible to the camera, zeros otherwise. Enqueued only.
  void fill_background(Buffer<float>& rays, std::uint32_t n_rays) const;

  std::uint32_t size() const { return m_dirs.batch(); }
  bool visible() const { return m_visible; }
  /// The directions of the last draw (N_e x 3, unit, pointing away from the scattering point).
  const nn::BatchMatrix& dirs() const { return m_dirs; }
  /// E(w_j) / (pdf(w_j) N_e) per direction (N_e x 3, RGB).
  const nn::BatchMatrix& weights() const { return m_weights; }

 private:
  Device m_device;
  Buffer<float> m_texels, m_pdf_uv, m_marginal, m_conditional;  // texels: RGBA per texel, as the image
  int m_width = 0, m_height = 0;
  float m_scale = 1.0f;
  bool m_visible = false;
  nn::BatchMatrix m_dirs, m_weights;
};

}  // namespace relit::render
