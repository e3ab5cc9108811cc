// The Identity encoding: y = scale * x + offset.
#include "common.hpp"

#include <relit/nn/encodings.hpp>

namespace relit::nn {

IdentityEncoding::IdentityEncoding(std::uint32_t n_input_dims, Options options)
    : m_dims(n_input_dims), m_options(options) {
  if (n_input_dims == 0) throw InvalidArgument("Identity encoding: n_input_dims must be at least 1");
}

Json IdentityEncoding::hyperparams() const {
  return {{"type", type()}, {"scale", m_options.scale}, {"offset", m_options.offset}};
}

void IdentityEncoding::forward(const Device& device, ConstParamSlice, const BatchMatrix& input, std::uint32_t in_col,
                               BatchMatrix& output, std::uint32_t out_col, Workspace*) const {
  detail::check_matrix("Identity::forward", "input", input, in_col, m_dims);
  detail::check_matrix("Identity::forward", "output", output, out_col, m_dims, &input);
  Kernel k = device.kernel("enc_identity.cl", "identity_forward");
  k.args(detail::n_tiles(input), m_dims, m_options.scale, m_options.offset, input.data(), input.cols(), in_col,
         output.data(), output.cols(), out_col)
      .launch(detail::n_tiles(input), detail::local_size(k));
}

void IdentityEncoding::backward(const Device& device, ConstParamSlice, const BatchMatrix& input, std::uint32_t in_col,
                                const BatchMatrix& d_output, std::uint32_t out_col, ParamSlice, bool,
                                BatchMatrix* d_input, Workspace*) const {
  if (!d_input) return;  // no parameters: nothing else to compute
  detail::check_matrix("Identity::backward", "d_output", d_output, out_col, m_dims, &input);
  detail::check_matrix("Identity::backward", "d_input", *d_input, in_col, m_dims, &input);
  Kernel k = device.kernel("enc_identity.cl", "identity_backward");
  k.args(detail::n_tiles(input), m_dims, m_options.scale, d_output.data(), d_output.cols(), out_col, d_input->data(),
         d_input->cols(), in_col)
      .launch(detail::n_tiles(input), detail::local_size(k));
}

}  // namespace relit::nn
