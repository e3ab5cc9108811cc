// The baselines of docs/design.md §4.5 through the Model interface: Bi et al.'s hierarchical sampling and coarse/fine
// networks, NeRV's visibility/depth network and one-bounce indirect light; gradients against finite
// differences, and short trainings on a tiny generated scene.
#include "gradient_check.hpp"
#include "test_support.hpp"

#include <relit/dataset.hpp>
#include <relit/method/bi.hpp>
#include <relit/method/nerv.hpp>
#include <relit/method/model_io.hpp>
#include <relit/method/presets.hpp>
#include <relit/method/render_image.hpp>
#include <relit/method/trainer.hpp>
#include <relit/metrics.hpp>
#include <relit/render/rays.hpp>

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <iostream>
#include <map>
#include <random>

namespace relit {
namespace {

namespace fs = std::filesystem;

const Json kMlp = test::tiny_mlp();
const Json kFreq = test::tiny_frequency();

// Small smooth networks (frequency encodings) so that finite differences are meaningful.
Json tiny_bi() {
  return {{"renderer", {{"n_samples", 16}, {"n_fine_samples", 16}}},
          {"density_grid", {{"resolution", 8}, {"march_steps", 16}}},
          {"property", {{"encoding", kFreq}, {"network", kMlp}}},
          {"coarse", {{"encoding", kFreq}, {"network", kMlp}}},
          {"visibility", {{"position_encoding", kFreq}, {"direction_encoding", kFreq}, {"network", kMlp}}}};
}

struct Scene1 {
  Camera camera = Camera::look_at({0.3f, -3.5f, 1.0f}, {0, 0, 0}, {0, 0, 1}, 0.7f, 4, 4);
  PointLight light{{2.0f, -2.0f, 3.0f}, {500.0f, 400.0f, 300.0f}};
};

method::PassOptions training_options(const render::EnvironmentSamples* env = nullptr) {
  method::PassOptions o;
  o.training = true;
  o.seed = 1;
  o.jitter_seed = 3;
  o.env = env;
  return o;
}

// Ours' keys (sh left to the method's default: 5 for Ours, 1 for Ours + BRDF).
Json tiny_ours() { return test::tiny_ours_model(""); }

Json tiny_nerv() {
  return {{"renderer", {{"n_samples", 16}}},
          {"bounce", {{"n_dirs", 8}, {"n_dirs_env", 4}}},
          {"density_grid", {{"resolution", 8}, {"march_steps", 16}}},
          {"property", {{"encoding", kFreq}, {"network", kMlp}}},
          {"visibility",
           {{"position_encoding", kFreq}, {"direction_encoding", kFreq}, {"trunk", kMlp}, {"network", kMlp}}}};
}

// sum_j w_j colour_j of colour `which` over the rays of the tiny image, in double.
double weighted_colour(method::Model& model, method::ModelPass& pass, Buffer<float>& rays, std::uint32_t n,
                       std::uint32_t which, const std::vector<float>& w, const render::EnvironmentSamples* env) {
  model.render(pass, rays, n, training_options(env));
  const auto c = model.color(pass, which).read();
  double sum = 0;
  for (std::size_t j = 0; j < w.size(); ++j) sum += double(w[j]) * c[j];
  return sum;
}

// d(sum_j w_j colour_j)/dθ of colour `which` from backward() against central differences on θ[lo, hi)
// (gradient_check.hpp: per-parameter tolerances from three step sizes, small gradients and their signs, and a
// random direction); the gradient outside [lo, hi) must be zero.
void check_gradients(method::Model& model, std::uint32_t which, std::size_t lo, std::size_t hi,
                     const render::EnvironmentSamples* env = nullptr) {
  const Device& dev = model.device();
  Scene1 sc;
  const std::uint32_t n = 16;
  Buffer<float> rays(dev, std::size_t(n) * render::kRayFloats);
  render::image_rays(dev, sc.camera, sc.light, 0, n, rays);
  if (env) env->fill_background(rays, n);
  auto pass = model.make_pass();
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  std::vector<float> w(3 * n);
  for (auto& x : w) x = u(rng);
  weighted_colour(model, *pass, rays, n, which, w, env);
  if (auto* p = dynamic_cast<method::NeRVPass*>(pass.get())) p->keep_termination = true;
  std::vector<Buffer<float>> d;
  std::vector<const Buffer<float>*> d_ptrs;
  for (std::uint32_t i = 0; i < model.n_colors(); ++i)
    d.emplace_back(dev, i == which ? w : std::vector<float>(w.size(), 0.0f));
  for (auto& b : d) d_ptrs.push_back(&b);
  model.backward(*pass, rays, d_ptrs, training_options(env));
  const auto grads = model.grads().read();
  const auto params = model.params().read();
  test::GradientCheck check;
  check.lo = check.random_lo = lo;
  check.hi = hi;
  test::check_gradient(
      [&](const std::vector<float>& theta) {
        model.params().write(theta);
        return weighted_colour(model, *pass, rays, n, which, w, env);
      },
      params, grads, check);
  model.params().write(params);
}

TEST(NeRV, EnvironmentRenderGradientMatchesFiniteDifferences) {
  // Under an environment: its direct light along the ray and at the bounce points.
  const Device dev = test::test_device();
  Json config = tiny_nerv();
  config["environment"] = {{"enabled", true}, {"n_dirs", 4}, {"n_dirs_training", 4}};
  method::NeRV model(dev, test::smooth_networks(config));
  model.initialize(6);
  model.refresh_density_grid();
  render::EnvironmentSamples env(dev, EnvironmentLight::sky(16, 8, 2, 0.5f, true), 4);
  env.draw(1, 2);
  check_gradients(model, 0, 0, model.n_params(), &env);
}

TEST(Methods, ImagesRenderInTilesOfAnySize) {
  // The last tile of an image is smaller than the others, so the pass's matrices shrink and keep their larger
  // padding: every method renders it (with and without an environment) to finite pixels, and Bi et al.
  // (deterministic at inference) gives the same image for any tiling.
  const Device dev = test::test_device();
  const EnvironmentLight sky = EnvironmentLight::sky(16, 8, 2, 0.5f, true);
  Camera camera = Camera::look_at({0.3f, -3.5f, 1.0f}, {0, 0, 0}, {0, 0, 1}, 0.7f, 9, 7);
  const PointLight light{{2.0f, -2.0f, 3.0f}, {500.0f, 400.0f, 300.0f}};
  for (const std::string m : {"bi", "nerv"}) {
    SCOPED_TRACE(m);
    Json config = m == "bi" ? tiny_bi() : tiny_nerv();
    config["environment"] = {{"enabled", true}, {"n_dirs", 4}};
    const auto model = method::create_model(dev, m, config);
    for (const EnvironmentLight* env : {static_cast<const EnvironmentLight*>(nullptr), &sky}) {
      method::ImageRenderSettings whole, tiles;
      whole.environment = tiles.environment = env;
      whole.tile_rays = 63;
      tiles.tile_rays = 20;  // 20, 20, 20, 3
      const Image a = method::render_image(*model, camera, light, whole);
      const Image b = method::render_image(*model, camera, light, tiles);
      for (float v : b.pixels) ASSERT_TRUE(std::isfinite(v));
      if (m == "bi" && !env) {
        EXPECT_EQ(a.pixels, b.pixels);
      }
    }
  }
}

TEST(Methods, SamplesPerPixelAverageAGridInEachPixel) {
  // spp = 4 rays through the centres of each pixel's 2 x 2 cells: with Bi et al. (deterministic per ray) the
  // image is the 2 x 2 box-filtered image of the same camera at twice the resolution and spp = 1, and it
  // differs from the spp = 1 image at the lower resolution (so the comparison can fail).
  const Device dev = test::test_device();
  const auto model = method::create_model(dev, "bi", tiny_bi());
  const PointLight light{{2.0f, -2.0f, 3.0f}, {500.0f, 400.0f, 300.0f}};
  const int w = 6, h = 4;
  const auto camera = [](int width, int height) {
    return Camera::look_at({0.3f, -2.5f, 0.8f}, {0, 0, 0}, {0, 0, 1}, 0.9f, width, height);
  };
  method::ImageRenderSettings one, four;
  four.spp = 4;
  four.tile_rays = 7;  // tiles that cut through the samples of a row
  const Image fine = method::render_image(*model, camera(2 * w, 2 * h), light, one);
  const Image coarse = method::render_image(*model, camera(w, h), light, one);
  const Image boxed = method::render_image(*model, camera(w, h), light, four);
  double max_err = 0, max_alias = 0, max_value = 0;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      for (int c = 0; c < 3; ++c) {
        double mean = 0;
        for (int dy = 0; dy < 2; ++dy)
          for (int dx = 0; dx < 2; ++dx) mean += fine.pixels[((2 * y + dy) * 2 * w + 2 * x + dx) * 3 + c] / 4.0;
        const std::size_t i = (std::size_t(y) * w + x) * 3 + c;
        max_err = std::max(max_err, std::abs(boxed.pixels[i] - mean));
        max_alias = std::max(max_alias, std::abs(coarse.pixels[i] - mean));
        max_value = std::max(max_value, std::abs(mean));
      }
  EXPECT_LT(max_err, 1e-5 * max_value) << "largest pixel value " << max_value;
  EXPECT_GT(max_alias, 1e-3 * max_value) << "the test scene has no detail below a pixel";
  method::ImageRenderSettings bad;
  bad.spp = 3;
  EXPECT_THROW(method::render_image(*model, camera(w, h), light, bad), InvalidArgument);
  bad.spp = 0;
  EXPECT_THROW(method::render_image(*model, camera(w, h), light, bad), InvalidArgument);
}

// ---- Ours + BRDF -------------------------------------------------------------------------------------------------

TEST(OursBrdf, RenderGradientMatchesFiniteDifferences) {
  // σ, diffuse albedo, roughness and the raw normal through the BRDF renderer, and the l_max = 1 SH head.
  const Device dev = test::test_device();
  const Json model = tiny_ours();
  method::OursBrdf m(dev, test::smooth_networks(model));
  EXPECT_EQ(m.settings().renderer.scattering, "brdf");
  EXPECT_EQ(m.settings().renderer.sh_lmax, 1);
  EXPECT_EQ(m.renderer().prop_cols(), 6u + 3u * 4u + 3u);
  m.initialize(3);
  check_gradients(m, 0, 0, m.n_params());
  Json bad = model;
  bad["renderer"]["closed_form_indirect"] = true;  // no closed form of the BRDF's convolution
  EXPECT_THROW(method::OursBrdf(dev, bad), ConfigError);
}

// ---- Bi et al. ------------------------------------------------------------------------------------------------

TEST(Bi, FineSamplesFollowTheCoarseWeights) {
  // For rays with random σ profiles, the fine samples' values of the expected CDF (the coarse weights spread
  // over their strata, computed here in double) must be uniform: Kolmogorov-Smirnov against U(0, 1). The
  // merged samples are sorted, hold every coarse sample, and their deltas tile [t_near, t_far].
  const Device dev = test::test_device();
  const std::uint32_t n_rays = 64, nc = 32, nf = 64, na = nc + nf;
  const Camera cam = Camera::look_at({0.2f, -3.0f, 0.5f}, {0, 0, 0}, {0, 0, 1}, 0.6f, 8, 8);
  Buffer<float> rays(dev, std::size_t(n_rays) * render::kRayFloats);
  render::image_rays(dev, cam, PointLight{{1, 1, 3}, {100, 100, 100}}, 0, n_rays, rays);
  render::VolumeRendererSettings rs;
  rs.n_samples = nc;
  rs.sh_lmax = -1;
  render::VolumeRenderer coarse(dev, rs);
  Buffer<float> tc(dev, n_rays * nc), dc(dev, n_rays * nc), tf_only(dev, n_rays * nf), t(dev, n_rays * na),
      delta(dev, n_rays * na);
  nn::BatchMatrix pc(dev, n_rays * nc, 3), props(dev, n_rays * nc, coarse.prop_cols()), pos(dev, n_rays * na, 3);
  coarse.sample(rays, n_rays, true, 9, tc, dc, pc);
  std::mt19937 rng(2);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  std::vector<float> host(std::size_t(n_rays) * nc * coarse.prop_cols(), 0.0f);
  for (std::uint32_t r = 0; r < n_rays; ++r) {  // a bump of random height, place and width per ray
    const float c = u(rng), width = 0.05f + 0.3f * u(rng), height = 20.0f * u(rng);
    for (std::uint32_t i = 0; i < nc; ++i) {
      const float x = (i + 0.5f) / nc;
      host[(std::size_t(r) * nc + i) * coarse.prop_cols()] = height * std::exp(-0.5f * std::pow((x - c) / width, 2.0f));
    }
  }
  props.upload_row_major(host);
  method::sample_fine(dev, rays, n_rays, nc, tc, dc, props, nf, true, 4, tf_only, t, delta, pos);
  const auto r_host = rays.read();
  const auto tc_h = tc.read(), dc_h = dc.read(), tf_h = tf_only.read(), t_h = t.read(), d_h = delta.read();
  const auto pos_h = pos.download_row_major();
  std::vector<double> cdf_values;
  for (std::uint32_t r = 0; r < n_rays; ++r) {
    const double tn = r_host[r * render::kRayFloats + render::kRayTNear],
                 tfar = r_host[r * render::kRayFloats + render::kRayTFar];
    if (tfar <= tn) continue;
    std::vector<double> w(nc);
    double T = 1, total = 0;
    for (std::uint32_t i = 0; i < nc; ++i) {
      const double sd = double(host[(std::size_t(r) * nc + i) * coarse.prop_cols()]) * dc_h[r * nc + i];
      w[i] = T * (1 - std::exp(-sd)) + 1e-5;
      T *= std::exp(-sd);
      total += w[i];
    }
    const double h = (tfar - tn) / nc;
    for (std::uint32_t j = 0; j < nf; ++j) {
      const double tj = tf_h[r * nf + j];
      ASSERT_GE(tj, tn - 1e-5);
      ASSERT_LE(tj, tfar + 1e-5);
      const std::uint32_t bin = std::min<std::uint32_t>(nc - 1, std::uint32_t(std::max(0.0, (tj - tn) / h)));
      double F = 0;
      for (std::uint32_t i = 0; i < bin; ++i) F += w[i];
      F += w[bin] * std::clamp((tj - (tn + bin * h)) / h, 0.0, 1.0);
      cdf_values.push_back(F / total);
    }
    // The merge: sorted, the coarse samples all present, deltas summing to the segment, positions on the ray.
    double sum = 0;
    for (std::uint32_t k = 0; k < na; ++k) {
      if (k) {
        ASSERT_LE(t_h[r * na + k - 1], t_h[r * na + k]);
      }
      sum += d_h[r * na + k];
      for (int a = 0; a < 3; ++a)
        ASSERT_NEAR(pos_h[(std::size_t(r) * na + k) * 3 + a],
                    r_host[r * render::kRayFloats + render::kRayOrigin + a] +
                        t_h[r * na + k] * r_host[r * render::kRayFloats + render::kRayDirection + a],
                    1e-4);
    }
    EXPECT_NEAR(sum, tfar - tn, 1e-4);
    for (std::uint32_t i = 0; i < nc; ++i)
      EXPECT_TRUE(std::binary_search(t_h.begin() + r * na, t_h.begin() + (r + 1) * na, tc_h[r * nc + i]));
  }
  ASSERT_GT(cdf_values.size(), 1000u);
  std::sort(cdf_values.begin(), cdf_values.end());
  double ks = 0;
  const double m = double(cdf_values.size());
  for (std::size_t k = 0; k < cdf_values.size(); ++k)
    ks = std::max({ks, std::fabs((k + 1) / m - cdf_values[k]), std::fabs(k / m - cdf_values[k])});
  // The 0.1 % critical value of the KS statistic is 1.95 / sqrt(m); stratification makes it much smaller.
  EXPECT_LT(ks, 1.95 / std::sqrt(m)) << "fine samples do not follow the coarse weights";
  // (Placing the fine samples uniformly in [t_near, t_far] instead gives a statistic of about 0.49 here.)
}

TEST(Bi, GradientsOfBothImagesMatchFiniteDifferences) {
  // θ = [fine net | coarse net]. The fine image depends on the fine net (the sample placement is not
  // differentiated, as NeRF), the coarse image on the coarse net only.
  const Device dev = test::test_device();
  method::NeuralReflectanceField model(dev, test::smooth_networks(tiny_bi()));
  model.initialize(7);
  const std::size_t fine = model.property_network().n_params();
  EXPECT_EQ(model.n_params(), fine + model.coarse_network().n_params());
  EXPECT_EQ(model.n_colors(), 2u);
  {
    SCOPED_TRACE("fine image");
    check_gradients(model, 1, 0, fine);
  }
  {
    SCOPED_TRACE("coarse image");
    check_gradients(model, 0, fine, model.n_params());
  }
}

// ---- NeRV ------------------------------------------------------------------------------------------------------

// Host reference of NeRV's indirect term (kernels/nerv.cl) in double: colour_r += W_r ⊙ E_r, with x_t given
// (a constant of the render loss).
struct NervInputs {
  std::uint32_t n_rays = 8, spr = 16, K = 8, pc = 6, n_env = 3;
  std::vector<float> rays, t, delta, props, dirs, vd, bprops,
      light_vd;                                      // props: n x 6 rows; bprops: (nq + n) x pc rows
  std::vector<float> env_dirs, env_weights, env_vd;  // n_env x 3, n_env x 3, nq n_env x 2 rows
  std::vector<double> x_t;                           // 3 per ray
  float g_scale = 0.95f;
};

double hg(double mu, double g) {
  const double d = 1 + g * g + 2 * g * mu;
  return (1 - g * g) / (4 * M_PI * d * std::sqrt(d));
}

// sum_r dc_r . (W_r ⊙ E_r) for the inputs (props and bprops may be perturbed; x_t stays).
double nerv_indirect_reference(const NervInputs& in, const std::vector<double>& props,
                               const std::vector<double>& bprops, const std::vector<float>& dc) {
  const std::uint32_t nq = in.n_rays * in.K;
  double out = 0;
  for (std::uint32_t r = 0; r < in.n_rays; ++r) {
    const float* ray = &in.rays[r * render::kRayFloats];
    double T = 1, W[3] = {0, 0, 0};
    for (std::uint32_t i = 0; i < in.spr; ++i) {
      const std::size_t s = r * in.spr + i;
      const double a = 1 - std::exp(-props[s * 6] * in.delta[s]);
      for (int c = 0; c < 3; ++c) W[c] += T * a * props[s * 6 + 1 + c];
      T *= 1 - a;
    }
    const double g_t = in.g_scale * bprops[(nq + r) * in.pc + 4];
    double E[3] = {0, 0, 0};
    for (std::uint32_t k = 0; k < in.K; ++k) {
      const std::size_t q = r * in.K + k;
      double w[3], x[3], to_l[3], r2 = 0, mu_l = 0, mu_t = 0;
      for (int a = 0; a < 3; ++a) w[a] = in.dirs[k * 3 + a];
      for (int a = 0; a < 3; ++a) x[a] = std::clamp(in.x_t[r * 3 + a] + in.vd[q * 2 + 1] * w[a], -1.0, 1.0);
      for (int a = 0; a < 3; ++a) to_l[a] = ray[render::kRayLightPosition + a] - x[a], r2 += to_l[a] * to_l[a];
      for (int a = 0; a < 3; ++a)
        mu_l += -w[a] * to_l[a] / std::sqrt(r2), mu_t += -ray[render::kRayDirection + a] * w[a];
      const double g = in.g_scale * bprops[q * in.pc + 4];
      double S[3];
      for (int c = 0; c < 3; ++c) S[c] = hg(mu_l, g) * in.light_vd[q * 2] / r2 * ray[render::kRayLightIntensity + c];
      for (std::uint32_t j = 0; j < in.n_env; ++j) {
        double mu_j = 0;
        for (int a = 0; a < 3; ++a) mu_j += -w[a] * in.env_dirs[j * 3 + a];
        for (int c = 0; c < 3; ++c) S[c] += hg(mu_j, g) * in.env_vd[(q * in.n_env + j) * 2] * in.env_weights[j * 3 + c];
      }
      for (int c = 0; c < 3; ++c) E[c] += hg(mu_t, g_t) * (1 - in.vd[q * 2]) * bprops[q * in.pc + 1 + c] * S[c];
    }
    for (int c = 0; c < 3; ++c) out += dc[r * 3 + c] * W[c] * E[c] * 4 * M_PI / in.K;
  }
  return out;
}

TEST(NeRV, IndirectBounceKernelsMatchAHostReferenceAndFiniteDifferences) {
  // The kernels of the indirect bounce on random inputs (point light and an environment of 3 directions): the colour
  // against a double-precision host reference, and dL/d(albedo, g) at the bounce points and x_t and dL/d(sigma, albedo)
  // along the ray against central differences of that reference.
  const Device dev = test::test_device();
  NervInputs in;
  const std::uint32_t n = in.n_rays * in.spr, nq = in.n_rays * in.K;
  Scene1 sc;
  Buffer<float> rays(dev, std::size_t(in.n_rays) * render::kRayFloats);
  render::image_rays(dev, Camera::look_at({0.3f, -3.5f, 1.0f}, {0, 0, 0}, {0, 0, 1}, 0.5f, 4, 2), sc.light, 0,
                     in.n_rays, rays);
  render::VolumeRendererSettings rs;
  rs.n_samples = in.spr;
  rs.sh_lmax = -1;
  render::VolumeRenderer renderer(dev, rs);
  Buffer<float> t(dev, n), delta(dev, n);
  nn::BatchMatrix positions(dev, n, 3);
  renderer.sample(rays, in.n_rays, true, 4, t, delta, positions);
  in.rays = rays.read();
  in.t = t.read();
  in.delta = delta.read();
  std::mt19937 rng(8);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  in.props.resize(std::size_t(n) * 6);
  for (std::size_t s = 0; s < n; ++s) {
    in.props[s * 6] = 3.0f * u(rng);
    for (int c = 1; c < 4; ++c) in.props[s * 6 + c] = u(rng);
    in.props[s * 6 + 4] = 2.0f * u(rng) - 1.0f;
  }
  in.bprops.resize(std::size_t(nq + in.n_rays) * in.pc);
  for (auto& x : in.bprops) x = u(rng);
  for (std::size_t q = 0; q < nq + in.n_rays; ++q) in.bprops[q * in.pc + 4] = 1.6f * u(rng) - 0.8f;
  in.vd.resize(std::size_t(nq) * 2);
  in.light_vd.resize(std::size_t(nq) * 2);
  for (std::size_t q = 0; q < nq; ++q) {
    in.vd[q * 2] = u(rng), in.vd[q * 2 + 1] = 1.5f * u(rng);
    in.light_vd[q * 2] = u(rng), in.light_vd[q * 2 + 1] = u(rng);
  }
  render::IndirectBasis basis(dev, in.K, -1);
  basis.draw(2, 0);
  in.dirs = basis.dirs().download_row_major();
  // The environment: n_env unit directions with RGB weights, and V toward them from every bounce point.
  render::IndirectBasis env_basis(dev, in.n_env, -1);
  env_basis.draw(5, 1);
  in.env_dirs = env_basis.dirs().download_row_major();
  for (std::uint32_t i = 0; i < 3 * in.n_env; ++i) in.env_weights.push_back(0.5f * u(rng));
  for (std::uint32_t i = 0; i < 2 * nq * in.n_env; ++i) in.env_vd.push_back(u(rng));
  nn::BatchMatrix env_weights(dev, in.n_env, 3), env_vd(dev, nq * in.n_env, 2);
  env_weights.upload_row_major(in.env_weights);
  env_vd.upload_row_major(in.env_vd);
  nn::BatchMatrix props(dev, n, 6), bprops(dev, nq + in.n_rays, in.pc), vd(dev, nq, 2), light_vd(dev, nq, 2),
      net_pos(dev, nq + in.n_rays, 3), light_in(dev, nq, 6), d_bprops(dev, nq + in.n_rays, in.pc), d_props(dev, n, 6);
  props.upload_row_major(in.props);
  bprops.upload_row_major(in.bprops);
  vd.upload_row_major(in.vd);
  light_vd.upload_row_major(in.light_vd);
  Buffer<float> albedo_sum(dev, 4 * in.n_rays), x_t(dev, 4 * in.n_rays), x_b(dev, 4 * nq), indirect(dev, 4 * in.n_rays),
      dw(dev, 4 * in.n_rays), direct(dev, 3 * in.n_rays), color(dev, 3 * in.n_rays);
  direct.fill(0.0f);
  dev.kernel("nerv.cl", "nerv_termination")
      .args(in.n_rays, in.spr, rays, t, delta, props.data(), 6u, albedo_sum, x_t, 0u)
      .launch(in.n_rays, 16);
  dev.kernel("nerv.cl", "nerv_bounce_points")
      .args(in.n_rays, in.K, rays, x_t, basis.dirs().data(), vd.data(), 2u, x_b, net_pos.data(), light_in.data())
      .launch(nq + in.n_rays, 64);
  dev.kernel("nerv.cl", "nerv_indirect")
      .args(in.n_rays, in.K, rays, basis.dirs().data(), x_b, bprops.data(), in.pc, in.g_scale, light_vd.data(), 2u,
            in.n_env, env_basis.dirs().data(), env_weights.data(), env_vd.data(), albedo_sum, direct, color, indirect)
      .launch(in.n_rays, 16);
  // x_t: the expected termination point, in double.
  const auto xt_dev = x_t.read();
  for (std::uint32_t r = 0; r < in.n_rays; ++r) {
    double T = 1, ws = 0, wt = 0;
    for (std::uint32_t i = 0; i < in.spr; ++i) {
      const std::size_t s = r * in.spr + i;
      const double a = 1 - std::exp(-double(in.props[s * 6]) * in.delta[s]);
      ws += T * a, wt += T * a * in.t[s];
      T *= 1 - a;
    }
    for (int a = 0; a < 3; ++a) {
      in.x_t.push_back(in.rays[r * render::kRayFloats + render::kRayOrigin + a] +
                       wt / ws * in.rays[r * render::kRayFloats + render::kRayDirection + a]);
      EXPECT_NEAR(xt_dev[r * 4 + a], in.x_t.back(), 1e-4);
    }
  }
  std::vector<float> ones(3 * in.n_rays, 1.0f), dc(3 * in.n_rays);
  for (auto& x : dc) x = 2.0f * u(rng) - 1.0f;
  const std::vector<double> p0(in.props.begin(), in.props.end()), b0(in.bprops.begin(), in.bprops.end());
  const auto c_dev = color.read();
  for (std::uint32_t r = 0; r < in.n_rays; ++r)
    for (int c = 0; c < 3; ++c) {
      std::vector<float> e(3 * in.n_rays, 0.0f);
      e[r * 3 + c] = 1.0f;
      const double ref = nerv_indirect_reference(in, p0, b0, e);
      EXPECT_NEAR(c_dev[r * 3 + c], ref, 1e-5 + 1e-4 * std::fabs(ref)) << "ray " << r << " channel " << c;
    }
  // Backward.
  Buffer<float> d_color(dev, dc);
  d_props.data().fill(0.0f);
  dev.kernel("nerv.cl", "nerv_indirect_backward")
      .args(in.n_rays, in.K, rays, basis.dirs().data(), x_b, bprops.data(), in.pc, in.g_scale, light_vd.data(), 2u,
            in.n_env, env_basis.dirs().data(), env_weights.data(), env_vd.data(), albedo_sum, indirect, d_color,
            d_bprops.data(), dw)
      .launch(in.n_rays, 16);
  dev.kernel("nerv.cl", "nerv_samples_backward")
      .args(in.n_rays, in.spr, delta, props.data(), 6u, dw, d_props.data())
      .launch(in.n_rays, 16);
  const auto gb = d_bprops.download_row_major(), gp = d_props.download_row_major();
  auto fd = [&](bool bounce, std::size_t idx) {
    std::vector<double> p = p0, b = b0;
    std::vector<double>& v = bounce ? b : p;
    const double h = 1e-4;
    v[idx] += h;
    const double fp = nerv_indirect_reference(in, p, b, dc);
    v[idx] -= 2 * h;
    const double fm = nerv_indirect_reference(in, p, b, dc);
    return (fp - fm) / (2 * h);
  };
  int checked = 0;
  for (std::size_t q = 0; q < nq + in.n_rays; q += 3)
    for (std::uint32_t c : {1u, 2u, 3u, 4u}) {
      if (q >= nq && c != 4) continue;  // x_t contributes its g only
      const double ref = fd(true, q * in.pc + c);
      EXPECT_NEAR(gb[q * in.pc + c], ref, 1e-4 + 1e-3 * std::fabs(ref)) << "bounce row " << q << " column " << c;
      ++checked;
    }
  for (std::size_t s = 0; s < n; s += 5)
    for (std::uint32_t c : {0u, 1u, 2u, 3u}) {
      const double ref = fd(false, s * 6 + c);
      EXPECT_NEAR(gp[s * 6 + c], ref, 1e-4 + 1e-3 * std::fabs(ref)) << "sample " << s << " column " << c;
      ++checked;
    }
  EXPECT_GT(checked, 150);
}

TEST(NeRV, MarchTargetsMatchAHomogeneousSphere) {
  // Visibility and expected termination depth of a homogeneous sphere (sigma 3, radius 0.6, in a 64^3 grid)
  // from inside and outside it, against the closed forms: with chord length L ahead of x,
  // V = exp(-sigma L) and D = t_in + 1/sigma - L exp(-sigma L) / (1 - exp(-sigma L)).
  const Device dev = test::test_device();
  const int res = 64;
  const double sigma = 3.0, radius = 0.6;
  std::vector<float> grid(std::size_t(res) * res * res);
  for (int z = 0; z < res; ++z)
    for (int y = 0; y < res; ++y)
      for (int x = 0; x < res; ++x) {
        const double p[3] = {(x + 0.5) / res * 2 - 1, (y + 0.5) / res * 2 - 1, (z + 0.5) / res * 2 - 1};
        grid[(std::size_t(z) * res + y) * res + x] =
            std::sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]) < radius ? sigma : 0.0;
      }
  Buffer<float> g(dev, grid);
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  const std::uint32_t n = 256;
  std::vector<float> rows(std::size_t(n) * 6);
  for (std::uint32_t s = 0; s < n; ++s) {
    double x[3], w[3], wn = 0;
    for (int a = 0; a < 3; ++a) x[a] = 0.7 * u(rng), w[a] = u(rng), wn += w[a] * w[a];
    for (int a = 0; a < 3; ++a)
      rows[s * 6 + a] = float(0.5 * x[a] + 0.5), rows[s * 6 + 3 + a] = float(w[a] / std::sqrt(wn));
  }
  nn::BatchMatrix in(dev, n, 6), out(dev, n, 2);
  in.upload_row_major(rows);
  dev.kernel("nerv.cl", "nerv_march_targets").args(n, in.data(), g, res, res, res, 512u, out.data(), 0u).launch(n, 64);
  const auto got = out.download_row_major();
  int hits = 0;
  double tau_error = 0;
  for (std::uint32_t s = 0; s < n; ++s) {
    double x[3], w[3];
    for (int a = 0; a < 3; ++a) x[a] = 2.0 * rows[s * 6 + a] - 1.0, w[a] = rows[s * 6 + 3 + a];
    // Ray-sphere: t^2 + 2 b t + c = 0.
    const double b = x[0] * w[0] + x[1] * w[1] + x[2] * w[2];
    const double c = x[0] * x[0] + x[1] * x[1] + x[2] * x[2] - radius * radius;
    const double disc = b * b - c;
    double t_in = 0, L = 0;
    if (disc > 0) {
      const double t0 = -b - std::sqrt(disc), t1 = -b + std::sqrt(disc);
      if (t1 > 0) t_in = std::max(t0, 0.0), L = t1 - t_in;
    }
    if (L < 0.05) continue;  // grazing chords: the voxelised boundary dominates
    ++hits;
    const double V = std::exp(-sigma * L);
    const double D = t_in + 1 / sigma - L * V / (1 - V);
    // The trilinear grid blurs the boundary over a voxel (2/64) at each end of the chord: optical depth within
    // sigma * 2 voxels, and close on average.
    const double tau = -std::log(std::max(double(got[s * 2]), 1e-12));
    EXPECT_NEAR(tau, sigma * L, 0.2) << "sample " << s;
    EXPECT_NEAR(got[s * 2 + 1], D, 0.05) << "sample " << s;
    tau_error += std::fabs(tau - sigma * L);
  }
  EXPECT_GT(hits, 100);
  EXPECT_LT(tau_error / hits, 0.06);
}

