// The "Ours" model and its trainer: end-to-end gradients against finite differences, gradient isolation,
// linearity in the light's intensity, the NaN/Inf guard, deterministic resume, presets and config errors.
#include "gradient_check.hpp"
#include "test_support.hpp"

#include <relit/dataset.hpp>
#include <relit/io/checkpoint.hpp>
#include <relit/io/file.hpp>
#include <relit/method/evaluate.hpp>
#include <relit/method/model_io.hpp>
#include <relit/method/presets.hpp>
#include <relit/method/render_image.hpp>
#include <relit/method/trainer.hpp>
#include <relit/nn/registry.hpp>
#include <relit/render/rays.hpp>

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <random>

namespace relit {
namespace {

namespace fs = std::filesystem;

Json tiny_model(const std::string& sh = "1") { return test::tiny_ours_model(sh); }

struct Scene1 {
  Camera camera = Camera::look_at({0.3f, -3.5f, 1.0f}, {0, 0, 0}, {0, 0, 1}, 0.7f, 4, 4);
  PointLight light{{2.0f, -2.0f, 3.0f}, {500.0f, 400.0f, 300.0f}};
};

// The 16 rays of Scene1's image and K = 8 indirect directions with their SH basis up to `sh_lmax`, drawn once.
struct TinyBatch {
  static constexpr std::uint32_t n = 16;
  Buffer<float> rays;
  render::IndirectBasis basis;
  TinyBatch(const Device& dev, int sh_lmax = 1)
      : rays(dev, std::size_t(n) * render::kRayFloats), basis(dev, 8, sh_lmax) {
    const Scene1 sc;
    render::image_rays(dev, sc.camera, sc.light, 0, n, rays);
    basis.draw(1, 0);
  }
};

Json tiny_env_model(const std::string& sh = "1") {
  Json m = tiny_model(sh);
  m["environment"] = {{"enabled", true},
                      {"n_dirs", 8},
                      {"n_dirs_training", 4},
                      {"visibility_fraction", 0.5},
                      {"network", {{"type", "FullyFusedMLP"}, {"n_neurons", 16}, {"n_hidden_layers", 1}}}};
  return m;
}

// A smooth, non-uniform environment (a procedural sky at low resolution), visible to the camera.
EnvironmentLight test_sky() { return EnvironmentLight::sky(16, 8, 2, 0.5f, true); }

// sum_j w_j colour_j over the rays of the tiny image, in double.
double weighted_colour(method::Ours& model, method::MediumPass& pass, Buffer<float>& rays, std::uint32_t n,
                       render::IndirectBasis& basis, const std::vector<float>& w,
                       const render::EnvironmentSamples* env = nullptr) {
  model.forward(pass, rays, n, true, 3, basis.dirs(), basis.basis(), false, nullptr, env);
  const auto c = pass.color.read();
  double sum = 0;
  for (std::size_t j = 0; j < w.size(); ++j) sum += double(w[j]) * c[j];
  return sum;
}

// d(sum_j w_j colour_j)/dθ from backward() against central differences (gradient_check.hpp: per-parameter
// tolerances from two step sizes, small gradients and their signs, and a random direction). `from`: the first
// parameter that may be picked at random.
test::GradientCheckReport check_gradients(method::Ours& model, const render::EnvironmentSamples* env,
                                          std::size_t from = 0) {
  const Device& dev = model.device();
  TinyBatch batch(dev, model.settings().renderer.sh_lmax);
  const std::uint32_t n = batch.n;
  Buffer<float>& rays = batch.rays;
  render::IndirectBasis& basis = batch.basis;
  if (env) env->fill_background(rays, n);
  method::MediumPass pass;
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  std::vector<float> w(3 * n);
  for (auto& x : w) x = u(rng);
  weighted_colour(model, pass, rays, n, basis, w, env);
  Buffer<float> d_color(dev, w);
  model.backward(pass, rays, basis.dirs(), basis.basis(), d_color, nullptr, env);
  const auto grads = model.grads().read();
  const auto params = model.params().read();
  test::GradientCheck check;
  check.hi = params.size();
  check.random_lo = from;
  const auto report = test::check_gradient(
      [&](const std::vector<float>& theta) {
        model.params().write(theta);
        return weighted_colour(model, pass, rays, n, basis, w, env);
      },
      params, grads, check);
  model.params().write(params);
  return report;
}

TEST(Method, RenderGradientMatchesFiniteDifferencesEndToEnd) {
  const Device dev = test::test_device();
  for (const std::string sh : {"none", "1", "1 closed form", "1 visibility input", "1 optical depth input",
                               "1 optical depth input and attenuation"}) {
    SCOPED_TRACE("sh " + sh);
    Json config = tiny_model(sh.substr(0, sh.find(' ')));
    config["renderer"]["closed_form_indirect"] = sh.find("closed") != std::string::npos;
    if (sh.find("visibility") != std::string::npos) config["indirect"]["visibility_input"] = true;
    if (sh.find("depth") != std::string::npos) config["indirect"]["optical_depth_input"] = 0.25;
    config["indirect"]["optical_depth_attenuation"] = sh.find("attenuation") != std::string::npos;
    method::Ours model(dev, test::smooth_networks(config));
    model.initialize(11);
    // The optical depth comes from the density grid: fill it (it stays fixed while θ is perturbed).
    if (sh.find("depth") != std::string::npos) model.refresh_density_grid();
    check_gradients(model, nullptr);
  }
}

TEST(Method, EnvironmentRenderGradientMatchesFiniteDifferences) {
  // With an environment light: S_env through the N_e visibility columns, and c_env's head (the last block of
  // θ, where the random picks are drawn from) through the SH columns it adds to.
  const Device dev = test::test_device();
  method::Ours model(dev, test::smooth_networks(tiny_env_model()));
  model.initialize(11);
  ASSERT_NE(model.environment_network(), nullptr);
  const EnvironmentLight sky = test_sky();
  render::EnvironmentSamples env(dev, sky, 4);
  env.draw(1, 0);
  check_gradients(model, &env, model.n_params() - model.environment_network()->n_params());
}

TEST(Method, GradientsAreIsolatedBothWays) {
  const Device dev = test::test_device();
  for (const bool extra_inputs : {false, true}) {
    SCOPED_TRACE(extra_inputs ? "SH head sees V and the optical depth" : "SH head without V");
    Json config = tiny_model();
    config["indirect"]["visibility_input"] = extra_inputs;
    if (extra_inputs) config["indirect"]["optical_depth_input"] = 0.5;
    method::Ours model(dev, config);
    TinyBatch batch(dev);
    const std::uint32_t n = batch.n;
    Buffer<float>& rays = batch.rays;
    const render::IndirectBasis& basis = batch.basis;
    method::MediumPass pass;
    model.refresh_density_grid();
    model.forward(pass, rays, n, true, 3, basis.dirs(), basis.basis());
    // The render loss does not reach the visibility network...
    model.vis_grads().fill(123.0f);
    Buffer<float> d_color(dev, std::vector<float>(3 * n, 1.0f));
    model.backward(pass, rays, basis.dirs(), basis.basis(), d_color);
    for (float g : model.vis_grads().read()) ASSERT_EQ(g, 123.0f);
    // ...and the visibility loss does not reach θ, while it does reach ψ.
    model.grads().fill(-7.0f);
    auto loss = nn::create_loss({{"type", "L2"}});
    Buffer<float> value(dev, 1);
    model.visibility_step(pass, rays, *loss, value);
    for (float g : model.grads().read()) ASSERT_EQ(g, -7.0f);
    double norm = 0;
    for (float g : model.vis_grads().read()) norm += std::fabs(g);
    EXPECT_GT(norm, 0.0);
    EXPECT_TRUE(std::isfinite(value.read()[0]));
  }
}

// The visibility network's training gradient (visibility_step: V_ψ on the samples of the first rays, toward the
// point light and, under an environment, toward each of its directions, against the marched targets) against
// central differences of the loss computed on the host in double from V_ψ's outputs and the targets; the host
// loss at ψ is the device's value.
TEST(Method, VisibilityTrainingGradientMatchesFiniteDifferences) {
  const Device dev = test::test_device();
  for (const bool environment : {false, true}) {
    SCOPED_TRACE(environment ? "point light and environment" : "point light");
    method::Ours model(dev, test::smooth_networks(environment ? tiny_env_model() : tiny_model()));
    model.initialize(8);
    model.refresh_density_grid();
    TinyBatch batch(dev);
    const EnvironmentLight sky = test_sky();
    render::EnvironmentSamples env(dev, sky, 4);
    env.draw(1, 0);
    const render::EnvironmentSamples* e = environment ? &env : nullptr;
    if (e) e->fill_background(batch.rays, batch.n);
    method::MediumPass pass;
    model.forward(pass, batch.rays, batch.n, true, 3, batch.basis.dirs(), batch.basis.basis(), false, nullptr, e);
    const auto loss = nn::create_loss({{"type", "L2"}});
    const float weight = 0.7f;
    Buffer<float> value(dev, 1);
    model.visibility_step(pass, batch.rays, *loss, value, weight, nullptr, e);
    const auto grads = model.vis_grads().read();
    const auto psi = model.vis_params().read();
    const double device_loss = value.read()[0];
    auto host_loss = [&](const std::vector<float>& p) {
      model.vis_params().write(p);
      model.visibility_step(pass, batch.rays, *loss, value, weight, nullptr, e);
      const auto v = pass.vis_sub.download_row_major(), t = pass.vis_target.download_row_major();
      double sum = 0;
      for (std::size_t i = 0; i < v.size(); ++i) sum += (double(v[i]) - t[i]) * (double(v[i]) - t[i]);
      return weight * sum / double(v.size());
    };
    const double at_psi = host_loss(psi);
    EXPECT_GT(pass.vis_sub.batch(), environment ? 16u * 3 : 16u);
    EXPECT_NEAR(at_psi, weight * device_loss, 1e-5 * at_psi)
        << "the host loss is not the device's (value: the unweighted mean)";
    test::GradientCheck check;
    check.hi = psi.size();
    test::check_gradient(host_loss, psi, grads, check);
    model.vis_params().write(psi);
  }
}

// With indirect.visibility_input the SH head's last input column is V toward the light, the network's or the
// march's, and the resolved config keeps the key.
TEST(Method, IndirectHeadCanSeeTheVisibility) {
  const Device dev = test::test_device();
  Json config = tiny_model();
  config["indirect"]["visibility_input"] = true;
  method::Ours with(dev, config);
  EXPECT_EQ(with.hyperparams()["indirect"]["visibility_input"], true);
  EXPECT_EQ(with.indirect_network().n_input_dims(), with.settings().n_features + 4);
  config["indirect"]["visibility_input"] = false;
  method::Ours without(dev, config);
  EXPECT_EQ(without.indirect_network().n_input_dims(), without.settings().n_features + 3);
  with.initialize(2);
  with.refresh_density_grid();
  TinyBatch batch(dev);
  const std::uint32_t n = batch.n;
  Buffer<float>& rays = batch.rays;
  const render::IndirectBasis& basis = batch.basis;
  for (const bool march : {false, true}) {
    method::MediumPass pass;
    with.forward(pass, rays, n, true, 3, basis.dirs(), basis.basis(), march);
    const auto vis = pass.vis.download_row_major(), in = pass.light_in.download_row_major();
    const std::uint32_t cols = pass.light_in.cols(), vcols = pass.vis.cols();
    double spread = 0;
    for (std::uint32_t i = 0; i < pass.light_in.batch(); ++i) {
      ASSERT_EQ(in[std::size_t(i) * cols + cols - 1], vis[std::size_t(i) * vcols]) << "sample " << i;
      spread += std::fabs(vis[std::size_t(i) * vcols] - vis[0]);
    }
    EXPECT_GT(spread, 0.0);  // not a constant column
  }
  config["indirect"]["visibility_input"] = "yes";
  EXPECT_THROW(method::Ours(dev, config), ConfigError);
}

// With indirect.optical_depth_input = k the SH head's last input column is exp(-k τ), τ marched toward the light
// through the density grid: the march's visibility to the power k. It follows V when both are inputs.
TEST(Method, IndirectHeadCanSeeTheOpticalDepth) {
  const Device dev = test::test_device();
  Json config = tiny_model();
  config["indirect"]["optical_depth_input"] = 0.25;
  config["indirect"]["visibility_input"] = true;
  method::Ours model(dev, config);
  EXPECT_FLOAT_EQ(model.hyperparams()["indirect"]["optical_depth_input"].get<float>(), 0.25f);
  EXPECT_EQ(model.indirect_network().n_input_dims(), model.settings().n_features + 5);
  model.initialize(2);
  model.refresh_density_grid();
  TinyBatch batch(dev);
  method::MediumPass pass;
  model.forward(pass, batch.rays, batch.n, true, 3, batch.basis.dirs(), batch.basis.basis(), true);
  const auto vis = pass.vis.download_row_major(), in = pass.light_in.download_row_major();
  const std::uint32_t cols = pass.light_in.cols(), vcols = pass.vis.cols();
  double spread = 0;
  for (std::uint32_t i = 0; i < pass.light_in.batch(); ++i) {
    const float v = vis[std::size_t(i) * vcols];
    ASSERT_EQ(in[std::size_t(i) * cols + cols - 2], v) << "sample " << i;
    ASSERT_NEAR(in[std::size_t(i) * cols + cols - 1], std::pow(double(v), 0.25), 2e-6) << "sample " << i;
    spread += std::fabs(v - vis[0]);
  }
  EXPECT_GT(spread, 0.0);
  for (const Json& bad : {Json(-0.5), Json("deep"), Json(1e9)}) {
    config["indirect"]["optical_depth_input"] = bad;
    EXPECT_THROW(method::Ours(dev, config), ConfigError) << bad.dump();
  }
  // The attenuation multiplies the head's SH output by the same exp(-k τ): the props' SH columns are the
  // unattenuated ones times the input column; it needs k > 0.
  config["indirect"]["optical_depth_input"] = 0.25;
  config["indirect"]["visibility_input"] = false;
  method::Ours plain(dev, config);
  config["indirect"]["optical_depth_attenuation"] = true;
  method::Ours attenuated(dev, config);
  for (method::Ours* m : {&plain, &attenuated}) {
    m->initialize(2);
    m->refresh_density_grid();
  }
  method::MediumPass p0, p1;
  plain.forward(p0, batch.rays, batch.n, true, 3, batch.basis.dirs(), batch.basis.basis());
  attenuated.forward(p1, batch.rays, batch.n, true, 3, batch.basis.dirs(), batch.basis.basis());
  const auto a0 = p0.props.download_row_major(), a1 = p1.props.download_row_major(),
             depth = p1.depth_in.download_row_major();
  const std::uint32_t pc = p0.props.cols(), n_sh = 4;
  for (std::uint32_t i = 0; i < p0.props.batch(); ++i)
    for (std::uint32_t c = 0; c < 3 * n_sh; ++c)
      ASSERT_FLOAT_EQ(a1[std::size_t(i) * pc + render::kSH + c], a0[std::size_t(i) * pc + render::kSH + c] * depth[i])
          << "sample " << i << " coefficient " << c;
  config["indirect"]["optical_depth_input"] = 0;
  EXPECT_THROW(method::Ours(dev, config), ConfigError);
}

TEST(Method, EnvironmentVisibilityColumnsAndTargetsComeFromTheirDirections) {
  // forward(): column env_col + j of sample s is V_ψ([x_s, w_j]) (network) or the march toward w_j (march);
  // visibility_step(): rows m + s N_e + j of the subset are [x_s, w_j] with the march toward w_j as target.
  const Device dev = test::test_device();
  method::Ours model(dev, tiny_env_model());
  model.initialize(3);
  model.refresh_density_grid();
  Scene1 sc;
  const std::uint32_t n = 16, n_env = 4, spr = 16;
  Buffer<float> rays(dev, std::size_t(n) * render::kRayFloats);
  render::image_rays(dev, sc.camera, sc.light, 0, n, rays);
  render::IndirectBasis basis(dev, 8, 1);
  basis.draw(1, 0);
  const EnvironmentLight sky = test_sky();
  render::EnvironmentSamples env(dev, sky, n_env);
  env.draw(4, 0);
  const auto dirs = env.dirs().download_row_major();
  const std::uint32_t col = model.renderer(n_env).env_visibility_col();
  method::MediumPass pass;
  for (const bool march : {false, true}) {
    SCOPED_TRACE(march ? "march" : "network");
    model.forward(pass, rays, n, true, 3, basis.dirs(), basis.basis(), march, nullptr, &env);
    const auto props = pass.props.download_row_major();
    const auto pos = pass.positions.download_row_major();
    const std::uint32_t cols = pass.props.cols();
    ASSERT_EQ(cols, col + n_env);
    // The expected values: V_ψ on hand-built rows, or the directional march.
    const std::uint32_t ns = n * spr;
    std::vector<float> expect(std::size_t(ns) * n_env);
    if (march) {
      nn::BatchMatrix out(dev, ns, n_env);
      render::march_visibility_directions(dev, pass.positions, env.dirs(), model.density_grid(), 16, out);
      expect = out.download_row_major();
    } else {
      std::vector<float> rows;
      for (std::uint32_t s = 0; s < ns; ++s)
        for (std::uint32_t j = 0; j < n_env; ++j) {
          for (int c = 0; c < 3; ++c) rows.push_back(0.5f * pos[s * 3 + c] + 0.5f);
          for (int c = 0; c < 3; ++c) rows.push_back(dirs[j * 3 + c]);
        }
      nn::BatchMatrix in(dev, ns * n_env, 6), out(dev, ns * n_env, 1);
      in.upload_row_major(rows);
      model.visibility_network().inference(dev, {&model.vis_params(), 0}, in, out);
      expect = out.download_row_major();
    }
    for (std::uint32_t s = 0; s < ns; ++s)
      for (std::uint32_t j = 0; j < n_env; ++j)
        ASSERT_NEAR(props[std::size_t(s) * cols + col + j], expect[std::size_t(s) * n_env + j], 1e-5f)
            << "sample " << s << " direction " << j;
  }
  auto loss = nn::create_loss({{"type", "L2"}});
  Buffer<float> value(dev, 1);
  model.grads().fill(-7.0f);
  model.visibility_step(pass, rays, *loss, value, 1.0f, nullptr, &env);
  for (float g : model.grads().read()) ASSERT_EQ(g, -7.0f);  // θ untouched
  // visibility_fraction 0.25 (default) and 0.5 of 16 rays: 4 and 8 rays of 16 samples.
  const std::uint32_t m = 4 * spr, m_env = 8 * spr;
  ASSERT_EQ(pass.vis_in_sub.batch(), m + m_env * n_env);
  const auto in = pass.vis_in_sub.download_row_major();
  const auto target = pass.vis_target.download_row_major();
  const auto pos = pass.positions.download_row_major();
  nn::BatchMatrix sub(dev, m_env, 3), marched(dev, m_env, n_env);
  sub.upload_row_major(std::vector<float>(pos.begin(), pos.begin() + std::size_t(m_env) * 3));
  render::march_visibility_directions(dev, sub, env.dirs(), model.density_grid(), 16, marched);
  const auto mv = marched.download_row_major();
  for (std::uint32_t s = 0; s < m_env; ++s)
    for (std::uint32_t j = 0; j < n_env; ++j) {
      const std::size_t r = m + std::size_t(s) * n_env + j;
      ASSERT_NEAR(target[r], mv[std::size_t(s) * n_env + j], 1e-6f) << "row " << r;
      for (int c = 0; c < 3; ++c) {
        ASSERT_NEAR(in[r * 6 + c], 0.5f * pos[s * 3 + c] + 0.5f, 1e-6f) << "row " << r;
        ASSERT_NEAR(in[r * 6 + 3 + c], dirs[j * 3 + c], 1e-6f) << "row " << r;
      }
    }
  EXPECT_TRUE(std::isfinite(value.read()[0]));
  double norm = 0;
  for (float g : model.vis_grads().read()) norm += std::fabs(g);
  EXPECT_GT(norm, 0.0);
}

TEST(Method, EnvironmentLightAddsAConstantToTheLinearPointLightTerm) {
  // Under an environment, C(I) = C_env + I B: the point light's part is linear in I (SH head scaled by I) and
  // the environment's part (S_env, c_env, background) does not depend on I, so C(3I) - C(2I) = C(2I) - C(I).
  // Exactly so with the closed-form indirect sum; the K-direction sum clamps c = I h + c_env as a whole.
  const Device dev = test::test_device();
  Json config = tiny_env_model("2");
  config["renderer"]["closed_form_indirect"] = true;
  method::Ours model(dev, config);
  model.initialize(4);
  Scene1 sc;
  const EnvironmentLight sky = test_sky();
  method::ImageRenderSettings rs;
  rs.environment = &sky;
  std::vector<Image> img;
  for (float k : {1.0f, 2.0f, 3.0f}) {
    PointLight l = sc.light;
    for (auto& i : l.intensity) i *= k;
    img.push_back(method::render_image(model, sc.camera, l, rs));
  }
  const Image point_only = method::render_image(model, sc.camera, sc.light);
  double env_part = 0;
  for (std::size_t p = 0; p < img[0].pixels.size(); ++p) {
    const float d1 = img[1].pixels[p] - img[0].pixels[p], d2 = img[2].pixels[p] - img[1].pixels[p];
    EXPECT_NEAR(d2, d1, 1e-4f * (1.0f + std::fabs(img[2].pixels[p])));
    env_part += std::fabs(img[0].pixels[p] - point_only.pixels[p]);
  }
  EXPECT_GT(env_part, 0.0);  // the environment adds light
  // A model trained without an environment refuses one.
  method::Ours plain(dev, tiny_model());
  EXPECT_THROW(method::render_image(plain, sc.camera, sc.light, rs), InvalidArgument);
}

TEST(Method, RadianceIsLinearInTheLightIntensity) {
  // Direct light is I V p / r^2 and the SH head's output is scaled by I, so doubling I doubles every pixel.
  const Device dev = test::test_device();
  method::Ours model(dev, tiny_model("2"));
  model.initialize(4);
  Scene1 sc;
  const Image a = method::render_image(model, sc.camera, sc.light);
  PointLight twice = sc.light;
  for (auto& i : twice.intensity) i *= 2.0f;
  const Image b = method::render_image(model, sc.camera, twice);
  double total = 0;
  for (std::size_t k = 0; k < a.pixels.size(); ++k) {
    EXPECT_NEAR(b.pixels[k], 2.0f * a.pixels[k], 1e-5f * (1.0f + std::fabs(b.pixels[k])));
    total += a.pixels[k];
  }
  EXPECT_GT(total, 0.0);
}

// Data parallelism splits the density-grid refresh: rank r of N evaluates its contiguous 1/N of the voxels and
// zeroes the rest, and the sum of the ranks' grids is the single-process grid, bit for bit (each voxel's σ does
// not depend on which voxels are evaluated with it).
TEST(Method, DensityGridRefreshSplitOverRanksSumsToTheWholeGrid) {
  const Device dev = test::test_device();
  method::Ours model(dev, tiny_model());
  model.initialize(2);
  model.refresh_density_grid();
  const std::vector<float> whole = model.density_grid().sigma.read();
  for (std::uint32_t n : {2u, 3u}) {
    std::vector<double> sum(whole.size(), 0.0);
    std::size_t nonzero_parts = 0;
    for (std::uint32_t r = 0; r < n; ++r) {
      model.refresh_density_grid({r, n});
      const std::vector<float> part = model.density_grid().sigma.read();
      std::size_t nonzero = 0;
      for (std::size_t i = 0; i < part.size(); ++i) {
        sum[i] += part[i];
        nonzero += part[i] != 0.0f;
      }
      nonzero_parts += nonzero > 0 && nonzero < part.size();
    }
    EXPECT_EQ(nonzero_parts, n) << "every rank evaluates a part, none the whole";
    for (std::size_t i = 0; i < whole.size(); ++i) ASSERT_EQ(float(sum[i]), whole[i]) << "voxel " << i << ", " << n;
  }
}

TEST(Method, InferenceVisibilityCanMarchTheDensityGrid) {
  const Device dev = test::test_device();
  method::Ours model(dev, tiny_model());
  model.initialize(2);
  model.refresh_density_grid();
  Scene1 sc;
  method::ImageRenderSettings net, march;
  march.visibility = "march";
  const Image a = method::render_image(model, sc.camera, sc.light, net);
  const Image b = method::render_image(model, sc.camera, sc.light, march);
  // Different visibility gives a different image; both finite.
  double diff = 0;
  for (std::size_t k = 0; k < a.pixels.size(); ++k) {
    ASSERT_TRUE(std::isfinite(a.pixels[k]) && std::isfinite(b.pixels[k]));
    diff += std::fabs(a.pixels[k] - b.pixels[k]);
  }
  EXPECT_GT(diff, 0.0);
  march.visibility = "sometimes";
  EXPECT_THROW(method::render_image(model, sc.camera, sc.light, march), InvalidArgument);
}

// training_visibility "march": a training pass takes V from the density-grid march (what forward() gives when
// asked to march), an inference pass keeps the model's inference_visibility; other values are config errors.
TEST(Method, TrainingVisibilityCanMarchTheDensityGrid) {
  const Device dev = test::test_device();
  Json config = tiny_model();
  config["training_visibility"] = "march";
  method::Ours model(dev, config);
  EXPECT_EQ(model.hyperparams()["training_visibility"], "march");
  model.initialize(2);
  model.refresh_density_grid();
  TinyBatch batch(dev);
  method::MediumPass marched, training, inference;
  model.forward(marched, batch.rays, batch.n, true, 3, batch.basis.dirs(), batch.basis.basis(), true);
  method::PassOptions o;
  o.training = true;
  o.seed = 1;
  o.jitter_seed = 3;
  model.render(training, batch.rays, batch.n, o);
  o.training = false;
  model.render(inference, batch.rays, batch.n, o);
  const auto want = marched.vis.download_row_major(), got = training.vis.download_row_major(),
             net = inference.vis.download_row_major();
  ASSERT_EQ(got.size(), want.size());
  double diff = 0;
  for (std::size_t i = 0; i < want.size(); ++i) {
    ASSERT_EQ(got[i], want[i]) << "sample " << i;
    diff += std::fabs(net[i] - want[i]);
  }
  EXPECT_GT(diff, 0.0);  // the inference pass asked the network
  config["training_visibility"] = "always";
  EXPECT_THROW(method::Ours(dev, config), ConfigError);
}

// initial_density sets the σ head's bias: the median σ of the freshly initialised density grid follows it
// (the hidden layers' random output spreads σ around softplus(bias), so the median, not every voxel).
TEST(Method, InitialDensitySetsTheStartingSigma) {
  const Device dev = test::test_device();
  const auto median_sigma = [&](double sigma0) {
    Json cfg = tiny_model();
    if (sigma0 > 0) cfg["initial_density"] = sigma0;
    method::Ours model(dev, cfg);
    model.initialize(3);
    model.refresh_density_grid();
    std::vector<float> s = model.density_grid().sigma.read();
    std::nth_element(s.begin(), s.begin() + s.size() / 2, s.end());
    return double(s[s.size() / 2]);
  };
  EXPECT_NEAR(median_sigma(0), std::log(2.0), 0.35);  // the default: a zero bias
  EXPECT_NEAR(median_sigma(10), 10.0, 1.0);
  EXPECT_NEAR(median_sigma(40), 40.0, 1.0);
  EXPECT_NEAR(median_sigma(0.05), 0.05, 0.05);
  Json bad = tiny_model();
  bad["initial_density"] = 0;
  EXPECT_THROW(method::Ours(dev, bad), ConfigError);
  bad["initial_density"] = 5;
  bad["property"]["network"]["bias"] = false;
  try {
    method::Ours m(dev, bad);
    FAIL() << "initial_density accepted without biases";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("/model/initial_density"), std::string::npos) << e.what();
  }
}

TEST(Method, ConfigErrorsNameTheKey) {
  const Device dev = test::test_device();
  Json bad = tiny_model();
  bad["colour"] = 1;
  try {
    method::Ours m(dev, bad);
    FAIL() << "unknown key accepted";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("/model/colour"), std::string::npos) << e.what();
  }
  bad = tiny_model();
  bad["property"]["network"]["output_heads"] = Json::array();
  EXPECT_THROW(method::Ours(dev, bad), ConfigError);
  bad = tiny_model();
  bad["renderer"]["n_samples"] = 20;
  EXPECT_THROW(method::Ours(dev, bad), ConfigError);
  bad = tiny_model();
  bad["renderer"]["sh"] = "12";
  EXPECT_THROW(method::Ours(dev, bad), ConfigError);
  EXPECT_THROW(method::preset("fastest"), InvalidArgument);
  EXPECT_THROW(method::load_run_config("/nonexistent/run.json"), IOError);
}

