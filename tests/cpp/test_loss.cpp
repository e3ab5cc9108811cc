// Losses: hand-computed values, a double-precision reference on random inputs, finite differences of
// the gradient, padding rows, and the config.
#include "test_support.hpp"

#include <relit/nn/registry.hpp>

#include <cmath>
#include <random>

namespace relit {

using nn::BatchMatrix;

namespace {

struct Evaluated {
  double value;
  std::vector<float> grad;
};

Evaluated evaluate(const Device& d, const std::string& type, std::uint32_t batch, std::uint32_t cols,
                   const std::vector<float>& p, const std::vector<float>& t, float scale = 1.0f) {
  auto loss = nn::create_loss({{"type", type}});
  BatchMatrix mp(d, batch, cols), mt(d, batch, cols), g(d, batch, cols);
  mp.upload_row_major(p);
  mt.upload_row_major(t);
  Buffer<float> value(d, 1);
  loss->evaluate(d, mp, mt, g, value, scale);
  return {value.read()[0], g.download_row_major()};
}

// Double-precision reference of one element's loss and its derivative w.r.t. p.
std::pair<double, double> loss_reference(const std::string& type, double p, double t) {
  if (type == "L2") return {(p - t) * (p - t), 2 * (p - t)};
  if (type == "RelativeL2") {
    const double den = p * p + 0.01;
    return {(p - t) * (p - t) / den, 2 * (p - t) / den};
  }
  if (type == "SrgbL2") {
    const auto srgb = [](double x) {
      const double a = std::abs(x);
      return std::copysign(a <= 0.0031308 ? 12.92 * a : 1.055 * std::pow(a, 1 / 2.4) - 0.055, x);
    };
    const double a = std::abs(p);
    const double slope = a <= 0.0031308 ? 12.92 : 1.055 / 2.4 * std::pow(a, 1 / 2.4 - 1);
    return {(srgb(p) - srgb(t)) * (srgb(p) - srgb(t)), 2 * (srgb(p) - srgb(t)) * slope};
  }
  const auto m = [](double x) { return x / (1 + std::abs(x)); };
  const double d = m(p) - m(t);
  return {d * d, 2 * d / ((1 + std::abs(p)) * (1 + std::abs(p)))};
}

}  // namespace

// The values below were computed by hand (and checked with a few lines of Python):
// prediction [[1, 2], [3, 4]], target [[0, 2], [1, 1]]: differences 1, 0, 2, 3.
TEST(Loss, HandComputedValues) {
  const Device d = test::test_device();
  const std::vector<float> p = {1, 2, 3, 4}, t = {0, 2, 1, 1};
  const auto l2 = evaluate(d, "L2", 2, 2, p, t);
  EXPECT_NEAR(l2.value, (1 + 0 + 4 + 9) / 4.0, 1e-6);                // 3.5
  EXPECT_EQ(l2.grad, (std::vector<float>{0.5f, 0.0f, 1.0f, 1.5f}));  // 2 d / 4
  // (1/1.01 + 0 + 4/9.01 + 9/16.01) / 4
  EXPECT_NEAR(evaluate(d, "RelativeL2", 2, 2, p, t).value, 0.4990497080905296, 1e-6);
  // m(1)=1/2, m(2)=2/3, m(3)=3/4, m(4)=4/5: ((1/2)^2 + 0 + (1/4)^2 + (3/10)^2) / 4
  EXPECT_NEAR(evaluate(d, "ToneMappedL2", 2, 2, p, t).value, 0.100625, 1e-6);
  // s(x) = 1.055 x^(1/2.4) - 0.055 above the knee: s(0) = 0, s(1) = 1, s(2) = 1.353256, s(3) = 1.612451,
  // s(4) = 1.824796: (1 + 0 + 0.612451^2 + 0.824796^2) / 4
  EXPECT_NEAR(evaluate(d, "SrgbL2", 2, 2, p, t).value, 0.513846173696779, 1e-6);
}

TEST(Loss, MatchesDoubleReferenceOnRandomInputsAndIgnoresPadding) {
  const Device d = test::test_device();
  for (const std::string type : {"L2", "RelativeL2", "ToneMappedL2", "SrgbL2"}) {
    for (const std::uint32_t batch : {1u, 77u, 300u}) {
      const std::uint32_t cols = 3;
      std::mt19937 rng(batch);
      std::uniform_real_distribution<float> u(-2.f, 5.f);
      std::vector<float> p(batch * cols), t(batch * cols);
      for (auto& v : p) v = u(rng);
      for (auto& v : t) v = u(rng);
      const auto got = evaluate(d, type, batch, cols, p, t, 2.0f);
      double sum = 0;
      for (std::size_t i = 0; i < p.size(); ++i) {
        const auto [value, grad] = loss_reference(type, p[i], t[i]);
        sum += value;
        const double expected = 2.0 * grad / p.size();
        EXPECT_NEAR(got.grad[i], expected, 1e-5 * (std::abs(expected) + 1e-3)) << type << " " << i;
      }
      EXPECT_NEAR(got.value, sum / p.size(), 1e-5 * (sum / p.size())) << type << " batch " << batch;
    }
  }
}

TEST(Loss, GradientMatchesFiniteDifferences) {
  const Device d = test::test_device();
  for (const std::string type : {"L2", "ToneMappedL2", "SrgbL2"}) {  // RelativeL2 stops the gradient by design
    const std::vector<float> p = {0.3f, 1.7f, -0.4f, 2.5f}, t = {0.1f, 2.0f, 0.2f, 1.0f};
    const auto base = evaluate(d, type, 4, 1, p, t);
    for (std::size_t i = 0; i < p.size(); ++i) {
      const float h = 1e-2f;
      auto plus = p, minus = p;
      plus[i] += h;
      minus[i] -= h;
      const double fd = (evaluate(d, type, 4, 1, plus, t).value - evaluate(d, type, 4, 1, minus, t).value) / (2 * h);
      EXPECT_NEAR(base.grad[i], fd, 2e-3 * (std::abs(fd) + 1e-2)) << type << " element " << i;
    }
  }
}

TEST(Loss, ShapeMismatchAndUnknownTypeAreErrors) {
  const Device d = test::test_device();
  auto loss = nn::create_loss({{"otype", "L2"}});
  EXPECT_EQ(loss->hyperparams(), (Json{{"type", "L2"}}));
  BatchMatrix a(d, 10, 3), b(d, 10, 2), g(d, 10, 3);
  Buffer<float> value(d, 1);
  EXPECT_THROW(loss->evaluate(d, a, b, g, value), InvalidArgument);
  EXPECT_THROW(nn::create_loss({{"type", "L3"}}), ConfigError);
  EXPECT_THROW(nn::create_loss({{"type", "RelativeL2"}, {"epsilon", -1}}), ConfigError);
  EXPECT_EQ(nn::create_loss({{"type", "RelativeL2"}})->hyperparams()["epsilon"], 0.01f);
}

}  // namespace relit