TEST(NeRV, RenderGradientMatchesFiniteDifferences) {
  // Direct light and the indirect bounce: through W (density and albedo along the ray) and the albedo and g at
  // the bounce points and at x_t (held fixed: the termination point is a constant for the render loss).
  const Device dev = test::test_device();
  method::NeRV model(dev, test::smooth_networks(tiny_nerv()));
  model.initialize(5);
  model.refresh_density_grid();
  check_gradients(model, 0, 0, model.n_params());
}

// training_visibility "march" with NeRV, whose V_ψ has two outputs (V, D): a training pass takes the direct
// light's V from the density-grid march (it threw for want of a one-column matrix), the same V as a pass asked
// to march; without the key the pass asks the network, which gives other values.
TEST(NeRV, TrainingVisibilityCanMarchTheDensityGrid) {
  const Device dev = test::test_device();
  Json config = tiny_nerv();
  config["initial_density"] = 3.0;  // a grid dense enough to shadow
  auto make = [&](const std::string& training_visibility) {
    Json c = config;
    c["training_visibility"] = training_visibility;
    auto model = method::create_model(dev, "nerv", c);
    model->initialize(2);
    model->refresh_density_grid();
    return model;
  };
  auto marching = make("march"), network = make("network");
  Scene1 sc;
  const std::uint32_t n = 16;
  Buffer<float> rays(dev, std::size_t(n) * render::kRayFloats);
  render::image_rays(dev, sc.camera, sc.light, 0, n, rays);
  auto visibility = [&](method::Model& model, bool march) {
    auto pass = model.make_pass();
    method::PassOptions o = training_options();
    o.march_visibility = march;
    model.render(*pass, rays, n, o);
    const auto v = dynamic_cast<method::MediumPass&>(*pass).vis.download_row_major();
    std::vector<float> first;  // column 0: V toward the point light
    for (std::size_t i = 0; i < v.size(); i += 2) first.push_back(v[i]);
    return first;
  };
  const auto got = visibility(*marching, false), want = visibility(*network, true), net = visibility(*network, false);
  ASSERT_EQ(got.size(), std::size_t(n) * 16);
  EXPECT_EQ(got, want);
  double diff = 0, shadowed = 0;
  for (std::size_t i = 0; i < got.size(); ++i) {
    ASSERT_GE(got[i], 0.0f);
    ASSERT_LE(got[i], 1.0f);
    diff += std::fabs(got[i] - net[i]);
    shadowed += 1.0 - got[i];
  }
  EXPECT_GT(diff, 0.0);
  EXPECT_GT(shadowed / got.size(), 0.05);
}

