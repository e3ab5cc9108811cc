// FullyFusedMLP: a multi-layer perceptron whose layers all run in one kernel per pass (tiny-cuda-nn's
// "FullyFusedMLP", written for CPU SIMD on PoCL and portable to GPUs).
//
//   {"type": "FullyFusedMLP", "n_neurons": 64, "n_hidden_layers": 2, "activation": "ReLU",
//    "output_activation": "None", "skip_layers": [], "bias": true, "kernel_variant": "auto"}
//   {"type": "FullyFusedMLP", "n_neurons": 256, "n_hidden_layers": 8, "skip_layers": [5],
//    "output_heads": [{"n_dims": 1, "activation": "Softplus"}, {"n_dims": 3, "activation": "Sigmoid"}, ...]}
//
// Network: x (n_input_dims) -> n_hidden_layers dense layers of n_neurons with `activation` -> a dense output
// layer (n_output_dims) with per-column output activations. A hidden layer l in skip_layers (1 <= l <
// n_hidden_layers) takes [h_(l-1), x] as its input (NeRF's skip connection). Any n_input_dims and
// n_output_dims work; nothing needs padding by the user.
//
// Parameter layout (see docs/networks.md): layer after layer, each a row-major [n_out][n_in + bias] matrix
// (PyTorch's nn.Linear weight with the bias appended as the last column). Weight gradients are reduced in a
// fixed order (no atomics): results are bit-for-bit reproducible on one device (for one kernel choice).
//
// Two kernel variants compute the same network: SIMD kernels for CPUs and work-group kernels for GPUs, chosen
// per device from a table, overridable by "kernel_variant" and RELIT_MLP_VARIANT (docs/networks.md).
//
// backward() must be given the input and output of the forward() call on the same workspace, unchanged: on
// CPUs with AVX-512 small networks train with one fused kernel that recomputes the activations from the
// input instead of saving them (docs/networks.md).
#pragma once

#include <relit/cl/kernel_variant.hpp>
#include <relit/nn/module.hpp>

#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

namespace relit::nn {

/// Output activations of the FullyFusedMLP (the codes match kernels/mlp.cl).
enum class Activation : std::uint8_t { None = 0, ReLU = 1, Sigmoid = 2, Softplus = 3, Tanh = 4 };

const char* activation_name(Activation a);
/// Applies an activation on the host (double precision): for references and tests.
double apply_activation(Activation a, double z);

/// A group of consecutive output columns with one activation (the property network's sigma/albedo/g heads).
struct OutputHead {
  std::uint32_t n_dims = 0;
  Activation activation = Activation::None;
};

class FullyFusedMLP final : public Network {
 public:
  /// Reads the config (keys in the file comment); throws ConfigError naming the key on bad values.
  FullyFusedMLP(config::Reader& reader, std::uint32_t n_input_dims, std::uint32_t n_output_dims);
  ~FullyFusedMLP() override;

  std::string type() const override { return "FullyFusedMLP"; }
  Json hyperparams() const override { return m_hyperparams; }
  std::uint32_t n_params() const override;
  void initialize_params(float* out, std::uint64_t seed) const override;

  std::uint32_t n_input_dims() const override { return m_n_input; }
  std::uint32_t n_output_dims() const override { return m_n_output; }

  std::unique_ptr<Workspace> make_workspace(const Device& device) const override;
  using Network::inference;
  void inference(const Device& device, ConstParamSlice params, const BatchMatrix& input,
                 BatchMatrix& output) const override;
  void forward(const Device& device, ConstParamSlice params, const BatchMatrix& input, BatchMatrix& output,
               Workspace& workspace) const override;
  void backward(const Device& device, ConstParamSlice params, const BatchMatrix& input, const BatchMatrix& output,
                const BatchMatrix& d_output, ParamSlice grads, bool accumulate, BatchMatrix* d_input,
                Workspace& workspace) const override;

  // Structure, for references, tests and benchmarks.
  std::uint32_t width() const { return m_width; }
  std::uint32_t n_hidden_layers() const { return m_n_hidden; }
  bool has_bias() const { return m_bias; }
  Activation hidden_activation() const { return m_hidden_activation; }
  /// The activation of every output column.
  const std::vector<Activation>& output_activations() const { return m_output_activations; }
  bool has_skip(std::uint32_t layer) const;
  /// Layer l = 0 .. n_hidden_layers (the last is the output layer): its input and output widths, and where
  /// its [n_out][n_in + bias] block starts in the network's parameters.
  std::uint32_t layer_inputs(std::uint32_t l) const;
  std::uint32_t layer_outputs(std::uint32_t l) const;
  std::uint32_t layer_offset(std::uint32_t l) const;

