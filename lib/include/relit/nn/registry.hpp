// Registries of the nn component families. Each component registers itself in the function of its
// family (register_encodings, register_networks, ... in lib/src/nn/), called once on first use.
#pragma once

#include <relit/config.hpp>
#include <relit/nn/module.hpp>

namespace relit::nn {

class Loss;
class Optimizer;

/// Encodings are built for a number of input dimensions: create(json, pointer, n_input_dims).
using EncodingRegistry = config::Registry<Encoding, std::uint32_t>;
/// Networks are built for (n_input_dims, n_output_dims).
using NetworkRegistry = config::Registry<Network, std::uint32_t, std::uint32_t>;

const EncodingRegistry& encodings();
const NetworkRegistry& networks();

std::unique_ptr<Encoding> create_encoding(const Json& json, std::uint32_t n_input_dims, const std::string& pointer = "");
std::unique_ptr<Network> create_network(const Json& json, std::uint32_t n_input_dims, std::uint32_t n_output_dims,
                                        const std::string& pointer = "");

// Registration hooks, one per source file family.
void register_encodings(EncodingRegistry& registry);
void register_networks(NetworkRegistry& registry);

}  // namespace relit::nn