// ---- the shadow gradient ------------------------------------------------------------------------------------------

// kernels/method.cl shadow_points against a double reference on random samples: each point lies on its
// sample's shadow ray inside the box, its σ gradient is -dL/dV V len scale / points, padding rows are zero,
// and a second launch gives the same bits.
TEST(ShadowGradient, PointsKernelMatchesAHostReference) {
  const Device dev = test::test_device();
  const std::uint32_t n_rays = 5, spr = 16, points = 3, cols = 7, prop_cols = 6;
  const std::uint32_t n = n_rays * spr, rows = n * points;
  Scene1 sc;
  Buffer<float> rays(dev, std::size_t(n_rays) * render::kRayFloats);
  render::image_rays(dev, sc.camera, sc.light, 0, n_rays, rays);
  const auto ray_data = rays.read();
  std::mt19937 rng(13);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  std::vector<float> pos(3 * n), props(prop_cols * n), d_props(prop_cols * n);
  for (auto& x : pos) x = 1.2f * u(rng);  // some samples outside the box
  for (auto& x : props) x = 0.5f + 0.5f * u(rng);
  for (auto& x : d_props) x = u(rng);
  nn::BatchMatrix p(dev, n, 3), pr(dev, n, prop_cols), dp(dev, n, prop_cols), out(dev, rows, 3), d_out(dev, rows, cols);
  p.upload_row_major(pos);
  pr.upload_row_major(props);
  dp.upload_row_major(d_props);
  const float scale = 4.0f;
  auto launch = [&] {
    dev.kernel("method.cl", "shadow_points")
        .args(rows, d_out.padded(), spr, points, 77u, 1u, 2u, scale, rays, p.data(), pr.data(), prop_cols, dp.data(),
              out.data(), d_out.data(), cols)
        .launch(d_out.padded(), 64);
    return std::make_pair(out.data().read(), d_out.data().read());
  };
  const auto first = launch();
  EXPECT_EQ(launch(), first);
  const auto y = out.download_row_major(), g = d_out.download_row_major();
  const auto all = d_out.data().read();
  int on_segment = 0;
  for (std::uint32_t q = 0; q < rows; ++q) {
    const std::uint32_t s = q / points, ray = s / spr;
    double x[3], w[3], dist = 0;
    for (int a = 0; a < 3; ++a) x[a] = pos[3 * s + a];
    for (int a = 0; a < 3; ++a)
      w[a] = ray_data[ray * render::kRayFloats + render::kRayLightPosition + a] - x[a], dist += w[a] * w[a];
    dist = std::sqrt(dist);
    double t0 = -1e30, t1 = 1e30;
    for (int a = 0; a < 3; ++a) {
      w[a] /= dist;
      const double ta = (-1 - x[a]) / w[a], tb = (1 - x[a]) / w[a];
      t0 = std::max(t0, std::min(ta, tb));
      t1 = std::min(t1, std::max(ta, tb));
    }
    const double start = std::max(t0, 0.0), len = t1 >= start ? std::max(std::min(t1, dist) - start, 0.0) : 0.0;
    const double want = -double(d_props[s * prop_cols + 5]) * props[s * prop_cols + 5] * len * scale / points;
    EXPECT_NEAR(g[q * cols], want, 1e-5 * std::abs(want) + 1e-6) << "row " << q;
    for (std::uint32_t f = 1; f < cols; ++f) EXPECT_EQ(g[q * cols + f], 0.0f) << "row " << q << " column " << f;
    if (len <= 0) continue;
    // y = x + t w with start <= t <= start + len, in network coordinates (y + 1) / 2.
    double t = 0;
    for (int a = 0; a < 3; ++a) t += (2.0 * y[q * 3 + a] - 1.0 - x[a]) * w[a];
    EXPECT_GE(t, start - 1e-5) << "row " << q;
    EXPECT_LE(t, start + len + 1e-5) << "row " << q;
    for (int a = 0; a < 3; ++a) EXPECT_NEAR(2.0 * y[q * 3 + a] - 1.0, x[a] + t * w[a], 1e-5) << "row " << q;
    ++on_segment;
  }
  EXPECT_GT(on_segment, int(rows / 2));
  for (std::size_t i = 0; i < all.size(); ++i)  // padding rows of the tiled matrix: zero gradient
    if (i / (std::size_t(cols) * 16) * 16 + i % 16 >= rows) {
      EXPECT_EQ(all[i], 0.0f) << i;
    }
}

