// Bi et al.'s Neural Reflectance Field adapted to participating media (Zheng et al. 2021, appendix D; docs/design.md
// §4.5), the "bi" method.
//
//   coarse: N_c stratified samples ──► coarse net ──► σ, albedo ──► coarse image     (HG phase with g = 0)
//           weights w_i ──► N_f importance samples (hierarchical sampling, kernels/hierarchical.cl)
//   fine:   N_c + N_f sorted samples ──► fine net ("property") ──► σ, albedo ──► the image
//   both:   direct light only (point light; environment when trained on 'env+point'), with V_ψ as Ours
//
// The render loss is the L2 of both images (the trainer sums them); V_ψ is trained against marches of the
// fine network's density, gradients isolated both ways as Ours. θ = [fine net | coarse net].
//
// A MediumModel (relit/method/medium.hpp) of the parts: the isotropic HG phase (g = 0), no SH head,
// hierarchical sampling; this class runs the coarse and the fine pass.
#pragma once

#include <relit/method/medium.hpp>

namespace relit::method {

/// A pass of Bi et al.: the fine pass (this MediumPass) and the coarse one.
struct BiPass : MediumPass {
  MediumPass coarse;
  Buffer<float> t_fine_only;  // the N_f importance samples of each ray before the merge
};

class NeuralReflectanceField : public MediumModel {
 public:
  NeuralReflectanceField(const Device& device, const Json& config, const std::string& pointer = "/model");
  static void describe(config::Docs& docs);
  static Json check(const Json& config, const std::string& pointer) {
    return NeuralReflectanceField().check_keys(config, pointer);
  }
  static MethodParts method_parts() {
    MethodParts p;
    p.scattering = Scattering::hg_phase(0.0f);
    p.sh_head = false;
    p.hierarchical = true;
    return p;
  }

  std::string method() const override { return "bi"; }
  std::uint32_t n_coarse_samples() const { return m_settings.renderer.n_samples; }
  std::uint32_t n_fine_samples() const { return m_settings.n_fine_samples; }
  const nn::NetworkWithInputEncoding& coarse_network() const { return *m_coarse; }
  std::uint32_t queries_per_ray() const override;

  std::unique_ptr<ModelPass> make_pass() const override { return std::make_unique<BiPass>(); }
  void render(ModelPass& pass, Buffer<float>& rays, std::uint32_t n_rays, const PassOptions& options) const override;
  /// Colour 0 is the coarse image, colour 1 the fine one (the model's image).
  std::uint32_t n_colors() const override { return 2; }
  const Buffer<float>& color(const ModelPass& pass, std::uint32_t i) const override;
  void backward(ModelPass& pass, const Buffer<float>& rays, const std::vector<const Buffer<float>*>& d_colors,
                const PassOptions& options) override;

 private:
  NeuralReflectanceField() : MediumModel(method_parts()) {}
  Branch coarse_branch() const { return {m_coarse.get(), own_params(), n_coarse_samples()}; }
  Branch fine_branch() const { return {m_property.get(), 0, n_coarse_samples() + n_fine_samples()}; }
};

/// Hierarchical sampling: from the coarse pass (its t, delta and σ in column 0 of `coarse_props`, n_coarse
/// samples per ray), places n_fine importance samples per ray and merges them with the coarse ones into
/// `t`, `delta` (n_rays (n_coarse + n_fine) each) and `positions` (tiled, 3 columns); `t_fine_only` receives
/// the n_fine drawn samples of each ray. `jitter`: stratified-random u (training) or stratum centres.
void sample_fine(const Device& device, const Buffer<float>& rays, std::uint32_t n_rays, std::uint32_t n_coarse,
                 const Buffer<float>& t_coarse, const Buffer<float>& delta_coarse, const nn::BatchMatrix& coarse_props,
                 std::uint32_t n_fine, bool jitter, std::uint32_t seed, Buffer<float>& t_fine_only, Buffer<float>& t,
                 Buffer<float>& delta, nn::BatchMatrix& positions, parallel::Share share = {});

}  // namespace relit::method
