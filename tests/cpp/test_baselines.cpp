// The baselines of DESIGN §4.5 through the Model interface: Bi et al.'s hierarchical sampling and coarse/fine
// networks, NeRV's visibility/depth network and one-bounce indirect light; gradients against finite
// differences, and short trainings on a tiny generated scene.
#include "test_support.hpp"

#include <relit/dataset.hpp>
#include <relit/method/bi.hpp>
#include <relit/method/trainer.hpp>
#include <relit/render/rays.hpp>

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>

namespace relit {
namespace {

namespace fs = std::filesystem;

const Json kMlp = {{"type", "FullyFusedMLP"}, {"n_neurons", 16}, {"n_hidden_layers", 1}};
const Json kFreq = {{"type", "Frequency"}, {"n_frequencies", 2}, {"include_input", true}};

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

method::PassOptions training_options() {
  method::PassOptions o;
  o.training = true;
  o.seed = 1;
  o.jitter_seed = 3;
  return o;
}

// sum_j w_j colour_j of colour `which` over the rays of the tiny image, in double.
double weighted_colour(method::Model& model, method::ModelPass& pass, Buffer<float>& rays, std::uint32_t n,
                       std::uint32_t which, const std::vector<float>& w) {
  model.render(pass, rays, n, training_options());
  const auto c = model.color(pass, which).read();
  double sum = 0;
  for (std::size_t j = 0; j < w.size(); ++j) sum += double(w[j]) * c[j];
  return sum;
}

// d(sum_j w_j colour_j)/dθ of colour `which` from backward() against central differences, on the 10 largest
// gradients and 10 random parameters of θ[lo, hi); the gradient outside [lo, hi) must be zero.
void check_gradients(method::Model& model, std::uint32_t which, std::size_t lo, std::size_t hi) {
  const Device& dev = model.device();
  Scene1 sc;
  const std::uint32_t n = 16;
  Buffer<float> rays(dev, std::size_t(n) * render::kRayFloats);
  render::image_rays(dev, sc.camera, sc.light, 0, n, rays);
  auto pass = model.make_pass();
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  std::vector<float> w(3 * n);
  for (auto& x : w) x = u(rng);
  weighted_colour(model, *pass, rays, n, which, w);
  std::vector<Buffer<float>> d;
  std::vector<const Buffer<float>*> d_ptrs;
  for (std::uint32_t i = 0; i < model.n_colors(); ++i)
    d.emplace_back(dev, i == which ? w : std::vector<float>(w.size(), 0.0f));
  for (auto& b : d) d_ptrs.push_back(&b);
  model.backward(*pass, rays, d_ptrs, training_options());
  const auto grads = model.grads().read();
  auto params = model.params().read();
  ASSERT_EQ(grads.size(), params.size());
  double max_g = 0;
  for (std::size_t i = lo; i < hi; ++i) max_g = std::max(max_g, double(std::fabs(grads[i])));
  ASSERT_GT(max_g, 0.0);
  for (std::size_t i = 0; i < grads.size(); ++i)
    if (i < lo || i >= hi) ASSERT_EQ(grads[i], 0.0f) << "parameter " << i << " outside the checked block";
  std::vector<std::size_t> order;
  for (std::size_t i = lo; i < hi; ++i) order.push_back(i);
  std::partial_sort(order.begin(), order.begin() + 10, order.end(),
                    [&](std::size_t a, std::size_t b) { return std::fabs(grads[a]) > std::fabs(grads[b]); });
  std::vector<std::size_t> picks(order.begin(), order.begin() + 10);
  for (int k = 0; k < 10; ++k) picks.push_back(lo + rng() % (hi - lo));
  for (std::size_t i : picks) {
    const float p0 = params[i];
    const float h = 1e-2f * std::max(1.0f, std::fabs(p0));
    params[i] = p0 + h;
    model.params().write(params);
    const double fp = weighted_colour(model, *pass, rays, n, which, w);
    params[i] = p0 - h;
    model.params().write(params);
    const double fm = weighted_colour(model, *pass, rays, n, which, w);
    params[i] = p0;
    model.params().write(params);
    const double fd = (fp - fm) / (2.0 * h);
    EXPECT_NEAR(grads[i], fd, 2e-2 * max_g + 2e-2 * std::fabs(fd)) << "parameter " << i;
  }
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
  render::RendererSettings rs;
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
    const double tn = r_host[r * render::kRayFloats + 3], tfar = r_host[r * render::kRayFloats + 7];
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
      if (k) ASSERT_LE(t_h[r * na + k - 1], t_h[r * na + k]);
      sum += d_h[r * na + k];
      for (int a = 0; a < 3; ++a)
        ASSERT_NEAR(pos_h[(std::size_t(r) * na + k) * 3 + a],
                    r_host[r * render::kRayFloats + a] + t_h[r * na + k] * r_host[r * render::kRayFloats + 4 + a], 1e-4);
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
  method::NeuralReflectanceField model(dev, tiny_bi());
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

}  // namespace
}  // namespace relit