TEST(Method, PresetsBuildAndResolveToThemselves) {
  const Device dev = test::test_device();
  const auto names = method::preset_names();
  EXPECT_NE(std::find(names.begin(), names.end(), "fast"), names.end());
  EXPECT_NE(std::find(names.begin(), names.end(), "paper"), names.end());
  for (const auto& name : names) {
    SCOPED_TRACE(name);
    const Json cfg = method::preset(name);
    const std::string m = cfg.value("method", "ours");
    EXPECT_EQ(name.rfind(m == "ours" ? "" : m + "-", 0), 0u) << "a baseline's preset is named after its method";
    const auto model = method::create_model(dev, m, cfg.at("model"));
    const auto again = method::create_model(dev, m, model->hyperparams());
    EXPECT_EQ(model->method(), m);
    EXPECT_EQ(again->hyperparams(), model->hyperparams());
    EXPECT_EQ(again->n_params(), model->n_params());
  }
}

TEST(Method, CheckRunConfigReadsWhatTheTrainerReadsWithoutADevice) {
  const Device dev = test::test_device();
  for (const auto& name : method::preset_names()) {
    SCOPED_TRACE(name);
    const Json cfg = method::preset(name);
    const Json resolved = method::check_run_config(cfg);
    const std::string m = cfg.value("method", "ours");
    EXPECT_EQ(resolved.at("method"), m);
    EXPECT_EQ(resolved.at("model"), method::create_model(dev, m, cfg.at("model"))->hyperparams());
    EXPECT_TRUE(resolved.at("training").contains("optimizer"));
  }
  const auto pointer_of = [](const Json& cfg) {
    try {
      method::check_run_config(cfg);
    } catch (const ConfigError& e) {
      return e.pointer();
    }
    return std::string("(accepted)");
  };
  EXPECT_EQ(pointer_of({{"training", {{"stepz", 1}}}}), "/training/stepz");
  EXPECT_EQ(pointer_of({{"model", {{"renderer", {{"n_samples", 20}}}}}}), "/model/renderer/n_samples");
  EXPECT_EQ(pointer_of({{"method", "nerv"}, {"model", {{"bounce", {{"n_dirs", 0}}}}}}), "/model/bounce/n_dirs");
  EXPECT_EQ(pointer_of({{"colour", 1}}), "/colour");
  // A run's config.json names its dataset: accepted as input (the dataset argument decides), not resolved.
  EXPECT_EQ(pointer_of({{"dataset", "/data/elsewhere"}}), "(accepted)");
  EXPECT_FALSE(method::check_run_config({{"dataset", "/data/elsewhere"}}).contains("dataset"));
  EXPECT_EQ(pointer_of({{"dataset", 3}}), "/dataset");
  EXPECT_THROW(method::check_run_config(Json::array()), ConfigError);
}

