// EnvironmentSamples, the environment light of the neural renderer: its draws follow the map's pdf, their
// weights are E / (pdf N_e) of the host map and sum to an unbiased estimate of the map's integral, draws are
// reproducible per (seed, iteration), and the background radiance matches the host lookup.
#include "test_support.hpp"

#include <relit/render/environment.hpp>
#include <relit/render/volume_renderer.hpp>

#include <cmath>
#include <random>

namespace relit {

using render::EnvironmentSamples;
using render::kRayFloats;

namespace {

using test::kPi;

// A sky with a small bright sun: a strongly non-uniform pdf.
EnvironmentLight test_sky(bool visible) { return EnvironmentLight::sky(32, 16, 3, 0.8f, visible); }

// The integral of the map's radiance over the sphere, texel by texel (nearest-texel lookup).
std::array<double, 3> map_integral(const EnvironmentLight& light) {
  const Image& img = light.image();
  std::array<double, 3> total{0, 0, 0};
  for (int y = 0; y < img.height; ++y) {
    const double solid_angle =
        2 * kPi / img.width * (std::cos(kPi * y / img.height) - std::cos(kPi * (y + 1) / img.height));
    for (int x = 0; x < img.width; ++x)
      for (int c = 0; c < 3; ++c) total[c] += img.at(x, y, c) * light.scale() * solid_angle;
  }
  return total;
}

int texel_of(const EnvironmentLight& light, const float* d) {
  const int w = light.image().width, h = light.image().height;
  double phi = std::atan2(double(d[1]), double(d[0]));
  if (phi < 0) phi += 2 * kPi;
  const int x = std::min(int(phi / (2 * kPi) * w), w - 1);
  const int y = std::min(int(std::acos(std::clamp(double(d[2]), -1.0, 1.0)) / kPi * h), h - 1);
  return y * w + x;
}

}  // namespace

TEST(EnvironmentSamples, DrawsFollowTheMapPdfAndWeightsAreRadianceOverPdf) {
  const Device dev = test::test_device();
  const EnvironmentLight light = test_sky(false);
  const std::uint32_t n_env = 32, n_draws = 600;
  EnvironmentSamples env(dev, light, n_env);
  const int w = light.image().width, h = light.image().height;
  std::vector<double> count(std::size_t(w) * h, 0.0);
  std::array<double, 3> sum{0, 0, 0}, sum_sq{0, 0, 0};
  int mismatched = 0;
  for (std::uint32_t it = 0; it < n_draws; ++it) {
    env.draw(5, it);
    const auto dirs = env.dirs().download_row_major(), weights = env.weights().download_row_major();
    std::array<double, 3> draw_sum{0, 0, 0};
    for (std::uint32_t j = 0; j < n_env; ++j) {
      const float* d = &dirs[3 * j];
      ASSERT_NEAR(std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]), 1.0, 1e-5);
      count[texel_of(light, d)] += 1;
      const Float3 dir{d[0], d[1], d[2]};
      const Float3 e = light.radiance(dir);
      const double pdf = light.pdf(dir);
      for (int c = 0; c < 3; ++c) {
        const double expected = e[c] / (pdf * n_env);
        // A draw on a texel border may fall on either side in float and double; those are rare.
        if (std::abs(weights[3 * j + c] - expected) > 1e-4 * expected + 1e-7) ++mismatched;
        draw_sum[c] += weights[3 * j + c];
      }
    }
    for (int c = 0; c < 3; ++c) sum[c] += draw_sum[c], sum_sq[c] += draw_sum[c] * draw_sum[c];
  }
  EXPECT_LE(mismatched, int(3 * n_env * n_draws / 1000)) << "weights must be E / (pdf N_e) of the host map";
  // Pooled over draws, the texel histogram follows pdf_uv / (w h) (chi-square; rare texels pooled).
  double chi2 = 0, pooled_c = 0, pooled_e = 0;
  int bins = 0;
  const double total = double(n_env) * n_draws;
  for (std::size_t t = 0; t < count.size(); ++t) {
    const double e = total * light.pdf_uv()[t] / (w * h);
    if (e < 10) {
      pooled_c += count[t], pooled_e += e;
      continue;
    }
    chi2 += (count[t] - e) * (count[t] - e) / e;
    ++bins;
  }
  if (pooled_e > 0) chi2 += (pooled_c - pooled_e) * (pooled_c - pooled_e) / pooled_e, ++bins;
  ASSERT_GT(bins, 50);
  EXPECT_LT(chi2, bins - 1 + 6 * std::sqrt(2.0 * (bins - 1)));
  // Each draw's weights sum to an unbiased estimate of the integral of E over the sphere.
  const auto integral = map_integral(light);
  for (int c = 0; c < 3; ++c) {
    const double mean = sum[c] / n_draws;
    const double se = std::sqrt(std::max(sum_sq[c] / n_draws - mean * mean, 0.0) / n_draws);
    EXPECT_NEAR(mean, integral[c], 4 * se + 1e-4 * integral[c]) << "channel " << c;
    EXPECT_LT(se, 0.02 * integral[c]) << "channel " << c;
  }
}

