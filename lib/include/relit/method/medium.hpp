// MediumModel: the model every method of relit is put together from: a participating medium whose
// properties a network predicts, lit through a learned visibility network (Zheng, Singh, Seidel, "Neural
// Relightable Participating Media Rendering", NeurIPS 2021, and the baselines of its appendix D).
//
//   positions x ──► property net F_θ ──► σ (softplus), the scattering part's heads, feature f
//   [f, p_l]   ──► indirect SH head h_θ ──► c = (I / I_ref) ⊙ h + c_env  (scaled by the light's RGB intensity)
//   f          ──► environment head e_θ ──► c_env (position-only; only with an environment map)
//   [x, ω_l]   ──► visibility net V_ψ  ──► V (sigmoid), toward the point light and each environment direction
//   σ, a, g, V, c ──► VolumeRenderer ──► pixel colour
//
// A method says which parts it has in its MethodParts: the scattering model (the HG phase function with its
// g = s tanh(raw), or the UE4/Karis BRDF of solids), the SH indirect head or none, uniform or hierarchical
// (coarse-fine) sampling. Ours is all defaults; Bi et al. is the isotropic phase without SH head, sampled
// hierarchically; NeRV replaces the visibility net and adds one bounce of indirect light (relit/method/nerv.hpp).
// Each part reads its own section of the "model" config (docs/config.md).
//
// θ ([property net | SH head | environment head | coarse net]) and ψ (visibility net) live in two flat
// parameter buffers with their own optimisers. Gradients are isolated both ways (the paper's appendix C):
// the render loss reaches θ only (the renderer gives no gradient to V), and the visibility loss — against the
// transmittance of the learned density, marched through a cached density grid — reaches ψ only (the targets
// are constants). "model/shadow_gradient" (ShadowGradientSettings, off by default) lifts the first half of
// the isolation: the render loss's dL/dV is passed on to the density along the shadow rays.
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

/// The environment light of 'env+point' datasets (docs/design.md §4.2-4.3): S_env over N_e importance-sampled
/// directions, each with its own visibility query, and the position-only SH head c_env(x).
struct EnvironmentSettings {
  bool enabled = false;                 ///< the model has c_env and trains S_env (relit train sets it from the dataset)
  std::uint32_t n_dirs = 32;            ///< N_e when rendering under the environment
  std::uint32_t n_dirs_training = 4;    ///< N_e of a training step (fresh directions every step)
  float visibility_fraction = 0.0625f;  ///< share of a batch's rays whose samples train V_ψ toward the N_e directions
};

/// The scattering part: how the property net's heads after σ become the renderer's scattering properties.
struct Scattering {
  enum class Kind { phase, brdf };
  Kind kind = Kind::phase;
  /// Column 4 of the renderer's properties is g_scale times the head: the HG phase's g = g_scale tanh(raw)
  /// (0.95; 0 is the isotropic phase), or the BRDF's roughness, a sigmoid (scale 1).
  float g_scale = 0.95f;

  /// The Henyey-Greenstein phase function with g = g_scale tanh(raw).
  static Scattering hg_phase(float g_scale) { return {Kind::phase, g_scale}; }
  /// The UE4/Karis BRDF of solids (kernels/brdf.clh): a roughness and a raw normal.
  static Scattering brdf() { return {Kind::brdf, 1.0f}; }
  bool is_brdf() const { return kind == Kind::brdf; }
  /// The property net's output heads before the features: σ (softplus), albedo (sigmoid, 3), then g (tanh), or
  /// the roughness (sigmoid) and the raw normal (3).
  Json heads() const;
  std::uint32_t n_heads() const { return is_brdf() ? 8u : 5u; }
  /// Whether the renderer offers the closed-form indirect light (the phase function's SH convolution).
  bool has_closed_form_indirect() const { return !is_brdf(); }
};

/// The shadow gradient (docs/baselines.md, "Training stability"): the render loss's dL/dV toward the point
/// light, passed on to the density along each sample's shadow ray, dL/dσ(y) = -dL/dV V for y on the segment
/// from the sample to the light inside the box. `points` uniform random points per sample estimate the line
/// integral (counter-based, so deterministic); the samples of the first `fraction` of a batch's rays take
/// part, their gradient scaled by 1 / fraction. Without it V is a constant of the render loss (appendix C).
struct ShadowGradientSettings {
  bool enabled = false;
  std::uint32_t points = 1;  ///< points per sample on its shadow ray
  float fraction = 0.25f;    ///< share of a batch's rays whose samples pass the gradient on
};

