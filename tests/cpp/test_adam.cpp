// Adam: two steps computed by hand, weight decay, the learning-rate schedule, and state handling.
#include "test_support.hpp"

#include <relit/nn/registry.hpp>

namespace relit {

namespace {
std::unique_ptr<nn::Optimizer> adam(Json extra = Json::object()) {
  Json j = {{"type", "Adam"}, {"learning_rate", 0.1}, {"beta1", 0.9}, {"beta2", 0.99}, {"epsilon", 1e-8}};
  j.update(extra);
  return nn::create_optimizer(j);
}
}  // namespace

// By hand, with lr 0.1, betas 0.9/0.99, eps 1e-8, p0 = 1:
//   step 1, g = 0.5:  m = 0.05, v = 0.0025, m^ = 0.5, v^ = 0.25 → p = 1 - 0.1 * 0.5/(0.5 + 1e-8) = 0.900000002
//   step 2, g = -1:   m = -0.055, v = 0.012475, m^ = -0.055/0.19, v^ = 0.012475/0.0199 → p = 0.93656077287
TEST(Adam, TwoStepsComputedByHand) {
  const Device d = test::test_device();
  auto opt = adam();
  opt->allocate(d, 1);
  Buffer<float> p(d, std::vector<float>{1.0f}), g(d, std::vector<float>{0.5f});
  opt->step(p, g);
  EXPECT_NEAR(p.read()[0], 0.900000002, 1e-6);
  g.write(std::vector<float>{-1.0f});
  opt->step(p, g);
  EXPECT_NEAR(p.read()[0], 0.9365607728717226, 1e-6);
  EXPECT_EQ(opt->step_count(), 2u);
  const auto m = opt->state_buffers()[0].second->read();
  EXPECT_NEAR(m[0], -0.055, 1e-7);
}

// Decoupled weight decay 0.1, p0 = 2, g = 0.5: p = 2 - 0.1 * (1 + 0.1 * 2) = 1.88 (update ≈ 1 as above).
TEST(Adam, DecoupledWeightDecay) {
  const Device d = test::test_device();
  auto opt = adam({{"weight_decay", 0.1}});
  opt->allocate(d, 1);
  Buffer<float> p(d, std::vector<float>{2.0f}), g(d, std::vector<float>{0.5f});
  opt->step(p, g);
  EXPECT_NEAR(p.read()[0], 1.880000002, 1e-6);
}

TEST(Adam, ExponentialLearningRateDecay) {
  const Device d = test::test_device();
  auto opt = adam({{"decay_rate", 0.5}, {"decay_steps", 10}});
  opt->allocate(d, 3);
  EXPECT_FLOAT_EQ(opt->learning_rate(), 0.1f);
  Buffer<float> p(d, std::vector<float>(3, 0.f)), g(d, std::vector<float>(3, 1.f));
  for (int i = 0; i < 10; ++i) opt->step(p, g);
  EXPECT_FLOAT_EQ(opt->learning_rate(), 0.05f);
  opt->set_step_count(20);
  EXPECT_FLOAT_EQ(opt->learning_rate(), 0.025f);
}

TEST(Adam, ManyParametersMatchTheScalarRecurrence) {
  const Device d = test::test_device();
  const std::size_t n = 1000;  // not a multiple of the work-group size
  auto opt = adam();
  opt->allocate(d, n);
  std::vector<float> p0(n), g0(n);
  for (std::size_t i = 0; i < n; ++i) {
    p0[i] = 0.01f * i;
    g0[i] = std::sin(0.1f * i);
  }
  Buffer<float> p(d, p0), g(d, g0);
  opt->step(p, g);
  const auto got = p.read();
  for (std::size_t i = 0; i < n; ++i) {
    // First step: m^ = g, v^ = g², so the update is g / (|g| + eps).
    const double expected = p0[i] - 0.1 * g0[i] / (std::abs(double(g0[i])) + 1e-8);
    ASSERT_NEAR(got[i], expected, 1e-5) << i;
  }
}

TEST(Adam, SizeMismatchAndBadConfigAreErrors) {
  const Device d = test::test_device();
  auto opt = adam();
  opt->allocate(d, 4);
  Buffer<float> p(d, 5), g(d, 5);
  EXPECT_THROW(opt->step(p, g), InvalidArgument);
  EXPECT_THROW(nn::create_optimizer({{"type", "Adam"}, {"beta1", 1.5}}), ConfigError);
  EXPECT_THROW(nn::create_optimizer({{"type", "Adam"}, {"momentum", 0.9}}), ConfigError);
  EXPECT_THROW(nn::create_optimizer({{"type", "SGD"}}), ConfigError);
}

}  // namespace relit