TEST(EnvironmentSamples, DrawsAreReproduciblePerSeedAndIteration) {
  const Device dev = test::test_device();
  EnvironmentSamples env(dev, test_sky(false), 32);
  env.draw(1, 7);
  const auto first = env.dirs().download_row_major(), first_w = env.weights().download_row_major();
  env.draw(1, 8);
  EXPECT_NE(env.dirs().download_row_major(), first);
  env.draw(2, 7);
  EXPECT_NE(env.dirs().download_row_major(), first);
  env.draw(1, 7);
  EXPECT_EQ(env.dirs().download_row_major(), first);
  EXPECT_EQ(env.weights().download_row_major(), first_w);
}

TEST(EnvironmentSamples, BackgroundIsTheMapRadianceWhenVisibleElseZero) {
  const Device dev = test::test_device();
  const std::uint32_t n_rays = 300;
  std::mt19937 rng(8);
  std::normal_distribution<float> nd;
  std::vector<float> rays(n_rays * kRayFloats, 7.0f);  // stale values everywhere, to see them overwritten
  for (std::uint32_t r = 0; r < n_rays; ++r) {
    float d[3] = {nd(rng), nd(rng), nd(rng)};
    const float len = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    for (int a = 0; a < 3; ++a) rays[r * kRayFloats + render::kRayDirection + a] = d[a] / len;
  }
  for (const bool visible : {true, false}) {
    const EnvironmentLight light = test_sky(visible);
    EnvironmentSamples env(dev, light, 4);
    Buffer<float> buf(dev, rays);
    env.fill_background(buf, n_rays);
    const auto got = buf.read();
    int mismatched = 0;
    for (std::uint32_t r = 0; r < n_rays; ++r) {
      const float* rec = &got[r * kRayFloats];
      const Float3 e =
          light.radiance({rec[render::kRayDirection], rec[render::kRayDirection + 1], rec[render::kRayDirection + 2]});
      for (int c = 0; c < 3; ++c) {
        const float expected = visible ? e[c] : 0.0f;
        if (std::abs(rec[render::kRayBackground + c] - expected) > 1e-5f * expected) ++mismatched;
      }
      for (std::uint32_t f = 0; f < render::kRayBackground; ++f)
        ASSERT_EQ(rec[f], rays[r * kRayFloats + f]) << "ray " << r << " float " << f;
      ASSERT_EQ(rec[render::kRayBackground + 3], 7.0f);
    }
    EXPECT_LE(mismatched, 3) << "visible " << visible;  // a direction on a texel border may round either way
  }
}

TEST(EnvironmentSamples, BadInputIsAnError) {
  const Device dev = test::test_device();
  EXPECT_THROW(EnvironmentSamples(dev, EnvironmentLight(), 32), InvalidArgument);
  const EnvironmentLight light = EnvironmentLight::uniform({1, 1, 1}, true);
  EXPECT_THROW(EnvironmentSamples(dev, light, 0), InvalidArgument);
  EXPECT_THROW(EnvironmentSamples(dev, light, 100000), InvalidArgument);
  EnvironmentSamples env(dev, light, 8);
  Buffer<float> small(dev, kRayFloats);
  EXPECT_THROW(env.fill_background(small, 2), InvalidArgument);
}

}  // namespace relit
