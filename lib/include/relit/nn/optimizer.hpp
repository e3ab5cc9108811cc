// Optimizer: updates a model's flat parameter buffer from its twin gradient buffer.
//
//   auto adam = nn::create_optimizer({{"type", "Adam"}, {"learning_rate", 1e-2}});
//   adam->allocate(device, n_params);
//   adam->step(params, grads);        // one fused kernel, asynchronous
//
// The learning-rate schedule is exponential: lr(t) = learning_rate * decay_rate^(t / decay_steps), t the
// number of steps taken so far (tiny-cuda-nn's "ExponentialDecay" and NeRF's schedule are instances).
#pragma once

#include <relit/cl/buffer.hpp>
#include <relit/config.hpp>

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace relit::nn {

class Optimizer {
 public:
  virtual ~Optimizer() = default;
  virtual std::string type() const = 0;
  virtual Json hyperparams() const = 0;

  /// Prepares (zeroed) optimiser state for `n_params` parameters on `device`, and resets the step count.
  virtual void allocate(const Device& device, std::size_t n_params) = 0;
  /// One update, enqueued on the parameters' device.
  virtual void step(Buffer<float>& params, const Buffer<float>& grads) = 0;
  /// A one-float device buffer read by every later step: when its value is not finite (the step's loss
  /// was NaN/Inf) the step leaves parameters and state unchanged. nullptr (the default) disables the guard.
  /// The buffer must outlive the optimiser's steps.
  virtual void set_guard(const Buffer<float>* guard) = 0;
  /// Steps taken so far.
  virtual std::uint64_t step_count() const = 0;
  /// The learning rate the next step will use.
  virtual float learning_rate() const = 0;

  /// Optimiser state for checkpoints: named device buffers (e.g. Adam's "m" and "v") and the step count.
  virtual std::vector<std::pair<std::string, Buffer<float>*>> state_buffers() = 0;
  virtual void set_step_count(std::uint64_t step) = 0;
};

}  // namespace relit::nn
