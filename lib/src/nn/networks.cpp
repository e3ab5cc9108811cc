// Registration of the networks (one registry entry per network type).
#include <relit/nn/registry.hpp>

namespace relit::nn {

void register_networks(NetworkRegistry& registry) { (void)registry; }

}  // namespace relit::nn
