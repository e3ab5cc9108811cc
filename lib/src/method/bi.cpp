// Bi et al.'s Neural Reflectance Field (Zheng et al. 2021, appendix D): coarse and fine networks joined by hierarchical
// sampling, on the renderer and visibility machinery every method shares (MediumModel).
#include <relit/cl/program.hpp>
#include <relit/method/bi.hpp>

#include "common.hpp"
#include "registration.hpp"

namespace relit::method {

namespace {

BiPass& bi_pass(ModelPass& pass) {
  auto* p = dynamic_cast<BiPass*>(&pass);
  if (!p) throw InvalidArgument("NeuralReflectanceField: give a pass of its make_pass()");
  return *p;
}

}  // namespace

NeuralReflectanceField::NeuralReflectanceField(const Device& device, const Json& config, const std::string& pointer)
    : MediumModel(device, method_parts()) {
  build(config, pointer);
}

void NeuralReflectanceField::describe(config::Docs& docs) { NeuralReflectanceField().describe_keys(docs); }

RELIT_REGISTER_METHODS(bi) {
  registry.add<NeuralReflectanceField>("bi", 30, "Bi et al.'s Neural Reflectance Field: docs/design.md §4.5");
}

std::uint32_t NeuralReflectanceField::queries_per_ray() const {
  const std::uint32_t per_sample = 1 + (has_environment() ? env_dirs() : 0);
  return (2 * n_coarse_samples() + n_fine_samples()) * per_sample;
}

void NeuralReflectanceField::render(ModelPass& base, Buffer<float>& rays, std::uint32_t n_rays,
                                    const PassOptions& o) const {
  BiPass& pass = bi_pass(base);
  begin_pass(pass, o);
  begin_pass(pass.coarse, o);
  draw_basis(pass, o);
  const Branch coarse = coarse_branch(), fine = fine_branch();
  forward_branch(pass.coarse, coarse, rays, n_rays, o.training, o.jitter_seed, pass.basis->dirs(), pass.basis->basis(),
                 marches(o), o.timer, o.env, true);
  prepare_branch(pass, fine, n_rays, pass.coarse.n_env);
  detail::ensure_size(pass.t_fine_only, m_device, std::size_t(n_rays) * n_fine_samples());
  sample_fine(m_device, rays, n_rays, coarse.n_samples, pass.coarse.t, pass.coarse.delta, pass.coarse.props,
              n_fine_samples(), o.training, o.jitter_seed ^ 0x5bd1e995u, pass.t_fine_only, pass.t, pass.delta,
              pass.positions, o.share);
  if (o.timer) o.timer->mark("hierarchical sampling");
  forward_branch(pass, fine, rays, n_rays, o.training, o.jitter_seed, pass.basis->dirs(), pass.basis->basis(),
                 marches(o), o.timer, o.env, false);
}

const Buffer<float>& NeuralReflectanceField::color(const ModelPass& base, std::uint32_t i) const {
  const BiPass& pass = bi_pass(const_cast<ModelPass&>(base));
  if (i > 1) throw InvalidArgument("Bi et al. renders two colours (coarse 0, fine 1), asked for " + std::to_string(i));
  return i == 0 ? pass.coarse.color : pass.color;
}

void NeuralReflectanceField::backward(ModelPass& base, const Buffer<float>& rays,
                                      const std::vector<const Buffer<float>*>& d_colors, const PassOptions& o) {
  BiPass& pass = bi_pass(base);
  if (d_colors.size() != 2 || !pass.basis)
    throw InvalidArgument(
        "NeuralReflectanceField::backward: give dL/dcolour of the coarse and the fine image of a "
        "training render()");
  backward_branch(pass, fine_branch(), rays, pass.basis->dirs(), pass.basis->basis(), *d_colors[1], o.timer, o.env);
  backward_branch(pass.coarse, coarse_branch(), rays, pass.basis->dirs(), pass.basis->basis(), *d_colors[0], o.timer,
                  o.env);
}

void sample_fine(const Device& device, const Buffer<float>& rays, std::uint32_t n_rays, std::uint32_t n_coarse,
                 const Buffer<float>& t_coarse, const Buffer<float>& delta_coarse, const nn::BatchMatrix& coarse_props,
                 std::uint32_t n_fine, bool jitter, std::uint32_t seed, Buffer<float>& t_fine_only, Buffer<float>& t,
                 Buffer<float>& delta, nn::BatchMatrix& positions, parallel::Share share) {
  const std::size_t n_all = std::size_t(n_rays) * (n_coarse + n_fine);
  if (t.size() < n_all || delta.size() < n_all || positions.batch() < n_all || positions.cols() != 3 ||
      t_fine_only.size() < std::size_t(n_rays) * n_fine || coarse_props.batch() < std::size_t(n_rays) * n_coarse)
    throw InvalidArgument("sample_fine: buffers too small for " + std::to_string(n_rays) + " rays");
  const Defines defines{{"N_COARSE", std::to_string(n_coarse)},
                        {"N_FINE", std::to_string(n_fine)},
                        {"N_ALL", std::to_string(n_coarse + n_fine)}};
  device.kernel("hierarchical.cl", "sample_fine", defines)
      .args(n_rays, jitter ? 1u : 0u, seed, rays, t_coarse, delta_coarse, coarse_props.data(), coarse_props.cols(),
            t_fine_only, t, delta, positions.data(), share.first, share.stride)
      .launch(n_rays, 16);
}

}  // namespace relit::method
