#include <relit/version.hpp>

namespace relit {
const char* version() { return RELIT_VERSION_STRING; }
}  // namespace relit
