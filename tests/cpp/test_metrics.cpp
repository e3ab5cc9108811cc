// PSNR and SSIM against a double-precision reference, and known answers.
#include "test_support.hpp"

#include <relit/metrics.hpp>

#include <cmath>
#include <random>

namespace relit {

namespace {

double srgb(double x) {
  x = std::min(std::max(x, 0.0), 1.0);
  return x <= 0.0031308 ? 12.92 * x : 1.055 * std::pow(x, 1 / 2.4) - 0.055;
}

// Wang et al. 2004 with an 11x11 Gaussian (sigma 1.5): the SSIM of every interior pixel (x, y), summed over the
// channels, at (y - 5) * (w - 10) + x - 5.
std::vector<double> reference_ssim_map(const std::vector<float>& a, const std::vector<float>& b, int w, int h, int ch) {
  double taps[11], norm = 0;
  for (int i = -5; i <= 5; ++i) norm += taps[i + 5] = std::exp(-0.5 * i * i / 2.25);
  std::vector<double> out;
  for (int y = 5; y < h - 5; ++y)
    for (int x = 5; x < w - 5; ++x) {
      double pixel = 0;
      for (int c = 0; c < ch; ++c) {
        double ma = 0, mb = 0, saa = 0, sbb = 0, sab = 0;
        for (int dy = -5; dy <= 5; ++dy)
          for (int dx = -5; dx <= 5; ++dx) {
            const double wt = taps[dy + 5] * taps[dx + 5] / (norm * norm);
            const std::size_t i = (std::size_t(y + dy) * w + (x + dx)) * ch + c;
            const double va = srgb(a[i]), vb = srgb(b[i]);
            ma += wt * va;
            mb += wt * vb;
            saa += wt * va * va;
            sbb += wt * vb * vb;
            sab += wt * va * vb;
          }
        const double C1 = 1e-4, C2 = 9e-4;
        pixel += ((2 * ma * mb + C1) * (2 * (sab - ma * mb) + C2)) /
                 ((ma * ma + mb * mb + C1) * (saa - ma * ma + sbb - mb * mb + C2));
      }
      out.push_back(pixel);
    }
  return out;
}

double reference_ssim(const std::vector<float>& a, const std::vector<float>& b, int w, int h, int ch) {
  double total = 0;
  for (double v : reference_ssim_map(a, b, w, h, ch)) total += v;
  return total / (double(h - 10) * (w - 10) * ch);
}

}  // namespace

TEST(Metrics, MatchDoubleReferenceOnRandomImages) {
  const Device d = test::test_device();
  const int w = 37, h = 23, ch = 3;
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(-0.2f, 1.3f), noise(-0.1f, 0.1f);
  std::vector<float> a(w * h * ch), b(w * h * ch);
  for (std::size_t i = 0; i < a.size(); ++i) {
    a[i] = u(rng);
    b[i] = a[i] + noise(rng);
  }
  const auto m = metrics::compare(d, a, b, w, h, ch);
  double mse = 0;
  for (std::size_t i = 0; i < a.size(); ++i) mse += (srgb(a[i]) - srgb(b[i])) * (srgb(a[i]) - srgb(b[i]));
  mse /= a.size();
  EXPECT_NEAR(m.mse, mse, 1e-6 * mse);
  EXPECT_NEAR(m.psnr, 10 * std::log10(1 / mse), 1e-4);
  EXPECT_NEAR(m.ssim, reference_ssim(a, b, w, h, ch), 1e-5);
}

// The object metrics against the double reference: a random mask, HDR values (some clip), 4 channels.
TEST(Metrics, ObjectMetricsMatchDoubleReferenceOnRandomImages) {
  const Device d = test::test_device();
  const int w = 29, h = 41, ch = 3;
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> u(0.0f, 2.5f), noise(-0.2f, 0.2f), coin(0, 1);
  std::vector<float> a(w * h * ch), b(w * h * ch), ref_alpha(w * h), pred_alpha(w * h);
  for (std::size_t i = 0; i < a.size(); ++i) {
    b[i] = u(rng);
    a[i] = std::max(0.0f, b[i] + noise(rng));
  }
  for (int p = 0; p < w * h; ++p) {
    ref_alpha[p] = coin(rng) < 0.3f ? coin(rng) : 0.0f;
    pred_alpha[p] = coin(rng) < 0.1f ? 0.5f : 0.005f;  // 0.005: below the threshold
  }
  const auto mask = metrics::object_mask(ref_alpha, pred_alpha, w * h);
  const auto m = metrics::compare(d, a, b, w, h, ch, &mask);
  double se = 0, rel = 0, ssim = 0;
  std::size_t pixels = 0, clipped = 0, interior = 0, prediction_only = 0;
  const auto ssim_map = reference_ssim_map(a, b, w, h, ch);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const int p = y * w + x;
      // 1 where the reference's alpha marks the object, 2 where only the prediction's does, 0 elsewhere.
      ASSERT_EQ(mask[p], ref_alpha[p] > 0.01f ? 1 : pred_alpha[p] > 0.01f ? 2 : 0);
      if (!mask[p]) continue;
      ++pixels;
      prediction_only += mask[p] == 2;
      bool clips = false;
      for (int c = 0; c < ch; ++c) {
        const double pa = a[p * ch + c], pb = b[p * ch + c];
        se += (srgb(pa) - srgb(pb)) * (srgb(pa) - srgb(pb));
        rel += (pa - pb) * (pa - pb) / (pb * pb + 0.01);
        clips = clips || pb > 1;
      }
      clipped += clips;
      if (x >= 5 && x < w - 5 && y >= 5 && y < h - 5) {
        ssim += ssim_map[std::size_t(y - 5) * (w - 10) + (x - 5)];
        ++interior;
      }
    }
  ASSERT_GT(pixels, 100u);
  ASSERT_GT(clipped, 10u);
  EXPECT_EQ(m.object.pixels, pixels);
  EXPECT_DOUBLE_EQ(m.object.fraction, double(pixels) / (w * h));
  const double mse = se / (pixels * ch);
  EXPECT_NEAR(m.object.mse, mse, 1e-6 * mse);
  EXPECT_NEAR(m.object.psnr, 10 * std::log10(1 / mse), 1e-4);
  EXPECT_NEAR(m.object.ssim, ssim / (interior * ch), 1e-5);
  EXPECT_NEAR(m.object.rel_mse, rel / (pixels * ch), 1e-5 * rel / (pixels * ch));
  EXPECT_DOUBLE_EQ(m.object.clipped, double(clipped) / pixels);
  ASSERT_GT(prediction_only, 10u);
  EXPECT_DOUBLE_EQ(m.object.prediction_only, double(prediction_only) / pixels);
  // The whole-image numbers do not depend on the mask.
  const auto whole = metrics::compare(d, a, b, w, h, ch);
  EXPECT_EQ(whole.psnr, m.psnr);
  EXPECT_EQ(whole.ssim, m.ssim);
  EXPECT_EQ(whole.object.pixels, 0u);
  EXPECT_TRUE(std::isnan(whole.object.psnr));
}