// ---- the trainer, on a tiny generated dataset ----------------------------------------------------------------

class MethodTrainer : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    s_dir = new test::TempDir("method");
    const DatasetSettings s = test::tiny_dataset(4, 2);
    generate_dataset(test::test_device(), Scene::from_json(Scene::builtin_json("cloud", 1, 16)), dataset(), s);
  }
  static void TearDownTestSuite() {
    delete s_dir;
    s_dir = nullptr;
  }
  static std::string dataset() { return (s_dir->path() / "ds").string(); }
  static Json config() {
    return {{"model", tiny_model()},
            {"training", {{"batch_rays", 64}, {"validate_every", 0}, {"checkpoint_every", 0}, {"log_every", 2}}}};
  }
  static test::TempDir* s_dir;
};
test::TempDir* MethodTrainer::s_dir = nullptr;

TEST_F(MethodTrainer, ResumeGivesTheSameParametersAsAnUninterruptedRun) {
  const Device dev = test::test_device();
  method::Trainer straight(dev, dataset(), config());
  straight.run(6);
  test::TempDir out("run");
  method::Trainer first(dev, dataset(), config());
  first.set_output(out.path().string());
  first.run(3);
  ASSERT_TRUE(fs::exists(out.path() / "checkpoint.relit"));
  ASSERT_TRUE(fs::exists(out.path() / "config.json"));
  ASSERT_TRUE(fs::exists(out.path() / "log.jsonl"));
  method::Trainer resumed(dev, dataset(), config());
  resumed.load_checkpoint((out.path() / "checkpoint.relit").string());
  EXPECT_EQ(resumed.steps(), 3u);
  resumed.run(3);
  EXPECT_EQ(resumed.model().params().read(), straight.model().params().read());
  EXPECT_EQ(resumed.model().vis_params().read(), straight.model().vis_params().read());
  // The checkpoint reloads as a model that renders like the trainer's.
  const auto model = method::load_model(dev, (out.path() / "checkpoint.relit").string());
  Scene1 sc;
  EXPECT_EQ(method::render_image(*model, sc.camera, sc.light).pixels,
            method::render_image(first.model(), sc.camera, sc.light).pixels);
  // Another config is refused.
  Json other = config();
  other["model"]["n_features"] = 5;
  method::Trainer wrong(dev, dataset(), other);
  EXPECT_THROW(wrong.load_checkpoint((out.path() / "checkpoint.relit").string()), InvalidArgument);
}