// The shadow gradient against finite differences of the whole render loss, V included: the training renders
// march the density grid for V (training_visibility "march"), and every evaluation of the differences refreshes
// the grid from the perturbed θ, so V follows θ as the shadow gradient says it does. Its estimate (random
// points on the shadow rays, integrating the network's σ) differs from the grid march's derivative (trilinear
// σ at voxel centres, midpoint rule) by the discretisation and the sampling noise; the check is that it
// removes most of what the render gradient alone misses, along random directions of θ.
TEST(ShadowGradient, MatchesFiniteDifferencesOfTheMarchedShadow) {
  const Device dev = test::test_device();
  Json config = test::tiny_ours_model("none");
  config["training_visibility"] = "march";
  config["initial_density"] = 3.0;
  config["density_grid"] = {{"resolution", 48}, {"march_steps", 96}};
  auto make = [&](bool shadow) {
    Json c = config;
    c["shadow_gradient"] = {{"enabled", shadow}, {"points", 64}, {"fraction", 1.0}};
    auto model = method::create_model(dev, "ours", test::smooth_networks(c));
    model->initialize(5);
    model->refresh_density_grid();
    return model;
  };
  auto with = make(true), without = make(false);
  ASSERT_EQ(with->params().read(), without->params().read());
  Scene1 sc;
  const std::uint32_t n = 16;
  Buffer<float> rays(dev, std::size_t(n) * render::kRayFloats);
  render::image_rays(dev, sc.camera, sc.light, 0, n, rays);
  std::mt19937 rng(9);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  std::vector<float> w(3 * n);
  for (auto& x : w) x = u(rng);
  auto gradient = [&](method::Model& model) {
    auto pass = model.make_pass();
    weighted_colour(model, *pass, rays, n, 0, w, nullptr);
    Buffer<float> d(dev, w);
    model.backward(*pass, rays, {&d}, training_options());
    return model.grads().read();
  };
  const auto g_with = gradient(*with), g_without = gradient(*without);
  const auto theta = with->params().read();
  auto pass = with->make_pass();
  auto loss = [&](const std::vector<float>& t) {
    with->params().write(t);
    with->refresh_density_grid();
    return weighted_colour(*with, *pass, rays, n, 0, w, nullptr);
  };
  double missed = 0, left = 0;  // over the directions: |fd - g_without . v|, |fd - g_with . v|
  for (int k = 0; k < 6; ++k) {
    std::vector<float> v(theta.size());
    for (auto& x : v) x = u(rng);
    const double h = 1e-3;
    std::vector<float> plus = theta, minus = theta;
    for (std::size_t i = 0; i < v.size(); ++i) plus[i] += float(h) * v[i], minus[i] -= float(h) * v[i];
    const double fd = (loss(plus) - loss(minus)) / (2 * h);
    double d_with = 0, d_without = 0;
    for (std::size_t i = 0; i < v.size(); ++i)
      d_with += double(g_with[i]) * v[i], d_without += double(g_without[i]) * v[i];
    std::cout << "direction " << k << ": differences " << fd << ", render gradient " << d_without
              << ", with the shadow gradient " << d_with << "\n";
    missed += std::abs(fd - d_without);
    left += std::abs(fd - d_with);
  }
  with->params().write(theta);
  EXPECT_GT(missed, 1e-3) << "the shadow must matter in this scene";
  EXPECT_LT(left, 0.1 * missed);  // measured: 0.006
}

