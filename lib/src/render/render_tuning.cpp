// VolumeRenderer's per-device kernel table (as mlp_tuning.cpp for the fused MLP): which variant of the lighting
// and compositing kernels runs on a device, with which work-group parameters, and what those are based on.
#include <relit/render/volume_renderer.hpp>

#include <relit/error.hpp>

namespace relit::render {

namespace {

using WorkGroupParams = VolumeRenderer::WorkGroupParams;

struct Row {
  const char* name;
  const char* type;    // DeviceInfo::type, "" for any
  const char* vendor;  // fragments of DeviceInfo::vendor separated by '|' (case-insensitive), "" for any
  KernelVariant variant;
  WorkGroupParams workgroup;
  bool tuned;
};

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
  return std::string(kernel_variant_name(variant)) +
         (variant == KernelVariant::WorkGroup ? " " + workgroup.str() : "") + " (" + source +
         (tuned ? "" : ", untuned") + ")";
}

VolumeRenderer::KernelChoice VolumeRenderer::device_default(const DeviceInfo& info) {
  for (const Row& row : kTable) {
    if (!device_matches(info, row.type, row.vendor)) continue;
    KernelChoice c;
    c.variant = row.variant;
    c.workgroup = row.workgroup;
    c.tuned = row.tuned;
    c.source = std::string("table: ") + row.name;
    return c;
  }
  throw Error("VolumeRenderer: the kernel table has no row for " + info.description());  // the last matches all
}

VolumeRenderer::KernelChoice VolumeRenderer::default_kernels(const DeviceInfo& info) {
  KernelChoice c = device_default(info);
  const std::optional<KernelVariant> env = kernel_variant_from_env("RELIT_RENDER_VARIANT");
  if (!env) return c;
  if (*env != c.variant) c.tuned = false;  // a row's tuning is for its own variant
  c.variant = *env;
  c.source = "RELIT_RENDER_VARIANT";
  return c;
}

}  // namespace relit::render
