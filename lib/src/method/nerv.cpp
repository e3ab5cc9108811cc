// NeRV (Zheng et al. 2021, appendix D): the shared property network and renderer for the direct light, a two-stage
// visibility network that also predicts the expected termination depth, and one indirect bounce per camera ray
// (kernels/nerv.cl).
#include <relit/cl/program.hpp>
#include <relit/method/nerv.hpp>
#include <relit/nn/columns.hpp>
#include <relit/nn/encodings.hpp>
#include <relit/nn/registry.hpp>

#include "common.hpp"
#include "registration.hpp"

#include <algorithm>

namespace relit::method {

namespace {

// NeRV's visibility MLP as one nn::Network on the encoded input [enc(x) (n_pos cols) | enc(ω)]: a trunk on
// enc(x) gives n_trunk outputs, which joined with enc(ω) go through the head (V sigmoid, D softplus).
// Parameters: [trunk | head].
class TwoStageNetwork final : public nn::Network {
 public:
  TwoStageNetwork(std::unique_ptr<nn::Network> trunk, std::unique_ptr<nn::Network> head, std::uint32_t n_pos,
                  std::uint32_t n_dir)
      : m_trunk(std::move(trunk)), m_head(std::move(head)), m_pos(n_pos), m_dir(n_dir) {}
  std::string type() const override { return "NeRVVisibility"; }
  Json hyperparams() const override { return {{"trunk", m_trunk->hyperparams()}, {"head", m_head->hyperparams()}}; }
  std::uint32_t n_params() const override { return m_trunk->n_params() + m_head->n_params(); }
  void initialize_params(float* out, std::uint64_t seed) const override {
    m_trunk->initialize_params(out, seed);
    m_head->initialize_params(out + m_trunk->n_params(), seed + 7);
  }
  std::uint32_t n_input_dims() const override { return m_pos + m_dir; }
  std::uint32_t n_output_dims() const override { return m_head->n_output_dims(); }

  struct Work final : nn::Workspace {
    nn::BatchMatrix trunk_in, trunk_out, head_in, d_head_in, d_trunk_out, d_trunk_in;
    std::unique_ptr<nn::Workspace> trunk, head;
  };
  std::unique_ptr<nn::Workspace> make_workspace(const Device& device) const override {
    auto w = std::make_unique<Work>();
    w->trunk = m_trunk->make_workspace(device);
    w->head = m_head->make_workspace(device);
    return w;
  }
  void inference(const Device& device, nn::ConstParamSlice params, const nn::BatchMatrix& input,
                 nn::BatchMatrix& output) const override {
    auto w = make_workspace(device);
    run(device, params, input, output, static_cast<Work&>(*w), false);
  }
  void inference(const Device& device, nn::ConstParamSlice params, const nn::BatchMatrix& input,
                 nn::BatchMatrix& output, nn::Workspace& workspace) const override {
    run(device, params, input, output, work(workspace), false);
  }
  void forward(const Device& device, nn::ConstParamSlice params, const nn::BatchMatrix& input, nn::BatchMatrix& output,
               nn::Workspace& workspace) const override {
    run(device, params, input, output, work(workspace), true);
  }
  void backward(const Device& device, nn::ConstParamSlice params, const nn::BatchMatrix& input,
                const nn::BatchMatrix& output, const nn::BatchMatrix& d_output, nn::ParamSlice grads, bool accumulate,
                nn::BatchMatrix* d_input, nn::Workspace& workspace) const override {
    (void)input;
    Work& w = work(workspace);
    const std::uint32_t nt = m_trunk->n_output_dims();
    nn::match_rows(w.d_head_in, output, nt + m_dir);
    nn::match_rows(w.d_trunk_out, output, nt);
    m_head->backward(device, {params.buffer, params.offset + m_trunk->n_params()}, w.head_in, output, d_output,
                     {grads.buffer, grads.offset + m_trunk->n_params()}, accumulate, &w.d_head_in, *w.head);
    nn::copy_columns(device, w.d_head_in, 0, w.d_trunk_out, 0, nt);
    if (d_input) nn::match_rows(w.d_trunk_in, output, m_pos);
    m_trunk->backward(device, params, w.trunk_in, w.trunk_out, w.d_trunk_out, grads, accumulate,
                      d_input ? &w.d_trunk_in : nullptr, *w.trunk);
    if (d_input) {
      nn::copy_columns(device, w.d_trunk_in, 0, *d_input, 0, m_pos);
      nn::copy_columns(device, w.d_head_in, nt, *d_input, m_pos, m_dir);
    }
  }

