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
#include <relit/method/model.hpp>
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
  bool enabled = false;                 ///< the model has c_env and trains S_env (relit train sets it from the dataset)
  std::uint32_t n_dirs = 32;            ///< N_e when rendering under the environment
  std::uint32_t n_dirs_training = 4;    ///< N_e of a training step (fresh directions every step)
  float visibility_fraction = 0.0625f;  ///< share of a batch's rays whose samples train V_ψ toward the N_e directions
};

/// Resolved settings of the model (the non-network keys of the "model" config object).
struct OursSettings {
  render::RendererSettings renderer;
  std::uint32_t n_features = 11;           ///< feature columns the property net passes to the SH head
  float intensity_reference = 1000.0f;     ///< I_ref: the SH head predicts indirect light per I / I_ref
  float light_position_scale = 0.125f;     ///< the SH head sees the light position times this
  bool light_conditioned = true;           ///< false: c = c(x), the position-only ablation
  bool indirect_visibility_input = false;  ///< the SH head also sees V(x, ω_l) (indirect.visibility_input)
  bool indirect_depth_attenuation =
      false;  ///< the SH head's output is multiplied by exp(-k τ) (indirect.optical_depth_attenuation)
  float indirect_optical_depth =
      0.0f;  ///< k > 0: the SH head also sees exp(-k τ(x → p_l)) (indirect.optical_depth_input)
  float initial_density = 0.6931472f;            ///< σ of the property net at initialisation (softplus of its σ bias)
  std::uint32_t grid_resolution = 64;            ///< density grid for visibility targets (per axis)
  std::uint32_t grid_refresh = 16;               ///< refresh the grid every this many training steps
  std::uint32_t march_steps = 64;                ///< midpoint steps of the visibility-target march
  float visibility_fraction = 0.25f;             ///< share of a batch's rays whose samples train the visibility net
  std::string inference_visibility = "network";  ///< "network" (as the paper) or "march" (density grid)
  std::string training_visibility = "network";   ///< V of the training renders: "network" (as the paper) or "march"
  EnvironmentSettings environment;
};

/// Scratch matrices of one pass over a batch of rays; reused across iterations (no allocation once sized).
struct OursPass : ModelPass {
  std::uint32_t n_samples = 0;  ///< samples per ray of the last forward pass
  Buffer<float> t, delta, color, transmittance;
  nn::BatchMatrix positions, net_pos, props_raw, light_in, indirect_raw, vis_in, vis, props, radiance;
  nn::BatchMatrix depth_in;  // indirect.optical_depth_input: exp(-k τ) toward the light, marched
  nn::BatchMatrix d_props, d_radiance, d_props_raw, d_indirect_raw, d_light_in;
  nn::BatchMatrix vis_in_sub, positions_sub, vis_sub, vis_target, d_vis;  // the visibility net's training subset
  // With an environment: V_ψ's inputs toward the N_e directions (sample-major rows s N_e + j), its outputs, the
  // head's c_env, and the march targets of the environment rows of the visibility subset.
  std::uint32_t n_env = 0;
  nn::BatchMatrix view_basis;  // closed-form indirect: Y(-w_o) per ray, in place of the K directions' basis
  nn::BatchMatrix env_vis_in, env_vis, env_raw, d_env_raw, d_env_in, env_march, env_positions_sub, env_target,
      point_target;
  std::unique_ptr<nn::Workspace> ws_property, ws_indirect, ws_visibility, ws_env_visibility, ws_environment;
  std::unique_ptr<render::IndirectBasis> basis;  // the K directions of render(), drawn per iteration
};

class Ours : public Model {
 public:
  /// Builds the networks from the "model" config object (at JSON pointer `pointer`); unknown keys and bad
  /// values are ConfigErrors naming the pointer.
  Ours(const Device& device, const Json& config, const std::string& pointer = "/model");
  /// Every key of the model config, per JSON object (for docs/config.md).
  static void describe(config::Docs& docs);

  std::string method() const override { return "ours"; }
  const OursSettings& settings() const { return m_settings; }
  /// The renderer without environment light; renderer(N_e) the one for N_e environment directions.
  const render::VolumeRenderer& renderer() const { return *m_renderer; }
  const render::VolumeRenderer& renderer(std::uint32_t n_env_dirs) const {
    return renderer_for(m_settings.renderer.n_samples, n_env_dirs);
  }

  /// θ: [property net | SH head | environment head]; ψ: the visibility net.
  void initialize(std::uint64_t seed) override;
  /// Sets the σ head's bias in θ so that σ starts near OursSettings::initial_density.
  void set_initial_density(float* theta) const;

