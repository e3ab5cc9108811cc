// Column moves between batch matrices (kernels/columns.cl).
#include <relit/cl/program.hpp>
#include <relit/nn/columns.hpp>

namespace relit::nn {

namespace {
void check(const BatchMatrix& src, std::uint32_t src_col, const BatchMatrix& dst, std::uint32_t dst_col,
           std::uint32_t count, const char* what) {
  if (src.batch() != dst.batch() || src_col + count > src.cols() || dst_col + count > dst.cols())
    throw InvalidArgument(std::string(what) + ": columns [" + std::to_string(src_col) + ", " +
                          std::to_string(src_col + count) + ") of a " + std::to_string(src.batch()) + "x" +
                          std::to_string(src.cols()) + " matrix do not fit columns [" + std::to_string(dst_col) + ", " +
                          std::to_string(dst_col + count) + ") of a " + std::to_string(dst.batch()) + "x" +
                          std::to_string(dst.cols()) + " one");
}
}  // namespace

void copy_columns(const Device& device, const BatchMatrix& src, std::uint32_t src_col, BatchMatrix& dst,
                  std::uint32_t dst_col, std::uint32_t count, float scale, bool accumulate) {
  check(src, src_col, dst, dst_col, count, "copy_columns");
  // The tiles of the samples (a matrix resized down keeps a larger padding than the other may have).
  const std::uint32_t n_tiles = (src.batch() + kBatchTile - 1) / kBatchTile;
  device.kernel("columns.cl", "copy_columns")
      .args(n_tiles, count, src.data(), src.cols(), src_col, dst.data(), dst.cols(), dst_col, scale,
            std::uint32_t(accumulate))
      .launch(n_tiles, 16);
}

void multiply_columns(const Device& device, const BatchMatrix& factor, BatchMatrix& m, std::uint32_t col,
                      std::uint32_t count) {
  if (factor.cols() != 1) throw InvalidArgument("multiply_columns: the factor must have one column");
  check(m, col, m, col, count, "multiply_columns");
  if (factor.batch() != m.batch())
    throw InvalidArgument("multiply_columns: the factor has " + std::to_string(factor.batch()) + " rows, the matrix " +
                          std::to_string(m.batch()));
  const std::uint32_t n_tiles = (m.batch() + kBatchTile - 1) / kBatchTile;
  if (n_tiles == 0 || count == 0) return;
  device.kernel("columns.cl", "multiply_columns")
      .args(n_tiles, count, factor.data(), m.data(), m.cols(), col)
      .launch(n_tiles, 16);
}

}  // namespace relit::nn
