// Kernel variants: the two shapes relit's hot kernels come in, and what their per-device tables share.
//
//   simd       one work-item owns 16-sample tiles as float16 lanes; no barriers, no local memory (CPUs, where
//              PoCL turns the lanes into SIMD code and a work-group runs on one core)
//   workgroup  one work-item per sample (or sample x level, ...), work-groups that share data through local
//              memory and reduce in a fixed order (GPUs)
//
// Each component with both (FullyFusedMLP, HashGridEncoding, VolumeRenderer) chooses per device from its own
// table of rows by device type and vendor, as CLBlast keeps a database of tuned parameters per device; a
// config key and an environment variable override the row's variant (docs/networks.md, "Kernel variants").
#pragma once

#include <relit/cl/device.hpp>

#include <cstdint>
#include <optional>
#include <string>

namespace relit {

enum class KernelVariant : std::uint8_t { Simd, WorkGroup };

/// "simd", "workgroup".
const char* kernel_variant_name(KernelVariant v);

/// "simd" or "workgroup" (any case) as a variant, "auto" or "" as std::nullopt (the device's choice); throws
/// InvalidArgument naming `what` (a key or variable) on anything else.
std::optional<KernelVariant> parse_kernel_variant(const std::string& value, const std::string& what);

/// parse_kernel_variant() of the environment variable `name`; std::nullopt when it is unset.
std::optional<KernelVariant> kernel_variant_from_env(const char* name);

/// Whether a table row matches a device: `type` is DeviceInfo::type ("" for any), `vendor` fragments of
/// DeviceInfo::vendor separated by '|', matched case-insensitively ("" for any).
bool device_matches(const DeviceInfo& info, const char* type, const char* vendor);

}  // namespace relit