// An object on a matching background: the image's PSNR is mostly background, the object's is its own.
TEST(Metrics, ObjectPsnrIsTheObjectsOwn) {
  const Device d = test::test_device();
  const int w = 32, h = 32;
  std::vector<float> ref(w * h, 0.0f), pred(w * h, 0.0f), alpha(w * h, 0.0f);
  auto linear_of = [](double s) { return float(std::pow((s + 0.055) / 1.055, 2.4)); };
  for (int y = 12; y < 20; ++y)
    for (int x = 12; x < 20; ++x) {  // 64 of 1024 pixels, off by 0.1 in sRGB
      ref[y * w + x] = linear_of(0.5);
      pred[y * w + x] = linear_of(0.6);
      alpha[y * w + x] = 1.0f;
    }
  const auto mask = metrics::object_mask(alpha, {}, w * h);
  const auto m = metrics::compare(d, pred, ref, w, h, 1, &mask);
  EXPECT_NEAR(m.object.psnr, 20.0, 1e-3);
  EXPECT_NEAR(m.psnr, 20.0 + 10 * std::log10(1024.0 / 64.0), 1e-3);  // 32.04 dB: the background is exact
  EXPECT_EQ(m.object.pixels, 64u);
  EXPECT_DOUBLE_EQ(m.object.clipped, 0.0);
  EXPECT_DOUBLE_EQ(m.object.prediction_only, 0.0);
  // A haze the prediction adds around the object (alpha 0.02, no radiance): the mask grows by the prediction-only
  // pixels, which the object metrics then average over (the error is the same, spread over more pixels), and
  // prediction_only says how much of the mask they are.
  std::vector<float> haze(w * h, 0.02f);
  const auto hazy = metrics::object_mask(alpha, haze, w * h);
  const auto diluted = metrics::compare(d, pred, ref, w, h, 1, &hazy);
  EXPECT_EQ(diluted.object.pixels, 1024u);
  EXPECT_DOUBLE_EQ(diluted.object.prediction_only, 960.0 / 1024.0);
  EXPECT_NEAR(diluted.object.psnr, m.psnr, 1e-3);
  // An empty mask: no object metrics; a mask of the wrong size or alphas of the wrong size: errors.
  const std::vector<std::uint8_t> none(w * h, 0), short_mask(10, 1);
  EXPECT_TRUE(std::isnan(metrics::compare(d, pred, ref, w, h, 1, &none).object.rel_mse));
  EXPECT_THROW(metrics::compare(d, pred, ref, w, h, 1, &short_mask), InvalidArgument);
  EXPECT_THROW(metrics::object_mask(alpha, std::vector<float>(5), w * h), InvalidArgument);
  EXPECT_EQ(metrics::object_mask({}, {}, 4), std::vector<std::uint8_t>(4, 0));
}

