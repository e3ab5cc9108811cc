// The SphericalHarmonics encoding; the kernels are in kernels/enc_sh.cl, the host reference in src/sh.cpp.
#include "common.hpp"

#include <relit/nn/encodings.hpp>

namespace relit::nn {

SphericalHarmonicsEncoding::SphericalHarmonicsEncoding(std::uint32_t n_input_dims, Options options)
    : m_options(options) {
  if (n_input_dims != 3)
    throw InvalidArgument("SphericalHarmonics encoding: encodes 3-D unit directions, got " +
                          std::to_string(n_input_dims) + " input dims");
  if (options.degree < 1 || options.degree > kMaxDegree)
    throw InvalidArgument("SphericalHarmonics encoding: degree must be in [1, " + std::to_string(kMaxDegree) +
                          "], got " + std::to_string(options.degree));
}

Json SphericalHarmonicsEncoding::hyperparams() const { return {{"type", type()}, {"degree", m_options.degree}}; }

void SphericalHarmonicsEncoding::forward(const Device& device, ConstParamSlice, const BatchMatrix& input,
                                         std::uint32_t in_col, BatchMatrix& output, std::uint32_t out_col,
                                         Workspace*) const {
  detail::check_matrix("SphericalHarmonics::forward", "input", input, in_col, 3);
  detail::check_matrix("SphericalHarmonics::forward", "output", output, out_col, n_output_dims(), &input);
  Kernel k = device.kernel("enc_sh.cl", "sh_forward", {{"DEGREE", std::to_string(m_options.degree)}});
  k.args(detail::n_tiles(input), input.data(), input.cols(), in_col, output.data(), output.cols(), out_col)
      .launch(detail::n_tiles(input), detail::local_size(k));
}

void SphericalHarmonicsEncoding::backward(const Device& device, ConstParamSlice, const BatchMatrix& input,
                                          std::uint32_t in_col, const BatchMatrix& d_output, std::uint32_t out_col,
                                          ParamSlice, bool, BatchMatrix* d_input, Workspace*) const {
  if (!d_input) return;
  detail::check_matrix("SphericalHarmonics::backward", "input", input, in_col, 3);
  detail::check_matrix("SphericalHarmonics::backward", "d_output", d_output, out_col, n_output_dims(), &input);
  detail::check_matrix("SphericalHarmonics::backward", "d_input", *d_input, in_col, 3, &input);
  Kernel k = device.kernel("enc_sh.cl", "sh_backward", {{"DEGREE", std::to_string(m_options.degree)}});
  k.args(detail::n_tiles(input), input.data(), input.cols(), in_col, d_output.data(), d_output.cols(), out_col,
         d_input->data(), d_input->cols())
      .launch(detail::n_tiles(input), detail::local_size(k));
}

}  // namespace relit::nn
