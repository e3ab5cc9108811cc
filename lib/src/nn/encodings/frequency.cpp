// The Frequency (NeRF positional) encoding; the kernels are in kernels/enc_frequency.cl.
#include "common.hpp"

#include <relit/nn/encodings.hpp>

namespace relit::nn {

FrequencyEncoding::FrequencyEncoding(std::uint32_t n_input_dims, Options options)
    : m_dims(n_input_dims), m_options(options) {
  if (n_input_dims == 0) throw InvalidArgument("Frequency encoding: n_input_dims must be at least 1");
  if (options.n_frequencies < 1 || options.n_frequencies > 24)
    throw InvalidArgument("Frequency encoding: n_frequencies must be in [1, 24], got " +
                          std::to_string(options.n_frequencies));
}

Json FrequencyEncoding::hyperparams() const {
  return {{"type", type()}, {"n_frequencies", m_options.n_frequencies}, {"include_input", m_options.include_input}};
}

Defines FrequencyEncoding::defines() const {
  return {{"N_FREQ", std::to_string(m_options.n_frequencies)},
          {"INCLUDE_INPUT", m_options.include_input ? "1" : "0"},
          {"ANCHOR", std::to_string(kAnchorInterval)}};
}

void FrequencyEncoding::forward(const Device& device, ConstParamSlice, const BatchMatrix& input, std::uint32_t in_col,
                                BatchMatrix& output, std::uint32_t out_col, Workspace*) const {
  detail::check_matrix("Frequency::forward", "input", input, in_col, m_dims);
  detail::check_matrix("Frequency::forward", "output", output, out_col, n_output_dims(), &input);
  Kernel k = device.kernel("enc_frequency.cl", "frequency_forward", defines());
  k.args(detail::n_tiles(input), m_dims, input.data(), input.cols(), in_col, output.data(), output.cols(), out_col)
      .launch(detail::n_tiles(input), detail::local_size(k));
}

void FrequencyEncoding::backward(const Device& device, ConstParamSlice, const BatchMatrix& input, std::uint32_t in_col,
                                 const BatchMatrix& d_output, std::uint32_t out_col, ParamSlice, bool,
                                 BatchMatrix* d_input, Workspace*) const {
  if (!d_input) return;
  detail::check_matrix("Frequency::backward", "input", input, in_col, m_dims);
  detail::check_matrix("Frequency::backward", "d_output", d_output, out_col, n_output_dims(), &input);
  detail::check_matrix("Frequency::backward", "d_input", *d_input, in_col, m_dims, &input);
  Kernel k = device.kernel("enc_frequency.cl", "frequency_backward", defines());
  k.args(detail::n_tiles(input), m_dims, input.data(), input.cols(), in_col, d_output.data(), d_output.cols(), out_col,
         d_input->data(), d_input->cols())
      .launch(detail::n_tiles(input), detail::local_size(k));
}

}  // namespace relit::nn
