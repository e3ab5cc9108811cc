// VolumeRenderer's per-device kernel table (as mlp_tuning.cpp for the fused MLP): which variant of the lighting
// and compositing kernels runs on a device, with which work-group parameters, and what those are based on.
#include <relit/render/volume_renderer.hpp>

#include <relit/error.hpp>

namespace relit::render {

namespace {

using WorkGroupParams = VolumeRenderer::WorkGroupParams;

using Row = KernelTableRow<WorkGroupParams>;

// Work-items per ray group, and local-memory staging. None of the GPU rows is tuned (no GPU was available to
// measure on); they are starting points: one work-item per sample at the usual 64 samples per ray (two NVIDIA
// warps, one AMD wavefront), 32 on Intel GPUs (SIMD8-32 sub-groups; two samples per item), and the shared
// directions staged in local memory, which every GPU has on chip.
const Row kTable[] = {
    // CPUs: the SIMD kernels (measured, docs/renderer.md); the work-group parameters are used only when the
    // work-group variant is forced (tests, benchmarks).
    {"CPU", "cpu", "", KernelVariant::Simd, {64, true}, true},
    {"NVIDIA GPU", "gpu", "nvidia", KernelVariant::WorkGroup, {64, true}, false},
    {"AMD GPU", "gpu", "advanced micro devices|amd", KernelVariant::WorkGroup, {64, true}, false},
    {"Intel GPU", "gpu", "intel", KernelVariant::WorkGroup, {32, true}, false},
    {"other device", "", "", KernelVariant::WorkGroup, {64, true}, false},
};

}  // namespace

bool VolumeRenderer::WorkGroupParams::operator==(const WorkGroupParams& o) const {
  return items == o.items && stage == o.stage;
}

std::string VolumeRenderer::WorkGroupParams::str() const {
  return "N" + std::to_string(items) + (stage ? " staged" : " unstaged");
}

std::string VolumeRenderer::KernelChoice::str() const {
  return kernel_choice_text(variant, variant == KernelVariant::WorkGroup ? workgroup.str() : "", source, tuned);
}

VolumeRenderer::KernelChoice VolumeRenderer::device_default(const DeviceInfo& info) {
  return table_kernel_choice<KernelChoice>(kTable, info, "VolumeRenderer");
}

VolumeRenderer::KernelChoice VolumeRenderer::default_kernels(const DeviceInfo& info) {
  return with_env_variant(device_default(info), "RELIT_RENDER_VARIANT");
}

}  // namespace relit::render
