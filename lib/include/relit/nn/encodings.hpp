// The input encodings of the nn family (tiny-cuda-nn's set, in relit's tiled batch layout):
//
//   Identity            x -> scale * x + offset
//   Frequency           NeRF positional encoding: sin, cos of 2^k pi x (double-angle recurrences)
//   SphericalHarmonics  real SH of a unit direction (Zheng et al. 2021, eq. 2), degree 1..10
//   HashGrid            instant-ngp multiresolution hash encoding (trainable)
//   Composite           nested encodings over consecutive input dims, outputs concatenated
//
// Each is an nn::Encoding (relit/nn/module.hpp): built from JSON by nn::create_encoding() (keys, defaults
// and ranges in docs/encodings.md), or directly from its Options struct in C++. Every encoding writes its
// n_output_dims() columns at any column offset of the output matrix, so a Composite (or the renderer)
// assembles one MLP input matrix without copies.
#pragma once

#include <relit/cl/kernel_variant.hpp>
#include <relit/nn/module.hpp>

#include <array>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

namespace relit::nn {

class IdentityEncoding final : public Encoding {
 public:
  struct Options {
    float scale = 1.0f;
    float offset = 0.0f;
  };
  IdentityEncoding(std::uint32_t n_input_dims, Options options);

  std::string type() const override { return "Identity"; }
  Json hyperparams() const override;
  std::uint32_t n_params() const override { return 0; }
  void initialize_params(float*, std::uint64_t) const override {}
  std::uint32_t n_input_dims() const override { return m_dims; }
  std::uint32_t n_output_dims() const override { return m_dims; }
  using Encoding::backward;
  using Encoding::forward;
  void forward(const Device& device, ConstParamSlice params, const BatchMatrix& input, std::uint32_t in_col,
               BatchMatrix& output, std::uint32_t out_col, Workspace* workspace) const override;
  void backward(const Device& device, ConstParamSlice params, const BatchMatrix& input, std::uint32_t in_col,
                const BatchMatrix& d_output, std::uint32_t out_col, ParamSlice grads, bool accumulate,
                BatchMatrix* d_input, Workspace* workspace) const override;

 private:
  std::uint32_t m_dims;
  Options m_options;
};

/// Per input dim i and octave k = 0..n_frequencies-1: sin(2^k pi x_i), cos(2^k pi x_i) (NeRF's convention:
/// the highest frequency is 2^(n_frequencies-1), "max freq 2^9" means n_frequencies = 10). Output columns:
/// [x_0..x_{d-1} if include_input], then for each dim i: sin k=0, cos k=0, sin k=1, cos k=1, ...
class FrequencyEncoding final : public Encoding {
 public:
  struct Options {
    std::uint32_t n_frequencies = 10;
    bool include_input = false;
  };
  /// Octaves between exact re-evaluations of the double-angle recurrence (see kernels/enc_frequency.cl).
  static constexpr std::uint32_t kAnchorInterval = 3;

  FrequencyEncoding(std::uint32_t n_input_dims, Options options);

  std::string type() const override { return "Frequency"; }
  Json hyperparams() const override;
  std::uint32_t n_params() const override { return 0; }
  void initialize_params(float*, std::uint64_t) const override {}
  std::uint32_t n_input_dims() const override { return m_dims; }
  std::uint32_t n_output_dims() const override {
    return m_dims * 2 * m_options.n_frequencies + (m_options.include_input ? m_dims : 0);
  }
  using Encoding::backward;
  using Encoding::forward;
  void forward(const Device& device, ConstParamSlice params, const BatchMatrix& input, std::uint32_t in_col,
               BatchMatrix& output, std::uint32_t out_col, Workspace* workspace) const override;
  void backward(const Device& device, ConstParamSlice params, const BatchMatrix& input, std::uint32_t in_col,
                const BatchMatrix& d_output, std::uint32_t out_col, ParamSlice grads, bool accumulate,
                BatchMatrix* d_input, Workspace* workspace) const override;

 private:
  Defines defines() const;
  std::uint32_t m_dims;
  Options m_options;
};

/// Real SH of a 3-D unit direction, bands l = 0..degree-1 (degree^2 outputs, column l*l + l + m), exactly
/// as relit::sh::eval (relit/sh.hpp). The direction is not renormalised: pass unit vectors.
class SphericalHarmonicsEncoding final : public Encoding {
 public:
  struct Options {
    std::uint32_t degree = 4;
  };
  static constexpr std::uint32_t kMaxDegree = 10;

  SphericalHarmonicsEncoding(std::uint32_t n_input_dims, Options options);

