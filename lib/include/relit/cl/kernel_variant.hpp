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
#include <relit/error.hpp>

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <utility>

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

/// "<variant> [<parameters>] (<source>[, untuned])": how the tables' choices print (relit devices, relit bench).
std::string kernel_choice_text(KernelVariant variant, const std::string& parameters, const std::string& source,
                               bool tuned);

/// A row of a component's kernel table: the devices it matches and what they run.
template <class WorkGroupParams>
struct KernelTableRow {
  const char* name;
  const char* type;    ///< DeviceInfo::type, "" for any
  const char* vendor;  ///< fragments of DeviceInfo::vendor separated by '|' (case-insensitive), "" for any
  KernelVariant variant;
  WorkGroupParams workgroup;
  bool tuned;  ///< measured on such a device, or a starting point
};

/// The first row of a component's table that matches the device, as that component's KernelChoice (variant,
/// work-group parameters, tuned, source "table: <row name>"). Rows have name, type, vendor, variant,
/// workgroup and tuned; the last row of every table matches every device (otherwise: Error naming `who`).
template <class Choice, class Row, std::size_t N>
Choice table_kernel_choice(const Row (&table)[N], const DeviceInfo& info, const char* who) {
  for (const Row& row : table) {
    if (!device_matches(info, row.type, row.vendor)) continue;
    Choice c;
    c.variant = row.variant;
    c.workgroup = row.workgroup;
    c.tuned = row.tuned;
    c.source = std::string("table: ") + row.name;
    return c;
  }
  throw Error(std::string(who) + ": the kernel table has no row for " + info.description());
}

/// `c` with the variant the environment variable `name` forces, if it is set (source: the variable's name;
/// not tuned when it differs from the row's, whose tuning is for its own variant).
template <class Choice>
Choice with_env_variant(Choice c, const char* name) {
  const std::optional<KernelVariant> env = kernel_variant_from_env(name);
  if (!env) return c;
  if (*env != c.variant) c.tuned = false;
  c.variant = *env;
  c.source = name;
  return c;
}

/// Logs that `who`'s work-group kernels (`parameters`) do not fit `device_name` (`why`) and that the SIMD kernels,
/// which run on every device, run instead; `env` is the variable that silences it.
void warn_work_group_fallback(const std::string& who, const std::string& parameters, const std::string& device_name,
                              const std::string& why, const char* env);

/// A work-group choice that does not fit its device becomes the SIMD kernels, with that warning: a working
/// component rather than an error.
template <class Choice>
void fall_back_to_simd(Choice& c, const std::string& who, const std::string& device_name, const std::string& why,
                       const char* env) {
  warn_work_group_fallback(who, c.workgroup.str(), device_name, why, env);
  c.variant = KernelVariant::Simd;
  c.tuned = false;
  c.source += ", work-group kernels did not fit";
}

/// What a component runs: `forced` (its set_kernels(), with `params` or the row's) over the environment
/// variable (already applied in `with_env`, whose source then names it) over the config's `config_variant`
/// ("auto", "simd" or "workgroup") over the table's `row`. Tuned only when it is the row's own variant and
/// parameters.
template <class Choice, class Params>
Choice resolve_kernel_choice(Choice with_env, const Choice& row, const char* env_name,
                             const std::optional<KernelVariant>& forced, const std::optional<Params>& params,
                             const std::string& config_variant) {
  Choice c = std::move(with_env);
  if (forced) {
    c.variant = *forced;
    c.workgroup = params ? *params : row.workgroup;
    c.source = "set_kernels()";
  } else if (c.source != env_name && config_variant != "auto") {
    c.variant = *parse_kernel_variant(config_variant, "kernel_variant");
    c.source = "kernel_variant";
  }
  c.tuned = row.tuned && c.variant == row.variant && (c.variant == KernelVariant::Simd || c.workgroup == row.workgroup);
  return c;
}

}  // namespace relit
