// MediumModel, the model every method is put together from: the forward pass that assembles the renderer's
// properties from its parts, and the two isolated backward passes (kernels/method.cl holds the glue kernels).
// Each part's configuration is in medium_config.cpp.
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

using detail::indirect_input_cols;

void check_pass(const MediumPass& pass, const char* what) {
  if (pass.n_rays == 0)
    throw InvalidArgument(std::string("MediumModel::") + what + ": the pass holds no forward results");
}

void mark(StageTimer* timer, const char* stage) {
  if (timer) timer->mark(stage);
}

}  // namespace

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
  if (place_samples) renderer.sample(rays, n_rays, training, seed, pass.t, pass.delta, pass.positions, pass.share);
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
  if (march) {  // V into the first of V_ψ's columns (NeRV's V_ψ also gives D)
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
  if (m_settings.shadow_gradient.enabled) add_shadow_gradient(pass, rays, timer);
}

void MediumModel::add_shadow_gradient(MediumPass& pass, const Buffer<float>& rays, StageTimer* timer) {
  const ShadowGradientSettings& g = m_settings.shadow_gradient;
  const std::uint32_t spr = pass.n_samples;
  const detail::Subset subset = detail::visibility_subset(pass.n_rays, g.fraction, pass.share, pass.batch_rays);
  if (subset.local == 0) return;  // this rank holds none of the global batch's first rays
  // The first rays of the pass are its share of the global batch's first subset.global rays: their gradient is
  // scaled by batch / subset, so that it estimates the whole batch's.
  const float scale = float(double(subset.batch) / subset.global);
  const std::uint32_t rows = subset.local * spr * g.points;
  const std::uint32_t cols = prop_heads() + m_settings.n_features;
  nn::ensure_rows(pass.shadow_pos, m_device, rows, 3);
  nn::ensure_rows(pass.shadow_props, m_device, rows, cols);
  nn::ensure_rows(pass.d_shadow, m_device, rows, cols);
  if (!pass.ws_shadow) pass.ws_shadow = m_property->make_workspace(m_device);
  m_device.kernel("method.cl", "shadow_points")
      .args(rows, pass.d_shadow.padded(), spr, g.points, pass.shadow_seed, pass.share.first, pass.share.stride, scale,
            rays, pass.positions.data(), pass.props.data(), pass.props.cols(), pass.d_props.data(),
            pass.shadow_pos.data(), pass.d_shadow.data(), cols)
      .launch(pass.d_shadow.padded(), 64);
  const nn::ConstParamSlice theta{&m_params, 0};
  m_property->forward(m_device, theta, pass.shadow_pos, pass.shadow_props, *pass.ws_shadow);
  m_property->backward(m_device, theta, pass.shadow_pos, pass.shadow_props, pass.d_shadow, {&m_grads, 0}, true, nullptr,
                       *pass.ws_shadow);
  mark(timer, "shadow gradient");
}

double MediumModel::visibility_step(MediumPass& pass, const Buffer<float>& rays, const nn::Loss& loss,
                                    Buffer<float>& value, float weight, StageTimer* timer,
                                    const render::EnvironmentSamples* env, parallel::Share share,
                                    std::uint32_t batch_rays) {
  check_pass(pass, "visibility_step");
  const std::uint32_t n_env = env ? env->size() : 0;
  if (n_env != pass.n_env)
    throw InvalidArgument("MediumModel::visibility_step: give the environment samples of the forward pass (" +
                          std::to_string(pass.n_env) + " directions), got " + std::to_string(n_env));
  const std::uint32_t spr = pass.n_samples;
  const detail::Subset point =
      detail::visibility_subset(pass.n_rays, m_settings.visibility_fraction, share, batch_rays);
  const detail::Subset environment =
      detail::visibility_subset(pass.n_rays, m_settings.environment.visibility_fraction, share, batch_rays);
  // Rows [0, m): the samples of the first rays toward their point light; rows [m, m + m_env N_e): the samples of
  // the first rays toward each environment direction (sample-major). m is a multiple of 16, so the tiled
  // matrices of the two parts simply follow each other.
  const std::uint32_t m = point.local * spr;
  const std::uint32_t m_env = n_env ? environment.local * spr : 0;
  const std::uint32_t rows = m + m_env * n_env;
  const double global_rows = double(point.global) * spr + (n_env ? double(environment.global) * spr * n_env : 0.0);
  const double fraction = double(rows) / global_rows;
  if (rows == 0) {  // this rank holds none of the global batch's first rays (more ranks than such rays)
    m_vis_grads.fill(0.0f);
    value.fill(0.0f);
    return 0.0;
  }
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
  loss.evaluate(m_device, pass.vis_sub, pass.vis_target, pass.d_vis, value, weight * float(fraction));
  m_visibility->backward(m_device, psi, pass.vis_in_sub, pass.vis_sub, pass.d_vis, {&m_vis_grads, 0}, false, nullptr,
                         *pass.ws_visibility);
  mark(timer, "visibility net training");
  return fraction;
}

void MediumModel::refresh_density_grid(parallel::Share share) {
  const auto& d = m_grid.dims;
  const std::uint32_t total = std::uint32_t(d[0]) * d[1] * d[2];
  // This rank's voxels [lo, hi); each voxel's σ does not depend on which others are evaluated with it.
  const std::uint32_t lo = std::uint32_t(std::uint64_t(total) * share.first / share.stride);
  const std::uint32_t hi = std::uint32_t(std::uint64_t(total) * (share.first + 1) / share.stride);
  if (!share.whole()) m_grid.sigma.fill(0.0f);
  const std::uint32_t chunk = std::min<std::uint32_t>(total, 1u << 17);
  if (m_grid_positions.cols() != 3) {
    m_grid_positions = nn::BatchMatrix(m_device, chunk, 3);
    m_grid_props = nn::BatchMatrix(m_device, chunk, prop_heads() + m_settings.n_features);
    m_grid_ws = m_property->make_workspace(m_device);
  }
  for (std::uint32_t first = lo; first < hi; first += chunk) {
    const std::uint32_t n = std::min(chunk, hi - first);
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
  begin_pass(pass, o);
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

// Bi et al.'s fine branch and NeRV's camera rays are the MediumPass itself: its transmittance is the image's.
const Buffer<float>& MediumModel::transmittance(const ModelPass& pass) const { return medium_pass(pass).transmittance; }

void MediumModel::backward(ModelPass& base, const Buffer<float>& rays,
                           const std::vector<const Buffer<float>*>& d_colors, const PassOptions& o) {
  MediumPass& pass = medium_pass(base);
  if (d_colors.size() != 1 || !pass.basis)
    throw InvalidArgument("MediumModel::backward: give dL/dcolour of the one colour of a training render()");
  backward(pass, rays, pass.basis->dirs(), pass.basis->basis(), *d_colors[0], o.timer, o.env);
}

double MediumModel::train_visibility(ModelPass& pass, const Buffer<float>& rays, const nn::Loss& loss,
                                     Buffer<float>& value, float weight, const PassOptions& o) {
  return visibility_step(medium_pass(pass), rays, loss, value, weight, o.timer, o.env, o.share, o.batch_rays);
}

}  // namespace relit::method
