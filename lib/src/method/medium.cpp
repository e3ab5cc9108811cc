// MediumModel, the model every method is put together from: its parts, each configured from its own section
// of the "model" object, the forward pass that assembles the renderer's properties, and the two isolated
// backward passes (kernels/method.cl holds the glue kernels).
#include <relit/cl/program.hpp>
#include <relit/method/medium.hpp>
#include <relit/nn/fully_fused_mlp.hpp>
#include <relit/nn/columns.hpp>
#include <relit/nn/registry.hpp>

#include "common.hpp"

#include <algorithm>
#include <cmath>

namespace relit::method {

namespace {

using detail::strip_heads;
using detail::with_heads;

Json default_property() {
  return {{"encoding",
           {{"type", "HashGrid"},
            {"n_levels", 12},
            {"n_features_per_level", 2},
            {"log2_hashmap_size", 17},
            {"base_resolution", 16},
            {"per_level_scale", 1.32}}},
          {"network", {{"type", "FullyFusedMLP"}, {"n_neurons", 64}, {"n_hidden_layers", 2}}}};
}
Json default_indirect() {
  return {{"light_encoding", {{"type", "Frequency"}, {"n_frequencies", 4}, {"include_input", true}}},
          {"network", {{"type", "FullyFusedMLP"}, {"n_neurons", 64}, {"n_hidden_layers", 2}}}};
}
Json default_environment() {
  return {{"network", {{"type", "FullyFusedMLP"}, {"n_neurons", 64}, {"n_hidden_layers", 1}}}};
}
Json default_visibility() {
  return {{"position_encoding",
           {{"type", "HashGrid"},
            {"n_levels", 8},
            {"n_features_per_level", 2},
            {"log2_hashmap_size", 15},
            {"base_resolution", 8},
            {"per_level_scale", 1.5}}},
          {"direction_encoding", {{"type", "SphericalHarmonics"}, {"degree", 4}}},
          {"network", {{"type", "FullyFusedMLP"}, {"n_neurons", 64}, {"n_hidden_layers", 2}}}};
}

// Reads an object-valued key of `r` with its own Reader over the given sub-keys (each a component JSON,
// defaulting to the entry of `defaults`).
struct SubConfig {
  config::Reader reader;
  config::Docs* docs;
  SubConfig(config::Reader& parent, const std::string& key, const Json& defaults, const std::string& description,
            config::Docs* docs_out)
      : reader(parent.sub(key, defaults, "object", description), parent.pointer(key), key), docs(docs_out) {}
  Json component(const std::string& key, const Json& defaults, const std::string& description) {
    return reader.sub(key, defaults.at(key), "component", description);
  }
  /// Rejects unknown keys and records the object's keys for the config reference.
  void finish() {
    reader.finish();
    if (docs) docs->emplace_back(reader.pointer(), reader.docs());
  }
};

// Columns of the SH head's input: the features, the light position, V toward the light, exp(-k τ) toward it.
std::uint32_t indirect_input_cols(const MediumSettings& s) {
  return s.n_features + (s.light_conditioned ? 3 : 0) + (s.indirect_visibility_input ? 1 : 0) +
         (s.indirect_optical_depth > 0.0f ? 1 : 0);
}

void check_pass(const MediumPass& pass, const char* what) {
  if (pass.n_rays == 0)
    throw InvalidArgument(std::string("MediumModel::") + what + ": the pass holds no forward results");
}

std::uint32_t sh_count(int sh_lmax) { return sh_lmax < 0 ? 0 : std::uint32_t((sh_lmax + 1) * (sh_lmax + 1)); }

void mark(StageTimer* timer, const char* stage) {
  if (timer) timer->mark(stage);
}

}  // namespace

Json Scattering::heads() const {
  Json heads = Json::array({{{"n_dims", 1}, {"activation", "Softplus"}}, {{"n_dims", 3}, {"activation", "Sigmoid"}}});
  if (is_brdf()) {  // roughness in (0, 1), the raw normal
    heads.push_back({{"n_dims", 1}, {"activation", "Sigmoid"}});
    heads.push_back({{"n_dims", 3}, {"activation", "None"}});
  } else {
    heads.push_back({{"n_dims", 1}, {"activation", "Tanh"}});
  }
  return heads;
}

void MediumModel::build(const Json& config, const std::string& pointer) {
  configure(config, pointer, nullptr);
  allocate();
}

void MediumModel::configure(const Json& config, const std::string& pointer, config::Docs* docs) {
  if (!config.is_object()) throw ConfigError(pointer, "the model config must be an object, got " + config.dump());
  const std::size_t first_doc = docs ? docs->size() : 0;
  config::Reader r(config, pointer, "model");
  configure_renderer(r, docs);
  configure_indirect_keys(r);
  m_settings.initial_density = r.number("initial_density", 0.6931472f, 1e-3f, 1e3f,
                                        "σ everywhere at initialisation (the σ head's bias is softplus⁻¹ of it; the "
                                        "default, ln 2, is a zero bias). A dense start keeps the interiors that camera "
                                        "rays never reach opaque, so shadows do not leak");
  configure_density_grid(r, docs);
  configure_visibility_modes(r);
  const Json env_network = configure_environment(r, docs);
  configure_property(r, docs);
  configure_indirect(r, docs);
  configure_environment_head(r, env_network);
  if (m_parts.hierarchical) configure_coarse(r, docs);
  configure_method(r, docs);
  configure_visibility(r, docs);
  r.finish();
  m_resolved = r.resolved();
  if (docs) docs->insert(docs->begin() + std::ptrdiff_t(first_doc), {r.pointer(), r.docs()});
}

// "renderer": the samples of each ray (and the fine samples of hierarchical sampling), the SH head's bands and
// directions.
void MediumModel::configure_renderer(config::Reader& r, config::Docs* docs) {
  auto& s = m_settings.renderer;
  config::Reader rr(r.sub("renderer", Json::object(), "object", "the volume renderer (docs/design.md §4.2)"),
                    r.pointer("renderer"), "renderer");
  s.n_samples = rr.uint("n_samples", 64, 16, 1024,
                        m_parts.hierarchical ? "stratified samples per ray of the coarse network (a multiple of 16)"
                                             : "samples per ray (a multiple of 16)");
  if (s.n_samples % 16) rr.fail("n_samples", "must be a multiple of 16, got " + std::to_string(s.n_samples));
  if (m_parts.hierarchical) {
    auto& n_fine = m_settings.n_fine_samples;
    n_fine = rr.uint("n_fine_samples", 128, 16, 1024,
                     "importance samples per ray drawn from the coarse weights (a multiple of 16); the fine network "
                     "sees these and the coarse ones");
    if (n_fine % 16) rr.fail("n_fine_samples", "must be a multiple of 16, got " + std::to_string(n_fine));
  }
  if (m_parts.scattering.is_brdf()) s.scattering = "brdf";
  const std::string sh =
      !m_parts.sh_head ? std::string("none")
                       : rr.choice("sh", m_parts.default_sh, {"none", "0", "1", "2", "3", "4", "5", "6", "7", "8", "9"},
                                   "SH bands of the indirect light: l_max, or none (no indirect light)");
  s.sh_lmax = sh == "none" ? -1 : std::stoi(sh);
  if (m_parts.sh_head) s.n_dirs = rr.uint("n_dirs", 64, 1, 4096, "K, uniform directions of the indirect-light sum");
  if (m_parts.sh_head && m_parts.scattering.has_closed_form_indirect())
    s.closed_form_indirect = rr.boolean("closed_form_indirect", false,
                                        "closed-form indirect light sum_lm g^l c_lm Y_lm(-w_o) instead of the "
                                        "K-direction sum (no max(0, .) clamp)");
  rr.finish();
  if (docs) docs->emplace_back(rr.pointer(), rr.docs());
  r.set_resolved("renderer", rr.resolved());
}

// The SH head's keys of the "model" object itself.
void MediumModel::configure_indirect_keys(config::Reader& r) {
  auto& s = m_settings;
  if (!m_parts.sh_head) {
    s.n_features = 1;  // no SH head: one unused feature column keeps the property net's heads alike
    s.light_conditioned = false;
    return;
  }
  s.n_features = r.uint("n_features", 11, 1, 256, "feature columns passed from the property net to the SH head");
  s.intensity_reference = r.number("intensity_reference", 1000.0f, 1e-6f, 1e9f,
                                   "I_ref [W/sr]: the SH head predicts indirect light per unit I / I_ref");
  s.light_position_scale =
      r.number("light_position_scale", 0.125f, 1e-6f, 1e3f, "the SH head sees the light position times this");
  s.light_conditioned = r.boolean("light_conditioned", true,
                                  "condition the SH head on the light position (false: c = c(x), an ablation)");
}

// "density_grid": the cached density of the visibility targets.
void MediumModel::configure_density_grid(config::Reader& r, config::Docs* docs) {
  auto& s = m_settings;
  config::Reader gr(r.sub("density_grid", Json::object(), "object", "the cached density grid of visibility targets"),
                    r.pointer("density_grid"), "density_grid");
  s.grid_resolution = gr.uint("resolution", 64, 4, 512, "voxels per axis");
  s.grid_refresh = gr.uint("refresh_every", 16, 1, 1u << 20, "training steps between refreshes from the property net");
  s.march_steps = gr.uint("march_steps", 64, 1, 4096, "midpoint steps of each visibility-target march");
  s.visibility_fraction = gr.number("visibility_fraction", 0.25f, 1e-3f, 1.0f,
                                    "share of each batch's rays whose samples train the visibility net");
  gr.finish();
  if (docs) docs->emplace_back(gr.pointer(), gr.docs());
  r.set_resolved("density_grid", gr.resolved());
}

void MediumModel::configure_visibility_modes(config::Reader& r) {
  m_settings.inference_visibility =
      r.choice("inference_visibility", "network", {"network", "march"},
               "visibility when rendering: the network (as the paper) or a density-grid march");
  m_settings.training_visibility = r.choice("training_visibility", "network", {"network", "march"},
                                            "visibility of the training renders: the network (as the paper) or a march "
                                            "of the density grid (the visibility net still trains, for "
                                            "inference_visibility \"network\")");
}

// "environment": S_env over N_e directions; with an SH head also the network of c_env (built by
// configure_environment_head() once the SH bands and the features are known).
Json MediumModel::configure_environment(config::Reader& r, config::Docs* docs) {
  const bool env_head = m_parts.sh_head;
  SubConfig sub(r, "environment", env_head ? default_environment() : Json::object(),
                env_head ? "the environment light of 'env+point' data: S_env and the position-only SH head c_env"
                         : "the environment light of 'env+point' data: its direct light S_env",
                docs);
  auto& e = m_settings.environment;
  e.enabled =
      sub.reader.boolean("enabled", false, "the model has an environment light (relit train sets it from the dataset)");
  e.n_dirs = sub.reader.uint("n_dirs", 32, 1, 1024, "N_e, importance-sampled environment directions when rendering");
  e.n_dirs_training = sub.reader.uint("n_dirs_training", 4, 1, 1024,
                                      "N_e of a training step (drawn anew every step; each costs a visibility query "
                                      "per sample)");
  e.visibility_fraction = sub.reader.number("visibility_fraction", 0.0625f, 1e-3f, 1.0f,
                                            "share of each batch's rays whose samples train the visibility net "
                                            "toward the environment directions");
  Json network;
  if (env_head)
    network = sub.component("network", default_environment(), "the c_env head's MLP on the features (output: none)");
  sub.finish();
  r.set_resolved("environment", sub.reader.resolved());
  return network;
}

// "property": the property network, [0,1]^3 position → σ, the scattering part's heads, features.
void MediumModel::configure_property(config::Reader& r, config::Docs* docs) {
  const auto& s = m_settings;
  SubConfig sub(
      r, "property", default_property(),
      m_parts.hierarchical ? "the fine network F_θ: {encoding, network}" : "property network F_θ: {encoding, network}",
      docs);
  const Json enc = sub.component("encoding", default_property(), "position encoding (3 dims)");
  Json net = sub.component("network", default_property(), "the trunk; its output heads are set by the model");
  sub.finish();
  const std::string ptr = r.pointer("property");
  Json heads = m_parts.scattering.heads();
  heads.push_back({{"n_dims", s.n_features}, {"activation", "None"}});
  net = with_heads(net, ptr + "/network", heads);
  auto e = nn::create_encoding(enc, 3, ptr + "/encoding");
  auto n = nn::create_network(net, e->n_output_dims(), prop_heads() + s.n_features, ptr + "/network");
  m_property = std::make_unique<nn::NetworkWithInputEncoding>(std::move(e), std::move(n));
  const auto* mlp = dynamic_cast<const nn::FullyFusedMLP*>(&m_property->network());
  if (s.initial_density != MediumSettings{}.initial_density && !(mlp && mlp->has_bias()))
    throw ConfigError(r.pointer("initial_density"),
                      "needs a property network with biases (" + ptr + "/network: FullyFusedMLP with \"bias\": true)");
  Json res = m_property->hyperparams();
  res["network"] = strip_heads(res["network"]);
  r.set_resolved("property", res);
}

// "indirect": the SH head, [features, light position (, V toward the light) (, exp(-k τ) toward it)] → 3 n_sh
// coefficients per unit intensity. With sh "none" the section is accepted and unused.
void MediumModel::configure_indirect(config::Reader& r, config::Docs* docs) {
  if (!m_parts.sh_head) return;
  auto& s = m_settings;
  const std::uint32_t n_sh = sh_count(s.renderer.sh_lmax);
  if (n_sh == 0) {
    r.sub("indirect", default_indirect(), "object", "indirect SH head h_θ: {light_encoding, network}");
    return;
  }
  SubConfig sub(r, "indirect", default_indirect(),
                "indirect SH head h_θ: {light_encoding, network, visibility_input, optical_depth_input}", docs);
  const Json lenc = sub.component("light_encoding", default_indirect(), "encoding of the light position (3 dims)");
  Json net = sub.component("network", default_indirect(), "the head's MLP (output activation: none)");
  s.indirect_visibility_input = sub.reader.boolean(
      "visibility_input", false,
      "the head also sees V(x, ω_l), the visibility toward the point light (the network's, or the march's when "
      "marching; no gradient reaches ψ): whether x lies in the light's shadow, which the features and the "
      "light position alone encode only through the head's own capacity");
  s.indirect_optical_depth = sub.reader.number(
      "optical_depth_input", 0.0f, 0.0f, 1e3f,
      "k: with k > 0 the head also sees exp(-k τ), τ the optical depth from x toward the point light marched "
      "through the density grid (no gradient reaches the density). Unlike V = exp(-τ), which is 0 wherever the "
      "light arrives only as multiply scattered light, it still tells how deep in the medium x lies; 0: off");
  s.indirect_depth_attenuation = sub.reader.boolean(
      "optical_depth_attenuation", false,
      "multiply the head's output by the same exp(-k τ) (needs optical_depth_input > 0): the indirect light "
      "then falls off into the medium by construction, and the head predicts what multiplies that falloff");
  if (s.indirect_depth_attenuation && s.indirect_optical_depth <= 0.0f)
    sub.reader.fail("optical_depth_attenuation", "needs optical_depth_input > 0 (the k of the falloff)");
  sub.finish();
  const std::string ptr = r.pointer("indirect");
  net = with_heads(net, ptr + "/network", Json::array({{{"n_dims", 3 * n_sh}, {"activation", "None"}}}));
  Json nested = Json::array({{{"type", "Identity"}, {"n_dims_to_encode", s.n_features}}});
  if (s.light_conditioned) {
    Json l = lenc;
    l["n_dims_to_encode"] = 3;
    nested.push_back(l);
  }
  if (s.indirect_visibility_input) nested.push_back({{"type", "Identity"}, {"n_dims_to_encode", 1}});
  if (s.indirect_optical_depth > 0.0f) nested.push_back({{"type", "Identity"}, {"n_dims_to_encode", 1}});
  auto e =
      nn::create_encoding({{"type", "Composite"}, {"nested", nested}}, indirect_input_cols(s), ptr + "/light_encoding");
  auto n = nn::create_network(net, e->n_output_dims(), 3 * n_sh, ptr + "/network");
  m_indirect = std::make_unique<nn::NetworkWithInputEncoding>(std::move(e), std::move(n));
  Json res{{"light_encoding", s.light_conditioned ? m_indirect->encoding().hyperparams()["nested"][1] : lenc},
           {"network", strip_heads(m_indirect->network().hyperparams())},
           {"visibility_input", s.indirect_visibility_input},
           {"optical_depth_input", s.indirect_optical_depth},
           {"optical_depth_attenuation", s.indirect_depth_attenuation}};
  res["light_encoding"].erase("n_dims_to_encode");
  r.set_resolved("indirect", res);
}

// The environment SH head: features → 3 n_sh coefficients of the environment's indirect light (not scaled by I).
void MediumModel::configure_environment_head(config::Reader& r, const Json& network) {
  const std::uint32_t n_sh = sh_count(m_settings.renderer.sh_lmax);
  if (!m_settings.environment.enabled || n_sh == 0) return;
  const std::string ptr = r.pointer("environment");
  const Json net = with_heads(network, ptr + "/network", Json::array({{{"n_dims", 3 * n_sh}, {"activation", "None"}}}));
  auto e = nn::create_encoding({{"type", "Identity"}}, m_settings.n_features, ptr);
  auto n = nn::create_network(net, e->n_output_dims(), 3 * n_sh, ptr + "/network");
  m_environment = std::make_unique<nn::NetworkWithInputEncoding>(std::move(e), std::move(n));
  Json res = r.resolved()["environment"];
  res["network"] = strip_heads(m_environment->network().hyperparams());
  r.set_resolved("environment", res);
}

// "coarse": hierarchical sampling's coarse network, with the heads of the fine one ("property").
void MediumModel::configure_coarse(config::Reader& r, config::Docs* docs) {
  SubConfig sub(r, "coarse", default_property(),
                "the coarse network {encoding, network} (\"property\" is the fine network)", docs);
  const Json enc = sub.component("encoding", default_property(), "position encoding (3 dims)");
  Json net = sub.component("network", default_property(), "the MLP; its heads are set by the model");
  sub.finish();
  const std::string ptr = r.pointer("coarse");
  net = with_heads(net, ptr + "/network", m_property->network().hyperparams()["output_heads"]);
  auto e = nn::create_encoding(enc, 3, ptr + "/encoding");
  auto n = nn::create_network(net, e->n_output_dims(), m_property->n_output_dims(), ptr + "/network");
  m_coarse = std::make_unique<nn::NetworkWithInputEncoding>(std::move(e), std::move(n));
  Json res = m_coarse->hyperparams();
  res["network"] = strip_heads(res["network"]);
  r.set_resolved("coarse", res);
}

// "visibility": [position, direction] → V.
void MediumModel::configure_visibility(config::Reader& r, config::Docs* docs) {
  SubConfig sub(r, "visibility", default_visibility(),
                "visibility network V_ψ: {position_encoding, direction_encoding, network}", docs);
  Json penc = sub.component("position_encoding", default_visibility(), "position encoding (3 dims)");
  Json denc = sub.component("direction_encoding", default_visibility(), "direction encoding (3 dims)");
  Json net = sub.component("network", default_visibility(), "the MLP (output: one sigmoid)");
  sub.finish();
  const std::string ptr = r.pointer("visibility");
  net = with_heads(net, ptr + "/network", Json::array({{{"n_dims", 1}, {"activation", "Sigmoid"}}}));
  penc["n_dims_to_encode"] = 3;
  denc["n_dims_to_encode"] = 3;
  auto e = nn::create_encoding({{"type", "Composite"}, {"nested", {penc, denc}}}, 6, ptr);
  auto n = nn::create_network(net, e->n_output_dims(), 1, ptr + "/network");
  m_visibility = std::make_unique<nn::NetworkWithInputEncoding>(std::move(e), std::move(n));
  const Json nested = m_visibility->encoding().hyperparams()["nested"];
  Json res{{"position_encoding", nested[0]},
           {"direction_encoding", nested[1]},
           {"network", strip_heads(m_visibility->network().hyperparams())}};
  res["position_encoding"].erase("n_dims_to_encode");
  res["direction_encoding"].erase("n_dims_to_encode");
  r.set_resolved("visibility", res);
}

void MediumModel::allocate() {
  m_renderer = std::make_unique<render::VolumeRenderer>(m_device, m_settings.renderer);
  allocate_storage(own_params() + (m_coarse ? m_coarse->n_params() : 0), m_visibility->n_params(),
                   m_settings.grid_resolution);
  initialize(0);
}

std::uint32_t MediumModel::own_params() const {
  return m_property->n_params() + (m_indirect ? m_indirect->n_params() : 0) +
         (m_environment ? m_environment->n_params() : 0);
}

std::uint32_t MediumModel::queries_per_ray() const {
  return m_settings.renderer.n_samples * (1 + (m_settings.environment.enabled ? m_settings.environment.n_dirs : 0));
}

const render::VolumeRenderer& MediumModel::renderer_for(std::uint32_t n_samples, std::uint32_t n_env) const {
  if (n_env == 0 && n_samples == m_settings.renderer.n_samples) return *m_renderer;
  auto& r = m_renderers[{n_samples, n_env}];
  if (!r) {
    render::VolumeRendererSettings rs = m_settings.renderer;
    rs.n_samples = n_samples;
    rs.n_env_dirs = n_env;
    r = std::make_unique<render::VolumeRenderer>(m_device, rs);
  }
  return *r;
}

void MediumModel::initialize(std::uint64_t seed) {
  std::vector<float> theta(n_params()), psi(n_vis_params());
  m_property->initialize_params(theta.data(), seed);
  set_initial_density(theta.data());
  if (m_indirect) m_indirect->initialize_params(theta.data() + m_property->n_params(), seed + 1000);
  if (m_environment)
    m_environment->initialize_params(theta.data() + m_property->n_params() + m_indirect->n_params(), seed + 3000);
  if (m_coarse) m_coarse->initialize_params(theta.data() + own_params(), seed + 4000);
  m_visibility->initialize_params(psi.data(), seed + 2000);
  m_params.write(theta);
  m_vis_params.write(psi);
}

void MediumModel::set_initial_density(float* theta) const {
  const float sigma0 = m_settings.initial_density;
  if (sigma0 == MediumSettings{}.initial_density) return;  // a zero bias, as the network's own initialisation
  const auto* mlp = dynamic_cast<const nn::FullyFusedMLP*>(&m_property->network());
  if (!mlp || !mlp->has_bias()) return;  // refused when the config was read
  // softplus⁻¹(σ0) = log(expm1(σ0)), written to stay finite for large σ0.
  const double bias =
      sigma0 > 20.0f ? double(sigma0) + std::log(-std::expm1(-double(sigma0))) : std::log(std::expm1(double(sigma0)));
  const std::uint32_t out_layer = mlp->n_hidden_layers();
  theta[m_property->encoding().n_params() + mlp->layer_offset(out_layer) + mlp->layer_inputs(out_layer)] =
      static_cast<float>(bias);  // row 0 (σ) of the output layer, its bias column
}

void MediumModel::prepare_branch(MediumPass& pass, const Branch& branch, std::uint32_t n_rays,
                                 std::uint32_t n_env) const {
  const std::uint32_t n = n_rays * branch.n_samples;
  const std::uint32_t n_sh = m_renderer->n_sh();
  const std::uint32_t prop_out = prop_heads() + m_settings.n_features;
  const std::uint32_t light_cols = indirect_input_cols(m_settings);
  auto ensure = [&](Buffer<float>& b, std::size_t count) { detail::ensure_size(b, m_device, count); };
  auto matrix = [&](nn::BatchMatrix& m, std::uint32_t cols) { nn::ensure_rows(m, m_device, n, cols); };
  ensure(pass.t, n);
  ensure(pass.delta, n);
  ensure(pass.color, 3 * std::size_t(n_rays));
  ensure(pass.transmittance, n_rays);
  matrix(pass.positions, 3);
  matrix(pass.props_raw, prop_out);
  matrix(pass.vis_in, 6);
  matrix(pass.vis, m_visibility->n_output_dims());  // V (NeRV: V and depth)
  const std::uint32_t prop_cols = renderer_for(branch.n_samples, n_env).prop_cols();
  matrix(pass.props, prop_cols);
  matrix(pass.radiance, 3);
  matrix(pass.d_props, prop_cols);
  matrix(pass.d_radiance, 3);
  matrix(pass.d_props_raw, prop_out);
  matrix(pass.net_pos, 3);
  if (n_sh > 0) {
    matrix(pass.light_in, light_cols);
    matrix(pass.indirect_raw, 3 * n_sh);
    matrix(pass.d_indirect_raw, 3 * n_sh);
    matrix(pass.d_light_in, light_cols);
  }
  if (n_env > 0) {
    // Sample-major rows s N_e + j: V_ψ's queries toward the environment directions.
    const std::uint32_t rows = n * n_env;
    if (pass.env_vis_in.cols() != 6) pass.env_vis_in = nn::BatchMatrix(m_device, rows, 6);
    if (pass.env_vis.cols() != m_visibility->n_output_dims())
      pass.env_vis = nn::BatchMatrix(m_device, rows, m_visibility->n_output_dims());
    pass.env_vis_in.resize(rows);
    pass.env_vis.resize(rows);
    if (m_environment) {
      matrix(pass.env_raw, 3 * n_sh);
      matrix(pass.d_env_raw, 3 * n_sh);
      matrix(pass.d_env_in, light_cols);
    }
  }
  if (!pass.ws_property) {
    pass.ws_property = branch.property->make_workspace(m_device);
    if (m_indirect) pass.ws_indirect = m_indirect->make_workspace(m_device);
    pass.ws_visibility = m_visibility->make_workspace(m_device);
  }
  if (n_env > 0 && !pass.ws_env_visibility) pass.ws_env_visibility = m_visibility->make_workspace(m_device);
  if (m_environment && n_env > 0 && !pass.ws_environment) pass.ws_environment = m_environment->make_workspace(m_device);
  pass.n_rays = n_rays;
  pass.n_samples = branch.n_samples;
  pass.n_env = n_env;
}

void MediumModel::forward_branch(MediumPass& pass, const Branch& branch, Buffer<float>& rays, std::uint32_t n_rays,
                                 bool training, std::uint32_t seed, const nn::BatchMatrix& dirs,
                                 const nn::BatchMatrix& sh_basis, bool march, StageTimer* timer,
                                 const render::EnvironmentSamples* env, bool place_samples) const {
  if (env && !m_settings.environment.enabled)
    throw InvalidArgument(
        "MediumModel::forward: an environment light was given, but the model was trained without one "
        "(model/environment/enabled is false); render it under its point light alone");
  const std::uint32_t n_env = env ? env->size() : 0;
  if (place_samples) prepare_branch(pass, branch, n_rays, n_env);
  const std::uint32_t spr = branch.n_samples;
  const std::uint32_t n = n_rays * spr;
  const std::uint32_t n_sh = m_renderer->n_sh();
  const render::VolumeRenderer& renderer = renderer_for(spr, n_env);
  if (place_samples) renderer.sample(rays, n_rays, training, seed, pass.t, pass.delta, pass.positions);
  const std::uint32_t light_cols = n_sh > 0 ? pass.light_in.cols() : 0;
  Buffer<float>& light_data = n_sh > 0 ? pass.light_in.data() : pass.vis_in.data();
  m_device.kernel("method.cl", "light_inputs")
      .args(n, spr, rays, pass.positions.data(), m_settings.light_position_scale, pass.net_pos.data(), light_data,
            m_settings.light_conditioned ? light_cols : 0u, m_settings.n_features, pass.vis_in.data())
      .launch(n, 64);
  mark(timer, "sampling");
  const nn::ConstParamSlice theta{&m_params, branch.theta_offset};
  if (training)
    branch.property->forward(m_device, theta, pass.net_pos, pass.props_raw, *pass.ws_property);
  else
    branch.property->inference(m_device, theta, pass.net_pos, pass.props_raw, *pass.ws_property);
  nn::copy_columns(m_device, pass.props_raw, 0, pass.props, render::kSigma, 4);  // sigma, albedo
  // g (or the roughness) through the scattering part's scale; the isotropic phase: g = 0
  nn::copy_columns(m_device, pass.props_raw, 4, pass.props, render::kG, 1, m_parts.scattering.g_scale);
  if (renderer.brdf()) nn::copy_columns(m_device, pass.props_raw, 5, pass.props, renderer.normal_col(), 3);
  mark(timer, "property net forward");
  forward_visibility(pass, rays, n_rays, spr, march, env);
  mark(timer, "visibility net forward");
  if (n_sh > 0) {
    forward_indirect(pass, rays, n_rays, spr, training, n_env);
    mark(timer, "SH head forward");
  }
  const nn::BatchMatrix* basis = &sh_basis;
  if (m_settings.renderer.closed_form_indirect && n_sh > 0) {  // the closed form needs Y(-w_o) of every ray
    if (pass.view_basis.cols() != n_sh || pass.view_basis.padded() != nn::padded_batch(n_rays))
      pass.view_basis = nn::BatchMatrix(m_device, n_rays, n_sh);
    m_renderer->view_basis(rays, n_rays, pass.view_basis);
    basis = &pass.view_basis;
  }
  renderer.forward(rays, n_rays, pass.t, pass.delta, pass.props, dirs, *basis, pass.radiance, pass.color,
                   pass.transmittance, env);
  mark(timer, "lighting + compositing forward");
}

// V toward the point light and each environment direction: the visibility net's (inference: the render loss
// does not train ψ) or a march through the density grid.
void MediumModel::forward_visibility(MediumPass& pass, Buffer<float>& rays, std::uint32_t n_rays, std::uint32_t spr,
                                     bool march, const render::EnvironmentSamples* env) const {
  const std::uint32_t n = n_rays * spr;
  const std::uint32_t n_env = env ? env->size() : 0;
  const std::uint32_t n_sh = m_renderer->n_sh();
  const nn::ConstParamSlice psi{&m_vis_params, 0};
  if (march) {
    render::march_visibility(m_device, rays, n_rays, spr, pass.positions, m_grid, m_settings.march_steps, pass.vis);
  } else {
    // The render loss does not train ψ: inference, its scratch in the workspace visibility_step() reuses.
    m_visibility->inference(m_device, psi, pass.vis_in, pass.vis, *pass.ws_visibility);
  }
  nn::copy_columns(m_device, pass.vis, 0, pass.props, render::kVisibility, 1);
  if (n_env > 0) {
    const std::uint32_t env_col = render::env_visibility_column(n_sh);
    if (march) {
      if (pass.env_march.cols() != n_env) pass.env_march = nn::BatchMatrix(m_device, n, n_env);
      pass.env_march.resize(n);
      render::march_visibility_directions(m_device, pass.positions, env->dirs(), m_grid, m_settings.march_steps,
                                          pass.env_march);
      nn::copy_columns(m_device, pass.env_march, 0, pass.props, env_col, n_env);
    } else {
      m_device.kernel("method.cl", "env_visibility_inputs")
          .args(n, n_env, pass.net_pos.data(), env->dirs().data(), pass.env_vis_in.data(), 0u)
          .launch(std::size_t(n) * n_env, 64);
      m_visibility->inference(m_device, psi, pass.env_vis_in, pass.env_vis, *pass.ws_env_visibility);
      m_device.kernel("method.cl", "env_rows_to_columns")
          .args(n, n_env, pass.env_vis.data(), pass.env_vis.cols(), pass.props.data(), pass.props.cols(), env_col)
          .launch(std::size_t(n) * n_env, 64);
    }
  }
}

// The SH head's coefficients (and c_env's under an environment) into the renderer's SH columns.
void MediumModel::forward_indirect(MediumPass& pass, Buffer<float>& rays, std::uint32_t n_rays, std::uint32_t spr,
                                   bool training, std::uint32_t n_env) const {
  const std::uint32_t n = n_rays * spr;
  const std::uint32_t n_sh = m_renderer->n_sh();
  const nn::ConstParamSlice theta_sh{&m_params, m_property->n_params()};
  nn::copy_columns(m_device, pass.props_raw, prop_heads(), pass.light_in, 0, m_settings.n_features);
  const std::uint32_t depth_col = m_settings.indirect_optical_depth > 0.0f ? 1 : 0;
  if (m_settings.indirect_visibility_input)  // an input only: its gradient column is dropped (ψ stays isolated)
    nn::copy_columns(m_device, pass.vis, 0, pass.light_in, indirect_input_cols(m_settings) - 1 - depth_col, 1);
  if (depth_col) {  // an input only, marched through the density grid: no gradient reaches σ
    nn::ensure_rows(pass.depth_in, m_device, n, 1);
    render::march_visibility(m_device, rays, n_rays, spr, pass.positions, m_grid, m_settings.march_steps, pass.depth_in,
                             m_settings.indirect_optical_depth);
    nn::copy_columns(m_device, pass.depth_in, 0, pass.light_in, indirect_input_cols(m_settings) - 1, 1);
  }
  if (training)
    m_indirect->forward(m_device, theta_sh, pass.light_in, pass.indirect_raw, *pass.ws_indirect);
  else
    m_indirect->inference(m_device, theta_sh, pass.light_in, pass.indirect_raw, *pass.ws_indirect);
  renderer_for(spr, n_env)
      .scale_rgb_by_ray_intensity(rays, pass.indirect_raw, 0, pass.props, render::kSH, n_sh,
                                  1.0f / m_settings.intensity_reference);
  if (m_settings.indirect_depth_attenuation)
    nn::multiply_columns(m_device, pass.depth_in, pass.props, render::kSH, 3 * n_sh);
  if (m_environment && n_env > 0) {  // c += c_env(f(x)): the environment's indirect light, not scaled by I
    const nn::ConstParamSlice theta_env{&m_params, m_property->n_params() + m_indirect->n_params()};
    if (training)
      m_environment->forward(m_device, theta_env, pass.light_in, pass.env_raw, *pass.ws_environment);
    else
      m_environment->inference(m_device, theta_env, pass.light_in, pass.env_raw, *pass.ws_environment);
    nn::copy_columns(m_device, pass.env_raw, 0, pass.props, render::kSH, 3 * n_sh, 1.0f, true);
  }
}

void MediumModel::backward_branch(MediumPass& pass, const Branch& branch, const Buffer<float>& rays,
                                  const nn::BatchMatrix& dirs, const nn::BatchMatrix& sh_basis,
                                  const Buffer<float>& d_color, StageTimer* timer,
                                  const render::EnvironmentSamples* env) {
  check_pass(pass, "backward");
  const std::uint32_t n_env = env ? env->size() : 0;
  if (n_env != pass.n_env)
    throw InvalidArgument("MediumModel::backward: give the environment samples of the forward pass (" +
                          std::to_string(pass.n_env) + " directions), got " + std::to_string(n_env));
  const std::uint32_t spr = branch.n_samples;
  const std::uint32_t n_sh = m_renderer->n_sh();
  const bool closed = m_settings.renderer.closed_form_indirect && n_sh > 0;
  renderer_for(spr, n_env)
      .backward(rays, pass.n_rays, pass.t, pass.delta, pass.props, dirs, closed ? pass.view_basis : sh_basis,
                pass.radiance, pass.color, d_color, pass.d_radiance, pass.d_props, env);
  add_property_gradients(pass, branch, rays, d_color);
  mark(timer, "lighting + compositing backward");
  // No SH head: the features receive no gradient.
  if (n_sh == 0) pass.d_props_raw.data().fill(0.0f);
  // d props_raw: sigma and albedo as they are, g through the 0.95 scale, features from the SH head.
  nn::copy_columns(m_device, pass.d_props, render::kSigma, pass.d_props_raw, 0, 4);
  nn::copy_columns(m_device, pass.d_props, render::kG, pass.d_props_raw, 4, 1, m_parts.scattering.g_scale);
  if (m_settings.renderer.scattering == "brdf")
    nn::copy_columns(m_device, pass.d_props, renderer_for(spr, n_env).normal_col(), pass.d_props_raw, 5, 3);
  if (n_sh > 0) {
    renderer_for(spr, n_env)
        .scale_rgb_by_ray_intensity(rays, pass.d_props, render::kSH, pass.d_indirect_raw, 0, n_sh,
                                    1.0f / m_settings.intensity_reference);
    if (m_settings.indirect_depth_attenuation)
      nn::multiply_columns(m_device, pass.depth_in, pass.d_indirect_raw, 0, 3 * n_sh);
    m_indirect->backward(m_device, {&m_params, m_property->n_params()}, pass.light_in, pass.indirect_raw,
                         pass.d_indirect_raw, {&m_grads, m_property->n_params()}, false, &pass.d_light_in,
                         *pass.ws_indirect);
    nn::copy_columns(m_device, pass.d_light_in, 0, pass.d_props_raw, prop_heads(), m_settings.n_features);
    if (m_environment) {
      const std::uint32_t offset = m_property->n_params() + m_indirect->n_params();
      if (n_env > 0) {
        nn::copy_columns(m_device, pass.d_props, render::kSH, pass.d_env_raw, 0, 3 * n_sh);
        m_environment->backward(m_device, {&m_params, offset}, pass.light_in, pass.env_raw, pass.d_env_raw,
                                {&m_grads, offset}, false, &pass.d_env_in, *pass.ws_environment);
        nn::copy_columns(m_device, pass.d_env_in, 0, pass.d_props_raw, prop_heads(), m_settings.n_features, 1.0f, true);
      } else {
        m_grads.fill(0.0f, offset, m_environment->n_params());  // c_env took no part in this pass
      }
    }
    mark(timer, "SH head backward");
  }
  branch.property->backward(m_device, {&m_params, branch.theta_offset}, pass.net_pos, pass.props_raw, pass.d_props_raw,
                            {&m_grads, branch.theta_offset}, false, nullptr, *pass.ws_property);
  mark(timer, "property net backward");
}

void MediumModel::visibility_step(MediumPass& pass, const Buffer<float>& rays, const nn::Loss& loss,
                                  Buffer<float>& value, float weight, StageTimer* timer,
                                  const render::EnvironmentSamples* env) {
  check_pass(pass, "visibility_step");
  const std::uint32_t n_env = env ? env->size() : 0;
  if (n_env != pass.n_env)
    throw InvalidArgument("MediumModel::visibility_step: give the environment samples of the forward pass (" +
                          std::to_string(pass.n_env) + " directions), got " + std::to_string(n_env));
  const std::uint32_t spr = pass.n_samples;
  auto subset = [&](float fraction) { return detail::rays_in_share(pass.n_rays, fraction); };
  // Rows [0, m): the samples of the first rays toward their point light; rows [m, m + m_env N_e): the samples of
  // the first rays toward each environment direction (sample-major). m is a multiple of 16, so the tiled
  // matrices of the two parts simply follow each other.
  const std::uint32_t m = subset(m_settings.visibility_fraction) * spr;
  const std::uint32_t m_env = n_env ? subset(m_settings.environment.visibility_fraction) * spr : 0;
  const std::uint32_t rows = m + m_env * n_env;
  auto matrix = [&](nn::BatchMatrix& mat, std::uint32_t cols, std::uint32_t batch) {
    nn::ensure_rows(mat, m_device, batch, cols);
  };
  matrix(pass.vis_in_sub, 6, rows);
  matrix(pass.positions_sub, 3, m);
  matrix(pass.vis_sub, 1, rows);
  matrix(pass.vis_target, 1, rows);
  matrix(pass.d_vis, 1, rows);
  // The first m samples of a tiled matrix are its first m * cols floats (m is a multiple of 16).
  pass.vis_in_sub.data().copy_from(pass.vis_in.data(), std::size_t(m) * 6);
  pass.positions_sub.data().copy_from(pass.positions.data(), std::size_t(m) * 3);
  if (n_env == 0) {
    render::march_visibility(m_device, rays, m / spr, spr, pass.positions_sub, m_grid, m_settings.march_steps,
                             pass.vis_target);
  } else {
    matrix(pass.point_target, 1, m);
    render::march_visibility(m_device, rays, m / spr, spr, pass.positions_sub, m_grid, m_settings.march_steps,
                             pass.point_target);
    pass.vis_target.data().copy_from(pass.point_target.data(), m);
    matrix(pass.env_positions_sub, 3, m_env);
    matrix(pass.env_target, n_env, m_env);
    pass.env_positions_sub.data().copy_from(pass.positions.data(), std::size_t(m_env) * 3);
    render::march_visibility_directions(m_device, pass.env_positions_sub, env->dirs(), m_grid, m_settings.march_steps,
                                        pass.env_target);
    const std::size_t queries = std::size_t(m_env) * n_env;
    m_device.kernel("method.cl", "env_columns_to_rows")
        .args(m_env, n_env, pass.env_target.data(), pass.vis_target.data(), m)
        .launch(queries, 64);
    m_device.kernel("method.cl", "env_visibility_inputs")
        .args(m_env, n_env, pass.net_pos.data(), env->dirs().data(), pass.vis_in_sub.data(), m)
        .launch(queries, 64);
  }
  mark(timer, "visibility targets (march)");
  const nn::ConstParamSlice psi{&m_vis_params, 0};
  m_visibility->forward(m_device, psi, pass.vis_in_sub, pass.vis_sub, *pass.ws_visibility);
  loss.evaluate(m_device, pass.vis_sub, pass.vis_target, pass.d_vis, value, weight);
  m_visibility->backward(m_device, psi, pass.vis_in_sub, pass.vis_sub, pass.d_vis, {&m_vis_grads, 0}, false, nullptr,
                         *pass.ws_visibility);
  mark(timer, "visibility net training");
}

void MediumModel::refresh_density_grid() {
  const auto& d = m_grid.dims;
  const std::uint32_t total = std::uint32_t(d[0]) * d[1] * d[2];
  const std::uint32_t chunk = std::min<std::uint32_t>(total, 1u << 17);
  if (m_grid_positions.cols() != 3) {
    m_grid_positions = nn::BatchMatrix(m_device, chunk, 3);
    m_grid_props = nn::BatchMatrix(m_device, chunk, prop_heads() + m_settings.n_features);
    m_grid_ws = m_property->make_workspace(m_device);
  }
  for (std::uint32_t first = 0; first < total; first += chunk) {
    const std::uint32_t n = std::min(chunk, total - first);
    m_grid_positions.resize(n);
    m_grid_props.resize(n);
    m_device.kernel("method.cl", "grid_positions")
        .args(n, first, d[0], d[1], d[2], m_grid_positions.data())
        .launch(n, 64);
    m_property->inference(m_device, {&m_params, 0}, m_grid_positions, m_grid_props, *m_grid_ws);
    m_device.kernel("method.cl", "column_to_flat")
        .args(n, m_grid_props.cols(), 0u, m_grid_props.data(), m_grid.sigma, first)
        .launch(n, 64);
  }
}

// ---- the Model interface ---------------------------------------------------------------------------------

namespace {
MediumPass& medium_pass(ModelPass& pass) {
  auto* p = dynamic_cast<MediumPass*>(&pass);
  if (!p) throw InvalidArgument("this model's passes come from its make_pass()");
  return *p;
}
const MediumPass& medium_pass(const ModelPass& pass) { return medium_pass(const_cast<ModelPass&>(pass)); }
}  // namespace

void MediumModel::render(ModelPass& base, Buffer<float>& rays, std::uint32_t n_rays, const PassOptions& o) const {
  MediumPass& pass = medium_pass(base);
  draw_basis(pass, o);
  forward(pass, rays, n_rays, o.training, o.jitter_seed, pass.basis->dirs(), pass.basis->basis(), marches(o), o.timer,
          o.env);
}

void MediumModel::draw_basis(MediumPass& pass, const PassOptions& o) const {
  const auto& rs = m_settings.renderer;
  if (!pass.basis) pass.basis = std::make_unique<render::IndirectBasis>(m_device, rs.n_dirs, rs.sh_lmax);
  pass.basis->draw(o.seed, o.iteration);
}

const Buffer<float>& MediumModel::color(const ModelPass& pass, std::uint32_t i) const {
  if (i != 0) throw InvalidArgument("this method renders one colour per pass, asked for colour " + std::to_string(i));
  return medium_pass(pass).color;
}

void MediumModel::backward(ModelPass& base, const Buffer<float>& rays,
                           const std::vector<const Buffer<float>*>& d_colors, const PassOptions& o) {
  MediumPass& pass = medium_pass(base);
  if (d_colors.size() != 1 || !pass.basis)
    throw InvalidArgument("MediumModel::backward: give dL/dcolour of the one colour of a training render()");
  backward(pass, rays, pass.basis->dirs(), pass.basis->basis(), *d_colors[0], o.timer, o.env);
}

void MediumModel::train_visibility(ModelPass& pass, const Buffer<float>& rays, const nn::Loss& loss,
                                   Buffer<float>& value, float weight, const PassOptions& o) {
  visibility_step(medium_pass(pass), rays, loss, value, weight, o.timer, o.env);
}

}  // namespace relit::method