// ---- every method trains, checkpoints and reloads ----------------------------------------------------------------

class MethodsTrain : public ::testing::TestWithParam<std::string> {
 protected:
  static void SetUpTestSuite() {
    s_dir = new test::TempDir("baselines");
    const DatasetSettings s = test::tiny_dataset(6, 4);
    generate_dataset(test::test_device(), Scene::from_json(Scene::builtin_json("cloud", 1, 16)), dataset("cloud"), s);
    generate_dataset(test::test_device(), Scene::from_json(Scene::builtin_json("spheres", 1, 16)), dataset("spheres"),
                     s);
  }
  static void TearDownTestSuite() {
    delete s_dir;
    s_dir = nullptr;
  }
  static std::string dataset(const std::string& scene) { return (s_dir->path() / scene).string(); }
  static test::TempDir* s_dir;
};
test::TempDir* MethodsTrain::s_dir = nullptr;

Json tiny_config(const std::string& method) {
  Json model = method == "bi" ? tiny_bi() : method == "nerv" ? tiny_nerv() : tiny_ours();
  // A small hash grid gives the property net the capacity to fit the scene in a few hundred steps.
  model["property"]["encoding"] = {{"type", "HashGrid"},      {"n_levels", 6},        {"n_features_per_level", 2},
                                   {"log2_hashmap_size", 14}, {"base_resolution", 4}, {"per_level_scale", 1.5}};
  if (method == "bi") model["coarse"]["encoding"] = model["property"]["encoding"];
  if (method != "ours") {  // the baselines' and Ours + BRDF's presets: the marched shadow and its gradient
    model["training_visibility"] = "march";
    model["shadow_gradient"] = {{"enabled", true}};
    model["density_grid"] = {{"resolution", 32}, {"march_steps", 32}};  // the scene's 16³ resolved
  }
  // Bi et al. oscillates at Adam's 1e-2 (with the former L2 and isolated V its loss jumped between 0.02 and 1.3
  // from step 200 on); 3e-3 is its preset's rate. Ours + BRDF's fit of the spheres at 1e-2 depends on the MLP
  // kernels' rounding alone (24.6-36.6 dB after 600 steps with four dW reduction orders, 21.9-34.6 after 1000);
  // at 5e-3 it ended at 39.3-44.7 dB with the same four. The others are best at 1e-2. SrgbL2 as the `*-fast`
  // presets.
  const double lr = method == "bi" ? 3e-3 : method == "ours_brdf" ? 5e-3 : 1e-2;
  return {{"method", method},
          {"model", model},
          {"training",
           {{"batch_rays", 256},
            {"validate_every", 100000},
            {"checkpoint_every", 0},
            {"log_every", 50},
            {"validation_views", 1},
            {"loss", {{"type", "SrgbL2"}}},
            {"optimizer", {{"type", "Adam"}, {"learning_rate", lr}, {"epsilon", 1e-15}}}}}};
}

