// The "Ours" model (DESIGN §4.3): the networks of the method and the passes that join them to the volume
// renderer.
//
//   positions x ──► property net F_θ ──► σ (softplus), albedo (sigmoid), g (0.95 tanh), feature f
//   [f, p_l]   ──► indirect SH head h_θ ──► c = (I / I_ref) ⊙ h + c_env  (scaled by the light's RGB intensity)
//   f          ──► environment head e_θ ──► c_env (position-only; only with an environment map)
//   [x, ω_l]   ──► visibility net V_ψ  ──► V (sigmoid), toward the point light and each environment direction
//   σ, a, g, V, c ──► VolumeRenderer ──► pixel colour
//
// θ (property net + SH head) and ψ (visibility net) live in two flat parameter buffers with their own
// optimisers. Gradients are isolated both ways (seed appendix C): the render loss reaches θ only (the
// renderer gives no gradient to V), and the visibility loss — against the transmittance of the learned
// density, marched through a cached density grid — reaches ψ only (the targets are constants).
//
// The model is configured by the "model" object of a run config (docs/method.md; keys in docs/config.md).
#pragma once

#include <relit/config.hpp>
#include <relit/nn/loss.hpp>
#include <relit/nn/module.hpp>
#include <relit/nn/network_with_encoding.hpp>
#include <relit/render/environment.hpp>
#include <relit/render/visibility.hpp>
#include <relit/render/volume_renderer.hpp>

#include <map>
#include <memory>
#include <string>
#include <utility>
#include <vector>

namespace relit::method {

/// The environment light of 'env+point' datasets (DESIGN §4.2-4.3): S_env over N_e importance-sampled
/// directions, each with its own visibility query, and the position-only SH head c_env(x).
struct EnvironmentSettings {
  bool enabled = false;                   ///< the model has c_env and trains S_env (relit train sets it from the dataset)
  std::uint32_t n_dirs = 32;              ///< N_e when rendering under the environment
  std::uint32_t n_dirs_training = 4;      ///< N_e of a training step (fresh directions every step)
  float visibility_fraction = 0.0625f;    ///< share of a batch's rays whose samples train V_ψ toward the N_e directions
};

/// Resolved settings of the model (the non-network keys of the "model" config object).
struct OursSettings {
  render::RendererSettings renderer;
  std::uint32_t n_features = 11;          ///< feature columns the property net passes to the SH head
  float intensity_reference = 1000.0f;    ///< I_ref: the SH head predicts indirect light per I / I_ref
  float light_position_scale = 0.125f;    ///< the SH head sees the light position times this
  bool light_conditioned = true;          ///< false: c = c(x), the position-only ablation
  std::uint32_t grid_resolution = 64;     ///< density grid for visibility targets (per axis)
  std::uint32_t grid_refresh = 16;        ///< refresh the grid every this many training steps
  std::uint32_t march_steps = 64;         ///< midpoint steps of the visibility-target march
  float visibility_fraction = 0.25f;      ///< share of a batch's rays whose samples train the visibility net
  std::string inference_visibility = "network";  ///< "network" (as the paper) or "march" (density grid)
  EnvironmentSettings environment;
};

/// Per-stage timing of a training step, for profiling: when enabled, mark() waits for the device and adds the
/// time since the previous mark to `stage`. Disabled (the default) it does nothing, so steps stay asynchronous.
class StageTimer {
 public:
  void enable(const Device& device);
  bool enabled() const { return m_enabled; }
  void start();
  void mark(const std::string& stage);
  /// Seconds per stage, in first-marked order.
  const std::vector<std::pair<std::string, double>>& seconds() const { return m_seconds; }
  void clear() { m_seconds.clear(); }

 private:
  bool m_enabled = false;
  Device m_device;
  double m_last = 0;
  std::vector<std::pair<std::string, double>> m_seconds;
};

/// Scratch matrices of one pass over a batch of rays; reused across iterations (no allocation once sized).
struct OursPass {
  std::uint32_t n_rays = 0;
  Buffer<float> t, delta, color, transmittance;
  nn::BatchMatrix positions, net_pos, props_raw, light_in, indirect_raw, vis_in, vis, props, radiance;
  nn::BatchMatrix d_props, d_radiance, d_props_raw, d_indirect_raw, d_light_in;
  nn::BatchMatrix vis_in_sub, positions_sub, vis_sub, vis_target, d_vis;  // the visibility net's training subset
  // With an environment: V_ψ's inputs toward the N_e directions (sample-major rows s N_e + j), its outputs, the
  // head's c_env, and the march targets of the environment rows of the visibility subset.
  std::uint32_t n_env = 0;
  nn::BatchMatrix view_basis;  // closed-form indirect: Y(-w_o) per ray, in place of the K directions' basis
  nn::BatchMatrix env_vis_in, env_vis, env_raw, d_env_raw, d_env_in, env_march, env_positions_sub, env_target,
      point_target;
  std::unique_ptr<nn::Workspace> ws_property, ws_indirect, ws_visibility, ws_env_visibility, ws_environment;
};

class Ours {
 public:
  /// Builds the networks from the "model" config object (at JSON pointer `pointer`); unknown keys and bad
  /// values are ConfigErrors naming the pointer.
  Ours(const Device& device, const Json& config, const std::string& pointer = "/model");
  /// Every key of the model config, per JSON object (for docs/config.md).
  static void describe(config::Docs& docs);