/// What a method is made of (a method's own parts, such as NeRV's bounce, are its class's).
struct MethodParts {
  Scattering scattering;
  /// The SH indirect head h_θ with its keys (renderer sh, n_dirs; n_features, intensity_reference, ...; the
  /// "indirect" section) and the environment's c_env head; without it the model has direct light only.
  bool sh_head = true;
  std::string default_sh = "5";  ///< its default SH l_max ("model/renderer/sh")
  /// Hierarchical sampling (Bi et al.): a coarse network ("coarse") on renderer.n_samples stratified samples,
  /// whose weights place renderer.n_fine_samples more for the fine network ("property").
  bool hierarchical = false;
};

/// Resolved settings of the model (the non-network keys of the "model" config object).
struct MediumSettings {
  render::VolumeRendererSettings renderer;
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
  std::uint32_t n_fine_samples = 128;            ///< hierarchical sampling: importance samples per ray
  std::uint32_t grid_resolution = 64;            ///< density grid for visibility targets (per axis)
  std::uint32_t grid_refresh = 16;               ///< refresh the grid every this many training steps
  std::uint32_t march_steps = 64;                ///< midpoint steps of the visibility-target march
  float visibility_fraction = 0.25f;             ///< share of a batch's rays whose samples train the visibility net
  std::string inference_visibility = "network";  ///< "network" (as the paper) or "march" (density grid)
  std::string training_visibility = "network";   ///< V of the training renders: "network" (as the paper) or "march"
  EnvironmentSettings environment;
  ShadowGradientSettings shadow_gradient;
};

/// Scratch matrices of one pass over a batch of rays; reused across iterations (no allocation once sized).
struct MediumPass : ModelPass {
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
  // The shadow gradient: points on the shadow rays of the first rays' samples, the property net there, and
  // dL/d(its outputs) (σ only); the global batch and the seed of the pass that drew them.
  nn::BatchMatrix shadow_pos, shadow_props, d_shadow;
  std::unique_ptr<nn::Workspace> ws_shadow;
  std::uint32_t batch_rays = 0, shadow_seed = 0;
};

/// The model of a method: its MethodParts' networks and the passes that join them to the volume renderer.
/// A method's class derives from it, gives its parts and builds itself (build()), and overrides what it does
/// differently (Bi et al.'s coarse-fine passes, NeRV's visibility net and bounce).
class MediumModel : public Model {
 public:
  const MethodParts& parts() const { return m_parts; }
  const MediumSettings& settings() const { return m_settings; }
  /// The renderer without environment light; renderer(N_e) the one for N_e environment directions.
  const render::VolumeRenderer& renderer() const { return *m_renderer; }
  const render::VolumeRenderer& renderer(std::uint32_t n_env_dirs) const {
    return renderer_for(m_settings.renderer.n_samples, n_env_dirs);
  }

  /// θ: [property net | SH head | environment head | coarse net]; ψ: the visibility net.
  void initialize(std::uint64_t seed) override;
  /// Sets the σ head's bias in θ so that σ starts near MediumSettings::initial_density.
  void set_initial_density(float* theta) const;

  const nn::NetworkWithInputEncoding& property_network() const { return *m_property; }
  const nn::NetworkWithInputEncoding& indirect_network() const { return *m_indirect; }
  const nn::NetworkWithInputEncoding& visibility_network() const { return *m_visibility; }
  /// The position-only environment SH head (null without an environment or without SH).
  const nn::NetworkWithInputEncoding* environment_network() const { return m_environment.get(); }

  /// Sizes the pass for `n_rays` rays and `n_env` environment directions (allocates only when it grows).
  void prepare(MediumPass& pass, std::uint32_t n_rays, std::uint32_t n_env = 0) const {
    prepare_branch(pass, main_branch(), n_rays, n_env);
  }

  /// Samples the rays (sample positions, jittered when training), runs the networks and assembles the
  /// renderer's property matrix. `training` keeps the activations for backward(); `march_visibility`
  /// replaces the visibility network by a march through the density grid (inference option). `env`: the
  /// environment directions of this pass (EnvironmentSamples::draw()), for a model trained with an
  /// environment; null renders under the point light alone (S_env = 0, c_env = 0).
  void forward(MediumPass& pass, Buffer<float>& rays, std::uint32_t n_rays, bool training, std::uint32_t seed,
               const nn::BatchMatrix& dirs, const nn::BatchMatrix& sh_basis, bool march_visibility = false,
               StageTimer* timer = nullptr, const render::EnvironmentSamples* env = nullptr) const {
    forward_branch(pass, main_branch(), rays, n_rays, training, seed, dirs, sh_basis, march_visibility, timer, env,
                   true);
  }

