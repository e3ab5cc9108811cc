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

// Wang et al. 2004 with an 11x11 Gaussian (sigma 1.5), interior pixels only, mean over channels.
double reference_ssim(const std::vector<float>& a, const std::vector<float>& b, int w, int h, int ch) {
  double taps[11], norm = 0;
  for (int i = -5; i <= 5; ++i) norm += taps[i + 5] = std::exp(-0.5 * i * i / 2.25);
  double total = 0;
  for (int y = 5; y < h - 5; ++y)
    for (int x = 5; x < w - 5; ++x)
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
        total += ((2 * ma * mb + C1) * (2 * (sab - ma * mb) + C2)) /
                 ((ma * ma + mb * mb + C1) * (saa - ma * ma + sbb - mb * mb + C2));
      }
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
