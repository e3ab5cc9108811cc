// NetworkWithInputEncoding: an Encoding followed by a Network, as one Network (tiny-cuda-nn's composition).
//
// Parameters are [encoding | network] in one flat slice; the encoded batch lives in the workspace, so a
// training loop allocates nothing after its first step.
#pragma once

#include <relit/nn/registry.hpp>

namespace relit::nn {

class NetworkWithInputEncoding final : public Network {
 public:
  NetworkWithInputEncoding(std::unique_ptr<Encoding> encoding, std::unique_ptr<Network> network);
  /// Builds both from JSON: {"encoding": {...}, "network": {...}}.
  static std::unique_ptr<NetworkWithInputEncoding> create(const Json& config, std::uint32_t n_input_dims,
                                                          std::uint32_t n_output_dims);

  std::string type() const override { return "NetworkWithInputEncoding"; }
  Json hyperparams() const override;
  std::uint32_t n_params() const override { return m_encoding->n_params() + m_network->n_params(); }
  void initialize_params(float* out, std::uint64_t seed) const override;
  std::uint32_t n_input_dims() const override { return m_encoding->n_input_dims(); }
  std::uint32_t n_output_dims() const override { return m_network->n_output_dims(); }

  std::unique_ptr<Workspace> make_workspace(const Device& device) const override;
  using Network::inference;
  void inference(const Device& device, ConstParamSlice params, const BatchMatrix& input,
                 BatchMatrix& output) const override;
  void inference(const Device& device, ConstParamSlice params, const BatchMatrix& input, BatchMatrix& output,
                 Workspace& workspace) const override;
  void forward(const Device& device, ConstParamSlice params, const BatchMatrix& input, BatchMatrix& output,
               Workspace& workspace) const override;
  void backward(const Device& device, ConstParamSlice params, const BatchMatrix& input, const BatchMatrix& output,
                const BatchMatrix& d_output, ParamSlice grads, bool accumulate, BatchMatrix* d_input,
                Workspace& workspace) const override;

  const Encoding& encoding() const { return *m_encoding; }
  const Network& network() const { return *m_network; }

 private:
  std::unique_ptr<Encoding> m_encoding;
  std::unique_ptr<Network> m_network;
};

}  // namespace relit::nn
