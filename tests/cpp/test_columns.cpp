// Column moves between batch matrices: exact copies, scaling, accumulation.
#include "test_support.hpp"

#include <relit/nn/columns.hpp>

namespace relit {

using nn::BatchMatrix;

TEST(Columns, CopyScaleAndAccumulate) {
  const Device d = test::test_device();
  const std::uint32_t n = 150;  // padded to 256 rows
  std::vector<float> a(n * 4), b(n * 6, 1.0f);
  for (std::size_t i = 0; i < a.size(); ++i) a[i] = float(i);
  BatchMatrix src(d, n, 4), dst(d, n, 6);
  src.upload_row_major(a);
  dst.upload_row_major(b);
  nn::copy_columns(d, src, 1, dst, 3, 2, 2.0f);
  nn::copy_columns(d, src, 0, dst, 0, 1, 1.0f, true);
  const auto out = dst.download_row_major();
  for (std::uint32_t s = 0; s < n; ++s) {
    EXPECT_EQ(out[s * 6 + 0], 1.0f + a[s * 4 + 0]);
    EXPECT_EQ(out[s * 6 + 1], 1.0f);
    EXPECT_EQ(out[s * 6 + 3], 2.0f * a[s * 4 + 1]);
    EXPECT_EQ(out[s * 6 + 4], 2.0f * a[s * 4 + 2]);
    EXPECT_EQ(out[s * 6 + 5], 1.0f);
  }
  EXPECT_THROW(nn::copy_columns(d, src, 3, dst, 0, 2), InvalidArgument);
  BatchMatrix other(d, n + 1, 6);
  EXPECT_THROW(nn::copy_columns(d, src, 0, other, 0, 1), InvalidArgument);
}

}  // namespace relit