TEST(Metrics, KnownAnswers) {
  const Device d = test::test_device();
  const int w = 16, h = 16;
  std::vector<float> grey(w * h, 0.5f), same = grey;
  auto m = metrics::compare(d, grey, same, w, h, 1);
  EXPECT_EQ(m.mse, 0.0);
  EXPECT_TRUE(std::isinf(m.psnr));
  EXPECT_NEAR(m.ssim, 1.0, 1e-6);
  // Black against white: sRGB difference 1 everywhere → MSE 1, PSNR 0 dB. Values above 1 clamp to white.
  std::vector<float> black(w * h, 0.0f), white(w * h, 7.0f);
  m = metrics::compare(d, black, white, w, h, 1);
  EXPECT_NEAR(m.mse, 1.0, 1e-7);
  EXPECT_NEAR(m.psnr, 0.0, 1e-5);
  // Constant images: SSIM = (2 mu_a mu_b + C1) / (mu_a^2 + mu_b^2 + C1) = C1 / (1 + C1).
  EXPECT_NEAR(m.ssim, 1e-4 / (1 + 1e-4), 1e-7);
  // A uniform offset of 0.1 in sRGB: PSNR = 20 dB.
  std::vector<float> lo(w * h), hi(w * h);
  for (int i = 0; i < w * h; ++i) {
    lo[i] = 0.2f;
    hi[i] = 0.2f;
  }
  // Pick linear values whose sRGB encodings are 0.5 and 0.6.
  auto linear_of = [](double s) { return float(std::pow((s + 0.055) / 1.055, 2.4)); };
  std::fill(lo.begin(), lo.end(), linear_of(0.5));
  std::fill(hi.begin(), hi.end(), linear_of(0.6));
  EXPECT_NEAR(metrics::compare(d, lo, hi, w, h, 1).psnr, 20.0, 1e-3);
}

TEST(Metrics, BadInputsAreErrors) {
  const Device d = test::test_device();
  std::vector<float> a(10 * 10 * 3, 0.f), b(10 * 10 * 3, 0.f);
  EXPECT_THROW(metrics::compare(d, a, b, 10, 10, 3), InvalidArgument);  // smaller than the SSIM window
  std::vector<float> c(12 * 12 * 3, 0.f), e(12 * 12 * 3, 0.f);
  EXPECT_THROW(metrics::compare(d, c, a, 12, 12, 3), InvalidArgument);  // size mismatch
  e[5] = std::nanf("");
  EXPECT_THROW(metrics::compare(d, c, e, 12, 12, 3), InvalidArgument);
}

}  // namespace relit
