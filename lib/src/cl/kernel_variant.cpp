// The helpers of the per-device kernel tables (relit/cl/kernel_variant.hpp).
#include <relit/cl/kernel_variant.hpp>

#include <relit/error.hpp>
#include <relit/log.hpp>

#include "shared.hpp"

#include <algorithm>
#include <cctype>
#include <cstdlib>

namespace relit {

namespace {

using ::relit::detail::lower;

}  // namespace

const char* kernel_variant_name(KernelVariant v) { return v == KernelVariant::Simd ? "simd" : "workgroup"; }

std::optional<KernelVariant> parse_kernel_variant(const std::string& value, const std::string& what) {
  const std::string v = lower(value);
  if (v.empty() || v == "auto") return std::nullopt;
  if (v == "simd") return KernelVariant::Simd;
  if (v == "workgroup") return KernelVariant::WorkGroup;
  throw InvalidArgument(what + " must be simd, workgroup or auto, got '" + value + "'");
}

std::optional<KernelVariant> kernel_variant_from_env(const char* name) {
  const char* env = std::getenv(name);
  return env ? parse_kernel_variant(env, name) : std::nullopt;
}

bool device_matches(const DeviceInfo& info, const char* type, const char* vendor) {
  if (*type && info.type != type) return false;
  const std::string fragments = vendor;
  if (fragments.empty()) return true;
  const std::string v = lower(info.vendor);
  std::size_t start = 0;
  while (start <= fragments.size()) {
    const std::size_t end = std::min(fragments.find('|', start), fragments.size());
    if (v.find(fragments.substr(start, end - start)) != std::string::npos) return true;
    start = end + 1;
  }
  return false;
}

void warn_work_group_fallback(const std::string& who, const std::string& parameters, const std::string& device_name,
                              const std::string& why, const char* env) {
  log_warning(who + ": the work-group kernels (" + parameters + ") do not fit " + device_name + ": " + why +
              "; running the SIMD kernels (set kernel_variant or " + env + " to simd to silence this)");
}

std::string kernel_choice_text(KernelVariant variant, const std::string& parameters, const std::string& source,
                               bool tuned) {
  return std::string(kernel_variant_name(variant)) + (parameters.empty() ? "" : " " + parameters) + " (" + source +
         (tuned ? "" : ", untuned") + ")";
}

}  // namespace relit
