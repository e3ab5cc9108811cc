// Registration of the encodings (one registry entry per encoding type).
#include <relit/nn/registry.hpp>

namespace relit::nn {

void register_encodings(EncodingRegistry& registry) { (void)registry; }

}  // namespace relit::nn
