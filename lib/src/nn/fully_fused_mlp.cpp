// FullyFusedMLP: config, parameter layout and initialisation, and the launches of kernels/mlp.cl.
#include <relit/nn/fully_fused_mlp.hpp>

#include <relit/cl/program.hpp>
#include <relit/error.hpp>

#include <algorithm>
#include <cmath>
#include <string>

namespace relit::nn {

namespace {

const std::vector<std::string> kActivationNames = {"None", "ReLU", "Sigmoid", "Softplus", "Tanh"};

Activation activation_from_name(const std::string& name) {
  for (std::size_t i = 0; i < kActivationNames.size(); ++i)
    if (kActivationNames[i] == name) return static_cast<Activation>(i);
  throw InvalidArgument("unknown activation '" + name + "'");
}

// Weight-gradient partials: the batch is cut into a few chunks per compute unit (load balance; the partial
// buffer is chunks x parameters, kept under kMaxPartialFloats), each walked in sub-chunks whose input rows
// (kSubChunkBytes) stay in a core's L2 + its share of L3 while every register block of the work-item's rows
// reads them. Longer sub-chunks amortise the horizontal sums of the register blocks; on the 2-core AVX2
// machine 1 MB beat 256 KB at width 256 and tied at width 64 (docs/networks.md).
constexpr std::size_t kChunksPerComputeUnit = 8;
constexpr std::size_t kSubChunkBytes = 1024 * 1024;
constexpr std::size_t kMinSubChunk = 128, kMaxSubChunk = 2048;  // samples
constexpr std::size_t kMaxPartialFloats = std::size_t(1) << 23;
constexpr std::uint32_t kOuterBlock = 512;  // samples per block of the outer-product weight gradients

// splitmix64: a fixed, portable generator (std:: distributions differ between standard libraries).
struct SplitMix {
  std::uint64_t state;
  std::uint64_t next() {
    std::uint64_t z = (state += 0x9e3779b97f4a7c15ull);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
    return z ^ (z >> 31);
  }
  double uniform() { return static_cast<double>(next() >> 11) * 0x1.0p-53; }  // [0, 1)
};

// Floats per sample of the training workspace's act before the inputs h_(l-1) of hidden layer l >= 1 (l =
// n_hidden + 1: all of them): the feature-major rows [x, ones, h_0, ...], or, transposed for the outer-product
// weight gradients, the vectors of x (zero-padded to 16 columns) and of every hidden layer, no ones row.
std::size_t act_floats_before(bool transposed, std::uint32_t n_input, std::uint32_t width, std::uint32_t l) {
  return (transposed ? round_up(n_input, 16) : n_input + 1) + std::size_t(width) * (l - 1);
}

struct ChunkPlan {
  std::uint32_t n_samples = 0, chunk_len = 1, n_chunks = 1, sub = 1;  // samples, multiples of kBatchTile
};

class MlpWorkspace final : public Workspace {
 public:
  explicit MlpWorkspace(Device device) : device(std::move(device)) {}
  Device device;
  std::uint32_t padded = 0;  // batch capacity of act/dz (0 until forward())
  bool saved = false;        // forward() saved the activations into act (not for the fused training)
  // Feature-major (row f = feature f of every sample, `padded` floats per row): act holds the rows
  // [x (n_input), ones, h_0 (width), ..., h_(L-1)] (with the outer-product weight gradients the same features
  // transposed in vectors of 16, without the ones row: act_floats_before), dz the rows
  // [dZ_0 (width), ..., dZ_(L-1), dZ_out].
  Buffer<float> act, dz, partial;
  // The SIMD kernels' ReLU masks of the hidden layers (kernels/mlp.cl): [layer][tile][feature], bit s = sample s.
  Buffer<std::uint16_t> mask;
  Buffer<float> scratch;  // the fused training kernel's per-chunk scratch
  // The SIMD backward kernels' copy of the parameters with every layer's block transposed (kernels/mlp.cl,
  // mlp_transpose_params), refreshed by every backward().
  Buffer<float> wt;
};

}  // namespace

const char* activation_name(Activation a) { return kActivationNames.at(static_cast<std::size_t>(a)).c_str(); }

double apply_activation(Activation a, double z) {
  switch (a) {
    case Activation::ReLU: return z > 0.0 ? z : 0.0;
    case Activation::Sigmoid: return 1.0 / (1.0 + std::exp(-z));
    case Activation::Softplus: return std::max(z, 0.0) + std::log1p(std::exp(-std::abs(z)));
    case Activation::Tanh: return std::tanh(z);
    case Activation::None: break;
  }
  return z;
}

bool FullyFusedMLP::Blocking::operator==(const Blocking& o) const {
  return forward_tiles == o.forward_tiles && forward_rows == o.forward_rows && backward_rows == o.backward_rows &&
         dw_vector == o.dw_vector && dw_rows == o.dw_rows && dw_cols == o.dw_cols && dw_region == o.dw_region &&
         fused_train_max_params == o.fused_train_max_params && train_group == o.train_group &&
         train_saved == o.train_saved;
}

std::string FullyFusedMLP::Blocking::str() const {
  return "T" + std::to_string(forward_tiles) + " R" + std::to_string(forward_rows) + " B" +
         std::to_string(backward_rows) + " V" + std::to_string(dw_vector) + " " + std::to_string(dw_rows) + "x" +
         std::to_string(dw_cols) + "/" + std::to_string(dw_region) + " F" + std::to_string(fused_train_max_params) +
         " G" + std::to_string(train_group) + (train_saved ? " S" : "");
}

void FullyFusedMLP::set_blocking(std::optional<Blocking> blocking) {
  if (blocking) {
    const Blocking& b = *blocking;
    auto check = [](bool ok, const std::string& what) {
      if (!ok) throw InvalidArgument("FullyFusedMLP::set_blocking: " + what);
    };
    check(b.forward_tiles >= 1 && b.forward_tiles <= 4, "forward_tiles must be in [1, 4]");
    check(b.forward_rows >= 1 && b.forward_rows <= 16, "forward_rows must be in [1, 16]");
    check(b.backward_rows >= 1 && b.backward_rows <= 16, "backward_rows must be in [1, 16]");
    check(b.dw_vector == 1 || b.dw_vector == 8 || b.dw_vector == 16, "dw_vector must be 1, 8 or 16");
    check(b.dw_vector != 1 || b.dw_cols <= 4, "dw_cols must be at most 4 with dw_vector 1");
    check(b.dw_rows >= 1 && b.dw_rows <= 8 && b.dw_cols >= 1 && b.dw_cols <= 8, "dw_rows, dw_cols must be in [1, 8]");
    check(b.dw_region >= b.dw_rows && b.dw_region % b.dw_rows == 0, "dw_region must be a multiple of dw_rows");
    check(b.train_group >= b.forward_tiles && b.train_group <= 64 && b.train_group % b.forward_tiles == 0,
          "train_group must be a multiple of forward_tiles, at most 64");
    check(!b.train_saved || b.dw_vector == 1, "train_saved needs the outer-product weight gradients (dw_vector 1)");
  }
  std::lock_guard<std::mutex> lock(m_mutex);
  m_blocking = blocking;
  m_workgroup.reset();
  m_kernels.clear();
}

void FullyFusedMLP::set_workgroup(std::optional<WorkGroupParams> params) {
  if (params) {
    const WorkGroupParams& p = *params;
    auto check = [](bool ok, const std::string& what) {
      if (!ok) throw InvalidArgument("FullyFusedMLP::set_workgroup: " + what);
    };
    check(p.samples >= 16 && p.samples <= 512 && p.samples % 16 == 0, "samples must be a multiple of 16 in [16, 512]");
    check(p.items >= 1 && p.items <= 1024, "items must be in [1, 1024]");
    check(p.rows >= 1 && p.rows <= 16 && p.cols >= 1 && p.cols <= 16, "rows, cols must be in [1, 16]");
    check(p.k_tile >= 1 && p.k_tile <= 64, "k_tile must be in [1, 64]");
    check(p.dw_block >= 1 && p.dw_block <= 8 && p.dw_tile % p.dw_block == 0 && p.dw_tile >= p.dw_block,
          "dw_block must be in [1, 8] and divide dw_tile");
    check((p.dw_tile / p.dw_block) * (p.dw_tile / p.dw_block) <= 1024, "(dw_tile / dw_block)^2 must be at most 1024");
    check(p.dw_samples >= 1 && p.dw_samples <= 128, "dw_samples must be in [1, 128]");
    check(p.dw_chunk >= 16 && p.dw_chunk % 16 == 0, "dw_chunk must be a positive multiple of 16");
  }
  std::lock_guard<std::mutex> lock(m_mutex);
  m_workgroup = params;
  m_blocking.reset();
  m_kernels.clear();
}

FullyFusedMLP::Blocking FullyFusedMLP::blocking(const Device& device) const {
  std::lock_guard<std::mutex> lock(m_mutex);
  return choice_locked(device).blocking;
}

FullyFusedMLP::KernelChoice FullyFusedMLP::choice_locked(const Device& device) const {
  KernelChoice c = default_kernels(device.info());
  const KernelChoice row = device_default(device.info());
  auto force = [&](Variant v, const std::string& source) {
    if (v != row.variant) c.tuned = false;
    c.variant = v;
    c.source = source;
  };
  // Forced parameters are tuned when they are the device row's own.
  if (m_blocking) {
    c.blocking = *m_blocking;
    force(Variant::Simd, "set_blocking()");
    c.tuned = row.tuned && row.variant == Variant::Simd && c.blocking == row.blocking;
  } else if (m_workgroup) {
    c.workgroup = *m_workgroup;
    force(Variant::WorkGroup, "set_workgroup()");
    c.tuned = row.tuned && row.variant == Variant::WorkGroup && c.workgroup == row.workgroup;
  } else if (c.source != "RELIT_MLP_VARIANT" && m_variant_config != "auto") {
    force(m_variant_config == "simd" ? Variant::Simd : Variant::WorkGroup, "kernel_variant");
  }
  return c;
}

struct FullyFusedMLP::Kernels {
  Device device;
  KernelChoice choice;
  Blocking blocking;  // choice.blocking
  bool workgroup = false;
  // The outer-product weight gradients (the SIMD kernels with dw_vector 1); the training forward then saves the
  // activations transposed for them (kernels/mlp.cl, SAVE_T; the widths are multiples of 16).
  bool outer() const { return !workgroup && blocking.dw_vector == 1; }
  Kernel forward, backward, weight_grad, reduce, train, transpose;  // transpose: the SIMD kernels only
  std::size_t local_forward = 0, local_backward = 0, local_weight_grad = 0, local_reduce = 0;
};

FullyFusedMLP::FullyFusedMLP(config::Reader& r, std::uint32_t n_input_dims, std::uint32_t n_output_dims)
    : m_n_input(n_input_dims), m_n_output(n_output_dims) {
  if (n_input_dims == 0 || n_output_dims == 0)
    r.fail("", "FullyFusedMLP needs at least one input and one output dimension (got " + std::to_string(n_input_dims) +
                   " -> " + std::to_string(n_output_dims) + ")");
  m_width = r.uint_choice("n_neurons", 64, {16, 32, 64, 128, 256}, "width of every hidden layer");
  m_n_hidden = r.uint("n_hidden_layers", 2, 1, 32, "number of hidden layers");
  m_hidden_activation = activation_from_name(
      r.choice("activation", "ReLU", {"ReLU", "None"}, "activation of the hidden layers (None: for tests)"));
  m_bias = r.boolean("bias", true, "dense layers have biases (the last column of each layer's parameters)");
  m_skip_layers = r.uint_list("skip_layers", {}, 1, 1000,
                              "hidden layers l (1 <= l < n_hidden_layers) whose input is [h_(l-1), network input]");
  std::sort(m_skip_layers.begin(), m_skip_layers.end());
  m_skip_layers.erase(std::unique(m_skip_layers.begin(), m_skip_layers.end()), m_skip_layers.end());
  for (std::uint32_t l : m_skip_layers)
    if (l >= m_n_hidden)
      r.fail("skip_layers", "skip layer " + std::to_string(l) + " is out of range: with n_hidden_layers = " +
                                std::to_string(m_n_hidden) + " a skip layer must be in [1, " +
                                std::to_string(m_n_hidden - 1) + "]" + (m_n_hidden == 1 ? " (none possible)" : ""));

  m_variant_config = r.choice("kernel_variant", "auto", {"auto", "simd", "workgroup"},
                              "which kernels run the network: auto (the device's table: SIMD kernels on CPUs, "
                              "work-group kernels on GPUs), simd or workgroup; RELIT_MLP_VARIANT overrides it "
                              "(docs/networks.md)");
  const bool has_heads = r.has("output_heads");
  if (has_heads && r.has("output_activation"))
    r.fail("output_heads", "give either output_activation or output_heads, not both");
  const std::string out_act = r.choice("output_activation", "None", kActivationNames,
                                       "activation of every output (when output_heads is not given)");
  const Json heads = r.sub("output_heads", Json::array(), "array",
                           "list of {\"n_dims\": k, \"activation\": A} covering the outputs in order; the n_dims "
                           "sum to n_output_dims");
  if (!has_heads) {
    m_output_activations.assign(m_n_output, activation_from_name(out_act));
  } else {
    if (!heads.is_array() || heads.empty())
      r.fail("output_heads", "must be a non-empty list of {\"n_dims\": k, \"activation\": A}, got " + heads.dump());
    Json resolved = Json::array();
    for (std::size_t i = 0; i < heads.size(); ++i) {
      const std::string ptr = r.pointer("output_heads") + "/" + std::to_string(i);
      if (!heads[i].is_object()) throw ConfigError(ptr, "an output head must be an object, got " + heads[i].dump());
      config::Reader hr(heads[i], ptr, "output head");
      const std::uint32_t n = hr.uint("n_dims", 1, 1, 1u << 20, "number of output columns of this head");
      const std::string a = hr.choice("activation", "None", kActivationNames, "activation of this head");
      hr.finish();
      m_output_activations.insert(m_output_activations.end(), n, activation_from_name(a));
      resolved.push_back(hr.resolved());
    }
    if (m_output_activations.size() != m_n_output)
      r.fail("output_heads", "the heads' n_dims sum to " + std::to_string(m_output_activations.size()) +
                                 " but the network has " + std::to_string(m_n_output) +
                                 " outputs; make them add up to n_output_dims");
    r.set_resolved("output_heads", resolved);
  }
  m_hyperparams = Json{{"type", "FullyFusedMLP"}};
  m_hyperparams.update(r.resolved());
  if (!has_heads) m_hyperparams.erase("output_heads");
}

FullyFusedMLP::~FullyFusedMLP() = default;

bool FullyFusedMLP::has_skip(std::uint32_t layer) const {
  return std::binary_search(m_skip_layers.begin(), m_skip_layers.end(), layer);
}

std::uint32_t FullyFusedMLP::layer_inputs(std::uint32_t l) const {
  if (l == 0) return m_n_input;
  return m_width + (has_skip(l) ? m_n_input : 0);
}

std::uint32_t FullyFusedMLP::layer_outputs(std::uint32_t l) const { return l == m_n_hidden ? m_n_output : m_width; }

std::uint32_t FullyFusedMLP::layer_stride(std::uint32_t l) const { return layer_inputs(l) + (m_bias ? 1 : 0); }

std::uint32_t FullyFusedMLP::layer_offset(std::uint32_t l) const {
  std::uint32_t off = 0;
  for (std::uint32_t i = 0; i < l; ++i) off += layer_outputs(i) * layer_stride(i);
  return off;
}

std::uint32_t FullyFusedMLP::n_params() const { return layer_offset(m_n_hidden + 1); }

double FullyFusedMLP::flops_per_sample() const {
  double f = 0.0;
  for (std::uint32_t l = 0; l <= m_n_hidden; ++l) f += 2.0 * layer_inputs(l) * layer_outputs(l);
  return f;
}

void FullyFusedMLP::initialize_params(float* out, std::uint64_t seed) const {
  // Uniform He (Kaiming) init for the ReLU layers, Xavier for the output layer; zero biases.
  SplitMix rng{seed ^ 0x6d6c702d696e6974ull};
  for (std::uint32_t l = 0; l <= m_n_hidden; ++l) {
    const std::uint32_t n_in = layer_inputs(l), n_out = layer_outputs(l), stride = layer_stride(l);
    const bool relu = l < m_n_hidden && m_hidden_activation == Activation::ReLU;
    const double bound = relu ? std::sqrt(6.0 / n_in) : std::sqrt(6.0 / (n_in + n_out));
    float* w = out + layer_offset(l);
    for (std::uint32_t j = 0; j < n_out; ++j)
      for (std::uint32_t k = 0; k < stride; ++k)
        w[j * stride + k] = k < n_in ? static_cast<float>((2.0 * rng.uniform() - 1.0) * bound) : 0.0f;
  }
}

const FullyFusedMLP::Kernels& FullyFusedMLP::kernels(const Device& device) const {
  std::lock_guard<std::mutex> lock(m_mutex);
  for (const auto& k : m_kernels)
    if (k->device == device) return *k;
  KernelChoice choice = choice_locked(device);
  std::uint32_t skip_mask = 0, top_skip = 0;
  for (std::uint32_t l : m_skip_layers) {
    skip_mask |= 1u << l;
    top_skip = std::max(top_skip, l);
  }
  std::string acts;
  for (Activation a : m_output_activations) acts += (acts.empty() ? "" : ",") + std::to_string(static_cast<int>(a));
  const Defines network = {{"N_IN", std::to_string(m_n_input)},
                           {"WIDTH", std::to_string(m_width)},
                           {"N_HIDDEN", std::to_string(m_n_hidden)},
                           {"N_OUT", std::to_string(m_n_output)},
                           {"SKIP_MASK", std::to_string(skip_mask) + "u"},
                           {"TOP_SKIP", std::to_string(top_skip)},
                           {"HIDDEN_ACT", std::to_string(static_cast<int>(m_hidden_activation))},
                           {"OUT_ACTS", acts},
                           {"BIAS", m_bias ? "1" : "0"}};
  auto k = std::make_unique<Kernels>();
  k->device = device;
  // The preferred multiple is the SIMD/warp width of the device; on a CPU each work-group runs on one core.
  auto local = [](const Kernel& kernel) {
    return std::max<std::size_t>(1, std::min(kernel.preferred_work_group_multiple(), kernel.max_work_group_size()));
  };

  if (choice.variant == Variant::WorkGroup) {
    // The largest tile (a multiple of 16 samples, at most the chosen one) whose local arrays fit the device.
    WorkGroupParams& p = choice.workgroup;
    const std::size_t weights = std::size_t(m_width) * (p.k_tile + 1);
    auto local_floats = [&](std::size_t s) {
      const std::size_t rows = m_skip_layers.empty() ? std::max(m_n_input, m_width) : m_n_input + m_width;
      const std::size_t fwd = rows * s + weights;  // kernels/mlp_wg.cl: X_ROWS + H_ROWS
      const std::size_t bwd = std::size_t(std::max(m_width, m_n_output)) * s + weights;
      const std::size_t dw = 2 * std::size_t(p.dw_tile) * (p.dw_samples + 1);
      return std::max({fwd, bwd, dw});
    };
    const std::uint64_t budget = device.info().local_memory;
    while (p.samples > 16 && local_floats(p.samples) * sizeof(float) > budget) p.samples -= 16;
    const std::size_t dw_items = std::size_t(p.dw_tile / p.dw_block) * (p.dw_tile / p.dw_block);
    std::string why;
    if (local_floats(p.samples) * sizeof(float) > budget)
      why = "they need " + std::to_string(local_floats(p.samples) * sizeof(float)) + " bytes of local memory and " +
            device.info().name + " has " + std::to_string(budget);
    else if (std::max<std::size_t>(p.items, dw_items) > device.info().max_work_group_size)
      why = "work-groups of " + std::to_string(std::max<std::size_t>(p.items, dw_items)) + " work-items exceed " +
            device.info().name + "'s limit of " + std::to_string(device.info().max_work_group_size);
    if (why.empty()) {
      Defines defines = network;
      defines.insert({{"WG_S", std::to_string(p.samples)},
                      {"WG_SIZE", std::to_string(p.items)},
                      {"WG_RJ", std::to_string(p.rows)},
                      {"WG_RS", std::to_string(p.cols)},
                      {"WG_KT", std::to_string(p.k_tile)},
                      {"DW_T", std::to_string(p.dw_tile)},
                      {"DW_R", std::to_string(p.dw_block)},
                      {"DW_S", std::to_string(p.dw_samples)}});
      const Program program = device.program("mlp_wg.cl", defines);
      k->forward = program.kernel("mlp_wg_forward");
      k->backward = program.kernel("mlp_wg_backward");
      k->weight_grad = program.kernel("mlp_wg_weight_grad");
      k->reduce = program.kernel("mlp_wg_reduce");
      const std::size_t limit = std::min({k->forward.max_work_group_size(), k->backward.max_work_group_size()});
      if (limit < p.items || k->weight_grad.max_work_group_size() < dw_items)
        why = "the compiled kernels accept at most " + std::to_string(limit) + " work-items per group";
    }
    if (why.empty()) {
      k->workgroup = true;
      k->local_forward = k->local_backward = p.items;
      k->local_weight_grad = dw_items;
      k->local_reduce = local(k->reduce);
    } else {
      fall_back_to_simd(choice, "FullyFusedMLP", device.info().name, why, "RELIT_MLP_VARIANT");
    }
  }
  if (!k->workgroup) {
    const Blocking& b = choice.blocking;
    Defines defines = network;
    defines.insert({{"FWD_T", std::to_string(b.forward_tiles)},
                    {"FWD_R", std::to_string(b.forward_rows)},
                    {"BWD_R", std::to_string(b.backward_rows)},
                    {"DW_VEC", std::to_string(b.dw_vector)},
                    {"DW_RJ", std::to_string(b.dw_rows)},
                    {"DW_RK", std::to_string(b.dw_cols)},
                    {"DW_ROWS", std::to_string(b.dw_region)},
                    {"TRAIN_G", std::to_string(b.train_group)},
                    {"TRAIN_SAVED", b.train_saved ? "1" : "0"}});
    const Program program = device.program("mlp.cl", defines);
    k->forward = program.kernel("mlp_forward");
    k->backward = program.kernel("mlp_backward");
    k->weight_grad = program.kernel(b.dw_vector == 1 ? "mlp_weight_grad_outer" : "mlp_weight_grad_partial");
    k->reduce = program.kernel("mlp_reduce_chunks");
    k->train = program.kernel("mlp_train_fused");
    k->transpose = program.kernel("mlp_transpose_params");
    k->local_forward = local(k->forward);
    k->local_backward = local(k->backward);
    k->local_weight_grad = local(k->weight_grad);
    k->local_reduce = local(k->reduce);
  }
  k->choice = choice;
  k->blocking = choice.blocking;
  m_kernels.push_back(std::move(k));
  return *m_kernels.back();
}

FullyFusedMLP::KernelChoice FullyFusedMLP::kernel_choice(const Device& device) const { return kernels(device).choice; }

void FullyFusedMLP::warm_up(const Device& device) const { kernels(device); }

bool FullyFusedMLP::fused_training(const Device& device) const {
  const auto& k = kernels(device);
  return !k.workgroup && n_params() <= k.blocking.fused_train_max_params;
}

bool FullyFusedMLP::recomputes_forward(const Device& device) const {
  return fused_training(device) && !kernels(device).blocking.train_saved;
}

void FullyFusedMLP::check_input(const char* what, const BatchMatrix& input) const {
  if (input.cols() != m_n_input)
    throw InvalidArgument(std::string("FullyFusedMLP::") + what + ": the input has " + std::to_string(input.cols()) +
                          " columns but the network takes " + std::to_string(m_n_input) + " inputs");
}

std::unique_ptr<Workspace> FullyFusedMLP::make_workspace(const Device& device) const {
  return std::make_unique<MlpWorkspace>(device);
}

void FullyFusedMLP::launch_forward(const Device& device, ConstParamSlice params, const BatchMatrix& input,
                                   BatchMatrix& output, Buffer<float>* act, std::uint32_t act_padded,
                                   const Buffer<std::uint16_t>* mask) const {
  if (!params.buffer || params.offset + n_params() > params.buffer->size())
    throw InvalidArgument("FullyFusedMLP: the parameter slice (offset " + std::to_string(params.offset) +
                          ") does not hold the network's " + std::to_string(n_params()) + " parameters");
  if (output.cols() != m_n_output)
    throw InvalidArgument("FullyFusedMLP: the output has " + std::to_string(output.cols()) +
                          " columns but the network has " + std::to_string(m_n_output) + " outputs");
  output.resize(input.batch());
  const auto& k = kernels(device);
  const std::uint32_t n_tiles = (input.batch() + kBatchTile - 1) / kBatchTile;
  if (n_tiles == 0) return;
  Kernel kernel = k.forward;
  // The SIMD kernel counts tiles of 16 samples, the work-group kernel samples (the batch rounded up to 16).
  kernel.args(k.workgroup ? n_tiles * kBatchTile : n_tiles, act_padded, *params.buffer,
              static_cast<std::uint32_t>(params.offset), input.data(), output.data(), act ? *act : output.data(),
              static_cast<std::uint32_t>(act ? 1 : 0));
  if (!k.workgroup) kernel.arg(8, mask ? *mask : Buffer<std::uint16_t>());  // ReLU masks (empty: not saved)
  if (k.workgroup) {
    const std::size_t s = k.choice.workgroup.samples, groups = (std::size_t(n_tiles) * kBatchTile + s - 1) / s;
    kernel.launch(groups * k.local_forward, k.local_forward);
  } else {
    kernel.launch((n_tiles + k.blocking.forward_tiles - 1) / k.blocking.forward_tiles, k.local_forward);
  }
}

void FullyFusedMLP::inference(const Device& device, ConstParamSlice params, const BatchMatrix& input,
                              BatchMatrix& output) const {
  check_input("inference", input);
  launch_forward(device, params, input, output, nullptr, 0);
}

void FullyFusedMLP::forward(const Device& device, ConstParamSlice params, const BatchMatrix& input, BatchMatrix& output,
                            Workspace& workspace) const {
  check_input("forward", input);
  auto* ws = dynamic_cast<MlpWorkspace*>(&workspace);
  if (!ws || ws->device != device)
    throw InvalidArgument(
        "FullyFusedMLP::forward: the workspace was not made by this network's make_workspace "
        "for this device");
  if (recomputes_forward(device)) {  // nothing to save
    ws->padded = std::max(ws->padded, input.padded());
    ws->saved = false;
    launch_forward(device, params, input, output, nullptr, 0);
    return;
  }
  const std::size_t act_floats = act_floats_before(kernels(device).outer(), m_n_input, m_width, m_n_hidden + 1);
  if (input.padded() > ws->padded || ws->act.size() < std::size_t(ws->padded) * act_floats) {
    // Grow only: a training loop reuses its buffers.
    ws->padded = std::max(ws->padded, input.padded());
    ws->act = Buffer<float>(device, std::size_t(ws->padded) * act_floats);
    ws->dz = Buffer<float>(device, std::size_t(ws->padded) * (std::size_t(m_width) * m_n_hidden + m_n_output));
  }
  // The SIMD kernels' ReLU masks, laid out for ws->padded samples; sized apart from act and dz so that a workspace
  // first used with the work-group kernels (which need none) gets them when the SIMD kernels take over.
  const std::size_t mask_size = std::size_t(ws->padded / kBatchTile) * m_width * m_n_hidden;
  if (!kernels(device).workgroup && m_hidden_activation == Activation::ReLU && ws->mask.size() != mask_size)
    ws->mask = Buffer<std::uint16_t>(device, mask_size);
  ws->saved = true;
  launch_forward(device, params, input, output, &ws->act, ws->padded, &ws->mask);
}

void FullyFusedMLP::backward(const Device& device, ConstParamSlice params, const BatchMatrix& input,
                             const BatchMatrix& output, const BatchMatrix& d_output, ParamSlice grads, bool accumulate,
                             BatchMatrix* d_input, Workspace& workspace) const {
  check_input("backward", input);
  auto* ws = dynamic_cast<MlpWorkspace*>(&workspace);
  if (!ws || ws->device != device || ws->padded < input.padded())
    throw InvalidArgument("FullyFusedMLP::backward: call forward() with this workspace and batch first");
  if (output.cols() != m_n_output || d_output.cols() != m_n_output || output.batch() != input.batch() ||
      d_output.batch() != input.batch())
    throw InvalidArgument("FullyFusedMLP::backward: output and d_output must have " + std::to_string(m_n_output) +
                          " columns and the input's batch of " + std::to_string(input.batch()) + " samples");
  if (!grads.buffer || grads.offset + n_params() > grads.buffer->size())
    throw InvalidArgument("FullyFusedMLP::backward: the gradient slice does not hold the network's " +
                          std::to_string(n_params()) + " parameters");
  if (!params.buffer || params.offset + n_params() > params.buffer->size())
    throw InvalidArgument("FullyFusedMLP::backward: the parameter slice does not hold the network's " +
                          std::to_string(n_params()) + " parameters");
  if (d_input) {
    if (d_input->cols() != m_n_input)
      throw InvalidArgument("FullyFusedMLP::backward: d_input must have " + std::to_string(m_n_input) + " columns");
    d_input->resize(input.batch());
  }
  const auto& k = kernels(device);
  const std::uint32_t batch = input.batch();
  const std::uint32_t n_tiles = (batch + kBatchTile - 1) / kBatchTile;
  const std::uint32_t np = n_params();
  if (n_tiles == 0) {
    if (!accumulate) grads.buffer->fill(0.0f, grads.offset, np);
    return;
  }
  if (!ws->saved && !recomputes_forward(device))  // every other path reads what forward() saved
    throw InvalidArgument("FullyFusedMLP::backward: call forward() with this workspace and batch first");

  const std::size_t wanted = kChunksPerComputeUnit * std::max(1u, device.info().compute_units);
  // The per-chunk partials in ws->partial, summed over chunks in a fixed order into the gradient slice.
  auto reduce_chunks = [&](std::uint32_t n_chunks) {
    Kernel rk = k.reduce;
    rk.args(np, n_chunks, ws->partial, np, *grads.buffer, static_cast<std::uint32_t>(grads.offset),
            static_cast<std::uint32_t>(accumulate ? 1 : 0));
    rk.launch((np + 7) / 8, k.local_reduce);
  };
  if (!k.workgroup) {  // the backward kernels stream rows of W^T (kernels/mlp.cl, BACK_MASKED_BLOCK)
    if (ws->wt.size() < np) ws->wt = Buffer<float>(device, np);
    Kernel t = k.transpose;
    t.args(*params.buffer, static_cast<std::uint32_t>(params.offset), ws->wt);
    t.launch(std::size_t(m_n_hidden + 1) * std::max(m_width, m_n_output));
  }
  if (fused_training(device)) {
    // Chunks of whole groups of TRAIN_G tiles, one work-item each (fixed for a given batch and device).
    const std::uint32_t t = k.blocking.train_group;
    const std::size_t groups = (n_tiles + t - 1) / t;
    const std::size_t chunks = std::clamp<std::size_t>(wanted, 1, groups);
    const std::uint32_t chunk_tiles = static_cast<std::uint32_t>((groups + chunks - 1) / chunks) * t;
    const std::uint32_t n_chunks = (n_tiles + chunk_tiles - 1) / chunk_tiles;
    const std::size_t rows = m_n_input + 1 + std::size_t(m_n_hidden) * m_width +
                             2 * round_up(std::max(m_width, m_n_output), k.blocking.dw_rows);
    // The accumulators (kernels/mlp.cl, mlp_train_fused), in float16s: one per parameter, or with the
    // outer-product weight gradients every layer's dW rows (rows padded to a multiple of dw_rows, columns to 16)
    // and, unless the kernel reads the saved activations, the group's transposed input rows.
    std::size_t acc16 = np;
    if (k.outer()) {
      std::size_t floats = 0, vectors = 0;
      for (std::uint32_t l = 0; l <= m_n_hidden; ++l) {  // the bias column apart (its own accumulators)
        const std::size_t cols = round_up(layer_inputs(l), 16);
        floats += round_up(layer_outputs(l), k.blocking.dw_rows) * cols + (m_bias ? 16 * layer_outputs(l) : 0);
        vectors = std::max(vectors, cols / 16);
      }
      acc16 = floats / 16 + (k.blocking.train_saved ? 0 : vectors * t * kBatchTile);
    }
    const std::size_t stride = round_up(16 * (acc16 + rows * t + m_n_input), 16);
    if (ws->scratch.size() < n_chunks * stride) ws->scratch = Buffer<float>(device, n_chunks * stride);
    if (ws->partial.size() < std::size_t(n_chunks) * np)
      ws->partial = Buffer<float>(device, std::size_t(n_chunks) * np);
    const bool saved = k.blocking.train_saved;
    Kernel tk = k.train;
    tk.args(n_tiles, batch, chunk_tiles, static_cast<std::uint32_t>(acc16), *params.buffer,
            static_cast<std::uint32_t>(params.offset), ws->wt, input.data(), output.data(), d_output.data(),
            d_input ? d_input->data() : ws->scratch, static_cast<std::uint32_t>(d_input ? 1 : 0), ws->scratch,
            static_cast<std::uint32_t>(stride), ws->partial, np, saved ? ws->act : Buffer<float>(),
            saved ? ws->mask : Buffer<std::uint16_t>(), static_cast<std::uint32_t>(saved ? ws->padded : 0));
    tk.launch(n_chunks, 1);
    reduce_chunks(n_chunks);
    return;
  }
  if (k.workgroup) {
    backward_workgroup(device, params, output, d_output, grads, accumulate, d_input, *ws);
    return;
  }

  // Chunks of the batch for the weight-gradient partials (fixed for a given batch and device: reproducible).
  std::uint32_t max_in = 0;
  for (std::uint32_t l = 0; l <= m_n_hidden; ++l) max_in = std::max(max_in, layer_inputs(l) + 1);
  ChunkPlan plan;
  plan.n_samples = n_tiles * kBatchTile;
  const std::size_t budget = std::max<std::size_t>(1, kMaxPartialFloats / np);
  std::size_t chunks = std::clamp<std::size_t>(std::min(wanted, budget), 1, n_tiles);
  // A whole number of chunks per compute unit: every chunk is one work-item of the same length, so 15 chunks on
  // two cores leave one core idle for the last.
  const std::size_t cus = std::max(1u, device.info().compute_units);
  if (chunks > cus) chunks = chunks / cus * cus;
  plan.chunk_len = static_cast<std::uint32_t>((n_tiles + chunks - 1) / chunks) * kBatchTile;
  plan.n_chunks = (plan.n_samples + plan.chunk_len - 1) / plan.chunk_len;
  const bool outer = k.outer();
  plan.sub =
      outer ? kOuterBlock
            : static_cast<std::uint32_t>(std::clamp<std::size_t>(kSubChunkBytes / (std::size_t(max_in) * sizeof(float)),
                                                                 kMinSubChunk, kMaxSubChunk) /
                                         kBatchTile * kBatchTile);
  if (ws->partial.size() < std::size_t(plan.n_chunks) * np)
    ws->partial = Buffer<float>(device, std::size_t(plan.n_chunks) * np);
  // The outer-product form (dw_vector 1): per work-item its dW rows (the bias column apart) and a float16 bias
  // accumulator per row (kernels/mlp.cl, mlp_weight_grad_outer); it walks its chunk in blocks of plan.sub
  // samples.
  std::uint32_t dw_stride = 0;
  if (outer) {
    const std::size_t cstride = round_up(max_in - 1, 16);
    dw_stride = static_cast<std::uint32_t>(round_up(k.blocking.dw_region * (cstride + 16), 16));
    const std::uint32_t max_out = std::max(m_width, m_n_output);
    const std::size_t items =
        std::size_t(plan.n_chunks) * ((max_out + k.blocking.dw_region - 1) / k.blocking.dw_region);
    if (ws->scratch.size() < items * dw_stride) ws->scratch = Buffer<float>(device, items * dw_stride);
  }

  // 1. dZ of every layer (and dL/dx), one work-item per tile.
  Kernel bk = k.backward;
  bk.args(n_tiles, ws->padded, batch, ws->wt, output.data(), d_output.data(), ws->mask, ws->dz,
          d_input ? d_input->data() : ws->dz, static_cast<std::uint32_t>(d_input ? 1 : 0));
  bk.launch((n_tiles + k.blocking.forward_tiles - 1) / k.blocking.forward_tiles, k.local_backward);

  // 2. Per-chunk partial weight gradients, layer by layer, into one [chunk][param] buffer.
  Kernel wk = k.weight_grad;
  for (std::uint32_t l = 0; l <= m_n_hidden; ++l) {
    const std::uint32_t n_out = layer_outputs(l);
    const std::uint32_t a_n = l == 0 ? 0 : m_width;
    const std::uint32_t regions = (n_out + k.blocking.dw_region - 1) / k.blocking.dw_region;
    const std::uint32_t x_n = (l == 0 || has_skip(l) ? m_n_input : 0) + (m_bias ? 1 : 0);
    // Where the layer's inputs start in act: rows, or with the outer-product form vectors of 16 columns (x's
    // first, no ones row: its x_row is 0).
    const std::uint32_t a_row =
        l == 0 ? 0u : static_cast<std::uint32_t>(act_floats_before(outer, m_n_input, m_width, l) / (outer ? 16 : 1));
    const std::uint32_t x_row = l == 0 || has_skip(l) || outer ? 0 : m_n_input;  // x rows then the ones row
    wk.args(plan.n_samples, plan.chunk_len, plan.n_chunks, plan.sub, ws->padded, ws->dz, l * m_width, n_out, ws->act,
            a_row, a_n, x_row, x_n, ws->partial, np, layer_offset(l));
    if (outer) wk.arg(16, ws->scratch).arg(17, dw_stride);
    // Few, long work-items: at least ~4 work-groups per compute unit for load balance, else groups of one. Only
    // these two sizes: a CPU driver builds a kernel for every work-group size it is launched with (PoCL: seconds
    // for this one), and halving the size step by step built it up to four times over for small batches.
    const std::size_t items = std::size_t(plan.n_chunks) * regions;
    std::size_t local = k.local_weight_grad;
    if (local > 1 && items / local < 4 * std::size_t(std::max(1u, device.info().compute_units))) local = 1;
    wk.launch(items, local);
  }

  // 3. Fixed-order sum over chunks into the gradient slice.
  reduce_chunks(plan.n_chunks);
}

// The work-group variant of backward(): dZ and dL/dx per tile of samples, then per layer the weight-gradient
// partials of chunks of dw_chunk samples (fewer, longer chunks when the partial buffer would exceed
// kMaxPartialFloats) and dW tiles, then their fixed-order sum (kernels/mlp_wg.cl).
void FullyFusedMLP::backward_workgroup(const Device& device, ConstParamSlice params, const BatchMatrix& output,
                                       const BatchMatrix& d_output, ParamSlice grads, bool accumulate,
                                       BatchMatrix* d_input, Workspace& workspace) const {
  auto& ws = static_cast<MlpWorkspace&>(workspace);
  const auto& k = kernels(device);
  const WorkGroupParams& p = k.choice.workgroup;
  const std::uint32_t batch = output.batch(), np = n_params();
  const std::uint32_t n_valid = (batch + kBatchTile - 1) / kBatchTile * kBatchTile;
  const std::size_t min_chunk = (n_valid + std::max<std::size_t>(1, kMaxPartialFloats / np) - 1) /
                                std::max<std::size_t>(1, kMaxPartialFloats / np);
  const std::uint32_t chunk_len =
      static_cast<std::uint32_t>(round_up(std::max<std::size_t>(p.dw_chunk, min_chunk), kBatchTile));
  const std::uint32_t n_chunks = (n_valid + chunk_len - 1) / chunk_len;
  if (ws.partial.size() < std::size_t(n_chunks) * np) ws.partial = Buffer<float>(device, std::size_t(n_chunks) * np);

  Kernel bk = k.backward;
  bk.args(n_valid, ws.padded, batch, *params.buffer, static_cast<std::uint32_t>(params.offset), output.data(),
          d_output.data(), ws.act, ws.dz, d_input ? d_input->data() : ws.dz,
          static_cast<std::uint32_t>(d_input ? 1 : 0));
  const std::size_t groups = (std::size_t(n_valid) + p.samples - 1) / p.samples;
  bk.launch(groups * k.local_backward, k.local_backward);

  Kernel wk = k.weight_grad;
  for (std::uint32_t l = 0; l <= m_n_hidden; ++l) {
    const std::uint32_t n_out = layer_outputs(l);
    const std::uint32_t a_n = l == 0 ? 0 : m_width;
    const std::uint32_t x_row = l == 0 || has_skip(l) ? 0 : m_n_input;  // x rows then the ones row
    const std::uint32_t x_n = (l == 0 || has_skip(l) ? m_n_input : 0) + (m_bias ? 1 : 0);
    const std::size_t tiles =
        std::size_t((n_out + p.dw_tile - 1) / p.dw_tile) * ((a_n + x_n + p.dw_tile - 1) / p.dw_tile);
    wk.args(n_valid, chunk_len, ws.padded, ws.dz, l * m_width, n_out, ws.act,
            l == 0 ? 0u : m_n_input + 1 + (l - 1) * m_width, a_n, x_row, x_n, ws.partial, np, layer_offset(l));
    wk.launch(n_chunks * tiles * k.local_weight_grad, k.local_weight_grad);
  }

  Kernel rk = k.reduce;
  rk.args(np, n_chunks, ws.partial, np, *grads.buffer, static_cast<std::uint32_t>(grads.offset),
          static_cast<std::uint32_t>(accumulate ? 1 : 0));
  rk.launch(np, k.local_reduce);
}

}  // namespace relit::nn