  /// FLOPs of one forward pass per sample (2 per multiply-add), as the benchmarks count them.
  double flops_per_sample() const;

  /// Builds (or fetches from the device's cache) the kernels once, so the first call is not slow.
  void warm_up(const Device& device) const;

  /// Register blocking of the kernels (the -D parameters of kernels/mlp.cl). Any valid blocking gives the
  /// same results up to float rounding; it only changes the speed.
  struct Blocking {
    std::uint32_t forward_tiles = 1;  ///< FWD_T: 16-sample tiles per work-item (forward and backward), 1..4
    std::uint32_t forward_rows = 4;   ///< FWD_R: outputs per register block of the forward pass, 1..16
    std::uint32_t backward_rows = 4;  ///< BWD_R: inputs per register block of the backward pass, 1..16
    /// DW_VEC: samples per weight-gradient accumulator: 8 or 16 (its lanes are samples, summed at the end), or
    /// 1: the outer-product form, whose lanes are 16 dW columns of one row (mlp_weight_grad_outer, dw_cols of
    /// them per block, at most 4)
    std::uint32_t dw_vector = 8;
    std::uint32_t dw_rows = 4;     ///< DW_RJ: dW rows per register block, 1..8
    std::uint32_t dw_cols = 3;     ///< DW_RK: dW columns (dw_vector 1: vectors of 16) per register block, 1..8
    std::uint32_t dw_region = 16;  ///< DW_ROWS: dW rows per work-item, a multiple of dw_rows
    /// The fused training kernel (mlp_train_fused: one work-item per batch chunk, forward recomputed, float16
    /// dW accumulators for every parameter in the work-item's scratch) runs backward() when the network has at
    /// most this many parameters; 0: never (the separate backward and weight-gradient kernels). For CPUs,
    /// where the accumulators (64 bytes per parameter) must stay in a core's cache.
    std::uint32_t fused_train_max_params = 0;
    std::uint32_t train_group =
        8;  ///< TRAIN_G: tiles per group of the fused training kernel, a multiple of forward_tiles
    /// TRAIN_SAVED: the fused training kernel reads the activations and ReLU masks the training forward saved
    /// (transposed, as the outer-product weight gradients read them) instead of recomputing the forward pass;
    /// dZ still stays in the work-item's scratch. Needs dw_vector 1.
    bool train_saved = false;
    bool operator==(const Blocking& o) const;
    std::string str() const;  ///< "T2 R8 B8 V16 4x4/16 F16384 G8", " S" appended with train_saved
  };
  /// The blocking for a device: AVX-512 CPUs (16-float native vectors) get wider blocks than AVX2 CPUs and
  /// GPUs (docs/networks.md).
  static Blocking default_blocking(const DeviceInfo& info);
  /// Runs the SIMD kernels with this blocking instead of the device's choice, for kernels built from now on
  /// (tests, tuning); std::nullopt restores the device's choice. Throws InvalidArgument on values out of range.
  void set_blocking(std::optional<Blocking> blocking);
  /// The blocking the SIMD kernels use (or would use) on `device`.
  Blocking blocking(const Device& device) const;

  /// The two kernel variants (docs/networks.md, "Kernel variants"): the SIMD kernels of kernels/mlp.cl
  /// (a work-item owns 16-sample tiles as float16 lanes; no barriers, no local memory: CPUs) and the
  /// work-group kernels of kernels/mlp_wg.cl (a work-group owns a tile of samples whose activations stay in
  /// local memory across the layers, weights staged through local memory: GPUs).
  using Variant = KernelVariant;
  static const char* variant_name(Variant v);  ///< "simd", "workgroup"