  std::string type() const override { return "SphericalHarmonics"; }
  Json hyperparams() const override;
  std::uint32_t n_params() const override { return 0; }
  void initialize_params(float*, std::uint64_t) const override {}
  std::uint32_t n_input_dims() const override { return 3; }
  std::uint32_t n_output_dims() const override { return m_options.degree * m_options.degree; }
  using Encoding::backward;
  using Encoding::forward;
  void forward(const Device& device, ConstParamSlice params, const BatchMatrix& input, std::uint32_t in_col,
               BatchMatrix& output, std::uint32_t out_col, Workspace* workspace) const override;
  void backward(const Device& device, ConstParamSlice params, const BatchMatrix& input, std::uint32_t in_col,
                const BatchMatrix& d_output, std::uint32_t out_col, ParamSlice grads, bool accumulate,
                BatchMatrix* d_input, Workspace* workspace) const override;

 private:
  Options m_options;
};

/// Multiresolution hash encoding over [0, 1]^d, d = 2 or 3 (inputs outside are clamped). Output column
/// level * n_features_per_level + f. See kernels/enc_hashgrid.cl for the exact grid convention.
///
/// Two kernel variants compute the same encoding (docs/encodings.md, "Kernel variants"): SIMD kernels for CPUs
/// (kernels/enc_hashgrid.cl) and work-group kernels for GPUs (kernels/enc_hashgrid_wg.cl), chosen per device
/// from a table (lib/src/nn/encodings/hash_grid_tuning.cpp), overridable by the "kernel_variant" key and the
/// RELIT_ENCODING_VARIANT environment variable. Both reduce the parameter gradient in a fixed order: it is
/// bit-for-bit reproducible on one device for one kernel choice.
class HashGridEncoding final : public Encoding {
 public:
  struct Options {
    std::uint32_t n_levels = 16;
    std::uint32_t n_features_per_level = 2;
    std::uint32_t log2_hashmap_size = 19;
    std::uint32_t base_resolution = 16;
    float per_level_scale = 2.0f;
    /// Table ranges per level in the parameter-gradient pass; 0 = per device (1 on CPUs). The gradient is
    /// bit-for-bit the same for any value: only the parallelism changes.
    std::uint32_t gradient_ranges = 0;
    /// "auto" (the device's table row), "simd" or "workgroup"; RELIT_ENCODING_VARIANT overrides it.
    std::string kernel_variant = "auto";
  };
  /// Parameters of the work-group kernels (the -D parameters of kernels/enc_hashgrid_wg.cl). Any valid set
  /// gives the same results (the parameter gradient bit for bit); it only changes the speed.
  struct WorkGroupParams {
    std::uint32_t items = 64;         ///< WG_ITEMS: samples (of one level) per group of the forward, 1..1024
    std::uint32_t grad_items = 64;    ///< GRAD_ITEMS: table ranges per group of the parameter gradient, 1..1024
    std::uint32_t grad_chunk = 64;    ///< GRAD_CHUNK: samples staged per step of the parameter gradient, a
                                      ///< multiple of 16 in 16..1024 (lowered to fit the device's local memory)
    std::uint32_t grad_groups = 2;    ///< parameter-gradient groups per compute unit, all levels together (at
                                      ///< least one per level), 1..256
    std::uint32_t input_samples = 4;  ///< IN_S: samples per group of the input gradient (x n_levels work-items,
                                      ///< lowered to fit the device's work-group limit), 1..256
    bool operator==(const WorkGroupParams& o) const;
    std::string str() const;  ///< "N64 G64/C64/x2 I4"
  };
  /// What runs on a device: the variant, the work-group parameters, and where the choice came from.
  struct KernelChoice {
    KernelVariant variant = KernelVariant::Simd;
    WorkGroupParams workgroup;  ///< the work-group kernels' parameters (as lowered to fit, from kernel_choice())
    bool tuned = false;         ///< the parameters were measured on such a device (false: a default)
    std::string source;         ///< "table: NVIDIA GPU", "RELIT_ENCODING_VARIANT", "kernel_variant", ...
    std::string str() const;    ///< "workgroup N256 G128/C128/x2 I8 (table: NVIDIA GPU, untuned)"
  };
  /// The device's row of the tuning table: CPUs run the SIMD kernels, GPUs and other devices the work-group
  /// kernels, with parameters per vendor.
  static KernelChoice device_default(const DeviceInfo& info);
  /// device_default() with RELIT_ENCODING_VARIANT (simd, workgroup or auto) applied: what an encoding whose
  /// kernel_variant is "auto" runs. Throws InvalidArgument on another value.
  static KernelChoice default_kernels(const DeviceInfo& info);
  /// One level's grid and its part of the parameter vector.
  struct Level {
    float scale;           ///< p = x * scale + 0.5 in vertex units
    std::uint32_t res;     ///< vertices per axis
    std::uint32_t size;    ///< table entries
    std::uint32_t offset;  ///< first parameter of the level (floats)
    bool hashed;           ///< false: one entry per vertex
  };
  static constexpr std::array<std::uint32_t, 3> kPrimes = {1u, 2654435761u, 805459861u};

