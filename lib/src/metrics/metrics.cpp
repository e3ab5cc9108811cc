// PSNR, SSIM and the object metrics: launches of kernels/metrics.cl, per-row partial sums added on the host in
// double, in row order; HDR-FLIP from flip.cpp.
#include <relit/cl/program.hpp>
#include <relit/metrics.hpp>

#include <cmath>
#include <limits>

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

// Row sums of `k` interleaved quantities, each added over the rows in double, in order.
std::vector<double> column_sums(const Buffer<float>& rows, std::size_t k) {
  const auto v = rows.read();
  std::vector<double> out(k, 0.0);
  for (std::size_t i = 0; i < v.size(); ++i) out[i % k] += v[i];
  return out;
}
}  // namespace

std::vector<std::uint8_t> object_mask(const std::vector<float>& reference_alpha,
                                      const std::vector<float>& prediction_alpha, std::size_t pixels) {
  for (const auto* alpha : {&reference_alpha, &prediction_alpha})
    if (!alpha->empty() && alpha->size() != pixels)
      throw InvalidArgument("metrics::object_mask: an alpha of " + std::to_string(alpha->size()) +
                            " values for an image of " + std::to_string(pixels) + " pixels");
  std::vector<std::uint8_t> mask(pixels, 0);
  for (std::size_t i = 0; i < prediction_alpha.size(); ++i)
    if (prediction_alpha[i] > kObjectAlpha) mask[i] = kMaskPredictionOnly;
  for (std::size_t i = 0; i < reference_alpha.size(); ++i)
    if (reference_alpha[i] > kObjectAlpha) mask[i] = kMaskReference;
  return mask;
}

ImageComparison compare(const Device& device, const std::vector<float>& prediction, const std::vector<float>& reference,
                        std::uint32_t width, std::uint32_t height, std::uint32_t channels,
                        const std::vector<std::uint8_t>* mask) {
  const std::size_t pixels = std::size_t(width) * height, n = pixels * channels;
  if (channels == 0 || prediction.size() != n || reference.size() != n)
    throw InvalidArgument("metrics::compare: expected two " + std::to_string(height) + "x" + std::to_string(width) +
                          "x" + std::to_string(channels) + " images (" + std::to_string(n) + " values), got " +
                          std::to_string(prediction.size()) + " and " + std::to_string(reference.size()));
  if (width < 2 * kRadius + 1 || height < 2 * kRadius + 1)
    throw InvalidArgument("metrics::compare: SSIM needs images of at least 11x11 pixels, got " + std::to_string(width) +
                          "x" + std::to_string(height));
  if (mask && mask->size() != pixels)
    throw InvalidArgument("metrics::compare: the mask has " + std::to_string(mask->size()) +
                          " values for an image of " + std::to_string(pixels) + " pixels");
  for (const auto* img : {&prediction, &reference})
    for (float v : *img)
      if (std::isnan(v))
        throw InvalidArgument(std::string("metrics::compare: the ") +
                              (img == &prediction ? "prediction" : "reference") + " contains NaN");
  Buffer<float> a(device, prediction), b(device, reference);
  Buffer<std::uint8_t> m(device, mask ? *mask : std::vector<std::uint8_t>(pixels, 0));
  const auto count = static_cast<std::uint32_t>(n);
  // The linear images first: the object's relative MSE and clipped pixels.
  Buffer<float> object_sums(device, 3 * std::size_t(height));
  device.kernel("metrics.cl", "object_rows")
      .args(width, height, channels, float(kRelMseEpsilon), a, b, m, object_sums)
      .launch(height, 1);
  device.kernel("metrics.cl", "to_srgb").args(count, a).launch(count, 64);
  device.kernel("metrics.cl", "to_srgb").args(count, b).launch(count, 64);

  Buffer<float> se_rows(device, 2 * std::size_t(height));
  device.kernel("metrics.cl", "squared_error_rows").args(width, height, channels, a, b, m, se_rows).launch(height, 1);
  const std::uint32_t ssim_rows = height - 2 * kRadius;
  Buffer<float> ssim_sums(device, 3 * std::size_t(ssim_rows)), taps(device, gaussian_taps());
  device.kernel("metrics.cl", "ssim_rows").args(width, height, channels, a, b, m, taps, ssim_sums).launch(ssim_rows, 1);

  const auto se = column_sums(se_rows, 2), ss = column_sums(ssim_sums, 3), obj = column_sums(object_sums, 3);
  const FlipResult f = flip(device, prediction, reference, width, height, channels);
  const auto psnr = [](double mse) {
    return mse > 0 ? 10.0 * std::log10(1.0 / mse) : std::numeric_limits<double>::infinity();
  };
  ImageComparison result;
  result.mse = se[0] / double(n);
  result.psnr = psnr(result.mse);
  result.ssim = ss[0] / (double(ssim_rows) * (width - 2 * kRadius) * channels);
  result.flip = f.mean;
  ObjectComparison& o = result.object;
  o.pixels = static_cast<std::uint64_t>(obj[1]);
  o.fraction = double(o.pixels) / double(pixels);
  if (o.pixels > 0) {
    o.mse = se[1] / (double(o.pixels) * channels);
    o.psnr = psnr(o.mse);
    o.rel_mse = obj[0] / (double(o.pixels) * channels);
    o.clipped = obj[2] / double(o.pixels);
    if (ss[2] > 0) o.ssim = ss[1] / (ss[2] * channels);
    double flip_sum = 0;
    std::uint64_t prediction_only = 0;
    for (std::size_t p = 0; p < pixels; ++p)
      if ((*mask)[p]) {
        flip_sum += f.error[p];
        prediction_only += (*mask)[p] == kMaskPredictionOnly;
      }
    o.flip = flip_sum / double(o.pixels);
    o.prediction_only = double(prediction_only) / double(o.pixels);
  }
  return result;
}

}  // namespace relit::metrics