  /// Parameters of the work-group kernels (the -D parameters of kernels/mlp_wg.cl). Any valid set gives the
  /// same results up to float rounding; it only changes the speed.
  struct WorkGroupParams {
    std::uint32_t samples = 64;     ///< WG_S: samples per work-group, a multiple of 16, 16..512 (lowered to
                                    ///< fit the device's local memory)
    std::uint32_t items = 64;       ///< WG_SIZE: work-items per work-group (forward, backward), 1..1024
    std::uint32_t rows = 4;         ///< WG_RJ: outputs per register block, 1..16
    std::uint32_t cols = 4;         ///< WG_RS: samples per register block, 1..16
    std::uint32_t k_tile = 16;      ///< WG_KT: weight columns staged in local memory at a time, 1..64
    std::uint32_t dw_tile = 32;     ///< DW_T: side of the dW tile of a work-group, a multiple of dw_block
    std::uint32_t dw_block = 4;     ///< DW_R: side of a work-item's dW register block, 1..8;
                                    ///< (dw_tile / dw_block)^2 work-items per group, at most 1024
    std::uint32_t dw_samples = 16;  ///< DW_S: samples staged per step of the weight-gradient kernel, 1..128
    std::uint32_t dw_chunk = 2048;  ///< samples per weight-gradient partial (split-K), a multiple of 16
    bool operator==(const WorkGroupParams& o) const;
    std::string str() const;  ///< "S64 N64 4x4 K16 dW32/4 S16 C2048"
  };

  /// What runs on a device: the variant, the parameters of both variants, and where the choice came from.
  struct KernelChoice {
    Variant variant = Variant::Simd;
    Blocking blocking;          ///< the SIMD kernels' parameters
    WorkGroupParams workgroup;  ///< the work-group kernels' parameters
    bool tuned = false;         ///< the parameters were measured on such a device (false: a default)
    std::string source;         ///< "table: NVIDIA GPU", "RELIT_MLP_VARIANT", "kernel_variant", ...
    std::string str() const;    ///< "workgroup S128 N128 4x8 K16 dW64/4 S16 C2048 (table: NVIDIA GPU, untuned)"
  };
  /// The row of the per-device tuning table (lib/src/nn/mlp_tuning.cpp) for a device: CPUs run the SIMD
  /// kernels, GPUs and other devices the work-group kernels, with parameters per vendor.
  static KernelChoice device_default(const DeviceInfo& info);
  /// device_default() with the RELIT_MLP_VARIANT environment variable (simd, workgroup or auto) applied:
  /// what a network whose kernel_variant is "auto" runs. Throws InvalidArgument on another value.
  static KernelChoice default_kernels(const DeviceInfo& info);
  /// Runs the work-group kernels with these parameters instead of the device's choice, for kernels built from
  /// now on (tests, tuning); std::nullopt restores the device's choice. Throws InvalidArgument on values out
  /// of range.
  void set_workgroup(std::optional<WorkGroupParams> params);
  /// What the kernels use (or will use) on `device`: set_blocking() / set_workgroup(), else
  /// RELIT_MLP_VARIANT, else the config's kernel_variant, else the device's table row; the work-group tile
  /// as lowered to fit the device's local memory (builds the kernels).
  KernelChoice kernel_choice(const Device& device) const;
  /// Whether backward() runs the fused training kernel on `device` (see Blocking::fused_train_max_params).
  bool fused_training(const Device& device) const;

 private:
  struct Kernels;
  const Kernels& kernels(const Device& device) const;
  KernelChoice choice_locked(const Device& device) const;  // before fitting the device, with m_mutex held
  void launch_forward(const Device& device, ConstParamSlice params, const BatchMatrix& input, BatchMatrix& output,
                      Buffer<float>* act, std::uint32_t act_padded, const Buffer<std::uint16_t>* mask = nullptr) const;
  void check_input(const char* what, const BatchMatrix& input) const;
  /// backward() runs the fused kernel that recomputes the forward pass: forward() saves nothing.
  bool recomputes_forward(const Device& device) const;
  std::uint32_t layer_stride(std::uint32_t l) const;  ///< a weight row: layer_inputs(l), plus the bias
  void backward_workgroup(const Device& device, ConstParamSlice params, const BatchMatrix& output,
                          const BatchMatrix& d_output, ParamSlice grads, bool accumulate, BatchMatrix* d_input,
                          Workspace& workspace) const;

  std::uint32_t m_n_input, m_n_output, m_width, m_n_hidden;
  bool m_bias;
  Activation m_hidden_activation;
  std::vector<Activation> m_output_activations;
  std::vector<std::uint32_t> m_skip_layers;
  Json m_hyperparams;

  std::string m_variant_config;                // kernel_variant: "auto", "simd" or "workgroup"
  std::optional<Blocking> m_blocking;          // set_blocking()
  std::optional<WorkGroupParams> m_workgroup;  // set_workgroup()
  mutable std::mutex m_mutex;
  mutable std::vector<std::unique_ptr<Kernels>> m_kernels;  // one set per device
};

}  // namespace relit::nn
