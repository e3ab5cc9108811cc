// Column moves between batch matrices: exact copies, scaling, accumulation, per-ray intensity scaling.
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

TEST(Columns, ScaleRgbBlocksByTheirRaysIntensity) {
  const Device d = test::test_device();
  const std::uint32_t spr = 16, n_rays = 3, n = spr * n_rays, per = 2;
  std::vector<float> rays(n_rays * 20, 0.0f);
  for (std::uint32_t r = 0; r < n_rays; ++r)
    for (int c = 0; c < 3; ++c) rays[r * 20 + 12 + c] = float(10 * (r + 1) + c);
  std::vector<float> h(n * 3 * per);
  for (std::size_t i = 0; i < h.size(); ++i) h[i] = 0.5f + float(i % 7);
  BatchMatrix src(d, n, 3 * per), dst(d, n, 1 + 3 * per);
  src.upload_row_major(h);
  Buffer<float> rb(d, rays);
  nn::scale_rgb_by_ray_intensity(d, rb, spr, src, 0, dst, 1, per);
  const auto out = dst.download_row_major();
  for (std::uint32_t s = 0; s < n; ++s)
    for (std::uint32_t c = 0; c < 3 * per; ++c)
      EXPECT_EQ(out[s * (1 + 3 * per) + 1 + c], rays[(s / spr) * 20 + 12 + c / per] * h[s * 3 * per + c])
          << s << " " << c;
  EXPECT_THROW(nn::scale_rgb_by_ray_intensity(d, rb, 24, src, 0, dst, 1, per), InvalidArgument);
}

}  // namespace relit
