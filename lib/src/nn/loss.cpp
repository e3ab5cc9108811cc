// The losses: L2, RelativeL2, ToneMappedL2 and SrgbL2, one kernel each (kernels/loss.cl) plus a fixed-order sum.
#include <relit/cl/program.hpp>
#include <relit/nn/registry.hpp>

#include <cmath>

namespace relit::nn {

namespace {

class KernelLoss final : public Loss {
 public:
  KernelLoss(std::string type, int code, float epsilon, Json hyperparams)
      : m_type(std::move(type)), m_code(code), m_epsilon(epsilon), m_hyperparams(std::move(hyperparams)) {}

  std::string type() const override { return m_type; }
  Json hyperparams() const override { return m_hyperparams; }

  void evaluate(const Device& device, const BatchMatrix& prediction, const BatchMatrix& target,
                BatchMatrix& d_prediction, Buffer<float>& value, float scale) const override {
    if (target.batch() != prediction.batch() || target.cols() != prediction.cols())
      throw InvalidArgument(m_type + " loss: target is " + std::to_string(target.batch()) + "x" +
                            std::to_string(target.cols()) + " but the prediction is " +
                            std::to_string(prediction.batch()) + "x" + std::to_string(prediction.cols()));
    if (d_prediction.cols() != prediction.cols()) throw InvalidArgument(m_type + " loss: gradient has the wrong width");
    d_prediction.resize(prediction.batch());
    if (value.size() < 1) throw InvalidArgument(m_type + " loss: the value buffer needs one element");
    const std::uint32_t n_tiles = prediction.padded() / kBatchTile;
    if (m_partials.size() < n_tiles) m_partials = Buffer<float>(device, n_tiles);
    const float inv_count =
        prediction.batch() ? 1.0f / (static_cast<float>(prediction.batch()) * prediction.cols()) : 0.0f;
    const Defines defines = {{"LOSS", std::to_string(m_code)}, {"RELATIVE_EPS", std::to_string(m_epsilon) + "f"}};
    device.kernel("loss.cl", "loss_forward_backward", defines)
        .args(prediction.batch(), prediction.cols(), scale, inv_count, prediction.data(), target.data(),
              d_prediction.data(), m_partials, n_tiles)
        .launch(n_tiles, 16);
    device.kernel("loss.cl", "reduce_sum", defines).args(n_tiles, m_partials, value).launch(1);
  }

 private:
  std::string m_type;
  int m_code;
  float m_epsilon;
  Json m_hyperparams;
  mutable Buffer<float> m_partials;
};

Json with_type(const std::string& type, const config::Reader& r) {
  Json j = {{"type", type}};
  j.update(r.resolved());
  return j;
}

}  // namespace

void register_losses(LossRegistry& registry) {
  registry.add("L2", "mean of (prediction - target)^2", [](config::Reader& r) -> std::unique_ptr<Loss> {
    return std::make_unique<KernelLoss>("L2", 0, 0.0f, with_type("L2", r));
  });
  registry.add("RelativeL2",
               "mean of (prediction - target)^2 / (prediction^2 + epsilon), no gradient through the "
               "denominator (robust to HDR targets)",
               [](config::Reader& r) -> std::unique_ptr<Loss> {
                 const float eps = r.number("epsilon", 0.01f, 1e-8f, 1e3f, "added to prediction^2 in the denominator");
                 return std::make_unique<KernelLoss>("RelativeL2", 1, eps, with_type("RelativeL2", r));
               });
  registry.add("ToneMappedL2",
               "mean of (m(prediction) - m(target))^2 with m(x) = x / (1 + |x|): L2 after "
               "Reinhard tone mapping of linear HDR radiance",
               [](config::Reader& r) -> std::unique_ptr<Loss> {
                 return std::make_unique<KernelLoss>("ToneMappedL2", 2, 0.0f, with_type("ToneMappedL2", r));
               });
  registry.add("SrgbL2",
               "mean of (s(prediction) - s(target))^2 with s the sRGB transfer curve (unclamped above 1, odd "
               "below 0): L2 in the space where PSNR/SSIM are measured",
               [](config::Reader& r) -> std::unique_ptr<Loss> {
                 return std::make_unique<KernelLoss>("SrgbL2", 3, 0.0f, with_type("SrgbL2", r));
               });
}

}  // namespace relit::nn