// A kill can leave log lines past the last checkpoint (an older relit) or a torn last line: resuming drops
// them, so the log holds each step once, in order, and only steps the checkpoint has.
TEST_F(MethodTrainer, ResumeDropsLogLinesTheCheckpointLacks) {
  const Device dev = test::test_device();
  test::TempDir out("run-log");
  Json cfg = config();
  cfg["training"]["log_every"] = 1;
  {
    method::Trainer t(dev, dataset(), cfg);
    t.set_output(out.path().string());
    t.run(4);
  }
  const std::string log = (out.path() / "log.jsonl").string();
  std::string text = io::read_file(log);
  io::write_file_atomic(log, text + "{\"step\": 99, \"loss\": 1}\n{\"step\": 5, \"lo");
  std::ofstream(out.path() / ".checkpoint.tmp-99999999-0.relit") << "a killed write";
  method::Trainer t(dev, dataset(), cfg);
  t.set_output(out.path().string());
  EXPECT_FALSE(fs::exists(out.path() / ".checkpoint.tmp-99999999-0.relit")) << "stale temporary left";
  t.load_checkpoint((out.path() / "checkpoint.relit").string());
  EXPECT_EQ(io::read_file(log), text);
  t.run(2);
  std::vector<std::uint64_t> steps;
  std::istringstream in(io::read_file(log));
  for (std::string line; std::getline(in, line);) steps.push_back(Json::parse(line).at("step").get<std::uint64_t>());
  EXPECT_EQ(steps, (std::vector<std::uint64_t>{1, 2, 3, 4, 5, 6}));
}