TEST_P(MethodsTrain, TrainsToAStatedPsnrAndReloadsIdentically) {
  // Each method (and Ours, for reference) fits a tiny generated scene (a cloud; spheres for Ours + BRDF) to a
  // stated PSNR, and its checkpoint reloads as a model that renders exactly as the trainer's.
  const std::string method = GetParam();
  const Device dev = test::test_device();
  const std::string ds = dataset(method == "ours_brdf" ? "spheres" : "cloud");
  method::Trainer t(dev, ds, tiny_config(method));
  EXPECT_EQ(t.model().method(), method);
  // PSNR on two training views (what a short training fits; six views do not pin down novel lights).
  const auto views = load_split(ds, "train", 2);
  auto fit_psnr = [&] {
    double sum = 0;
    for (std::size_t i = 0; i < views.size(); ++i) {
      const Image img = method::render_image(t.model(), views.cameras[i], views.lights[i]);
      sum += metrics::compare(dev, img.pixels, views.image(i), views.width, views.height, 3).psnr;
    }
    return sum / views.size();
  };
  const double before = fit_psnr();
  test::TempDir out("run-" + method);
  t.set_output(out.path().string());
  const auto s = t.run(600);
  const double after = fit_psnr();
  std::cout << method << ": training-view PSNR " << before << " -> " << after << " dB\n";
  EXPECT_EQ(s.skipped, 0u);
  EXPECT_GT(after, before + 3.0);
  // Measured (SrgbL2; the baselines with the marched shadow and its gradient, as their presets): Bi et al. 37.6,
  // NeRV 35.1, Ours + BRDF 41.7 (spheres; 21.7-23.0 with L2 and V from its network), Ours 38.0 dB; the bars sit
  // about 3 dB lower. Ours + BRDF's fit of the spheres in 600 steps depends on the rounding of the MLP kernels
  // that run: at Adam's 1e-2 on one Intel Xeon it ended at 28.3, 34.7, 37.9 and 41.7 dB with four kernel
  // variants (separate or fused backward, weight gradients with lanes of samples or of dW columns; all within
  // the gradient tests' tolerances) and on another at 24.6-36.6 dB with four group sizes of the fused kernel;
  // at 5e-3 and 3e-3 at 30.2-42.9 dB, and at 5e-3 (its rate here) at 39.3-44.7 with the four group sizes. Its
  // bar sits below the lowest of these.
  const std::map<std::string, double> bar{{"bi", 34.5}, {"nerv", 32.0}, {"ours_brdf", 28.0}, {"ours", 35.0}};
  EXPECT_GT(after, bar.at(method));
  const auto model = method::load_model(dev, (out.path() / "checkpoint.relit").string());
  EXPECT_EQ(model->method(), method);
  Scene1 sc;
  EXPECT_EQ(method::render_image(*model, sc.camera, sc.light).pixels,
            method::render_image(t.model(), sc.camera, sc.light).pixels);
  // A checkpoint of another method is refused by the trainer.
  Json other = tiny_config(method == "bi" ? "nerv" : "bi");
  method::Trainer wrong(dev, dataset("cloud"), other);
  EXPECT_THROW(wrong.load_checkpoint((out.path() / "checkpoint.relit").string()), Error);
}

