// nn::Trainer: fits a Network to (input, target) batches with a Loss and an Optimizer (tiny-cuda-nn's
// Trainer). Parameters and gradients live in two flat device buffers; a step only enqueues work.
//
//   nn::Trainer trainer(device, std::move(model), nn::create_loss(...), nn::create_optimizer(...), seed);
//   for (...) trainer.step(inputs, targets);       // no host synchronisation
//   float loss = trainer.loss();                    // reads the last step's loss (synchronises)
#pragma once

#include <relit/nn/loss.hpp>
#include <relit/nn/module.hpp>
#include <relit/nn/optimizer.hpp>

namespace relit::nn {

class Trainer {
 public:
  Trainer(const Device& device, std::unique_ptr<Network> model, std::unique_ptr<Loss> loss,
          std::unique_ptr<Optimizer> optimizer, std::uint64_t seed);

  /// Forward, loss, backward and one optimiser step on the batch.
  void step(const BatchMatrix& input, const BatchMatrix& target);
  /// The loss of the last step (reads one float from the device).
  float loss() const;
  /// Inference with the current parameters.
  void inference(const BatchMatrix& input, BatchMatrix& output) const;

  const Network& model() const { return *m_model; }
  Buffer<float>& params() { return m_params; }
  const Buffer<float>& grads() const { return m_grads; }
  Optimizer& optimizer() { return *m_optimizer; }

 private:
  Device m_device;
  std::unique_ptr<Network> m_model;
  std::unique_ptr<Loss> m_loss;
  std::unique_ptr<Optimizer> m_optimizer;
  std::unique_ptr<Workspace> m_workspace;
  Buffer<float> m_params, m_grads, m_loss_value;
  BatchMatrix m_output, m_d_output;
};

}  // namespace relit::nn