TEST_F(MethodTrainer, TrainingLowersTheLoss) {
  const Device dev = test::test_device();
  Json cfg = config();
  cfg["training"]["batch_rays"] = 256;
  method::Trainer t(dev, dataset(), cfg);
  t.step();
  const double first = t.stats().loss;
  const auto s = t.run(80);
  EXPECT_TRUE(std::isfinite(first));
  EXPECT_LT(s.loss, 0.5 * first);
  EXPECT_EQ(s.skipped, 0u);
  EXPECT_EQ(s.step, 81u);
}

// training.visibility_loss picks the visibility net's loss: the same first step scores differently under L2 and
// SrgbL2 (the sRGB curve is steep near 0), the resolved config names it, and an unknown type is an error.
TEST_F(MethodTrainer, VisibilityLossIsAConfigurableComponent) {
  const Device dev = test::test_device();
  method::Trainer l2(dev, dataset(), config());
  Json cfg = config();
  cfg["training"]["visibility_loss"] = {{"type", "SrgbL2"}};
  method::Trainer srgb(dev, dataset(), cfg);
  EXPECT_EQ(l2.config()["training"]["visibility_loss"]["type"], "L2");
  EXPECT_EQ(srgb.config()["training"]["visibility_loss"]["type"], "SrgbL2");
  l2.step();
  srgb.step();
  const double a = l2.stats().visibility_loss, b = srgb.stats().visibility_loss;
  EXPECT_TRUE(std::isfinite(a) && std::isfinite(b));
  EXPECT_GT(a, 0.0);
  EXPECT_NE(a, b);
  cfg["training"]["visibility_loss"] = {{"type", "Huber"}};
  EXPECT_THROW(method::Trainer(dev, dataset(), cfg), ConfigError);
}