  /// Given dL/dcolour (n_rays x 3, rows): writes dL/dθ into grads() (overwriting). The visibility network
  /// gets nothing (gradient isolation). `env` as given to forward().
  void backward(MediumPass& pass, const Buffer<float>& rays, const nn::BatchMatrix& dirs,
                const nn::BatchMatrix& sh_basis, const Buffer<float>& d_color, StageTimer* timer = nullptr,
                const render::EnvironmentSamples* env = nullptr) {
    backward_branch(pass, main_branch(), rays, dirs, sh_basis, d_color, timer, env);
  }

  /// One visibility-network gradient: on the samples of the pass's first visibility_fraction of rays, the
  /// loss of V_ψ against the transmittance of the density grid toward the light (constants, so θ gets
  /// nothing); after an environment forward pass, also on the samples of the first
  /// environment.visibility_fraction of rays toward each environment direction. Writes dL/dψ into
  /// vis_grads() (overwriting) and the mean loss over all these queries into `value` (on the device).
  /// Under data parallelism the first rays are those of the global batch of `batch_rays` rays, of which the pass
  /// holds `share`; returns the fraction of the global queries it trained on (Model::train_visibility()).
  double visibility_step(MediumPass& pass, const Buffer<float>& rays, const nn::Loss& loss, Buffer<float>& value,
                         float weight = 1.0f, StageTimer* timer = nullptr,
                         const render::EnvironmentSamples* env = nullptr, parallel::Share share = {},
                         std::uint32_t batch_rays = 0);

  /// Re-evaluates the density grid from the current θ (the property net's σ at the voxel centres).
  void refresh_density_grid(parallel::Share share = {}) override;
  std::uint32_t grid_refresh_every() const override { return m_settings.grid_refresh; }

  bool has_environment() const override { return m_settings.environment.enabled; }
  std::uint32_t env_dirs() const override { return m_settings.environment.n_dirs; }
  std::uint32_t env_dirs_training() const override { return m_settings.environment.n_dirs_training; }
  std::string inference_visibility() const override { return m_settings.inference_visibility; }
  std::uint32_t queries_per_ray() const override;

  std::unique_ptr<ModelPass> make_pass() const override { return std::make_unique<MediumPass>(); }
  void render(ModelPass& pass, Buffer<float>& rays, std::uint32_t n_rays, const PassOptions& options) const override;
  const Buffer<float>& color(const ModelPass& pass, std::uint32_t i) const override;
  const Buffer<float>& transmittance(const ModelPass& pass) const override;
  void backward(ModelPass& pass, const Buffer<float>& rays, const std::vector<const Buffer<float>*>& d_colors,
                const PassOptions& options) override;
  double train_visibility(ModelPass& pass, const Buffer<float>& rays, const nn::Loss& loss, Buffer<float>& value,
                          float weight, const PassOptions& options) override;

 protected:
  /// A method's constructor gives its parts and calls build() (so that its overrides take part).
  MediumModel(const Device& device, MethodParts parts) : Model(device), m_parts(std::move(parts)) {}
  explicit MediumModel(MethodParts parts) : m_parts(std::move(parts)) {}  // describe_keys() only
  /// Reads the "model" config object (at JSON pointer `pointer`; unknown keys and bad values are ConfigErrors
  /// naming it), builds the networks and allocates θ and ψ.
  void build(const Json& config, const std::string& pointer);
  /// Every key of the model config, per JSON object (for docs/config.md).
  void describe_keys(config::Docs& docs) { configure(Json::object(), "/model", &docs); }
  /// Reads `config` without building anything on a device (a method's static check()); the resolved config.
  Json check_keys(const Json& config, const std::string& pointer) {
    configure(config, pointer, nullptr);
    return m_resolved;
  }

  /// Reads the "model" object section by section, in this order; each part reads its own keys.
  void configure(const Json& config, const std::string& pointer, config::Docs* docs);
  void configure_renderer(config::Reader& r, config::Docs* docs);         // "renderer"
  void configure_indirect_keys(config::Reader& r);                        // the SH head's keys of "model" itself
  void configure_density_grid(config::Reader& r, config::Docs* docs);     // "density_grid"
  void configure_visibility_modes(config::Reader& r);                     // inference/training_visibility
  void configure_shadow_gradient(config::Reader& r, config::Docs* docs);  // "shadow_gradient"
  Json configure_environment(config::Reader& r, config::Docs* docs);      // "environment"; gives c_env's network
  void configure_property(config::Reader& r, config::Docs* docs);         // "property"
  void configure_indirect(config::Reader& r, config::Docs* docs);         // "indirect"
  void configure_environment_head(config::Reader& r, const Json& network);
  void configure_coarse(config::Reader& r, config::Docs* docs);  // "coarse" (hierarchical sampling)
  /// A method's own sections of the "model" object (NeRV: "bounce"), read before the visibility net.
  virtual void configure_method(config::Reader& r, config::Docs* docs) { (void)r, (void)docs; }
  /// The visibility net V_ψ(x, ω) → V from the "visibility" section (NeRV: its own, which also gives a depth).
  virtual void configure_visibility(config::Reader& r, config::Docs* docs);
  void allocate();

