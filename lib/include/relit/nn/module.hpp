// The nn component families: Encoding and Network (tiny-cuda-nn style).
//
// A component is built from JSON by its registry (relit/nn/registry.hpp), knows its parameter count and
// its resolved hyperparameters, and is *stateless* with respect to parameters: every call takes the slice of
// the model's flat parameter buffer that belongs to it. Parameters and their gradients live in two twin
// flat device buffers per model (fp32), so one fused Adam kernel updates a whole model.
//
// All batches are BatchMatrix (tiled layout, padded; see batch.hpp). Calls only enqueue work on the
// device's in-order queue: no host synchronisation, and no allocation when a Workspace is reused with a
// batch no larger than before.
#pragma once

#include <relit/cl/device.hpp>
#include <relit/config.hpp>
#include <relit/nn/batch.hpp>

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace relit::nn {

/// Scratch memory a component keeps between forward and backward (saved activations, ...). Created by
/// the component, reused across iterations.
class Workspace {
 public:
  virtual ~Workspace() = default;
};

class Module {
 public:
  virtual ~Module() = default;
  /// The registry name ("HashGrid", "FullyFusedMLP").
  virtual std::string type() const = 0;
  /// The fully resolved hyperparameters, with "type": building from this JSON gives the same component.
  virtual Json hyperparams() const = 0;
  /// Number of float parameters (0 for parameter-free encodings).
  virtual std::uint32_t n_params() const = 0;
  /// Writes the initial values of the n_params() parameters to `out` (host side), deterministically from
  /// `seed`.
  virtual void initialize_params(float* out, std::uint64_t seed) const = 0;
};

class Encoding : public Module {
 public:
  virtual std::uint32_t n_input_dims() const = 0;
  virtual std::uint32_t n_output_dims() const = 0;

  virtual std::unique_ptr<Workspace> make_workspace(const Device& device) const {
    (void)device;
    return nullptr;
  }

  /// Encodes columns [in_col, in_col + n_input_dims) of `input` into columns [out_col, out_col + n_output_dims)
  /// of `output`. The column offsets let a Composite (and the renderer) read its inputs from, and assemble its
  /// outputs into, one shared matrix without copies. `input` and `output` must have the same batch size.
  virtual void forward(const Device& device, ConstParamSlice params, const BatchMatrix& input, std::uint32_t in_col,
                       BatchMatrix& output, std::uint32_t out_col, Workspace* workspace) const = 0;

  /// Given dL/d(output) in columns [out_col, ...) of `d_output`: writes dL/d(params) into `grads` (adds to it
  /// when `accumulate`), and dL/d(input) into columns [in_col, in_col + n_input_dims) of `d_input` when it is
  /// non-null (overwriting those columns).
  virtual void backward(const Device& device, ConstParamSlice params, const BatchMatrix& input, std::uint32_t in_col,
                        const BatchMatrix& d_output, std::uint32_t out_col, ParamSlice grads, bool accumulate,
                        BatchMatrix* d_input, Workspace* workspace) const = 0;

  /// The common case: `input` holds exactly the n_input_dims columns to encode (in_col = 0).
  void forward(const Device& device, ConstParamSlice params, const BatchMatrix& input, BatchMatrix& output,
               std::uint32_t out_col, Workspace* workspace) const {
    forward(device, params, input, 0, output, out_col, workspace);
  }
  void backward(const Device& device, ConstParamSlice params, const BatchMatrix& input, const BatchMatrix& d_output,
                std::uint32_t out_col, ParamSlice grads, bool accumulate, BatchMatrix* d_input,
                Workspace* workspace) const {
    backward(device, params, input, 0, d_output, out_col, grads, accumulate, d_input, workspace);
  }
};

class Network : public Module {
 public:
  virtual std::uint32_t n_input_dims() const = 0;
  virtual std::uint32_t n_output_dims() const = 0;

  virtual std::unique_ptr<Workspace> make_workspace(const Device& device) const = 0;

  /// Inference: output = f(input), nothing saved.
  virtual void inference(const Device& device, ConstParamSlice params, const BatchMatrix& input,
                         BatchMatrix& output) const = 0;
  /// Inference that keeps its scratch (encoded inputs, ...) in `workspace` instead of allocating it, so a
  /// loop of inference calls allocates nothing. Leaves whatever a previous forward() saved there invalid.
  virtual void inference(const Device& device, ConstParamSlice params, const BatchMatrix& input, BatchMatrix& output,
                         Workspace& workspace) const {
    (void)workspace;
    inference(device, params, input, output);
  }
  /// Training forward: as inference, saving in `workspace` what backward needs.
  virtual void forward(const Device& device, ConstParamSlice params, const BatchMatrix& input, BatchMatrix& output,
                       Workspace& workspace) const = 0;
  /// Given dL/d(output): writes dL/d(params) into `grads` (adds when `accumulate`) and dL/d(input) into
  /// `d_input` when non-null. Uses the activations saved by the forward call on the same workspace.
  virtual void backward(const Device& device, ConstParamSlice params, const BatchMatrix& input,
                        const BatchMatrix& output, const BatchMatrix& d_output, ParamSlice grads, bool accumulate,
                        BatchMatrix* d_input, Workspace& workspace) const = 0;
};

}  // namespace relit::nn