  HashGridEncoding(std::uint32_t n_input_dims, Options options);

  std::string type() const override { return "HashGrid"; }
  Json hyperparams() const override;
  std::uint32_t n_params() const override { return m_n_params; }
  /// Uniform in [-1e-4, 1e-4] (instant-ngp), from a counter-based hash of (seed, index).
  void initialize_params(float* out, std::uint64_t seed) const override;
  std::uint32_t n_input_dims() const override { return m_dims; }
  std::uint32_t n_output_dims() const override { return m_options.n_levels * m_options.n_features_per_level; }
  const std::vector<Level>& levels() const { return m_levels; }
  const Options& options() const { return m_options; }
  using Encoding::backward;
  using Encoding::forward;
  void forward(const Device& device, ConstParamSlice params, const BatchMatrix& input, std::uint32_t in_col,
               BatchMatrix& output, std::uint32_t out_col, Workspace* workspace) const override;
  void backward(const Device& device, ConstParamSlice params, const BatchMatrix& input, std::uint32_t in_col,
                const BatchMatrix& d_output, std::uint32_t out_col, ParamSlice grads, bool accumulate,
                BatchMatrix* d_input, Workspace* workspace) const override;
  /// Table ranges per level in the parameter-gradient pass on `device` (Options::gradient_ranges, or 1 on
  /// CPUs and enough to occupy a GPU otherwise).
  std::uint32_t gradient_ranges(const Device& device) const;
  /// Runs `variant` (with `params` for the work-group kernels, else the device row's) whatever the config and
  /// environment say, for launches from now on (tests, benchmarks); std::nullopt restores the normal choice.
  /// Throws InvalidArgument on parameters out of range.
  void set_kernels(std::optional<KernelVariant> variant, std::optional<WorkGroupParams> params = std::nullopt);
  /// What the kernels use on `device`: set_kernels(), else RELIT_ENCODING_VARIANT, else the kernel_variant
  /// option, else the device's table row; the work-group parameters as lowered to fit the device. The
  /// launches resolve it once per device (as FullyFusedMLP's kernels: the environment is read when the
  /// encoding first runs on a device) until set_kernels().
  KernelChoice kernel_choice(const Device& device) const;

 private:
  /// A device's resolved choice and the -D definitions of its kernels' program.
  struct Launch {
    Device device;
    KernelChoice choice;
    Defines defines;
  };
  const Launch& launch(const Device& device) const;
  Defines defines(const Device& device) const;
  Defines workgroup_defines(const Device& device, const WorkGroupParams& p) const;
  std::uint32_t m_dims;
  Options m_options;
  std::optional<KernelVariant> m_forced_variant;  // set_kernels()
  std::optional<WorkGroupParams> m_forced_params;
  mutable std::mutex m_mutex;
  mutable std::vector<std::unique_ptr<Launch>> m_launches;  // one per device
  std::vector<Level> m_levels;
  std::uint32_t m_n_params = 0;
};

/// Nested encodings, each over its n_dims_to_encode consecutive input dims (the last one may take "the
/// rest"); outputs concatenated in order; parameters are the nested slices concatenated in order.
class CompositeEncoding final : public Encoding {
 public:
  struct Part {
    std::unique_ptr<Encoding> encoding;
    std::uint32_t n_dims_to_encode;
  };
  CompositeEncoding(std::vector<Part> parts, Json resolved);

  std::string type() const override { return "Composite"; }
  Json hyperparams() const override { return m_resolved; }
  std::uint32_t n_params() const override;
  void initialize_params(float* out, std::uint64_t seed) const override;
  std::uint32_t n_input_dims() const override;
  std::uint32_t n_output_dims() const override;
  const std::vector<Part>& parts() const { return m_parts; }
  using Encoding::backward;
  using Encoding::forward;
  void forward(const Device& device, ConstParamSlice params, const BatchMatrix& input, std::uint32_t in_col,
               BatchMatrix& output, std::uint32_t out_col, Workspace* workspace) const override;
  void backward(const Device& device, ConstParamSlice params, const BatchMatrix& input, std::uint32_t in_col,
                const BatchMatrix& d_output, std::uint32_t out_col, ParamSlice grads, bool accumulate,
                BatchMatrix* d_input, Workspace* workspace) const override;

 private:
  std::vector<Part> m_parts;
  Json m_resolved;
};

}  // namespace relit::nn