  /// Whether a pass marches the density grid for V: asked to, or a training pass with training_visibility "march".
  bool marches(const PassOptions& o) const {
    return o.march_visibility || (o.training && m_settings.training_visibility == "march");
  }
  /// Draws the pass's K indirect directions (and their SH basis) of iteration o.iteration.
  void draw_basis(MediumPass& pass, const PassOptions& o) const;
  /// Keeps what a pass's backward needs of its options: the share, the global batch, the seed.
  static void begin_pass(MediumPass& pass, const PassOptions& o) {
    pass.share = o.share;
    pass.batch_rays = o.batch_rays;
    pass.shadow_seed = o.jitter_seed ^ 0x2545f491u;
  }
  /// The property net's outputs before the features (the scattering part's heads).
  std::uint32_t prop_heads() const { return m_parts.scattering.n_heads(); }
  /// A property network with its θ offset and samples per ray (hierarchical sampling: a coarse and a fine one).
  struct Branch {
    const nn::NetworkWithInputEncoding* property = nullptr;
    std::uint32_t theta_offset = 0;
    std::uint32_t n_samples = 64;
  };
  Branch main_branch() const { return {m_property.get(), 0, m_settings.renderer.n_samples}; }
  const render::VolumeRenderer& renderer_for(std::uint32_t n_samples, std::uint32_t n_env) const;
  void prepare_branch(MediumPass& pass, const Branch& branch, std::uint32_t n_rays, std::uint32_t n_env) const;
  /// forward() for `branch`; with `place_samples` false the pass's t, delta and positions are given.
  void forward_branch(MediumPass& pass, const Branch& branch, Buffer<float>& rays, std::uint32_t n_rays, bool training,
                      std::uint32_t seed, const nn::BatchMatrix& dirs, const nn::BatchMatrix& sh_basis, bool march,
                      StageTimer* timer, const render::EnvironmentSamples* env, bool place_samples) const;
  /// forward_branch()'s visibility (V columns of the properties) and SH-head parts.
  void forward_visibility(MediumPass& pass, Buffer<float>& rays, std::uint32_t n_rays, std::uint32_t spr, bool march,
                          const render::EnvironmentSamples* env) const;
  void forward_indirect(MediumPass& pass, Buffer<float>& rays, std::uint32_t n_rays, std::uint32_t spr, bool training,
                        std::uint32_t n_env) const;
  void backward_branch(MediumPass& pass, const Branch& branch, const Buffer<float>& rays, const nn::BatchMatrix& dirs,
                       const nn::BatchMatrix& sh_basis, const Buffer<float>& d_color, StageTimer* timer,
                       const render::EnvironmentSamples* env);
  /// Called by backward_branch() between the renderer's backward pass and the networks': a method may add
  /// gradients of its own terms to dL/dproperties.
  virtual void add_property_gradients(MediumPass& pass, const Branch& branch, const Buffer<float>& rays,
                                      const Buffer<float>& d_color) {
    (void)pass, (void)branch, (void)rays, (void)d_color;
  }
  /// The shadow gradient of the pass's dL/dV (column kVisibility of d_props) into the property net's part of
  /// grads() (adding). The density behind V is the property net's (the grid is refreshed from it), whichever
  /// branch rendered.
  void add_shadow_gradient(MediumPass& pass, const Buffer<float>& rays, StageTimer* timer);
  /// θ of the property net, the SH head and the environment head (the coarse net follows).
  std::uint32_t own_params() const;

  MethodParts m_parts;
  MediumSettings m_settings;
  std::unique_ptr<render::VolumeRenderer> m_renderer;
  mutable std::map<std::pair<std::uint32_t, std::uint32_t>, std::unique_ptr<render::VolumeRenderer>> m_renderers;
  std::unique_ptr<nn::NetworkWithInputEncoding> m_property, m_indirect, m_visibility, m_environment, m_coarse;
  nn::BatchMatrix m_grid_positions, m_grid_props;
  std::unique_ptr<nn::Workspace> m_grid_ws;
};

}  // namespace relit::method
