// Column moves between BatchMatrix objects (kernels/columns.cl): assembling one matrix from several networks'
// outputs and splitting its gradient again, without host round trips.
#pragma once

#include <relit/nn/batch.hpp>

namespace relit::nn {

/// dst[:, dst_col + j] = scale * src[:, src_col + j] for j < count (added to dst when `accumulate`).
/// Both matrices must have the same batch size; the column ranges must fit.
void copy_columns(const Device& device, const BatchMatrix& src, std::uint32_t src_col, BatchMatrix& dst,
                  std::uint32_t dst_col, std::uint32_t count, float scale = 1.0f, bool accumulate = false);

/// m[:, col + j] *= factor[:, 0] for j < count, in place: a per-sample scale (its own adjoint). `factor` has one
/// column and m's batch size.
void multiply_columns(const Device& device, const BatchMatrix& factor, BatchMatrix& m, std::uint32_t col,
                      std::uint32_t count);

}  // namespace relit::nn
