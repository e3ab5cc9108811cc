#include <relit/parallel.hpp>
#include <relit/version.hpp>

#include <string>

namespace relit {
const char* version() { return RELIT_VERSION_STRING; }

const char* build_features() {
  static const std::string text = std::string(RELIT_WITH_OPENIMAGEIO ? "" : "no ") + "OpenImageIO, " +
                                  (RELIT_WITH_OPENVDB ? "" : "no ") + "OpenVDB, " +
                                  (parallel::built_with_mpi() ? "" : "no ") + "MPI";
  return text.c_str();
}
}  // namespace relit
