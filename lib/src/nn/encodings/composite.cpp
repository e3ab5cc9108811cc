// The Composite encoding: nested encodings side by side on consecutive input dims and output columns.
#include "common.hpp"

#include <relit/nn/encodings.hpp>

namespace relit::nn {

CompositeEncoding::CompositeEncoding(std::vector<Part> parts, Json resolved)
    : m_parts(std::move(parts)), m_resolved(std::move(resolved)) {
  if (m_parts.empty()) throw InvalidArgument("Composite encoding: needs at least one nested encoding");
  for (const auto& p : m_parts)
    if (!p.encoding || p.encoding->n_input_dims() != p.n_dims_to_encode)
      throw InvalidArgument("Composite encoding: a nested encoding does not take its n_dims_to_encode inputs");
}

std::uint32_t CompositeEncoding::n_params() const {
  std::uint32_t n = 0;
  for (const auto& p : m_parts) n += p.encoding->n_params();
  return n;
}

void CompositeEncoding::initialize_params(float* out, std::uint64_t seed) const {
  for (std::size_t i = 0; i < m_parts.size(); ++i) {
    m_parts[i].encoding->initialize_params(out, seed + 0x9e3779b9ull * (i + 1));
    out += m_parts[i].encoding->n_params();
  }
}

std::uint32_t CompositeEncoding::n_input_dims() const {
  std::uint32_t n = 0;
  for (const auto& p : m_parts) n += p.n_dims_to_encode;
  return n;
}

std::uint32_t CompositeEncoding::n_output_dims() const {
  std::uint32_t n = 0;
  for (const auto& p : m_parts) n += p.encoding->n_output_dims();
  return n;
}

void CompositeEncoding::forward(const Device& device, ConstParamSlice params, const BatchMatrix& input,
                                std::uint32_t in_col, BatchMatrix& output, std::uint32_t out_col,
                                Workspace* workspace) const {
  (void)workspace;  // the nested encodings keep nothing between forward and backward
  detail::check_slice("Composite::forward", "parameter", params, n_params());
  for (const auto& p : m_parts) {
    p.encoding->forward(device, params, input, in_col, output, out_col, nullptr);
    in_col += p.n_dims_to_encode;
    out_col += p.encoding->n_output_dims();
    params.offset += p.encoding->n_params();
  }
}

void CompositeEncoding::backward(const Device& device, ConstParamSlice params, const BatchMatrix& input,
                                 std::uint32_t in_col, const BatchMatrix& d_output, std::uint32_t out_col,
                                 ParamSlice grads, bool accumulate, BatchMatrix* d_input, Workspace*) const {
  if (grads.buffer) detail::check_slice("Composite::backward", "gradient", grads, n_params());
  for (const auto& p : m_parts) {
    p.encoding->backward(device, params, input, in_col, d_output, out_col, grads, accumulate, d_input, nullptr);
    in_col += p.n_dims_to_encode;
    out_col += p.encoding->n_output_dims();
    params.offset += p.encoding->n_params();
    grads.offset += p.encoding->n_params();
  }
}

}  // namespace relit::nn
