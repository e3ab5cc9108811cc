// Loss: a training loss over a batch, giving dL/dprediction and the loss value without host round trips.
//
//   auto loss = nn::create_loss({{"type", "L2"}});
//   loss->evaluate(device, prediction, target, d_prediction, value);   // value: Buffer<float> of 1, on device
//
// The value is the mean over the batch's real samples and all features; the gradient is that mean's
// derivative times `scale` (use it for loss weights). Padding rows get zero gradient.
#pragma once

#include <relit/config.hpp>
#include <relit/nn/batch.hpp>

#include <memory>
#include <string>

namespace relit::nn {

class Loss {
 public:
  virtual ~Loss() = default;
  virtual std::string type() const = 0;
  virtual Json hyperparams() const = 0;

  /// Writes dL/dprediction (times `scale`) to `d_prediction` (same shape as `prediction`) and the mean loss
  /// to `value[0]`, all asynchronously. `target` must have the prediction's shape.
  virtual void evaluate(const Device& device, const BatchMatrix& prediction, const BatchMatrix& target,
                        BatchMatrix& d_prediction, Buffer<float>& value, float scale = 1.0f) const = 0;
};

}  // namespace relit::nn