 private:
  static Work& work(nn::Workspace& w) {
    auto* p = dynamic_cast<Work*>(&w);
    if (!p) throw InvalidArgument("NeRV visibility network: the workspace was made by another component");
    return *p;
  }
  void run(const Device& device, nn::ConstParamSlice params, const nn::BatchMatrix& input, nn::BatchMatrix& output,
           Work& w, bool training) const {
    const std::uint32_t nt = m_trunk->n_output_dims();
    nn::match_rows(w.trunk_in, input, m_pos);
    nn::match_rows(w.trunk_out, input, nt);
    nn::match_rows(w.head_in, input, nt + m_dir);
    nn::copy_columns(device, input, 0, w.trunk_in, 0, m_pos);
    const nn::ConstParamSlice head{params.buffer, params.offset + m_trunk->n_params()};
    if (training)
      m_trunk->forward(device, params, w.trunk_in, w.trunk_out, *w.trunk);
    else
      m_trunk->inference(device, params, w.trunk_in, w.trunk_out, *w.trunk);
    nn::copy_columns(device, w.trunk_out, 0, w.head_in, 0, nt);
    nn::copy_columns(device, input, m_pos, w.head_in, nt, m_dir);
    if (training)
      m_head->forward(device, head, w.head_in, output, *w.head);
    else
      m_head->inference(device, head, w.head_in, output, *w.head);
  }
  std::unique_ptr<nn::Network> m_trunk, m_head;
  std::uint32_t m_pos, m_dir;
};

// The V-and-depth net: the shared visibility encodings, its trunk the shared visibility MLP, a smaller head.
Json nerv_visibility_defaults() {
  Json v = detail::default_visibility();
  v["trunk"] = v["network"];
  v["network"] = {{"type", "FullyFusedMLP"}, {"n_neurons", 64}, {"n_hidden_layers", 1}};
  return v;
}

NeRVPass& nerv_pass(ModelPass& pass) {
  auto* p = dynamic_cast<NeRVPass*>(&pass);
  if (!p) throw InvalidArgument("NeRV: give a pass of its make_pass()");
  return *p;
}

using detail::ensure_size;

}  // namespace

NeRV::NeRV(const Device& device, const Json& config, const std::string& pointer) : MediumModel(device, method_parts()) {
  build(config, pointer);
}

void NeRV::describe(config::Docs& docs) { NeRV().describe_keys(docs); }

RELIT_REGISTER_METHODS(nerv) { registry.add<NeRV>("nerv", 40, "NeRV: docs/design.md §4.5"); }

void NeRV::configure_method(config::Reader& r, config::Docs* docs) {
  detail::SubConfig sub(r, "bounce", Json::object(), "the one indirect bounce per camera ray", docs);
  config::Reader& b = sub.reader;
  m_nerv.n_dirs = b.uint("n_dirs", 128, 1, 4096,
                         "K of a training step: uniform bounce directions from the expected termination point");
  m_nerv.n_dirs_render = b.uint("n_dirs_render", 128, 1, 4096, "K when rendering images (128 in Zheng et al. 2021)");
  m_nerv.n_dirs_env = b.uint("n_dirs_env", 32, 1, 4096, "K when the scene is also lit by an environment map");
  m_nerv.visibility_fraction = b.number("visibility_fraction", 0.25f, 1e-3f, 1.0f,
                                        "share of each batch's rays whose bounce queries train the visibility net");
  sub.finish_into(r);
}

void NeRV::configure_visibility(config::Reader& r, config::Docs* docs) {
  const std::string ptr = r.pointer("visibility");
  const Json defaults = nerv_visibility_defaults();
  config::Reader v(
      r.sub("visibility", defaults, "object",
            "visibility net V_ψ: {position_encoding, trunk, n_trunk_outputs, direction_encoding, network}"),
      ptr, "visibility");
  Json penc = v.sub("position_encoding", defaults["position_encoding"], "component", "position encoding (3 dims)");
  Json denc = v.sub("direction_encoding", defaults["direction_encoding"], "component", "direction encoding (3 dims)");
  const Json trunk_json = v.sub("trunk", defaults["trunk"], "component", "the MLP on the encoded position");
  const std::uint32_t n_trunk =
      v.uint("n_trunk_outputs", 8, 1, 64, "the trunk's outputs, joined with the encoded direction");
  const Json head_json = v.sub("network", defaults["network"], "component",
                               "the head on [trunk outputs, encoded direction] (outputs: V sigmoid, depth softplus)");
  v.finish();
  if (docs) docs->emplace_back(v.pointer(), v.docs());
  penc["n_dims_to_encode"] = 3;
  denc["n_dims_to_encode"] = 3;
  auto enc = nn::create_encoding({{"type", "Composite"}, {"nested", {penc, denc}}}, 6, ptr);
  const auto& parts = dynamic_cast<const nn::CompositeEncoding&>(*enc).parts();
  const std::uint32_t n_pos = parts[0].encoding->n_output_dims(), n_dir = parts[1].encoding->n_output_dims();
  const Json tj =
      detail::with_heads(trunk_json, ptr + "/trunk", Json::array({{{"n_dims", n_trunk}, {"activation", "None"}}}));
  const Json hj = detail::with_heads(
      head_json, ptr + "/network",
      Json::array({{{"n_dims", 1}, {"activation", "Sigmoid"}}, {{"n_dims", 1}, {"activation", "Softplus"}}}));
  auto trunk = nn::create_network(tj, n_pos, n_trunk, ptr + "/trunk");
  auto head = nn::create_network(hj, n_trunk + n_dir, 2, ptr + "/network");
  Json res = v.resolved();
  const Json nested = enc->hyperparams()["nested"];
  res["position_encoding"] = nested[0];
  res["direction_encoding"] = nested[1];
  res["position_encoding"].erase("n_dims_to_encode");
  res["direction_encoding"].erase("n_dims_to_encode");
  res["trunk"] = detail::strip_heads(trunk->hyperparams());
  res["network"] = detail::strip_heads(head->hyperparams());
  r.set_resolved("visibility", res);
  m_visibility = std::make_unique<nn::NetworkWithInputEncoding>(
      std::move(enc), std::make_unique<TwoStageNetwork>(std::move(trunk), std::move(head), n_pos, n_dir));
}

std::uint32_t NeRV::queries_per_ray() const {
  const std::uint32_t env = has_environment() ? env_dirs() : 0;
  return m_settings.renderer.n_samples * (1 + env) + (3 + env) * bounce_dirs(env > 0, false) + 1;
}

void NeRV::render(ModelPass& base, Buffer<float>& rays, std::uint32_t n_rays, const PassOptions& o) const {
  NeRVPass& pass = nerv_pass(base);
  MediumModel::render(pass, rays, n_rays, o);  // direct light: the samples, σ, albedo, g, V and the colour
  const std::uint32_t K = bounce_dirs(o.env != nullptr, o.training), spr = m_settings.renderer.n_samples;
  const std::uint32_t nq = n_rays * K;
  if (!pass.bounce_dirs || pass.n_bounce != K)
    pass.bounce_dirs = std::make_unique<render::IndirectBasis>(m_device, K, -1);
  pass.n_bounce = K;
  pass.bounce_dirs->draw(o.seed ^ 0x2545F491u, o.iteration);
  const std::uint32_t vd = m_visibility->n_output_dims(), pc = m_property->n_output_dims();
  ensure_size(pass.albedo_sum, m_device, 4 * std::size_t(n_rays));
  ensure_size(pass.x_t, m_device, 4 * std::size_t(n_rays));
  ensure_size(pass.indirect, m_device, 4 * std::size_t(n_rays));
  ensure_size(pass.dw, m_device, 4 * std::size_t(n_rays));
  ensure_size(pass.total, m_device, 3 * std::size_t(n_rays));
  ensure_size(pass.x_b, m_device, 4 * std::size_t(nq));
  nn::ensure_rows(pass.bounce_in, m_device, nq, 6);
  nn::ensure_rows(pass.bounce_vd, m_device, nq, vd);
  nn::ensure_rows(pass.light_in, m_device, nq, 6);
  nn::ensure_rows(pass.light_vd, m_device, nq, vd);
  nn::ensure_rows(pass.bounce_pos, m_device, nq + n_rays, 3);
  nn::ensure_rows(pass.bounce_props, m_device, nq + n_rays, pc);
  if (!pass.ws_bounce_vis) {
    pass.ws_bounce_vis = m_visibility->make_workspace(m_device);
    pass.ws_light_vis = m_visibility->make_workspace(m_device);
    pass.ws_bounce_property = m_property->make_workspace(m_device);
  }
  const auto& dirs = pass.bounce_dirs->dirs();
  m_device.kernel("nerv.cl", "nerv_termination")
      .args(n_rays, spr, rays, pass.t, pass.delta, pass.props.data(), pass.props.cols(), pass.albedo_sum, pass.x_t,
            pass.keep_termination ? 1u : 0u)
      .launch(n_rays, 16);
  m_device.kernel("nerv.cl", "nerv_bounce_queries")
      .args(n_rays, K, pass.x_t, dirs.data(), pass.bounce_in.data())
      .launch(nq, 64);
  const nn::ConstParamSlice psi{&m_vis_params, 0};
  const auto& grid = m_grid;
  auto visibility = [&](const nn::BatchMatrix& in, nn::BatchMatrix& out, nn::Workspace& ws) {
    if (o.march_visibility) {
      m_device.kernel("nerv.cl", "nerv_march_targets")
          .args(in.batch(), in.data(), grid.sigma, grid.dims[0], grid.dims[1], grid.dims[2], m_settings.march_steps,
                out.data(), 0u)
          .launch(in.batch(), 64);
    } else {
      m_visibility->inference(m_device, psi, in, out, ws);  // the render loss does not train ψ
    }
  };
  visibility(pass.bounce_in, pass.bounce_vd, *pass.ws_bounce_vis);
  m_device.kernel("nerv.cl", "nerv_bounce_points")
      .args(n_rays, K, rays, pass.x_t, dirs.data(), pass.bounce_vd.data(), vd, pass.x_b, pass.bounce_pos.data(),
            pass.light_in.data())
      .launch(nq + n_rays, 64);
  const nn::ConstParamSlice theta{&m_params, 0};
  if (o.training)
    m_property->forward(m_device, theta, pass.bounce_pos, pass.bounce_props, *pass.ws_bounce_property);
  else
    m_property->inference(m_device, theta, pass.bounce_pos, pass.bounce_props, *pass.ws_bounce_property);
  visibility(pass.light_in, pass.light_vd, *pass.ws_light_vis);
  // Under an environment, the bounce points see its N_e directions too.
  pass.env = o.env;
  const std::uint32_t n_env = o.env ? o.env->size() : 0;
  nn::ensure_rows(pass.env_in, m_device, std::max<std::uint32_t>(nq * n_env, 1), 6);
  nn::ensure_rows(pass.env_vd, m_device, std::max<std::uint32_t>(nq * n_env, 1), vd);
  if (n_env) {
    if (!pass.ws_env_vis) pass.ws_env_vis = m_visibility->make_workspace(m_device);
    m_device.kernel("nerv.cl", "nerv_bounce_env_queries")
        .args(nq, n_env, pass.x_b, o.env->dirs().data(), pass.env_in.data())
        .launch(std::size_t(nq) * n_env, 64);
    visibility(pass.env_in, pass.env_vd, *pass.ws_env_vis);
  }
  const Buffer<float>& env_dirs = n_env ? o.env->dirs().data() : pass.env_in.data();
  const Buffer<float>& env_weights = n_env ? o.env->weights().data() : pass.env_in.data();
  m_device.kernel("nerv.cl", "nerv_indirect")
      .args(n_rays, K, rays, dirs.data(), pass.x_b, pass.bounce_props.data(), pc, m_parts.scattering.g_scale,
            pass.light_vd.data(), vd, n_env, env_dirs, env_weights, pass.env_vd.data(), pass.albedo_sum, pass.color,
            pass.total, pass.indirect)
      .launch(n_rays, 16);
  if (o.timer) o.timer->mark("indirect bounce forward");
}

const Buffer<float>& NeRV::color(const ModelPass& base, std::uint32_t i) const {
  if (i != 0) throw InvalidArgument("NeRV renders one colour per pass, asked for colour " + std::to_string(i));
  return nerv_pass(const_cast<ModelPass&>(base)).total;
}

void NeRV::add_property_gradients(MediumPass& base, const Branch& branch, const Buffer<float>& rays,
                                  const Buffer<float>& d_color) {
  (void)branch;
  NeRVPass& pass = nerv_pass(base);
  const std::uint32_t n_rays = pass.n_rays, K = pass.n_bounce;
  const std::uint32_t vd = m_visibility->n_output_dims(), pc = m_property->n_output_dims();
  nn::ensure_rows(pass.d_bounce_props, m_device, n_rays * K + n_rays, pc);
  const std::uint32_t n_env = pass.env ? pass.env->size() : 0;
  const Buffer<float>& env_dirs = n_env ? pass.env->dirs().data() : pass.env_in.data();
  const Buffer<float>& env_weights = n_env ? pass.env->weights().data() : pass.env_in.data();
  m_device.kernel("nerv.cl", "nerv_indirect_backward")
      .args(n_rays, K, rays, pass.bounce_dirs->dirs().data(), pass.x_b, pass.bounce_props.data(), pc,
            m_parts.scattering.g_scale, pass.light_vd.data(), vd, n_env, env_dirs, env_weights, pass.env_vd.data(),
            pass.albedo_sum, pass.indirect, d_color, pass.d_bounce_props.data(), pass.dw)
      .launch(n_rays, 16);
  m_device.kernel("nerv.cl", "nerv_samples_backward")
      .args(n_rays, pass.n_samples, pass.delta, pass.props.data(), pass.props.cols(), pass.dw, pass.d_props.data())
      .launch(n_rays, 16);
}

void NeRV::backward(ModelPass& base, const Buffer<float>& rays, const std::vector<const Buffer<float>*>& d_colors,
                    const PassOptions& o) {
  NeRVPass& pass = nerv_pass(base);
  if (pass.n_bounce == 0) throw InvalidArgument("NeRV::backward: no training render() before");
  MediumModel::backward(pass, rays, d_colors, o);  // direct light and W (add_property_gradients); overwrites dθ
  // The bounce points and x_t: their albedo and g, added to the property net's gradient.
  m_property->backward(m_device, {&m_params, 0}, pass.bounce_pos, pass.bounce_props, pass.d_bounce_props, {&m_grads, 0},
                       true, nullptr, *pass.ws_bounce_property);
  if (o.timer) o.timer->mark("indirect bounce backward");
}

double NeRV::train_visibility(ModelPass& base, const Buffer<float>& rays, const nn::Loss& loss, Buffer<float>& value,
                              float weight, const PassOptions& o) {
  (void)rays;
  NeRVPass& pass = nerv_pass(base);
  if (pass.n_bounce == 0) throw InvalidArgument("NeRV::train_visibility: no training render() before");
  const detail::Subset camera =
      detail::visibility_subset(pass.n_rays, m_settings.visibility_fraction, o.share, o.batch_rays);
  const detail::Subset bounce =
      detail::visibility_subset(pass.n_rays, m_nerv.visibility_fraction, o.share, o.batch_rays);
  // Rows [0, m): camera samples toward their point light; rows [m, m + mb): the bounce queries of the first rays.
  // m is a multiple of 16, so the tiled rows of the two parts follow each other.
  const std::uint32_t m = camera.local * pass.n_samples;
  const std::uint32_t mb = bounce.local * pass.n_bounce;
  const std::uint32_t rows = m + mb;
  const double fraction =
      double(rows) / (double(camera.global) * pass.n_samples + double(bounce.global) * pass.n_bounce);
  if (rows == 0) {  // this rank holds none of the global batch's first rays
    m_vis_grads.fill(0.0f);
    value.fill(0.0f);
    return 0.0;
  }
  nn::ensure_rows(pass.train_in, m_device, rows, 6);
  nn::ensure_rows(pass.train_out, m_device, rows, 2);
  nn::ensure_rows(pass.train_target, m_device, rows, 2);
  nn::ensure_rows(pass.d_train, m_device, rows, 2);
  pass.train_in.data().copy_from(pass.vis_in.data(), std::size_t(m) * 6);
  // Whole 16-row tiles of the bounce queries (rows past mb land in the padding, which the loss ignores).
  const std::size_t tiles_rows =
      std::min<std::size_t>({round_up(mb, 16), pass.bounce_in.padded(), std::size_t(pass.train_in.padded()) - m});
  pass.train_in.data().copy_from(pass.bounce_in.data(), tiles_rows * 6, 0, std::size_t(m) * 6);
  m_device.kernel("nerv.cl", "nerv_march_targets")
      .args(rows, pass.train_in.data(), m_grid.sigma, m_grid.dims[0], m_grid.dims[1], m_grid.dims[2],
            m_settings.march_steps, pass.train_target.data(), 0u)
      .launch(rows, 64);
  if (o.timer) o.timer->mark("visibility targets (march)");
  const nn::ConstParamSlice psi{&m_vis_params, 0};
  m_visibility->forward(m_device, psi, pass.train_in, pass.train_out, *pass.ws_visibility);
  loss.evaluate(m_device, pass.train_out, pass.train_target, pass.d_train, value, weight * float(fraction));
  m_visibility->backward(m_device, psi, pass.train_in, pass.train_out, pass.d_train, {&m_vis_grads, 0}, false, nullptr,
                         *pass.ws_visibility);
  if (o.timer) o.timer->mark("visibility net training");
  return fraction;
}

}  // namespace relit::method
