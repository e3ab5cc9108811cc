// The nn registries, filled on first use by each family's registration function.
#include <relit/nn/registry.hpp>

namespace relit::nn {

const EncodingRegistry& encodings() {
  static const EncodingRegistry registry = [] {
    EncodingRegistry r("encoding", "Identity");
    register_encodings(r);
    return r;
  }();
  return registry;
}

const NetworkRegistry& networks() {
  static const NetworkRegistry registry = [] {
    NetworkRegistry r("network", "FullyFusedMLP");
    register_networks(r);
    return r;
  }();
  return registry;
}

const LossRegistry& losses() {
  static const LossRegistry registry = [] {
    LossRegistry r("loss", "L2");
    register_losses(r);
    return r;
  }();
  return registry;
}

const OptimizerRegistry& optimizers() {
  static const OptimizerRegistry registry = [] {
    OptimizerRegistry r("optimizer", "Adam");
    register_optimizers(r);
    return r;
  }();
  return registry;
}

std::unique_ptr<Loss> create_loss(const Json& json, const std::string& pointer) {
  return losses().create(json, pointer);
}

std::unique_ptr<Optimizer> create_optimizer(const Json& json, const std::string& pointer) {
  return optimizers().create(json, pointer);
}

namespace {
// Dimensions beyond any real model (2^31 would overflow the parameter and workspace sizes).
constexpr std::uint32_t kMaxDims = 4096;
void check_dims(const char* what, std::uint32_t n) {
  if (n > kMaxDims)
    throw InvalidArgument(std::string(what) + " must be at most " + std::to_string(kMaxDims) + ", got " +
                          std::to_string(n));
}
}  // namespace

std::unique_ptr<Encoding> create_encoding(const Json& json, std::uint32_t n_input_dims, const std::string& pointer) {
  check_dims("n_input_dims", n_input_dims);
  return encodings().create(json, pointer, n_input_dims);
}

std::unique_ptr<Network> create_network(const Json& json, std::uint32_t n_input_dims, std::uint32_t n_output_dims,
                                        const std::string& pointer) {
  check_dims("n_input_dims", n_input_dims);
  check_dims("n_output_dims", n_output_dims);
  return networks().create(json, pointer, n_input_dims, n_output_dims);
}

}  // namespace relit::nn
