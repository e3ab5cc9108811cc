// nn::Trainer: one training step = forward, loss, backward, optimiser step, all enqueued.
#include <relit/nn/trainer.hpp>

namespace relit::nn {

Trainer::Trainer(const Device& device, std::unique_ptr<Network> model, std::unique_ptr<Loss> loss,
                 std::unique_ptr<Optimizer> optimizer, std::uint64_t seed)
    : m_device(device), m_model(std::move(model)), m_loss(std::move(loss)), m_optimizer(std::move(optimizer)) {
  std::vector<float> init(m_model->n_params());
  m_model->initialize_params(init.data(), seed);
  m_params = Buffer<float>(device, init);
  m_grads = Buffer<float>(device, init.size());
  m_grads.fill(0.0f);
  m_optimizer->allocate(device, init.size());
  m_workspace = m_model->make_workspace(device);
  m_loss_value = Buffer<float>(device, 1);
  m_loss_value.fill(0.0f);
  m_output = BatchMatrix(device, 0, m_model->n_output_dims());
  m_d_output = BatchMatrix(device, 0, m_model->n_output_dims());
}

void Trainer::step(const BatchMatrix& input, const BatchMatrix& target) {
  if (input.cols() != m_model->n_input_dims() || target.cols() != m_model->n_output_dims() ||
      input.batch() != target.batch())
    throw InvalidArgument("Trainer::step: inputs " + std::to_string(input.batch()) + "x" +
                          std::to_string(input.cols()) + " and targets " + std::to_string(target.batch()) + "x" +
                          std::to_string(target.cols()) + " do not fit a model of " +
                          std::to_string(m_model->n_input_dims()) + " → " + std::to_string(m_model->n_output_dims()));
  m_output.resize(input.batch());
  m_d_output.resize(input.batch());
  m_model->forward(m_device, {&m_params, 0}, input, m_output, *m_workspace);
  m_loss->evaluate(m_device, m_output, target, m_d_output, m_loss_value);
  m_model->backward(m_device, {&m_params, 0}, input, m_output, m_d_output, {&m_grads, 0}, false, nullptr, *m_workspace);
  m_optimizer->step(m_params, m_grads);
}

float Trainer::loss() const { return m_loss_value.read()[0]; }

void Trainer::inference(const BatchMatrix& input, BatchMatrix& output) const {
  m_model->inference(m_device, {&m_params, 0}, input, output);
}

}  // namespace relit::nn
