// Text files compiled into the library by cmake/EmbedFiles.cmake: the OpenCL sources of kernels/ and the
// preset configs of configs/.
#pragma once

#include <vector>

namespace relit::detail {

struct EmbeddedFile {
  const char* name;  ///< file name in its folder, e.g. "util.cl", "common.clh" or "fast.json"
  const char* text;
};

const std::vector<EmbeddedFile>& embedded_kernels();
const std::vector<EmbeddedFile>& embedded_presets();

}  // namespace relit::detail
