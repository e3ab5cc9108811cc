// FullyFusedMLP's per-device kernel table (as CLBlast keeps a database of tuned parameters per device): which
// kernel variant runs on a device, with which parameters, and what those parameters are based on.
#include <relit/nn/fully_fused_mlp.hpp>

#include <relit/cl/device.hpp>
#include <relit/cl/kernel_variant.hpp>
#include <relit/error.hpp>

#include <optional>
#include <string>

namespace relit::nn {

namespace {

using Variant = FullyFusedMLP::Variant;
using Blocking = FullyFusedMLP::Blocking;
using WorkGroupParams = FullyFusedMLP::WorkGroupParams;

// One row: the devices it matches (type, a vendor fragment, a least native float vector width) and what they
// run. The first matching row wins; the last matches every device.
struct Row {
  const char* name;
  const char* type;    // DeviceInfo::type, "" for any
  const char* vendor;  // fragments of DeviceInfo::vendor separated by '|' (case-insensitive), "" for any
  unsigned min_vector_width;
  Variant variant;
  Blocking blocking;
  WorkGroupParams workgroup;
  bool tuned;
};

// Register blocks (kernels/mlp.cl; measurements in docs/networks.md). A work-item's accumulators must fit the
// vector registers: NR x FWD_T float16 for the forward/backward blocks, DW_RJ x DW_RK vectors for dW.
//  - AVX2 CPUs and GPUs: one tile per work-item, 4 outputs per block (a float16 is two ymm registers on
//    AVX2: 8 accumulators of 16), float8 dW accumulators in 4 x 3 blocks.
//  - AVX-512 CPUs (16-float native vectors, 32 zmm registers): a float16 is one register and two loads per
//    cycle feed two FMAs, so a block must reuse each load: four tiles per work-item (every weight broadcast
//    feeds four FMAs) and 6 outputs per block (every activation load feeds six; 24 accumulators), float16 dW
//    accumulators in 8 x 3 blocks (the layers' 16, 64 and 256 outputs are multiples of 8, their 33 and 65
//    inputs with the bias multiples of 3: no padded rows, against 5 x 5's fifth of wasted output-layer
//    blocks; 2 % faster at width 64 and 3-10 % at width 256 than 5 x 5), and the fused training kernel for
//    small networks, whose separate backward kernels are bound by memory traffic, in groups of 16 tiles
//    (each dW accumulator load and store feeds 16 FMAs: 4 % faster than groups of 8 at width 64). A/B runs
//    on a quiet 2-core Zen 5, docs/networks.md. The outer-product weight gradients (dw_vector 1, below) on a
//    2-core Zen 3 (AVX2): 6 x 1 blocks tied with the lane form at width 256 and were 10-20 % slower at width
//    64 (also fused), so the AVX2 row keeps the lane form.
constexpr Blocking kAvx2{};
constexpr Blocking kAvx512{4, 6, 6, 16, 8, 3, 24, 16384, 16};
//  - Intel AVX-512 CPUs: the same forward and backward blocks, but a weight-gradient work-item owns all 256 rows
//    of a layer (not 24): its chunk's input rows (4.9 MB at width 256) are then read from memory once and
//    from L2 for every row block, not re-read from memory by the 11 work-items of each chunk (832-860 ms
//    against 915-922 for the width-256 training step with 24 rows). And the weight gradients in the
//    outer-product form (dw_vector 1), 8 rows x 3 vectors of 16 columns: the lane form's 8 dZ rows of a
//    sub-chunk did not stay in L1 beside the input rows it streams from L2; the outer form's blocks of 512
//    samples keep them there and need no horizontal sums. Its weight-gradient kernel took 1.02-1.07x the
//    backward kernel's time in perf samples, against 1.35x for the lane form, and the width-256 training step
//    1028-1060 ms against 1105-1175 (alternated, docs/benchmarks.md). The fused training kernel then also takes
//    its weight gradients in the outer-product form, with float accumulators (4 bytes per parameter instead
//    of 64), in groups of 4 tiles: the width-64 step 29.0-30.8 ms against 31.9-34.3 for the lane form in
//    groups of 16 (groups of 8 and 16 were 2-5 % slower than 4), and networks up to 65,536 parameters: the
//    width-128 step 131.6 / 132.7 ms against 166.8 / 161.4 with the separate kernels (the width-256 trunk,
//    2 MB of accumulators, was 8-12 % slower fused). On a 2-core Intel Xeon (AVX-512, 2 MB L2 per core).
//    Since then the fused kernel reads the activations and ReLU masks the training forward saved (train_saved)
//    instead of recomputing the forward pass, in the same groups of 4 tiles, which gives the same gradients bit
//    for bit: the width-64 step 23.1 / 22.4 ms against 28.7 / 27.4 recomputing, the width-128 step 96.7 / 93.8
//    against 108.6 / 118.9 (relit bench, alternated, on a 2-core Xeon, model 207). Groups of 8 were as fast but
//    change the reduction order, and with it the course of training (Ours + BRDF's 600-step test fit ended
//    at 24.6 dB instead of 34.5; 36.6 with groups of 16). The width-256 trunk fused this way (groups of 16 or
//    32) was no faster than the separate kernels.
constexpr Blocking kAvx512Intel{4, 6, 6, 1, 8, 3, 256, 65536, 4, true};

// Work-group parameters: samples, items, rows x cols register block, k_tile, dW tile / block / samples, dW
// chunk.
//  - NVIDIA: measured on an H200 (OpenCL 3.0 CUDA, driver 580; bench_mlp --workgroups, 12 settings at the
//    training batch of 76800 samples, docs/benchmarks.md). 256 work-items in 4 x 4 blocks were the fastest at
//    width 256 (forward 4.9 ms, training step 19.7 ms against 5.7 and 22.9 for the first guess below) and close at
//    width 64. The dW chunk matters most: tiny-cuda-nn's split-K chunks of 4096 samples leave 19 work-groups per
//    64 x 64 layer at this batch, for 132 compute units; chunks of 512 cut the width-64 training step from 3.0 ms
//    to 1.0. OpenCL on NVIDIA gets 48 KiB of local memory per group, so from width 128 the tile is lowered
//    (FullyFusedMLP fits it to the device).
//  - AMD, Intel and other devices: not measured (no such GPU was available). Starting points: AMD the NVIDIA
//    tile with 256 work-items (four 64-wide wavefronts on GCN/CDNA, eight 32-wide ones on RDNA; 64 KiB of LDS per
//    group); Intel 64 samples and 128 work-items (EUs run SIMD8-32 sub-groups; 64 KiB of SLM per sub-slice), 4 x 4
//    blocks, 32 x 32 dW tiles; any other device small groups (64 work-items) that every OpenCL device accepts.
//    All with dW chunks of 512 samples, for the reason measured on NVIDIA.
constexpr WorkGroupParams kWgNvidia{128, 256, 4, 4, 16, 64, 4, 16, 512};
constexpr WorkGroupParams kWgAmd{128, 256, 4, 8, 16, 64, 4, 16, 512};
constexpr WorkGroupParams kWgIntel{64, 128, 4, 4, 16, 32, 4, 16, 512};
constexpr WorkGroupParams kWgOther{64, 64, 4, 4, 16, 32, 4, 16, 512};

const Row kTable[] = {
    // CPUs: the SIMD kernels, measured (PoCL on 2-core AMD EPYC machines with AVX2 and with AVX-512, Zen 5,
    // and on a 2-core Intel Xeon with AVX-512; docs/networks.md). Their work-group parameters are only used when the
    // work-group variant is forced.
    {"Intel AVX-512 CPU", "cpu", "intel", 16, Variant::Simd, kAvx512Intel, kWgOther, true},
    {"AVX-512 CPU", "cpu", "", 16, Variant::Simd, kAvx512, kWgOther, true},
    {"CPU", "cpu", "", 0, Variant::Simd, kAvx2, kWgOther, true},
    {"NVIDIA GPU", "gpu", "nvidia", 0, Variant::WorkGroup, kAvx2, kWgNvidia, true},
    {"AMD GPU", "gpu", "advanced micro devices|amd", 0, Variant::WorkGroup, kAvx2, kWgAmd, false},
    {"Intel GPU", "gpu", "intel", 0, Variant::WorkGroup, kAvx2, kWgIntel, false},
    {"other device", "", "", 0, Variant::WorkGroup, kAvx2, kWgOther, false},
};

}  // namespace

const char* FullyFusedMLP::variant_name(Variant v) { return kernel_variant_name(v); }

bool FullyFusedMLP::WorkGroupParams::operator==(const WorkGroupParams& o) const {
  return samples == o.samples && items == o.items && rows == o.rows && cols == o.cols && k_tile == o.k_tile &&
         dw_tile == o.dw_tile && dw_block == o.dw_block && dw_samples == o.dw_samples && dw_chunk == o.dw_chunk;
}

std::string FullyFusedMLP::WorkGroupParams::str() const {
  return "S" + std::to_string(samples) + " N" + std::to_string(items) + " " + std::to_string(rows) + "x" +
         std::to_string(cols) + " K" + std::to_string(k_tile) + " dW" + std::to_string(dw_tile) + "/" +
         std::to_string(dw_block) + " S" + std::to_string(dw_samples) + " C" + std::to_string(dw_chunk);
}

std::string FullyFusedMLP::KernelChoice::str() const {
  return kernel_choice_text(variant, variant == Variant::Simd ? blocking.str() : workgroup.str(), source, tuned);
}

FullyFusedMLP::KernelChoice FullyFusedMLP::device_default(const DeviceInfo& info) {
  for (const Row& row : kTable) {
    if (!device_matches(info, row.type, row.vendor)) continue;
    if (info.preferred_vector_width_float < row.min_vector_width) continue;
    KernelChoice c;
    c.variant = row.variant;
    c.blocking = row.blocking;
    c.workgroup = row.workgroup;
    c.tuned = row.tuned;
    c.source = std::string("table: ") + row.name;
    return c;
  }
  throw Error("FullyFusedMLP: the kernel table has no row for " + info.description());  // the last row matches all
}

FullyFusedMLP::KernelChoice FullyFusedMLP::default_kernels(const DeviceInfo& info) {
  return with_env_variant(device_default(info), "RELIT_MLP_VARIANT");
}

FullyFusedMLP::Blocking FullyFusedMLP::default_blocking(const DeviceInfo& info) {
  return device_default(info).blocking;
}

}  // namespace relit::nn