TEST_F(MethodTrainer, EnvPointDatasetsTrainTheEnvironmentPartsAndResume) {
  // An 'env+point' dataset: relit turns the model's environment on, trains S_env and c_env, resumes exactly,
  // and evaluates its views under the dataset's environment; a config that says otherwise is an error.
  const Device dev = test::test_device();
  test::TempDir dir("method-env");
  const std::string ds = (dir.path() / "ds").string();
  DatasetSettings d;
  d.resolution = 12;
  d.train = 4;
  d.val = 1;
  d.test = 2;
  d.spp = 2;
  d.seed = 5;
  d.lighting = "env+point";
  d.env_visible = true;
  generate_dataset(dev, Scene::from_json(Scene::builtin_json("cloud", 1, 16)), ds, d);
  Json cfg = config();
  cfg["training"]["batch_rays"] = 128;
  method::Trainer straight(dev, ds, cfg);
  EXPECT_EQ(straight.config()["model"]["environment"]["enabled"], true);
  ASSERT_NE(dynamic_cast<method::Ours&>(straight.model()).environment_network(), nullptr);
  const auto env_before = straight.model().params().read();
  straight.run(6);
  // c_env's parameters (the last block of θ) moved.
  const std::size_t env_params = dynamic_cast<method::Ours&>(straight.model()).environment_network()->n_params();
  const auto after = straight.model().params().read();
  double moved = 0;
  for (std::size_t i = after.size() - env_params; i < after.size(); ++i) moved += std::fabs(after[i] - env_before[i]);
  EXPECT_GT(moved, 0.0);
  EXPECT_TRUE(std::isfinite(straight.stats().loss));
  EXPECT_TRUE(std::isfinite(straight.stats().visibility_loss));

  test::TempDir out("run-env");
  method::Trainer first(dev, ds, cfg);
  first.set_output(out.path().string());
  first.run(3);
  method::Trainer resumed(dev, ds, cfg);
  resumed.load_checkpoint((out.path() / "checkpoint.relit").string());
  resumed.run(3);
  EXPECT_EQ(resumed.model().params().read(), straight.model().params().read());
  EXPECT_EQ(resumed.model().vis_params().read(), straight.model().vis_params().read());

  // Evaluation renders the test views under the environment (the split carries it).
  const auto split = load_split(ds, "test");
  ASSERT_NE(split.environment, nullptr);
  EXPECT_TRUE(split.environment->visible());
  method::ImageRenderSettings lit, dark;
  lit.environment = split.environment.get();
  const Image a = method::render_image(straight.model(), split.cameras[0], split.lights[0], lit);
  const Image b = method::render_image(straight.model(), split.cameras[0], split.lights[0], dark);
  EXPECT_NE(a.pixels, b.pixels);
  const auto views = method::evaluate(straight.model(), ds, (out.path() / "eval").string());
  ASSERT_EQ(views.size(), 2u);
  EXPECT_TRUE(std::isfinite(views[0].metrics.psnr));

  Json wrong = cfg;
  wrong["model"]["environment"] = {{"enabled", false}};
  try {
    method::Trainer t(dev, ds, wrong);
    ADD_FAILURE() << "expected a ConfigError";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("/model/environment/enabled"), std::string::npos) << e.what();
  }
  wrong["model"]["environment"]["enabled"] = true;
  EXPECT_THROW(method::Trainer(dev, dataset(), wrong), ConfigError);  // a 'point' dataset has no environment
}

TEST_F(MethodTrainer, NonFiniteStepsAreSkippedAndCounted) {
  const Device dev = test::test_device();
  method::Trainer t(dev, dataset(), config());
  t.run(2);
  // (A NaN weight in front of a ReLU can vanish — fmax(NaN, 0) is 0 — so poison every parameter.)
  t.model().params().fill(std::nanf(""));
  const auto psi = t.model().vis_params().read();
  const auto s = t.run(2);
  EXPECT_EQ(s.skipped, 2u);
  EXPECT_FALSE(std::isfinite(s.loss));
  EXPECT_EQ(t.model().vis_params().read(), psi);  // both optimisers skipped the steps
}

TEST_F(MethodTrainer, BadDatasetsAreClearErrors) {
  const Device dev = test::test_device();
  EXPECT_THROW(method::Trainer(dev, "/nonexistent/dataset", config()), IOError);
  Json bad = config();
  bad["training"]["batch_rays"] = 0;
  EXPECT_THROW(method::Trainer(dev, dataset(), bad), ConfigError);
  bad = config();
  bad["method"] = "nerf";
  EXPECT_THROW(method::Trainer(dev, dataset(), bad), ConfigError);
}

}  // namespace
}  // namespace relit