  const OursSettings& settings() const { return m_settings; }
  /// The resolved "model" config: building from it gives the same model.
  const Json& hyperparams() const { return m_resolved; }
  /// The renderer without environment light; renderer(N_e) the one for N_e environment directions.
  const render::VolumeRenderer& renderer() const { return *m_renderer; }
  const render::VolumeRenderer& renderer(std::uint32_t n_env_dirs) const;
  const Device& device() const { return m_device; }

  /// θ: [property net | SH head | environment head]; ψ: the visibility net.
  std::uint32_t n_params() const;
  std::uint32_t n_vis_params() const;
  Buffer<float>& params() { return m_params; }
  Buffer<float>& vis_params() { return m_vis_params; }
  const Buffer<float>& params() const { return m_params; }
  const Buffer<float>& vis_params() const { return m_vis_params; }
  Buffer<float>& grads() { return m_grads; }
  Buffer<float>& vis_grads() { return m_vis_grads; }
  /// Re-initialises both parameter buffers deterministically from `seed`.
  void initialize(std::uint64_t seed);

  const nn::NetworkWithInputEncoding& property_network() const { return *m_property; }
  const nn::NetworkWithInputEncoding& indirect_network() const { return *m_indirect; }
  const nn::NetworkWithInputEncoding& visibility_network() const { return *m_visibility; }
  /// The position-only environment SH head (null without an environment or without SH).
  const nn::NetworkWithInputEncoding* environment_network() const { return m_environment.get(); }

  /// Sizes the pass for `n_rays` rays and `n_env` environment directions (allocates only when it grows).
  void prepare(OursPass& pass, std::uint32_t n_rays, std::uint32_t n_env = 0) const;

  /// Samples the rays (sample positions, jittered when training), runs the networks and assembles the
  /// renderer's property matrix. `training` keeps the activations for backward(); `march_visibility`
  /// replaces the visibility network by a march through the density grid (inference option). `env`: the
  /// environment directions of this pass (EnvironmentSamples::draw()), for a model trained with an
  /// environment; null renders under the point light alone (S_env = 0, c_env = 0).
  void forward(OursPass& pass, Buffer<float>& rays, std::uint32_t n_rays, bool training, std::uint32_t seed,
               const nn::BatchMatrix& dirs, const nn::BatchMatrix& sh_basis, bool march_visibility = false,
               StageTimer* timer = nullptr, const render::EnvironmentSamples* env = nullptr) const;

  /// Given dL/dcolour (n_rays x 3, rows): writes dL/dθ into grads() (overwriting). The visibility network
  /// gets nothing (gradient isolation). `env` as given to forward().
  void backward(OursPass& pass, const Buffer<float>& rays, const nn::BatchMatrix& dirs, const nn::BatchMatrix& sh_basis,
                const Buffer<float>& d_color, StageTimer* timer = nullptr,
                const render::EnvironmentSamples* env = nullptr);

  /// One visibility-network gradient: on the samples of the pass's first visibility_fraction of rays, the
  /// loss of V_ψ against the transmittance of the density grid toward the light (constants, so θ gets
  /// nothing); after an environment forward pass, also on the samples of the first
  /// environment.visibility_fraction of rays toward each environment direction. Writes dL/dψ into
  /// vis_grads() (overwriting) and the mean loss over all these queries into `value` (on the device).
  void visibility_step(OursPass& pass, const Buffer<float>& rays, const nn::Loss& loss, Buffer<float>& value,
                       float weight = 1.0f, StageTimer* timer = nullptr,
                       const render::EnvironmentSamples* env = nullptr);

  /// Re-evaluates the density grid from the current θ (the property net's σ at the voxel centres).
  void refresh_density_grid();
  const render::DensityGrid& density_grid() const { return m_grid; }
  render::DensityGrid& density_grid() { return m_grid; }

 private:
  Ours() = default;
  void configure(const Json& config, const std::string& pointer, config::Docs* docs);
  void allocate();
  Device m_device;
  OursSettings m_settings;
  Json m_resolved;
  std::unique_ptr<render::VolumeRenderer> m_renderer;
  mutable std::map<std::uint32_t, std::unique_ptr<render::VolumeRenderer>> m_env_renderers;  // by N_e
  std::unique_ptr<nn::NetworkWithInputEncoding> m_property, m_indirect, m_visibility, m_environment;
  Buffer<float> m_params, m_grads, m_vis_params, m_vis_grads;
  render::DensityGrid m_grid;
  nn::BatchMatrix m_grid_positions, m_grid_props;
  std::unique_ptr<nn::Workspace> m_grid_ws;
};

}  // namespace relit::method
