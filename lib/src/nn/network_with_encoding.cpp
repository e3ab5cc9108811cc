// NetworkWithInputEncoding: encoding → network, forward and backward.
#include <relit/nn/network_with_encoding.hpp>

namespace relit::nn {

namespace {
struct CompositeWorkspace final : Workspace {
  BatchMatrix encoded, d_encoded;
  BatchMatrix encoded_inference;  // inference's own, so a workspace shared with training keeps both sizes
  std::unique_ptr<Workspace> encoding, network;
};

CompositeWorkspace& cast(Workspace& w) {
  auto* c = dynamic_cast<CompositeWorkspace*>(&w);
  if (!c) throw InvalidArgument("NetworkWithInputEncoding: the workspace was made by another component");
  return *c;
}
}  // namespace

NetworkWithInputEncoding::NetworkWithInputEncoding(std::unique_ptr<Encoding> encoding, std::unique_ptr<Network> network)
    : m_encoding(std::move(encoding)), m_network(std::move(network)) {
  if (m_encoding->n_output_dims() != m_network->n_input_dims())
    throw InvalidArgument("NetworkWithInputEncoding: the encoding gives " +
                          std::to_string(m_encoding->n_output_dims()) + " dims but the network takes " +
                          std::to_string(m_network->n_input_dims()));
}

std::unique_ptr<NetworkWithInputEncoding> NetworkWithInputEncoding::create(const Json& config, std::uint32_t n_in,
                                                                           std::uint32_t n_out) {
  if (!config.is_object()) throw ConfigError("", "model config must be an object with \"encoding\" and \"network\"");
  for (auto it = config.begin(); it != config.end(); ++it)
    if (it.key() != "encoding" && it.key() != "network")
      throw ConfigError("/" + it.key(), "unknown key '" + it.key() + "'; valid keys: encoding, network");
  auto encoding = create_encoding(config.value("encoding", Json::object()), n_in, "/encoding");
  auto network = create_network(config.value("network", Json::object()), encoding->n_output_dims(), n_out, "/network");
  return std::make_unique<NetworkWithInputEncoding>(std::move(encoding), std::move(network));
}

Json NetworkWithInputEncoding::hyperparams() const {
  return {{"encoding", m_encoding->hyperparams()}, {"network", m_network->hyperparams()}};
}

void NetworkWithInputEncoding::initialize_params(float* out, std::uint64_t seed) const {
  m_encoding->initialize_params(out, seed);
  m_network->initialize_params(out + m_encoding->n_params(), seed + 1);
}

std::unique_ptr<Workspace> NetworkWithInputEncoding::make_workspace(const Device& device) const {
  auto w = std::make_unique<CompositeWorkspace>();
  w->encoded = BatchMatrix(device, 0, m_encoding->n_output_dims());
  w->d_encoded = BatchMatrix(device, 0, m_encoding->n_output_dims());
  w->encoding = m_encoding->make_workspace(device);
  w->network = m_network->make_workspace(device);
  return w;
}

void NetworkWithInputEncoding::inference(const Device& device, ConstParamSlice params, const BatchMatrix& input,
                                         BatchMatrix& output) const {
  // Without a workspace: encode into a temporary (the workspace overload reuses one).
  BatchMatrix encoded;
  match_rows(encoded, input, m_encoding->n_output_dims());
  auto ew = m_encoding->make_workspace(device);
  m_encoding->forward(device, params, input, encoded, 0, ew.get());
  m_network->inference(device, {params.buffer, params.offset + m_encoding->n_params()}, encoded, output);
}

void NetworkWithInputEncoding::inference(const Device& device, ConstParamSlice params, const BatchMatrix& input,
                                         BatchMatrix& output, Workspace& workspace) const {
  auto& w = cast(workspace);
  match_rows(w.encoded_inference, input, m_encoding->n_output_dims());
  m_encoding->forward(device, params, input, w.encoded_inference, 0, w.encoding.get());
  m_network->inference(device, {params.buffer, params.offset + m_encoding->n_params()}, w.encoded_inference, output);
}

void NetworkWithInputEncoding::forward(const Device& device, ConstParamSlice params, const BatchMatrix& input,
                                       BatchMatrix& output, Workspace& workspace) const {
  auto& w = cast(workspace);
  match_rows(w.encoded, input, m_encoding->n_output_dims());
  m_encoding->forward(device, params, input, w.encoded, 0, w.encoding.get());
  m_network->forward(device, {params.buffer, params.offset + m_encoding->n_params()}, w.encoded, output, *w.network);
}

void NetworkWithInputEncoding::backward(const Device& device, ConstParamSlice params, const BatchMatrix& input,
                                        const BatchMatrix& output, const BatchMatrix& d_output, ParamSlice grads,
                                        bool accumulate, BatchMatrix* d_input, Workspace& workspace) const {
  auto& w = cast(workspace);
  const bool need_d_encoded = m_encoding->n_params() > 0 || d_input;
  if (need_d_encoded) match_rows(w.d_encoded, input, m_encoding->n_output_dims());
  m_network->backward(device, {params.buffer, params.offset + m_encoding->n_params()}, w.encoded, output, d_output,
                      {grads.buffer, grads.offset + m_encoding->n_params()}, accumulate,
                      need_d_encoded ? &w.d_encoded : nullptr, *w.network);
  if (need_d_encoded)
    m_encoding->backward(device, params, input, w.d_encoded, 0, grads, accumulate, d_input, w.encoding.get());
}

}  // namespace relit::nn
