// Checks and launch helpers shared by the encodings (private to the library).
#pragma once

#include <relit/cl/program.hpp>
#include <relit/error.hpp>
#include <relit/nn/batch.hpp>

#include <string>

namespace relit::nn::detail {

/// Throws InvalidArgument unless `m` has columns [col, col + n) and the batch of `reference`.
inline void check_matrix(const std::string& who, const char* what, const BatchMatrix& m, std::uint32_t col,
                         std::uint32_t n, const BatchMatrix* reference = nullptr) {
  if (static_cast<std::uint64_t>(col) + n > m.cols())
    throw InvalidArgument(who + ": " + what + " has " + std::to_string(m.cols()) + " columns, columns [" +
                          std::to_string(col) + ", " + std::to_string(col + n) +
                          ") do not fit; allocate it with at least " + std::to_string(col + n) + " columns");
  if (reference && (m.batch() != reference->batch() || m.padded() != reference->padded()))
    throw InvalidArgument(who + ": " + what + " holds " + std::to_string(m.batch()) + " samples (padded to " +
                          std::to_string(m.padded()) + ") but the input holds " + std::to_string(reference->batch()) +
                          " (padded to " + std::to_string(reference->padded()) +
                          "); give them the same batch and padding");
}

/// Throws InvalidArgument unless the slice holds `n` floats from its offset.
template <class Slice>
void check_slice(const std::string& who, const char* what, const Slice& slice, std::uint32_t n) {
  if (n == 0) return;
  if (!slice.buffer || slice.offset + n > slice.buffer->size())
    throw InvalidArgument(who + ": the " + what + " slice needs " + std::to_string(n) + " floats from offset " +
                          std::to_string(slice.offset) + ", but the buffer holds " +
                          std::to_string(slice.buffer ? slice.buffer->size() : 0));
}

/// Work-items over 16-sample tiles: one per tile of the padded batch.
inline std::uint32_t n_tiles(const BatchMatrix& m) { return m.padded() / kBatchTile; }

/// Local size for the tile kernels: the kernel's preferred multiple (SIMD width on GPUs, 8 on PoCL), within
/// the device's limit for this kernel.
inline std::size_t local_size(const Kernel& kernel) {
  std::size_t local = kernel.preferred_work_group_multiple();
  const std::size_t max = kernel.max_work_group_size();
  if (local == 0 || local > max) local = max;
  return local ? local : 1;
}

}  // namespace relit::nn::detail
