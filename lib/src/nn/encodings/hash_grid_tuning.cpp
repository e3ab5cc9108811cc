// HashGridEncoding's per-device kernel table (as mlp_tuning.cpp for the fused MLP): which kernel variant runs
// on a device, with which work-group parameters, and what those are based on.
#include <relit/nn/encodings.hpp>

#include <relit/error.hpp>

#include <string>

namespace relit::nn {

namespace {

using WorkGroupParams = HashGridEncoding::WorkGroupParams;

using Row = KernelTableRow<WorkGroupParams>;

// Work-group parameters: forward items, gradient items / chunk / groups per compute unit, input-gradient samples.
// None of the GPU rows is tuned (no GPU was available to measure on); they are starting points, based on:
//  - NVIDIA: tiny-cuda-nn runs its grid kernels with 512 threads per block; 256 here, so that a level's 2^16
//    samples still spread over 256 groups. Gradient groups of 128 owners (4 warps) staging 128 samples (12 KiB
//    of local memory at 2 features), two per SM; input-gradient groups of 8 samples x the levels (128 at 16).
//  - AMD: 256-item groups (four 64-wide wavefronts) throughout.
//  - Intel: 128-item groups (SIMD8-32 sub-groups), smaller chunks for the smaller shared local memory.
//  - any other device: 64-item groups, which every OpenCL device accepts.
constexpr WorkGroupParams kWgNvidia{256, 128, 128, 2, 8};
constexpr WorkGroupParams kWgAmd{256, 256, 128, 2, 8};
constexpr WorkGroupParams kWgIntel{128, 128, 64, 2, 4};
constexpr WorkGroupParams kWgOther{64, 64, 64, 2, 4};

const Row kTable[] = {
    // CPUs: the SIMD kernels, measured (docs/encodings.md). Their work-group parameters are used only when the
    // work-group variant is forced (tests, benchmarks).
    {"CPU", "cpu", "", KernelVariant::Simd, kWgOther, true},
    {"NVIDIA GPU", "gpu", "nvidia", KernelVariant::WorkGroup, kWgNvidia, false},
    {"AMD GPU", "gpu", "advanced micro devices|amd", KernelVariant::WorkGroup, kWgAmd, false},
    {"Intel GPU", "gpu", "intel", KernelVariant::WorkGroup, kWgIntel, false},
    {"other device", "", "", KernelVariant::WorkGroup, kWgOther, false},
};

}  // namespace

bool HashGridEncoding::WorkGroupParams::operator==(const WorkGroupParams& o) const {
  return items == o.items && grad_items == o.grad_items && grad_chunk == o.grad_chunk && grad_groups == o.grad_groups &&
         input_samples == o.input_samples;
}

std::string HashGridEncoding::WorkGroupParams::str() const {
  return "N" + std::to_string(items) + " G" + std::to_string(grad_items) + "/C" + std::to_string(grad_chunk) + "/x" +
         std::to_string(grad_groups) + " I" + std::to_string(input_samples);
}

std::string HashGridEncoding::KernelChoice::str() const {
  return kernel_choice_text(variant, variant == KernelVariant::WorkGroup ? workgroup.str() : "", source, tuned);
}

HashGridEncoding::KernelChoice HashGridEncoding::device_default(const DeviceInfo& info) {
  return table_kernel_choice<KernelChoice>(kTable, info, "HashGridEncoding");
}

HashGridEncoding::KernelChoice HashGridEncoding::default_kernels(const DeviceInfo& info) {
  return with_env_variant(device_default(info), "RELIT_ENCODING_VARIANT");
}

}  // namespace relit::nn
