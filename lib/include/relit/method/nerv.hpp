// NeRV adapted to participating media (Zheng et al. 2021, appendix D; docs/design.md §4.5), the "nerv" method.
//
//   property MLP F_θ(x)       ──► σ, albedo, g                      (Ours' property net, no SH head)
//   visibility MLP V_ψ(x, ω)  ──► V and the expected termination depth D: a trunk on the encoded position
//                                 (8 outputs), concatenated with the encoded direction, then a head
//   direct light: one V_ψ query toward the point light per sample (N_e toward an environment), as Ours
//   one indirect bounce per camera ray: at the expected termination point x_t, K uniform directions ω_k (128,
//   or 32 under an environment) land at x_t + D(x_t, ω_k) ω_k, whose single-scattered light (point light and
//   environment) comes back through the phase at x_t (kernels/nerv.cl has the equations)
//
// V_ψ is trained against marches of the learned density (V and D, toward the light from camera samples and
// along the bounce directions from x_t), gradients isolated both ways as Ours.
//
// A MediumModel (relit/method/medium.hpp) of the parts: the HG phase (g = 0.95 tanh), no SH head, uniform
// samples; this class adds its own visibility net (V and D) and the bounce ("bounce").
#pragma once

#include <relit/method/medium.hpp>

namespace relit::method {

struct NeRVSettings {
  std::uint32_t n_dirs = 128;         ///< K, bounce directions per camera ray in a training step ('point' data)
  std::uint32_t n_dirs_render = 128;  ///< K when rendering images ('point' data)
  std::uint32_t n_dirs_env = 32;      ///< K under an environment light ('env+point' data)
  float visibility_fraction = 0.25f;  ///< share of rays whose bounce queries also train V_ψ
};

struct NeRVPass : MediumPass {
  std::uint32_t n_bounce = 0;
  /// Keep the termination points x_t of the previous pass (x_t is a constant for the render loss; finite
  /// differences of the colour match backward() only with x_t held).
  bool keep_termination = false;
  std::unique_ptr<render::IndirectBasis> bounce_dirs;
  Buffer<float> albedo_sum, x_t, x_b, indirect, dw;  // float4 per ray (x_b: per bounce)
  Buffer<float> total;  // the image: the direct colour (MediumPass::color, kept for its backward pass) + W ⊙ E
  nn::BatchMatrix bounce_in, bounce_vd, bounce_pos, bounce_props, d_bounce_props, light_in, light_vd, env_in, env_vd;
  const render::EnvironmentSamples* env = nullptr;  // the environment of the last render()
  nn::BatchMatrix train_in, train_out, train_target, d_train;
  std::unique_ptr<nn::Workspace> ws_bounce_vis, ws_light_vis, ws_env_vis, ws_bounce_property;
};

class NeRV : public MediumModel {
 public:
  NeRV(const Device& device, const Json& config, const std::string& pointer = "/model");
  static void describe(config::Docs& docs);
  static Json check(const Json& config, const std::string& pointer) { return NeRV().check_keys(config, pointer); }
  static MethodParts method_parts() {
    MethodParts p;
    p.sh_head = false;
    return p;
  }

  std::string method() const override { return "nerv"; }
  const NeRVSettings& nerv_settings() const { return m_nerv; }
  /// K of a pass: n_dirs (training) or n_dirs_render, or n_dirs_env with an environment.
  std::uint32_t bounce_dirs(bool environment, bool training) const {
    return environment ? m_nerv.n_dirs_env : training ? m_nerv.n_dirs : m_nerv.n_dirs_render;
  }
  std::uint32_t queries_per_ray() const override;

  std::unique_ptr<ModelPass> make_pass() const override { return std::make_unique<NeRVPass>(); }
  void render(ModelPass& pass, Buffer<float>& rays, std::uint32_t n_rays, const PassOptions& options) const override;
  const Buffer<float>& color(const ModelPass& pass, std::uint32_t i) const override;
  void backward(ModelPass& pass, const Buffer<float>& rays, const std::vector<const Buffer<float>*>& d_colors,
                const PassOptions& options) override;
  double train_visibility(ModelPass& pass, const Buffer<float>& rays, const nn::Loss& loss, Buffer<float>& value,
                          float weight, const PassOptions& options) override;

 protected:
  void configure_method(config::Reader& r, config::Docs* docs) override;  // "bounce"
  void configure_visibility(config::Reader& r, config::Docs* docs) override;
  void add_property_gradients(MediumPass& pass, const Branch& branch, const Buffer<float>& rays,
                              const Buffer<float>& d_color) override;

 private:
  NeRV() : MediumModel(method_parts()) {}
  NeRVSettings m_nerv;
};

}  // namespace relit::method
