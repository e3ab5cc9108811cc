// Kernel sources: embedded copies of kernels/, those added with relit::add_kernel_source(), or files from
// RELIT_KERNEL_DIR during kernel development.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace relit::detail {

/// The complete text of program `file` with every #include "x.clh" replaced by that header's text (once
/// each), so the OpenCL compiler needs no include path. Reads from RELIT_KERNEL_DIR when it is set and the
/// file exists there, else from the embedded copy or the added source. Throws IOError naming the missing file.
std::string resolve_kernel_source(const std::string& file);

/// The program files (*.cl): those relit ships, sorted, then the added ones, sorted.
std::vector<std::string> program_files();

/// FNV-1a 64-bit hash, for cache keys and saved-source names.
std::uint64_t fnv1a(const std::string& text);

}  // namespace relit::detail
