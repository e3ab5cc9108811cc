// Adam with decoupled weight decay and an exponential learning-rate schedule (kernels/adam.cl).
#include <relit/cl/program.hpp>
#include <relit/nn/registry.hpp>

#include <cmath>

namespace relit::nn {

namespace {

class Adam final : public Optimizer {
 public:
  explicit Adam(config::Reader& r) {
    m_lr = r.number("learning_rate", 1e-2f, 0.0f, 10.0f, "base step size");
    m_beta1 = r.number("beta1", 0.9f, 0.0f, 0.999999f, "decay of the first-moment average");
    m_beta2 = r.number("beta2", 0.99f, 0.0f, 0.99999999f, "decay of the second-moment average");
    m_epsilon = r.number("epsilon", 1e-15f, 0.0f, 1.0f,
                         "added to sqrt(v): 1e-15 for hash grids (instant-ngp), 1e-8 "
                         "for NeRF-style networks");
    m_weight_decay =
        r.number("weight_decay", 0.0f, 0.0f, 1.0f, "decoupled (AdamW) weight decay per unit learning rate");
    m_decay_rate = r.number("decay_rate", 1.0f, 1e-6f, 1.0f,
                            "learning rate multiplier per decay_steps steps: lr(t) = learning_rate * decay_rate^(t / "
                            "decay_steps); 1 keeps it constant");
    m_decay_steps = r.uint("decay_steps", 1000, 1, 1u << 30, "steps over which the learning rate decays by decay_rate");
    m_hyperparams = Json{{"type", "Adam"}};
    m_hyperparams.update(r.resolved());
  }

  std::string type() const override { return "Adam"; }
  Json hyperparams() const override { return m_hyperparams; }

  void allocate(const Device& device, std::size_t n_params) override {
    m_device = device;
    m_m = Buffer<float>(device, n_params);
    m_v = Buffer<float>(device, n_params);
    m_m.fill(0.0f);
    m_v.fill(0.0f);
    m_no_guard = Buffer<float>(device, 1);
    m_no_guard.fill(0.0f);
    m_step = 0;
  }

  void set_guard(const Buffer<float>* guard) override { m_guard = guard; }

  void step(Buffer<float>& params, const Buffer<float>& grads) override {
    if (params.size() != m_m.size() || grads.size() != m_m.size())
      throw InvalidArgument("Adam::step: " + std::to_string(params.size()) + " parameters and " +
                            std::to_string(grads.size()) + " gradients, but the optimiser was allocated for " +
                            std::to_string(m_m.size()) + "; call allocate() first");
    const float lr = learning_rate();
    ++m_step;
    const double t = static_cast<double>(m_step);
    const float inv_c1 = static_cast<float>(1.0 / (1.0 - std::pow(double(m_beta1), t)));
    const float inv_c2 = static_cast<float>(1.0 / (1.0 - std::pow(double(m_beta2), t)));
    const auto n = static_cast<std::uint32_t>(params.size());
    m_device.kernel("adam.cl", "adam_step")
        .args(n, lr, m_beta1, m_beta2, m_epsilon, m_weight_decay, inv_c1, inv_c2, params, grads, m_m, m_v,
              m_guard ? *m_guard : m_no_guard)
        .launch(n, 64);
  }

  std::uint64_t step_count() const override { return m_step; }
  float learning_rate() const override {
    return static_cast<float>(m_lr * std::pow(double(m_decay_rate), double(m_step) / m_decay_steps));
  }
  std::vector<std::pair<std::string, Buffer<float>*>> state_buffers() override { return {{"m", &m_m}, {"v", &m_v}}; }
  void set_step_count(std::uint64_t step) override { m_step = step; }

 private:
  float m_lr, m_beta1, m_beta2, m_epsilon, m_weight_decay, m_decay_rate;
  std::uint32_t m_decay_steps;
  Json m_hyperparams;
  Device m_device;
  Buffer<float> m_m, m_v, m_no_guard;
  const Buffer<float>* m_guard = nullptr;
  std::uint64_t m_step = 0;
};

}  // namespace

void register_optimizers(OptimizerRegistry& registry) {
  registry.add("Adam", "Adam with decoupled weight decay and exponential learning-rate decay, one fused kernel",
               [](config::Reader& r) -> std::unique_ptr<Optimizer> { return std::make_unique<Adam>(r); });
}

}  // namespace relit::nn
