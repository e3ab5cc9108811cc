// Registration of the networks (one registry entry per network type).
#include <relit/nn/fully_fused_mlp.hpp>
#include <relit/nn/registry.hpp>

namespace relit::nn {

void register_networks(NetworkRegistry& registry) {
  registry.add("FullyFusedMLP",
               "multi-layer perceptron with all layers fused in one kernel per pass (widths 16-256, skip "
               "connections, per-head output activations)",
               [](config::Reader& reader, std::uint32_t n_input_dims, std::uint32_t n_output_dims) {
                 return std::make_unique<FullyFusedMLP>(reader, n_input_dims, n_output_dims);
               });
}

}  // namespace relit::nn
