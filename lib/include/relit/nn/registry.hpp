// Registries of the nn component families. Each component registers itself in the function of its
// family (register_encodings, register_networks, ... in lib/src/nn/), called once on first use.
#pragma once

#include <relit/config.hpp>
#include <relit/nn/loss.hpp>
#include <relit/nn/module.hpp>
#include <relit/nn/optimizer.hpp>

namespace relit::nn {

/// Encodings are built for a number of input dimensions: create(json, pointer, n_input_dims).
using EncodingRegistry = config::Registry<Encoding, std::uint32_t>;
/// Networks are built for (n_input_dims, n_output_dims).
using NetworkRegistry = config::Registry<Network, std::uint32_t, std::uint32_t>;

using LossRegistry = config::Registry<Loss>;
using OptimizerRegistry = config::Registry<Optimizer>;

const EncodingRegistry& encodings();
const NetworkRegistry& networks();
const LossRegistry& losses();
const OptimizerRegistry& optimizers();

std::unique_ptr<Encoding> create_encoding(const Json& json, std::uint32_t n_input_dims,
                                          const std::string& pointer = "");
std::unique_ptr<Network> create_network(const Json& json, std::uint32_t n_input_dims, std::uint32_t n_output_dims,
                                        const std::string& pointer = "");
std::unique_ptr<Loss> create_loss(const Json& json, const std::string& pointer = "");
std::unique_ptr<Optimizer> create_optimizer(const Json& json, const std::string& pointer = "");

// Registration hooks, one per source file family.
void register_encodings(EncodingRegistry& registry);
void register_networks(NetworkRegistry& registry);
void register_losses(LossRegistry& registry);
void register_optimizers(OptimizerRegistry& registry);

}  // namespace relit::nn
