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
  // [x (n_input), ones, h_0 (width), ..., h_(L-1)], dz the rows [dZ_0 (width), ..., dZ_(L-1), dZ_out].
  Buffer<float> act, dz, partial;
  Buffer<float> scratch;  // the fused training kernel's per-chunk scratch
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
         fused_train_max_params == o.fused_train_max_params && train_group == o.train_group;
}

std::string FullyFusedMLP::Blocking::str() const {
  return "T" + std::to_string(forward_tiles) + " R" + std::to_string(forward_rows) + " B" +
         std::to_string(backward_rows) + " V" + std::to_string(dw_vector) + " " + std::to_string(dw_rows) + "x" +
         std::to_string(dw_cols) + "/" + std::to_string(dw_region) + " F" + std::to_string(fused_train_max_params) +
         " G" + std::to_string(train_group);
}

// Register blocks (kernels/mlp.cl; measurements in docs/networks.md). A work-item's accumulators must fit the
// vector registers: NR x FWD_T float16 for the forward/backward blocks, DW_RJ x DW_RK vectors for dW.
//  - AVX2 CPUs and GPUs: one tile per work-item, 4 outputs per block (a float16 is two ymm registers on
//    AVX2: 8 accumulators of 16), float8 dW accumulators in 4 x 3 blocks.
//  - AVX-512 CPUs (16-float native vectors, 32 zmm registers): a float16 is one register and two loads per
//    cycle feed two FMAs, so a block must reuse each load: four tiles per work-item (every weight broadcast
//    feeds four FMAs) and 6 outputs per block (every activation load feeds six; 24 accumulators), float16 dW
//    accumulators in 5 x 5 blocks, and the fused training kernel for small networks, whose separate
//    backward kernels are bound by memory traffic (2-core Zen 5, docs/networks.md).
FullyFusedMLP::Blocking FullyFusedMLP::default_blocking(const DeviceInfo& info) {
  Blocking b;
  if (info.type == "cpu" && info.preferred_vector_width_float >= 16) {
    b.forward_tiles = 4;
    b.forward_rows = 6;
    b.backward_rows = 6;
    b.dw_vector = 16;
    b.dw_rows = 5;
    b.dw_cols = 5;
    b.dw_region = 20;
    b.fused_train_max_params = 16384;  // 1 MiB of accumulators per work-item
    b.train_group = 8;
  }
  return b;
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
    check(b.dw_vector == 8 || b.dw_vector == 16, "dw_vector must be 8 or 16");
    check(b.dw_rows >= 1 && b.dw_rows <= 8 && b.dw_cols >= 1 && b.dw_cols <= 8, "dw_rows, dw_cols must be in [1, 8]");
    check(b.dw_region >= b.dw_rows && b.dw_region % b.dw_rows == 0, "dw_region must be a multiple of dw_rows");
    check(b.train_group >= b.forward_tiles && b.train_group <= 64 && b.train_group % b.forward_tiles == 0,
          "train_group must be a multiple of forward_tiles, at most 64");
  }
  std::lock_guard<std::mutex> lock(m_mutex);
  m_blocking = blocking;
  m_kernels.clear();
}

FullyFusedMLP::Blocking FullyFusedMLP::blocking(const Device& device) const {
  std::lock_guard<std::mutex> lock(m_mutex);
  return blocking_locked(device);
}

FullyFusedMLP::Blocking FullyFusedMLP::blocking_locked(const Device& device) const {
  return m_blocking ? *m_blocking : default_blocking(device.info());
}

