// BatchMatrix allocation and host conversion.
#include <relit/nn/batch.hpp>

namespace relit::nn {

BatchMatrix::BatchMatrix(const Device& device, std::uint32_t batch, std::uint32_t cols)
    : m_data(device, static_cast<std::size_t>(padded_batch(batch)) * cols),
      m_batch(batch),
      m_padded(padded_batch(batch)),
      m_cols(cols) {
  m_data.fill(0.0f);
}

void BatchMatrix::resize(std::uint32_t batch) {
  if (padded_batch(batch) > m_padded) *this = BatchMatrix(m_data.device(), batch, m_cols);
  m_batch = batch;
}

void ensure_rows(BatchMatrix& m, const Device& device, std::uint32_t batch, std::uint32_t cols) {
  if (m.cols() != cols) m = BatchMatrix(device, batch, cols);
  m.resize(batch);
}

void match_rows(BatchMatrix& m, const BatchMatrix& like, std::uint32_t cols) {
  if (m.cols() != cols || m.padded() != like.padded()) m = BatchMatrix(like.device(), like.padded(), cols);
  m.resize(like.batch());
}

void BatchMatrix::upload_row_major(const std::vector<float>& host) {
  if (host.size() != static_cast<std::size_t>(m_batch) * m_cols)
    throw InvalidArgument("BatchMatrix::upload_row_major: got " + std::to_string(host.size()) + " values for " +
                          std::to_string(m_batch) + " samples x " + std::to_string(m_cols) + " features");
  std::vector<float> tiled(static_cast<std::size_t>(m_padded) * m_cols, 0.0f);
  for (std::uint32_t s = 0; s < m_batch; ++s)
    for (std::uint32_t f = 0; f < m_cols; ++f)
      tiled[tiled_index(s, f, m_cols)] = host[static_cast<std::size_t>(s) * m_cols + f];
  m_data.write(tiled);
}

std::vector<float> BatchMatrix::download_row_major() const {
  const std::vector<float> tiled = m_data.read();
  std::vector<float> host(static_cast<std::size_t>(m_batch) * m_cols);
  for (std::uint32_t s = 0; s < m_batch; ++s)
    for (std::uint32_t f = 0; f < m_cols; ++f)
      host[static_cast<std::size_t>(s) * m_cols + f] = tiled[tiled_index(s, f, m_cols)];
  return host;
}

}  // namespace relit::nn
