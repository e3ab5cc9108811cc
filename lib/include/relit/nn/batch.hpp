// BatchMatrix: a batch of feature vectors on the device, in relit's tiled layout.
//
//   element (sample s, feature f) lives at  ((s / 16) * cols + f) * 16 + (s % 16)     (kernels/layout.clh)
//
//   tile 0: [f0: s0..s15][f1: s0..s15] ... [f(cols-1): s0..s15]   tile 1: [f0: s16..s31] ...
//
// 16 consecutive samples of one feature are contiguous: one float16 vector on a CPU (PoCL's SIMD lanes),
// 16 coalesced loads for 16 GPU work-items. Every kernel of the nn family reads and writes this layout;
// conversion to and from row-major happens only at the user-facing boundary (Python, tests).
//
// The batch is padded to a multiple of kBatchGranularity rows, which users never see: the logical size is
// `batch`, the allocated one `padded`. Padding rows are zero after allocation; a kernel may compute
// garbage-free values there, and losses write zero gradients for them, so weight gradients (sums over
// rows) are unaffected.
#pragma once

#include <relit/cl/buffer.hpp>
#include <relit/layout.clh>

#include <cstdint>
#include <vector>

namespace relit::nn {

constexpr std::uint32_t kBatchTile = RELIT_TILE;  // kernels/layout.clh
constexpr std::uint32_t kBatchGranularity = 128;

inline std::uint32_t padded_batch(std::uint32_t batch) {
  return static_cast<std::uint32_t>(round_up(batch, kBatchGranularity));
}

/// Index of element (sample s, feature f) in a tiled matrix with `cols` features.
inline std::size_t tiled_index(std::uint32_t s, std::uint32_t f, std::uint32_t cols) {
  return (static_cast<std::size_t>(s / kBatchTile) * cols + f) * kBatchTile + s % kBatchTile;
}

class BatchMatrix {
 public:
  BatchMatrix() = default;
  /// Zero-filled device storage for `batch` samples of `cols` features.
  BatchMatrix(const Device& device, std::uint32_t batch, std::uint32_t cols);

  /// Changes the logical batch size; reallocates (zero-filled) only when the padded size grows, so a
  /// training loop reuses its buffers.
  void resize(std::uint32_t batch);

  std::uint32_t batch() const { return m_batch; }
  std::uint32_t padded() const { return m_padded; }
  std::uint32_t cols() const { return m_cols; }
  Buffer<float>& data() { return m_data; }
  const Buffer<float>& data() const { return m_data; }
  const Device& device() const { return m_data.device(); }

  /// Host conversions (blocking). Row-major means sample-major: host[s * cols + f].
  void upload_row_major(const std::vector<float>& host);
  std::vector<float> download_row_major() const;

 private:
  Buffer<float> m_data;
  std::uint32_t m_batch = 0, m_padded = 0, m_cols = 0;
};

/// Sizes `m` as `batch` x `cols` scratch: reallocates when the columns differ, otherwise resize() (which keeps a
/// larger allocation and its padding).
void ensure_rows(BatchMatrix& m, const Device& device, std::uint32_t batch, std::uint32_t cols);

/// Makes `m` a `cols`-column matrix with exactly the rows of `like`: its batch and its padding (a matrix resized
/// down keeps a larger padding than padded_batch() of its batch). Scratch that kernels fill tile by tile
/// alongside `like` needs this.
void match_rows(BatchMatrix& m, const BatchMatrix& like, std::uint32_t cols);

/// A slice of a model's flat parameter (or gradient) buffer: where one component's parameters start.
struct ParamSlice {
  Buffer<float>* buffer = nullptr;
  std::size_t offset = 0;
};
struct ConstParamSlice {
  const Buffer<float>* buffer = nullptr;
  std::size_t offset = 0;
};

}  // namespace relit::nn