struct FullyFusedMLP::Kernels {
  Device device;
  Blocking blocking;
  Kernel forward, backward, weight_grad, reduce, train;
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

std::uint32_t FullyFusedMLP::layer_offset(std::uint32_t l) const {
  std::uint32_t off = 0;
  for (std::uint32_t i = 0; i < l; ++i) off += layer_outputs(i) * (layer_inputs(i) + (m_bias ? 1 : 0));
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
    const std::uint32_t n_in = layer_inputs(l), n_out = layer_outputs(l), stride = n_in + (m_bias ? 1 : 0);
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
  const Blocking b = blocking_locked(device);
  std::uint32_t skip_mask = 0, top_skip = 0;
  for (std::uint32_t l : m_skip_layers) {
    skip_mask |= 1u << l;
    top_skip = std::max(top_skip, l);
  }
  std::string acts;
  for (Activation a : m_output_activations) acts += (acts.empty() ? "" : ",") + std::to_string(static_cast<int>(a));
  const Defines defines = {{"N_IN", std::to_string(m_n_input)},
                           {"WIDTH", std::to_string(m_width)},
                           {"N_HIDDEN", std::to_string(m_n_hidden)},
                           {"N_OUT", std::to_string(m_n_output)},
                           {"SKIP_MASK", std::to_string(skip_mask) + "u"},
                           {"TOP_SKIP", std::to_string(top_skip)},
                           {"HIDDEN_ACT", std::to_string(static_cast<int>(m_hidden_activation))},
                           {"OUT_ACTS", acts},
                           {"BIAS", m_bias ? "1" : "0"},
                           {"FWD_T", std::to_string(b.forward_tiles)},
                           {"FWD_R", std::to_string(b.forward_rows)},
                           {"BWD_R", std::to_string(b.backward_rows)},
                           {"DW_VEC", std::to_string(b.dw_vector)},
                           {"DW_RJ", std::to_string(b.dw_rows)},
                           {"DW_RK", std::to_string(b.dw_cols)},
                           {"DW_ROWS", std::to_string(b.dw_region)},
                           {"TRAIN_G", std::to_string(b.train_group)}};
  const Program program = device.program("mlp.cl", defines);
  auto k = std::make_unique<Kernels>();
  k->device = device;
  k->blocking = b;
  k->forward = program.kernel("mlp_forward");
  k->backward = program.kernel("mlp_backward");
  k->weight_grad = program.kernel("mlp_weight_grad_partial");
  k->reduce = program.kernel("mlp_reduce_chunks");
  k->train = program.kernel("mlp_train_fused");
  // The preferred multiple is the SIMD/warp width of the device; on a CPU each work-group runs on one core.
  auto local = [](const Kernel& kernel) {
    return std::max<std::size_t>(1, std::min(kernel.preferred_work_group_multiple(), kernel.max_work_group_size()));
  };
  k->local_forward = local(k->forward);
  k->local_backward = local(k->backward);
  k->local_weight_grad = local(k->weight_grad);
  k->local_reduce = local(k->reduce);
  m_kernels.push_back(std::move(k));
  return *m_kernels.back();
}

void FullyFusedMLP::warm_up(const Device& device) const { kernels(device); }

bool FullyFusedMLP::fused_training(const Device& device) const {
  return n_params() <= kernels(device).blocking.fused_train_max_params;
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
                                   BatchMatrix& output, Buffer<float>* act, std::uint32_t act_padded) const {
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
  kernel.args(n_tiles, act_padded, *params.buffer, static_cast<std::uint32_t>(params.offset), input.data(),
              output.data(), act ? *act : output.data(), static_cast<std::uint32_t>(act ? 1 : 0));
  kernel.launch((n_tiles + k.blocking.forward_tiles - 1) / k.blocking.forward_tiles, k.local_forward);
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
  if (fused_training(device)) {  // backward() recomputes the activations: nothing to save
    ws->padded = std::max(ws->padded, input.padded());
    ws->saved = false;
    launch_forward(device, params, input, output, nullptr, 0);
    return;
  }
  if (input.padded() > ws->padded || ws->act.empty()) {  // grow only: a training loop reuses its buffers
    ws->padded = std::max(ws->padded, input.padded());
    ws->act = Buffer<float>(device, std::size_t(ws->padded) * (std::size_t(m_width) * m_n_hidden + m_n_input + 1));
    ws->dz = Buffer<float>(device, std::size_t(ws->padded) * (std::size_t(m_width) * m_n_hidden + m_n_output));
  }
  ws->saved = true;
  launch_forward(device, params, input, output, &ws->act, ws->padded);
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

  const std::size_t wanted = kChunksPerComputeUnit * std::max(1u, device.info().compute_units);
  // The per-chunk partials in ws->partial, summed over chunks in a fixed order into the gradient slice.
  auto reduce_chunks = [&](std::uint32_t n_chunks) {
    Kernel rk = k.reduce;
    rk.args(np, n_chunks, ws->partial, np, *grads.buffer, static_cast<std::uint32_t>(grads.offset),
            static_cast<std::uint32_t>(accumulate ? 1 : 0));
    rk.launch((np + 7) / 8, k.local_reduce);
  };
  if (fused_training(device)) {
    // Chunks of whole groups of TRAIN_G tiles, one work-item each (fixed for a given batch and device).
    const std::uint32_t t = k.blocking.train_group;
    const std::size_t groups = (n_tiles + t - 1) / t;
    const std::size_t chunks = std::clamp<std::size_t>(wanted, 1, groups);
    const std::uint32_t chunk_tiles = static_cast<std::uint32_t>((groups + chunks - 1) / chunks) * t;
    const std::uint32_t n_chunks = (n_tiles + chunk_tiles - 1) / chunk_tiles;
    const std::size_t rows = m_n_input + 1 + std::size_t(m_n_hidden) * m_width + 2 * std::max(m_width, m_n_output);
    const std::size_t stride = round_up(16 * (np + rows * t + m_n_input), 16);
    if (ws->scratch.size() < n_chunks * stride) ws->scratch = Buffer<float>(device, n_chunks * stride);
    if (ws->partial.size() < std::size_t(n_chunks) * np)
      ws->partial = Buffer<float>(device, std::size_t(n_chunks) * np);
    Kernel tk = k.train;
    tk.args(n_tiles, batch, chunk_tiles, np, *params.buffer, static_cast<std::uint32_t>(params.offset), input.data(),
            output.data(), d_output.data(), d_input ? d_input->data() : ws->scratch,
            static_cast<std::uint32_t>(d_input ? 1 : 0), ws->scratch, static_cast<std::uint32_t>(stride), ws->partial,
            np);
    tk.launch(n_chunks, 1);
    reduce_chunks(n_chunks);
    return;
  }
  if (!ws->saved) throw InvalidArgument("FullyFusedMLP::backward: call forward() with this workspace and batch first");

  // Chunks of the batch for the weight-gradient partials (fixed for a given batch and device: reproducible).
  std::uint32_t max_in = 0;
  for (std::uint32_t l = 0; l <= m_n_hidden; ++l) max_in = std::max(max_in, layer_inputs(l) + 1);
  ChunkPlan plan;
  plan.n_samples = n_tiles * kBatchTile;
  const std::size_t budget = std::max<std::size_t>(1, kMaxPartialFloats / np);
  const std::size_t chunks = std::clamp<std::size_t>(std::min(wanted, budget), 1, n_tiles);
  plan.chunk_len = static_cast<std::uint32_t>((n_tiles + chunks - 1) / chunks) * kBatchTile;
  plan.n_chunks = (plan.n_samples + plan.chunk_len - 1) / plan.chunk_len;
  plan.sub = static_cast<std::uint32_t>(
      std::clamp<std::size_t>(kSubChunkBytes / (std::size_t(max_in) * sizeof(float)), kMinSubChunk, kMaxSubChunk) /
      kBatchTile * kBatchTile);
  if (ws->partial.size() < std::size_t(plan.n_chunks) * np)
    ws->partial = Buffer<float>(device, std::size_t(plan.n_chunks) * np);

  // 1. dZ of every layer (and dL/dx), one work-item per tile.
  Kernel bk = k.backward;
  bk.args(n_tiles, ws->padded, batch, *params.buffer, static_cast<std::uint32_t>(params.offset), output.data(),
          d_output.data(), ws->act, ws->dz, d_input ? d_input->data() : ws->dz,
          static_cast<std::uint32_t>(d_input ? 1 : 0));
  bk.launch((n_tiles + k.blocking.forward_tiles - 1) / k.blocking.forward_tiles, k.local_backward);

  // 2. Per-chunk partial weight gradients, layer by layer, into one [chunk][param] buffer.
  Kernel wk = k.weight_grad;
  for (std::uint32_t l = 0; l <= m_n_hidden; ++l) {
    const std::uint32_t n_out = layer_outputs(l);
    const std::uint32_t a_n = l == 0 ? 0 : m_width;
    const std::uint32_t regions = (n_out + k.blocking.dw_region - 1) / k.blocking.dw_region;
    const std::uint32_t x_row = l == 0 || has_skip(l) ? 0 : m_n_input;  // x rows then the ones row
    const std::uint32_t x_n = (l == 0 || has_skip(l) ? m_n_input : 0) + (m_bias ? 1 : 0);
    wk.args(plan.n_samples, plan.chunk_len, plan.n_chunks, plan.sub, ws->padded, ws->dz, l * m_width, n_out, ws->act,
            l == 0 ? 0u : m_n_input + 1 + (l - 1) * m_width, a_n, x_row, x_n, ws->partial, np, layer_offset(l));
    // Few, long work-items: keep at least ~4 work-groups per compute unit for load balance.
    const std::size_t items = std::size_t(plan.n_chunks) * regions;
    std::size_t local = k.local_weight_grad;
    while (local > 1 && items / local < 4 * std::size_t(std::max(1u, device.info().compute_units))) local /= 2;
    wk.launch(items, local);
  }

  // 3. Fixed-order sum over chunks into the gradient slice.
  reduce_chunks(plan.n_chunks);
}

}  // namespace relit::nn
