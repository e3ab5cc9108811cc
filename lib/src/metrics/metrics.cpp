// PSNR and SSIM: launches of kernels/metrics.cl, partial sums added on the host in double.
#include <relit/cl/program.hpp>
#include <relit/metrics.hpp>

#include <cmath>
#include <limits>
#include <numeric>

namespace relit::metrics {

namespace {
constexpr int kRadius = 5;
constexpr double kSigma = 1.5;

std::vector<float> gaussian_taps() {
  std::vector<float> w(2 * kRadius + 1);
  double sum = 0;
  for (int i = -kRadius; i <= kRadius; ++i) sum += std::exp(-0.5 * i * i / (kSigma * kSigma));
  for (int i = -kRadius; i <= kRadius; ++i)
    w[i + kRadius] = static_cast<float>(std::exp(-0.5 * i * i / (kSigma * kSigma)) / sum);
  return w;
}

double sum_rows(const Buffer<float>& rows) {
  const auto v = rows.read();
  return std::accumulate(v.begin(), v.end(), 0.0);
}
}  // namespace

ImageComparison compare(const Device& device, const std::vector<float>& prediction, const std::vector<float>& reference,
                        std::uint32_t width, std::uint32_t height, std::uint32_t channels) {
  const std::size_t n = std::size_t(width) * height * channels;
  if (channels == 0 || prediction.size() != n || reference.size() != n)
    throw InvalidArgument("metrics::compare: expected two " + std::to_string(height) + "x" + std::to_string(width) +
                          "x" + std::to_string(channels) + " images (" + std::to_string(n) + " values), got " +
                          std::to_string(prediction.size()) + " and " + std::to_string(reference.size()));
  if (width < 2 * kRadius + 1 || height < 2 * kRadius + 1)
    throw InvalidArgument("metrics::compare: SSIM needs images of at least 11x11 pixels, got " + std::to_string(width) +
                          "x" + std::to_string(height));
  for (const auto* img : {&prediction, &reference})
    for (float v : *img)
      if (std::isnan(v))
        throw InvalidArgument(std::string("metrics::compare: the ") +
                              (img == &prediction ? "prediction" : "reference") + " contains NaN");
  Buffer<float> a(device, prediction), b(device, reference);
  const auto count = static_cast<std::uint32_t>(n);
  device.kernel("metrics.cl", "to_srgb").args(count, a).launch(count, 64);
  device.kernel("metrics.cl", "to_srgb").args(count, b).launch(count, 64);

  Buffer<float> se_rows(device, height);
  device.kernel("metrics.cl", "squared_error_rows").args(width, height, channels, a, b, se_rows).launch(height, 1);
  const std::uint32_t ssim_rows = height - 2 * kRadius;
  Buffer<float> ssim_sums(device, ssim_rows), taps(device, gaussian_taps());
  device.kernel("metrics.cl", "ssim_rows").args(width, height, channels, a, b, taps, ssim_sums).launch(ssim_rows, 1);

  ImageComparison result;
  result.mse = sum_rows(se_rows) / double(n);
  result.psnr = result.mse > 0 ? 10.0 * std::log10(1.0 / result.mse) : std::numeric_limits<double>::infinity();
  result.ssim = sum_rows(ssim_sums) / (double(ssim_rows) * (width - 2 * kRadius) * channels);
  return result;
}

}  // namespace relit::metrics