  const nn::NetworkWithInputEncoding& property_network() const { return *m_property; }
  const nn::NetworkWithInputEncoding& indirect_network() const { return *m_indirect; }
  const nn::NetworkWithInputEncoding& visibility_network() const { return *m_visibility; }
  /// The position-only environment SH head (null without an environment or without SH).
  const nn::NetworkWithInputEncoding* environment_network() const { return m_environment.get(); }

  /// Sizes the pass for `n_rays` rays and `n_env` environment directions (allocates only when it grows).
  void prepare(OursPass& pass, std::uint32_t n_rays, std::uint32_t n_env = 0) const {
    prepare_branch(pass, main_branch(), n_rays, n_env);
  }

  /// Samples the rays (sample positions, jittered when training), runs the networks and assembles the
  /// renderer's property matrix. `training` keeps the activations for backward(); `march_visibility`
  /// replaces the visibility network by a march through the density grid (inference option). `env`: the
  /// environment directions of this pass (EnvironmentSamples::draw()), for a model trained with an
  /// environment; null renders under the point light alone (S_env = 0, c_env = 0).
  void forward(OursPass& pass, Buffer<float>& rays, std::uint32_t n_rays, bool training, std::uint32_t seed,
               const nn::BatchMatrix& dirs, const nn::BatchMatrix& sh_basis, bool march_visibility = false,
               StageTimer* timer = nullptr, const render::EnvironmentSamples* env = nullptr) const {
    forward_branch(pass, main_branch(), rays, n_rays, training, seed, dirs, sh_basis, march_visibility, timer, env,
                   true);
  }

  /// Given dL/dcolour (n_rays x 3, rows): writes dL/dθ into grads() (overwriting). The visibility network
  /// gets nothing (gradient isolation). `env` as given to forward().
  void backward(OursPass& pass, const Buffer<float>& rays, const nn::BatchMatrix& dirs, const nn::BatchMatrix& sh_basis,
                const Buffer<float>& d_color, StageTimer* timer = nullptr,
                const render::EnvironmentSamples* env = nullptr) {
    backward_branch(pass, main_branch(), rays, dirs, sh_basis, d_color, timer, env);
  }

  /// One visibility-network gradient: on the samples of the pass's first visibility_fraction of rays, the
  /// loss of V_ψ against the transmittance of the density grid toward the light (constants, so θ gets
  /// nothing); after an environment forward pass, also on the samples of the first
  /// environment.visibility_fraction of rays toward each environment direction. Writes dL/dψ into
  /// vis_grads() (overwriting) and the mean loss over all these queries into `value` (on the device).
  void visibility_step(OursPass& pass, const Buffer<float>& rays, const nn::Loss& loss, Buffer<float>& value,
                       float weight = 1.0f, StageTimer* timer = nullptr,
                       const render::EnvironmentSamples* env = nullptr);

  /// Re-evaluates the density grid from the current θ (the property net's σ at the voxel centres).
  void refresh_density_grid() override;
  std::uint32_t grid_refresh_every() const override { return m_settings.grid_refresh; }

  bool has_environment() const override { return m_settings.environment.enabled; }
  std::uint32_t env_dirs() const override { return m_settings.environment.n_dirs; }
  std::uint32_t env_dirs_training() const override { return m_settings.environment.n_dirs_training; }
  std::string inference_visibility() const override { return m_settings.inference_visibility; }
  std::uint32_t queries_per_ray() const override;

  std::unique_ptr<ModelPass> make_pass() const override { return std::make_unique<OursPass>(); }
  void render(ModelPass& pass, Buffer<float>& rays, std::uint32_t n_rays, const PassOptions& options) const override;
  const Buffer<float>& color(const ModelPass& pass, std::uint32_t i) const override;
  void backward(ModelPass& pass, const Buffer<float>& rays, const std::vector<const Buffer<float>*>& d_colors,
                const PassOptions& options) override;
  void train_visibility(ModelPass& pass, const Buffer<float>& rays, const nn::Loss& loss, Buffer<float>& value,
                        float weight, const PassOptions& options) override;

