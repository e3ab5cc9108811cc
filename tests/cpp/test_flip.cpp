// FLIP and HDR-FLIP (kernels/flip.cl) against the double-precision 2-D reference (relit/verify/flip_reference.hpp)
// on random images, and known answers. NVIDIA's flip-evaluator checks them on real renders
// (tests/python/test_flip.py).
#include "test_support.hpp"

#include <relit/metrics.hpp>
#include <relit/verify/flip_reference.hpp>

#include <cfloat>
#include <cmath>
#include <random>

namespace relit {

namespace {

// Random images: blocks on a gradient with per-pixel noise and a few outliers in the test image; HDR (values up
// to ~8 scale, highlights) when `scale` > 1.
std::pair<std::vector<float>, std::vector<float>> random_pair(int w, int h, int ch, float scale, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(0.0f, 1.0f), noise(-0.15f, 0.15f);
  std::vector<float> ref(std::size_t(w) * h * ch), test(ref.size());
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      for (int c = 0; c < ch; ++c) {
        const std::size_t i = (std::size_t(y) * w + x) * ch + c;
        const float base = ((x / 6 + y / 5 + c) % 3 == 0 ? 0.8f : 0.2f) + 0.3f * float(x) / w;
        const float bright = scale > 1 && (x / 7 + y / 4) % 4 == 0 ? 8.0f : 1.0f;  // HDR: highlights 3 stops up
        ref[i] = scale * bright * base * (0.5f + u(rng));
        test[i] = std::max(0.0f, ref[i] * (1.0f + noise(rng)) + (u(rng) < 0.05f ? scale * 0.5f : 0.0f));
      }
  return {test, ref};
}

void expect_map_near(const std::vector<float>& got, const std::vector<double>& want, double tol) {
  ASSERT_EQ(got.size(), want.size());
  double worst = 0, mean_got = 0, mean_want = 0;
  for (std::size_t p = 0; p < got.size(); ++p) {
    worst = std::max(worst, std::fabs(got[p] - want[p]));
    mean_got += got[p];
    mean_want += want[p];
  }
  EXPECT_LT(worst, tol);
  EXPECT_NEAR(mean_got / got.size(), mean_want / want.size(), 1e-5);
}

}  // namespace

TEST(Flip, LdrMatchesDoubleReferenceOnRandomImages) {
  const Device d = test::test_device();
  const int w = 37, h = 29;
  const auto [test, ref] = random_pair(w, h, 3, 1.0f, 3);
  metrics::FlipOptions o;
  o.range = metrics::FlipRange::ldr;
  const auto f = metrics::flip(d, test, ref, w, h, 3, o);
  EXPECT_EQ(f.exposures.count, 1u);
  const auto want = reference::flip_map(test, ref, w, h, 3, metrics::kFlipPixelsPerDegree, false);
  expect_map_near(f.error, want, 2e-4);
  EXPECT_GT(f.mean, 0.05);
}

TEST(Flip, HdrMatchesDoubleReferenceOnRandomImages) {
  const Device d = test::test_device();
  const int w = 31, h = 23;
  const auto [test, ref] = random_pair(w, h, 3, 6.0f, 5);
  const auto f = metrics::flip(d, test, ref, w, h, 3);
  const auto e = reference::flip_exposures(ref, w, h, 3);
  EXPECT_NEAR(f.exposures.start, e.start, 1e-12);
  EXPECT_NEAR(f.exposures.stop, e.stop, 1e-12);
  EXPECT_EQ(int(f.exposures.count), e.count);
  EXPECT_GE(e.count, 3);
  const auto want =
      reference::flip_map(test, ref, w, h, 3, metrics::kFlipPixelsPerDegree, true, e.start, e.stop, e.count);
  expect_map_near(f.error, want, 2e-4);
}

// Given exposures, another viewing distance (a feature radius larger than the CSF's), one grey channel and RGBA.
TEST(Flip, HdrOptionsGreyAndAlphaMatchDoubleReference) {
  const Device d = test::test_device();
  const int w = 26, h = 21;
  metrics::FlipOptions o;
  o.pixels_per_degree = 30.0;
  o.start_exposure = -2.0;
  o.stop_exposure = 1.5;
  o.exposures = 3;
  for (int ch : {1, 4}) {
    const auto [test, ref] = random_pair(w, h, ch, 3.0f, 7 + ch);
    const auto f = metrics::flip(d, test, ref, w, h, ch, o);
    EXPECT_EQ(f.exposures.count, 3u);
    const auto want = reference::flip_map(test, ref, w, h, ch, 30.0, true, -2.0, 1.5, 3);
    expect_map_near(f.error, want, 2e-4);
  }
}

TEST(Flip, KnownAnswers) {
  const Device d = test::test_device();
  const int w = 16, h = 12;
  // The same image: no error anywhere.
  const auto [test, ref] = random_pair(w, h, 3, 4.0f, 1);
  const auto same = metrics::flip(d, ref, ref, w, h, 3);
  for (float v : same.error) EXPECT_EQ(v, 0.0f);
  EXPECT_EQ(same.mean, 0.0);
  // A constant reference: Y_max = Y_median, so start = stop and two exposures; x_max solves ACES(x) = 0.85.
  std::vector<float> grey(w * h * 3, 0.5f);
  const auto e = metrics::flip_exposures(grey, w, h, 3);
  EXPECT_DOUBLE_EQ(e.start, e.stop);
  EXPECT_EQ(e.count, 2u);
  const double x = 0.5 * std::exp2(e.start), x2 = x * x;
  EXPECT_NEAR((0.9036 * x2 + 0.018 * x) / (0.8748 * x2 + 0.354 * x + 0.14), 0.85, 1e-12);
  // Mostly black: the median is 0, floored at FLT_EPSILON (as flip-evaluator 1.7 does): a stop near 24.
  const auto lit = [&](int pixels) {
    std::vector<float> img(w * h * 3, 0.0f);
    std::fill(img.begin(), img.begin() + 3 * pixels, 1.0f);
    return img;
  };
  EXPECT_DOUBLE_EQ(metrics::flip_exposures(lit(w * h * 3 / 4), w, h, 3).stop, e.stop - 1.0);  // median 1 = 2 x 0.5
  const auto black = metrics::flip_exposures(lit(w * h / 4), w, h, 3);
  EXPECT_NEAR(black.stop, std::log2(0.5 * std::exp2(e.start) / FLT_EPSILON), 1e-9);
  // Black against white at any exposure: the largest colour error, 1, with no features (flat images).
  std::vector<float> zero(w * h * 3, 0.0f), white(w * h * 3, 1.0f);
  metrics::FlipOptions ldr;
  ldr.range = metrics::FlipRange::ldr;
  const auto bw = metrics::flip(d, zero, white, w, h, 3, ldr);
  EXPECT_GT(bw.mean, 0.9);
  EXPECT_LE(bw.mean, 1.0);
}

TEST(Flip, CompareReportsItOverTheImageAndTheObject) {
  const Device d = test::test_device();
  const int w = 24, h = 20;
  const auto [test, ref] = random_pair(w, h, 3, 2.0f, 11);
  std::vector<std::uint8_t> mask(w * h, 0);
  for (int p = 0; p < w * h; p += 3) mask[p] = 1;
  const auto m = metrics::compare(d, test, ref, w, h, 3, &mask);
  const auto f = metrics::flip(d, test, ref, w, h, 3);
  EXPECT_EQ(m.flip, f.mean);
  double sum = 0;
  int n = 0;
  for (int p = 0; p < w * h; ++p)
    if (mask[p]) sum += f.error[p], ++n;
  EXPECT_DOUBLE_EQ(m.object.flip, sum / n);
  EXPECT_TRUE(std::isnan(metrics::compare(d, test, ref, w, h, 3).object.flip));
}

TEST(Flip, BadInputsAreErrors) {
  const Device d = test::test_device();
  std::vector<float> a(8 * 8 * 3, 0.5f), b(8 * 8 * 3, 0.5f), small(10, 0.5f);
  EXPECT_THROW(metrics::flip(d, a, small, 8, 8, 3), InvalidArgument);
  metrics::FlipOptions o;
  o.pixels_per_degree = 0;
  EXPECT_THROW(metrics::flip(d, a, b, 8, 8, 3, o), InvalidArgument);
  o = {};
  o.start_exposure = 2;
  o.stop_exposure = 1;
  EXPECT_THROW(metrics::flip(d, a, b, 8, 8, 3, o), InvalidArgument);
  b[4] = std::nanf("");
  EXPECT_THROW(metrics::flip(d, a, b, 8, 8, 3), InvalidArgument);
}

}  // namespace relit
