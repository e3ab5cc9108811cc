// The HashGrid (multiresolution hash) encoding: level layout, initialisation and launches. The kernels and
// the reasoning behind their work order and gradient scheme are in kernels/enc_hashgrid.cl.
#include "common.hpp"

#include <relit/nn/encodings.hpp>

#include <algorithm>
#include <cmath>
#include <mutex>
#include <sstream>

namespace relit::nn {

namespace {

std::uint64_t splitmix64(std::uint64_t x) {
  x += 0x9e3779b97f4a7c15ull;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ull;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebull;
  return x ^ (x >> 31);
}

// "{a,b,c}" with each value printed by `print`: an OpenCL C array initialiser for a -D definition.
template <class F>
std::string initializer(const std::vector<HashGridEncoding::Level>& levels, F print) {
  std::ostringstream s;
  s << "{";
  for (std::size_t i = 0; i < levels.size(); ++i) s << (i ? "," : "") << print(levels[i]);
  s << "}";
  return s.str();
}

}  // namespace

HashGridEncoding::HashGridEncoding(std::uint32_t n_input_dims, Options o) : m_dims(n_input_dims), m_options(o) {
  const std::string who = "HashGrid encoding: ";
  if (n_input_dims != 2 && n_input_dims != 3)
    throw InvalidArgument(who + "encodes 2-D or 3-D positions in [0, 1]^d, got " + std::to_string(n_input_dims) +
                          " input dims");
  if (o.n_levels < 1 || o.n_levels > 32) throw InvalidArgument(who + "n_levels must be in [1, 32]");
  if (o.n_features_per_level != 1 && o.n_features_per_level != 2 && o.n_features_per_level != 4 &&
      o.n_features_per_level != 8)
    throw InvalidArgument(who + "n_features_per_level must be 1, 2, 4 or 8");
  if (o.log2_hashmap_size < 10 || o.log2_hashmap_size > 24)
    throw InvalidArgument(who + "log2_hashmap_size must be in [10, 24]");
  if (o.base_resolution < 2) throw InvalidArgument(who + "base_resolution must be at least 2");
  if (!(o.per_level_scale >= 1.0f && o.per_level_scale <= 8.0f))
    throw InvalidArgument(who + "per_level_scale must be in [1, 8]");
  if (o.gradient_ranges > 4096) throw InvalidArgument(who + "gradient_ranges must be in [0, 4096]");
  parse_kernel_variant(o.kernel_variant, who + "kernel_variant");

  const std::uint64_t table = 1ull << o.log2_hashmap_size;
  std::uint64_t offset = 0;
  for (std::uint32_t l = 0; l < o.n_levels; ++l) {
    const double scale = o.base_resolution * std::pow(static_cast<double>(o.per_level_scale), l) - 1.0;
    // Positions are float: beyond ~2^22 vertices per axis the in-cell position loses all its bits.
    if (scale > 4194304.0)
      throw InvalidArgument(who + "level " + std::to_string(l) + " would have " + std::to_string(scale) +
                            " cells per axis (more than 2^22, finer than float positions resolve); lower "
                            "per_level_scale, base_resolution or n_levels");
    Level level{};
    level.scale = static_cast<float>(scale);
    // floor(x * scale + 0.5) + 1 <= ceil(scale) + 1: every corner has its own vertex (no wrap-around).
    level.res = static_cast<std::uint32_t>(std::ceil(level.scale)) + 2;
    const double vertices = std::pow(static_cast<double>(level.res), n_input_dims);
    level.hashed = vertices > static_cast<double>(table);
    level.size = level.hashed ? static_cast<std::uint32_t>(table)
                              : static_cast<std::uint32_t>(round_up(static_cast<std::uint64_t>(vertices), 8));
    level.offset = static_cast<std::uint32_t>(offset);
    offset += static_cast<std::uint64_t>(level.size) * o.n_features_per_level;
    if (offset > (1ull << 30))
      throw InvalidArgument(who + "more than 2^30 parameters (4 GiB); lower log2_hashmap_size or n_levels");
    m_levels.push_back(level);
  }
  m_n_params = static_cast<std::uint32_t>(offset);
}

Json HashGridEncoding::hyperparams() const {
  return {{"type", type()},
          {"n_levels", m_options.n_levels},
          {"n_features_per_level", m_options.n_features_per_level},
          {"log2_hashmap_size", m_options.log2_hashmap_size},
          {"base_resolution", m_options.base_resolution},
          {"per_level_scale", m_options.per_level_scale},
          {"gradient_ranges", m_options.gradient_ranges},
          {"kernel_variant", m_options.kernel_variant}};
}

void HashGridEncoding::initialize_params(float* out, std::uint64_t seed) const {
  const std::uint64_t key = splitmix64(seed ^ 0x4861736847726964ull);
  for (std::uint32_t i = 0; i < m_n_params; ++i) {
    const double u = static_cast<double>(splitmix64(key + i) >> 11) * 0x1.0p-53;  // [0, 1)
    out[i] = static_cast<float>((2.0 * u - 1.0) * 1e-4);
  }
}

std::uint32_t HashGridEncoding::gradient_ranges(const Device& device) const {
  if (m_options.gradient_ranges) return m_options.gradient_ranges;
  if (device.info().type == "cpu") return 1;
  // Enough (level, range) work-items to occupy a GPU: each range rescans the batch, so no more than that.
  const std::uint32_t want = std::max(1u, device.info().compute_units) * 16;
  return std::min<std::uint32_t>(256, (want + m_options.n_levels - 1) / m_options.n_levels);
}

Defines HashGridEncoding::defines(const Device& device) const {
  Defines d;
  d["DIMS"] = std::to_string(m_dims);
  d["FEATS"] = std::to_string(m_options.n_features_per_level);
  d["N_LEVELS"] = std::to_string(m_levels.size());
  d["LEVEL_SCALES"] = initializer(m_levels, [](const Level& l) {
    std::ostringstream s;
    s << std::hexfloat << l.scale << "f";  // exact: the kernel must place samples exactly as the host reference
    return s.str();
  });
  d["LEVEL_RES"] = initializer(m_levels, [](const Level& l) { return std::to_string(l.res) + "u"; });
  d["LEVEL_SIZE"] = initializer(m_levels, [](const Level& l) { return std::to_string(l.size) + "u"; });
  d["LEVEL_OFFSET"] = initializer(m_levels, [](const Level& l) { return std::to_string(l.offset) + "u"; });
  d["LEVEL_HASHED"] = initializer(m_levels, [](const Level& l) { return std::string(l.hashed ? "1u" : "0u"); });
  d["N_RANGES"] = std::to_string(gradient_ranges(device));
  // Software prefetch (kernels/enc_hashgrid.cl): on CPUs, whose out-of-order window alone overlaps too few of
  // the table misses.
  d["PREFETCH"] = device.info().type == "cpu" ? "1" : "0";
  return d;
}

void HashGridEncoding::set_kernels(std::optional<KernelVariant> variant, std::optional<WorkGroupParams> params) {
  if (params) {
    const WorkGroupParams& p = *params;
    auto check = [](bool ok, const std::string& what) {
      if (!ok) throw InvalidArgument("HashGridEncoding::set_kernels: " + what);
    };
    check(p.items >= 1 && p.items <= 1024, "items must be in [1, 1024]");
    check(p.grad_items >= 1 && p.grad_items <= 1024, "grad_items must be in [1, 1024]");
    check(p.grad_chunk >= 16 && p.grad_chunk <= 1024 && p.grad_chunk % 16 == 0,
          "grad_chunk must be a multiple of 16 in [16, 1024]");
    check(p.grad_groups >= 1 && p.grad_groups <= 256, "grad_groups must be in [1, 256]");
    check(p.input_samples >= 1 && p.input_samples <= 256, "input_samples must be in [1, 256]");
  }
  std::lock_guard<std::mutex> lock(m_mutex);
  m_forced_variant = variant;
  m_forced_params = variant ? params : std::nullopt;
  m_launches.clear();
}

const HashGridEncoding::Launch& HashGridEncoding::launch(const Device& device) const {
  {
    std::lock_guard<std::mutex> lock(m_mutex);
    for (const auto& l : m_launches)
      if (l->device == device) return *l;
  }
  // Resolved outside the lock (kernel_choice() may build the work-group program to check its limits).
  auto l = std::make_unique<Launch>(Launch{device, kernel_choice(device), {}});
  l->defines =
      l->choice.variant == KernelVariant::WorkGroup ? workgroup_defines(device, l->choice.workgroup) : defines(device);
  std::lock_guard<std::mutex> lock(m_mutex);
  for (const auto& other : m_launches)  // another thread got there first
    if (other->device == device) return *other;
  m_launches.push_back(std::move(l));
  return *m_launches.back();
}

HashGridEncoding::KernelChoice HashGridEncoding::kernel_choice(const Device& device) const {
  const DeviceInfo& info = device.info();
  KernelChoice c = resolve_kernel_choice(default_kernels(info), device_default(info), "RELIT_ENCODING_VARIANT",
                                         m_forced_variant, m_forced_params, m_options.kernel_variant);
  if (c.variant == KernelVariant::Simd) return c;
  // Fit the device: work-group sizes within its limit, the gradient's staged pairs within its local memory.
  WorkGroupParams& p = c.workgroup;
  const std::size_t max_items = std::max<std::size_t>(1, info.max_work_group_size);
  const std::uint32_t levels = m_options.n_levels, feats = m_options.n_features_per_level;
  p.items = static_cast<std::uint32_t>(std::min<std::size_t>(p.items, max_items));
  p.grad_items = static_cast<std::uint32_t>(std::min<std::size_t>(p.grad_items, max_items));
  auto staged_bytes = [&](std::uint32_t chunk) { return std::uint64_t(chunk) * (1u << m_dims) * (1 + feats) * 4; };
  while (p.grad_chunk > 16 && staged_bytes(p.grad_chunk) > info.local_memory) p.grad_chunk -= 16;
  while (p.input_samples > 1 && std::size_t(p.input_samples) * levels > max_items) --p.input_samples;
  std::string why;
  if (staged_bytes(p.grad_chunk) > info.local_memory)
    why = "16 staged samples need " + std::to_string(staged_bytes(16)) + " bytes of local memory";
  else if (levels > max_items)
    why = "the input gradient needs work-groups of " + std::to_string(levels) + " work-items";
  if (why.empty()) {
    const Program program = device.program("enc_hashgrid_wg.cl", workgroup_defines(device, p));
    if (program.kernel("hashgrid_wg_forward").max_work_group_size() < p.items ||
        program.kernel("hashgrid_wg_backward_params").max_work_group_size() < p.grad_items ||
        program.kernel("hashgrid_wg_backward_input").max_work_group_size() < std::size_t(p.input_samples) * levels)
      why = "the compiled kernels accept smaller work-groups";
  }
  if (!why.empty()) fall_back_to_simd(c, "HashGrid encoding", info.name, why, "RELIT_ENCODING_VARIANT");
  return c;
}

Defines HashGridEncoding::workgroup_defines(const Device& device, const WorkGroupParams& p) const {
  Defines d = defines(device);
  d.erase("N_RANGES");
  d.erase("PREFETCH");
  d["WG_ITEMS"] = std::to_string(p.items);
  d["GRAD_ITEMS"] = std::to_string(p.grad_items);
  d["GRAD_CHUNK"] = std::to_string(p.grad_chunk);
  d["IN_S"] = std::to_string(p.input_samples);
  return d;
}

void HashGridEncoding::forward(const Device& device, ConstParamSlice params, const BatchMatrix& input,
                               std::uint32_t in_col, BatchMatrix& output, std::uint32_t out_col, Workspace*) const {
  detail::check_matrix("HashGrid::forward", "input", input, in_col, m_dims);
  detail::check_matrix("HashGrid::forward", "output", output, out_col, n_output_dims(), &input);
  detail::check_slice("HashGrid::forward", "parameter", params, m_n_params);
  const Launch& l = launch(device);
  if (l.choice.variant == KernelVariant::WorkGroup) {  // one work-item per (sample, level), level-major
    const WorkGroupParams& p = l.choice.workgroup;
    Kernel k = device.kernel("enc_hashgrid_wg.cl", "hashgrid_wg_forward", l.defines);
    const std::size_t per_level = round_up(input.padded(), p.items);
    k.args(input.padded(), static_cast<std::uint32_t>(per_level), *params.buffer,
           static_cast<std::uint32_t>(params.offset), input.data(), input.cols(), in_col, output.data(), output.cols(),
           out_col)
        .launch(per_level * m_levels.size(), p.items);
    return;
  }
  Kernel k = device.kernel("enc_hashgrid.cl", "hashgrid_forward", l.defines);
  const std::size_t items = static_cast<std::size_t>(detail::n_tiles(input)) * m_levels.size();
  k.args(detail::n_tiles(input), *params.buffer, static_cast<std::uint32_t>(params.offset), input.data(), input.cols(),
         in_col, output.data(), output.cols(), out_col)
      .launch(items, detail::local_size(k));
}

void HashGridEncoding::backward(const Device& device, ConstParamSlice params, const BatchMatrix& input,
                                std::uint32_t in_col, const BatchMatrix& d_output, std::uint32_t out_col,
                                ParamSlice grads, bool accumulate, BatchMatrix* d_input, Workspace*) const {
  detail::check_matrix("HashGrid::backward", "input", input, in_col, m_dims);
  detail::check_matrix("HashGrid::backward", "d_output", d_output, out_col, n_output_dims(), &input);
  if (grads.buffer) detail::check_slice("HashGrid::backward", "gradient", grads, m_n_params);
  if (d_input) {
    detail::check_matrix("HashGrid::backward", "d_input", *d_input, in_col, m_dims, &input);
    detail::check_slice("HashGrid::backward", "parameter", params, m_n_params);
  }
  const Launch& l = launch(device);
  const Defines& defs = l.defines;
  if (l.choice.variant == KernelVariant::WorkGroup) {
    const WorkGroupParams& p = l.choice.workgroup;
    const std::uint32_t levels = static_cast<std::uint32_t>(m_levels.size());
    if (grads.buffer) {
      // Enough groups to occupy the device, at least one per level (each group rescans the batch: no more).
      const std::uint32_t cus = std::max(1u, device.info().compute_units);
      const std::uint32_t groups = std::max(1u, (cus * p.grad_groups + levels - 1) / levels);
      Kernel k = device.kernel("enc_hashgrid_wg.cl", "hashgrid_wg_backward_params", defs);
      k.args(input.batch(), groups, input.data(), input.cols(), in_col, d_output.data(), d_output.cols(), out_col,
             *grads.buffer, static_cast<std::uint32_t>(grads.offset), static_cast<std::uint32_t>(accumulate ? 0 : 1))
          .launch(std::size_t(groups) * levels * p.grad_items, p.grad_items);
    }
    if (d_input) {
      Kernel k = device.kernel("enc_hashgrid_wg.cl", "hashgrid_wg_backward_input", defs);
      const std::size_t n_groups = (input.padded() + p.input_samples - 1) / p.input_samples;
      const std::size_t local = std::size_t(p.input_samples) * levels;
      k.args(input.padded(), *params.buffer, static_cast<std::uint32_t>(params.offset), input.data(), input.cols(),
             in_col, d_output.data(), d_output.cols(), out_col, d_input->data(), d_input->cols())
          .launch(n_groups * local, local);
    }
    return;
  }
  if (grads.buffer) {
    Kernel k = device.kernel("enc_hashgrid.cl", "hashgrid_backward_params", defs);
    const std::size_t items = m_levels.size() * static_cast<std::size_t>(gradient_ranges(device));
    // One (level, range) per work-group on a CPU, so that the levels spread over the cores.
    const std::size_t local = device.info().type == "cpu" ? 1 : detail::local_size(k);
    k.args(detail::n_tiles(input), input.batch(), input.data(), input.cols(), in_col, d_output.data(), d_output.cols(),
           out_col, *grads.buffer, static_cast<std::uint32_t>(grads.offset),
           static_cast<std::uint32_t>(accumulate ? 0 : 1))
        .launch(items, local);
  }
  if (d_input) {
    Kernel k = device.kernel("enc_hashgrid.cl", "hashgrid_backward_input", defs);
    k.args(detail::n_tiles(input), *params.buffer, static_cast<std::uint32_t>(params.offset), input.data(),
           input.cols(), in_col, d_output.data(), d_output.cols(), out_col, d_input->data(), d_input->cols())
        .launch(detail::n_tiles(input), detail::local_size(k));
  }
}

}  // namespace relit::nn