 protected:
  /// What the model varies for the methods built on it (NeuralReflectanceField, NeRV).
  enum class Variant { ours, ours_brdf, bi, nerv };
  /// A derived method's constructor calls configure() and allocate() itself (so that its hooks dispatch).
  Ours(const Device& device, Variant variant) : Model(device), m_variant(variant) {}
  explicit Ours(Variant variant) : m_variant(variant) {}  // describe() only
  /// Reads the derived method's own keys of the "model" object (before unknown keys are rejected).
  virtual void configure_extra(config::Reader& r, config::Docs* docs) { (void)r, (void)docs; }
  /// Reads the derived method's own keys of the "renderer" object.
  virtual void configure_renderer_extra(config::Reader& r) { (void)r; }
  /// Ours and Ours + BRDF have the SH heads and their keys; the baselines do not.
  bool has_sh_head() const { return m_variant == Variant::ours || m_variant == Variant::ours_brdf; }
  /// Whether a pass marches the density grid for V: asked to, or a training pass with training_visibility "march".
  bool marches(const PassOptions& o) const {
    return o.march_visibility || (o.training && m_settings.training_visibility == "march");
  }
  /// Draws the pass's K indirect directions (and their SH basis) of iteration o.iteration.
  void draw_basis(OursPass& pass, const PassOptions& o) const;
  /// HG g = g_scale() tanh(raw): 0.95, or 0 for Bi et al.'s isotropic phase (Ours + BRDF: the roughness, 1).
  float g_scale() const { return m_variant == Variant::bi ? 0.0f : m_variant == Variant::ours_brdf ? 1.0f : 0.95f; }
  /// The property net's outputs before the features: sigma, albedo (3), g or roughness, and for Ours + BRDF
  /// the raw normal (3).
  std::uint32_t prop_heads() const { return m_variant == Variant::ours_brdf ? 8u : 5u; }
  /// A property network with its θ offset and samples per ray (Bi et al. has a coarse and a fine one).
  struct Branch {
    const nn::NetworkWithInputEncoding* property = nullptr;
    std::uint32_t theta_offset = 0;
    std::uint32_t n_samples = 64;
  };
  Branch main_branch() const { return {m_property.get(), 0, m_settings.renderer.n_samples}; }
  const render::VolumeRenderer& renderer_for(std::uint32_t n_samples, std::uint32_t n_env) const;
  void prepare_branch(OursPass& pass, const Branch& branch, std::uint32_t n_rays, std::uint32_t n_env) const;
  /// forward() for `branch`; with `place_samples` false the pass's t, delta and positions are given.
  void forward_branch(OursPass& pass, const Branch& branch, Buffer<float>& rays, std::uint32_t n_rays, bool training,
                      std::uint32_t seed, const nn::BatchMatrix& dirs, const nn::BatchMatrix& sh_basis, bool march,
                      StageTimer* timer, const render::EnvironmentSamples* env, bool place_samples) const;
  void backward_branch(OursPass& pass, const Branch& branch, const Buffer<float>& rays, const nn::BatchMatrix& dirs,
                       const nn::BatchMatrix& sh_basis, const Buffer<float>& d_color, StageTimer* timer,
                       const render::EnvironmentSamples* env);
  /// Called by backward_branch() between the renderer's backward pass and the networks': a method may add
  /// gradients of its own terms to dL/dproperties.
  virtual void add_property_gradients(OursPass& pass, const Branch& branch, const Buffer<float>& rays,
                                      const Buffer<float>& d_color) {
    (void)pass, (void)branch, (void)rays, (void)d_color;
  }
  /// θ parameters after Ours' own (Bi et al.'s coarse network); initialize() calls initialize_extra on them.
  virtual std::uint32_t n_extra_params() const { return 0; }
  virtual void initialize_extra(float* theta, std::uint64_t seed) const { (void)theta, (void)seed; }
  /// Builds the networks, then allocate() sizes θ = Ours' networks + n_extra_params().
  void configure(const Json& config, const std::string& pointer, config::Docs* docs);
  void allocate();
  std::uint32_t own_params() const;
  Variant m_variant = Variant::ours;
  OursSettings m_settings;
  std::unique_ptr<render::VolumeRenderer> m_renderer;
  mutable std::map<std::pair<std::uint32_t, std::uint32_t>, std::unique_ptr<render::VolumeRenderer>> m_renderers;
  std::unique_ptr<nn::NetworkWithInputEncoding> m_property, m_indirect, m_visibility, m_environment;
  nn::BatchMatrix m_grid_positions, m_grid_props;
  std::unique_ptr<nn::Workspace> m_grid_ws;
};

/// "Ours + BRDF" for solid objects (DESIGN §4.4), the "ours_brdf" method: Ours with the UE4/Karis BRDF
/// (kernels/brdf.clh) in place of the phase function; the property net predicts σ, the diffuse albedo, the
/// roughness and a normal (normalised by the renderer). SH l_max defaults to 1.
class OursBrdf : public Ours {
 public:
  OursBrdf(const Device& device, const Json& config, const std::string& pointer = "/model");
  static void describe(config::Docs& docs);
  std::string method() const override { return "ours_brdf"; }

 private:
  explicit OursBrdf(Variant v) : Ours(v) {}
};

}  // namespace relit::method
