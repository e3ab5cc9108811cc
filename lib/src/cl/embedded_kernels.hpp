// The OpenCL sources of kernels/, compiled into the library by cmake/EmbedKernels.cmake.
#pragma once

#include <vector>

namespace relit::detail {

struct EmbeddedKernel {
  const char* name;  ///< file name in kernels/, e.g. "util.cl" or "common.clh"
  const char* text;
};

const std::vector<EmbeddedKernel>& embedded_kernels();

}  // namespace relit::detail