INSTANTIATE_TEST_SUITE_P(Baselines, MethodsTrain, ::testing::Values("bi", "nerv", "ours_brdf", "ours"),
                         [](const auto& info) { return info.param; });

TEST(Methods, UnknownMethodsAndMisplacedKeysAreConfigErrors) {
  const Device dev = test::test_device();
  try {
    method::create_model(dev, "nerf", Json::object());
    FAIL() << "unknown method accepted";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("bi"), std::string::npos) << e.what();
  }
  Json bad = tiny_bi();
  bad["bounce"] = {{"n_dirs", 8}};  // NeRV's key
  try {
    method::NeuralReflectanceField m(dev, bad);
    FAIL() << "NeRV's key accepted by Bi et al.";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("/model/bounce"), std::string::npos) << e.what();
  }
  bad = tiny_bi();
  bad["renderer"]["n_fine_samples"] = 20;
  EXPECT_THROW(method::NeuralReflectanceField(dev, bad), ConfigError);
  bad = tiny_nerv();
  bad["visibility"]["trunk"]["output_heads"] = Json::array();
  EXPECT_THROW(method::NeRV(dev, bad), ConfigError);
  Json named = {{"method", "bi"}};
  EXPECT_THROW(method::set_method(named, "nerv", "run.json"), ConfigError);
  method::set_method(named, "bi", "run.json");
  Json unnamed = Json::object();
  method::set_method(unnamed, "nerv", "run.json");
  EXPECT_EQ(unnamed["method"], "nerv");
  EXPECT_EQ(method::config_for_method("fast", "nerv"), "nerv-fast");
  EXPECT_EQ(method::config_for_method("fast", "ours"), "fast");
  EXPECT_EQ(method::config_for_method("run.json", "bi"), "run.json");
  EXPECT_THROW(method::config_for_method("fast", "nerf"), InvalidArgument);
}

}  // namespace
}  // namespace relit
