// MediumModel's configuration: each part (renderer, density grid, property net, SH head, environment,
// coarse net, visibility net) reads its own section of the "model" object; a method composes the parts it has
// (MethodParts) and may read sections of its own. The passes are in medium.cpp.
#include <relit/method/medium.hpp>
#include <relit/nn/fully_fused_mlp.hpp>
#include <relit/nn/registry.hpp>

#include "common.hpp"

#include <algorithm>
#include <cmath>

namespace relit::method {

namespace {
using detail::default_visibility;
using detail::indirect_input_cols;
using detail::strip_heads;
using detail::SubConfig;
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

std::uint32_t sh_count(int sh_lmax) { return sh_lmax < 0 ? 0 : std::uint32_t((sh_lmax + 1) * (sh_lmax + 1)); }

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
  configure_shadow_gradient(r, docs);
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
  SubConfig sub(r, "renderer", Json::object(), "the volume renderer (docs/design.md §4.2)", docs);
  config::Reader& rr = sub.reader;
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
  s.kernel_variant = rr.choice("kernel_variant", "auto", {"auto", "simd", "workgroup"},
                               "which kernels light and composite the samples: auto (the device's table: SIMD "
                               "kernels on CPUs, work-group kernels on GPUs), simd or workgroup; "
                               "RELIT_RENDER_VARIANT overrides it (docs/renderer.md)");
  sub.finish_into(r);
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
  SubConfig sub(r, "density_grid", Json::object(), "the cached density grid of visibility targets", docs);
  config::Reader& gr = sub.reader;
  s.grid_resolution = gr.uint("resolution", 64, 4, 512, "voxels per axis");
  s.grid_refresh = gr.uint("refresh_every", 16, 1, 1u << 20, "training steps between refreshes from the property net");
  s.march_steps = gr.uint("march_steps", 64, 1, 4096, "midpoint steps of each visibility-target march");
  s.visibility_fraction = gr.number("visibility_fraction", 0.25f, 1e-3f, 1.0f,
                                    "share of each batch's rays whose samples train the visibility net");
  sub.finish_into(r);
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

// "shadow_gradient": the render loss's dL/dV passed on to the density along the shadow rays.
void MediumModel::configure_shadow_gradient(config::Reader& r, config::Docs* docs) {
  auto& g = m_settings.shadow_gradient;
  SubConfig sub(r, "shadow_gradient", Json::object(),
                "the render loss's gradient through the point light's shadow: dL/dV passed on to the density along "
                "each sample's shadow ray (docs/baselines.md, \"Training stability\")",
                docs);
  g.enabled = sub.reader.boolean("enabled", false,
                                 "pass dL/dV on to σ (off: V is a constant of the render loss, the isolation of "
                                 "the paper's appendix C)");
  g.points = sub.reader.uint("points", 1, 1, 64, "random points per sample on its shadow ray");
  g.fraction = sub.reader.number("fraction", 0.25f, 1e-3f, 1.0f,
                                 "share of each batch's rays whose samples pass the gradient on (scaled by its "
                                 "inverse)");
  m_settings.renderer.visibility_gradient = g.enabled;
  sub.finish_into(r);
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
  sub.finish_into(r);
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

}  // namespace relit::method
