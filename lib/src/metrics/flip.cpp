// FLIP and HDR-FLIP: the separated filters, the exposure range, and one pass of kernels/flip.cl per exposure
// into a per-pixel maximum.
#include <relit/cl/program.hpp>
#include <relit/error.hpp>
#include <relit/metrics.hpp>

#include "shared.hpp"

#include <algorithm>
#include <array>
#include <cfloat>
#include <cmath>
#include <string>

namespace relit::metrics {

namespace {

using ::relit::detail::kPi;

// The colour pipeline's contrast sensitivity filters (FLIP, HPG 2020, Table 1): a1 sqrt(pi / b1) exp(-pi^2 r^2 /
// b1) + a2 sqrt(pi / b2) exp(-pi^2 r^2 / b2), r in degrees; achromatic and red-green are single Gaussians.
constexpr double kCsfY[2] = {1.0, 0.0047}, kCsfCx[2] = {1.0, 0.0053};
constexpr double kCsfCz[2][2] = {{34.1, 0.04}, {13.5, 0.025}};
constexpr double kCsfLargestB = 0.04;    // sets the filters' radius
constexpr double kFeatureWidth = 0.082;  // w: the edge detector's peak-to-trough width in degrees
constexpr double kQc = 0.7, kPc = 0.4;   // the colour error's exponent, and where (pc cmax) it reaches 0.95
constexpr double kToneTarget = 0.85;     // HDR: ACES(x_max) = 0.85 sets the exposure range

// ACES (Narkowicz) with FLIP's 0.6 pre-exposure cancellation: (k0 x^2 + k1 x) / (k3 x^2 + k4 x + k5).
constexpr double kAces[6] = {0.6 * 0.6 * 2.51, 0.6 * 0.03, 0.0, 0.6 * 0.6 * 2.43, 0.6 * 0.59, 0.14};

int csf_radius(double ppd) { return int(std::ceil(3.0 * std::sqrt(kCsfLargestB / (2.0 * kPi * kPi)) * ppd)); }
int feature_radius(double ppd) { return int(std::ceil(3.0 * 0.5 * kFeatureWidth * ppd)); }

// kernels/flip.cl's TAPS: 8 floats per offset -radius..radius.
std::vector<float> flip_taps(double ppd, int& radius) {
  const int rc = csf_radius(ppd), rf = feature_radius(ppd);
  radius = std::max(rc, rf);
  const int n = 2 * radius + 1;
  std::vector<double> t(std::size_t(n) * 8, 0.0);
  const auto at = [&](int k, int lane) -> double& { return t[std::size_t(k + radius) * 8 + lane]; };
  // The CSFs, evaluated at x = k / ppd degrees. Each Gaussian of a sum is separable as the product of two 1-D
  // factors sqrt(a sqrt(pi / b)) exp(-pi^2 x^2 / b); normalising every factor by the square root of the 2-D sum
  // makes the separated filters equal to the normalised 2-D ones.
  double sum_y = 0, sum_cx = 0, sum_cz[2] = {0, 0};
  for (int k = -rc; k <= rc; ++k) {
    const double x2 = double(k) * k / (ppd * ppd);
    at(k, 0) = kCsfY[0] * std::sqrt(kPi / kCsfY[1]) * std::exp(-kPi * kPi * x2 / kCsfY[1]);
    at(k, 1) = kCsfCx[0] * std::sqrt(kPi / kCsfCx[1]) * std::exp(-kPi * kPi * x2 / kCsfCx[1]);
    for (int j = 0; j < 2; ++j)
      at(k, 2 + j) = std::sqrt(kCsfCz[j][0] * std::sqrt(kPi / kCsfCz[j][1])) * std::exp(-kPi * kPi * x2 / kCsfCz[j][1]);
    sum_y += at(k, 0);
    sum_cx += at(k, 1);
    sum_cz[0] += at(k, 2);
    sum_cz[1] += at(k, 3);
  }
  const double cz_norm = std::sqrt(sum_cz[0] * sum_cz[0] + sum_cz[1] * sum_cz[1]);
  // The feature detectors: a Gaussian of sigma w ppd / 2 pixels and its first and second derivatives; the
  // Gaussian sums to 1, each derivative's positive and negative weights to +1 and -1.
  const double sd = 0.5 * kFeatureWidth * ppd;
  double sum_g = 0, pos[2] = {0, 0}, neg[2] = {0, 0};
  for (int k = -rf; k <= rf; ++k) {
    const double g = std::exp(-double(k) * k / (2 * sd * sd));
    at(k, 4) = g;
    at(k, 5) = -k * g;
    at(k, 6) = (double(k) * k / (sd * sd) - 1) * g;
    sum_g += g;
    for (int j = 0; j < 2; ++j) (at(k, 5 + j) > 0 ? pos[j] : neg[j]) += std::fabs(at(k, 5 + j));
  }
  std::vector<float> out(t.size());
  for (int k = -radius; k <= radius; ++k) {
    const double norm[7] = {sum_y, sum_cx, cz_norm, cz_norm, sum_g, 0, 0};
    for (int lane = 0; lane < 7; ++lane) {
      const double v = at(k, lane);
      const double d = lane < 5 ? norm[lane] : (v > 0 ? pos[lane - 5] : neg[lane - 5]);
      out[std::size_t(k + radius) * 8 + lane] = d > 0 ? float(v / d) : 0.0f;
    }
  }
  return out;
}

double luminance(const std::vector<float>& image, std::size_t p, std::uint32_t channels) {
  const std::size_t i = p * channels;
  if (channels < 3) return image[i];
  return 0.2126 * image[i] + 0.7152 * image[i + 1] + 0.0722 * image[i + 2];
}

// The largest colour difference: HyAB between Hunt-adjusted green and blue, to the power 0.7.
double flip_cmax() {
  const auto hunt_lab = [](double r, double g, double b) {
    const double w[3] = {0.950428545, 1.0, 1.088900371};
    const double xyz[3] = {(10135552.0 * r + 8788810.0 * g + 4435075.0 * b) / 24577794.0,
                           (2613072.0 * r + 8788810.0 * g + 887015.0 * b) / 12288897.0,
                           (1425312.0 * r + 8788810.0 * g + 70074185.0 * b) / 73733382.0};
    double f[3];
    const double delta = 6.0 / 29.0;
    for (int i = 0; i < 3; ++i) {
      const double t = xyz[i] / w[i];
      f[i] = t > delta * delta * delta ? std::cbrt(t) : t / (3 * delta * delta) + 4.0 / 29.0;
    }
    const double l = 116 * f[1] - 16;
    return std::array<double, 3>{l, 0.01 * l * 500 * (f[0] - f[1]), 0.01 * l * 200 * (f[1] - f[2])};
  };
  const auto g = hunt_lab(0, 1, 0), b = hunt_lab(0, 0, 1);
  return std::pow(std::fabs(g[0] - b[0]) + std::hypot(g[1] - b[1], g[2] - b[2]), kQc);
}

void check_images(const char* what, const std::vector<float>& prediction, const std::vector<float>& reference,
                  std::uint32_t width, std::uint32_t height, std::uint32_t channels) {
  const std::size_t n = std::size_t(width) * height * channels;
  if (width == 0 || height == 0 || channels == 0 || prediction.size() != n || reference.size() != n)
    throw InvalidArgument(std::string(what) + ": expected two " + std::to_string(height) + "x" + std::to_string(width) +
                          "x" + std::to_string(channels) + " images (" + std::to_string(n) + " values), got " +
                          std::to_string(prediction.size()) + " and " + std::to_string(reference.size()));
}

}  // namespace

FlipExposures flip_exposures(const std::vector<float>& reference, std::uint32_t width, std::uint32_t height,
                             std::uint32_t channels) {
  check_images("metrics::flip_exposures", reference, reference, width, height, channels);
  // x_max: the larger root of (k0 - t k3) x^2 + (k1 - t k4) x + (k2 - t k5) = 0, ACES(x_max) = t.
  const double qa = kAces[0] - kToneTarget * kAces[3], qb = kAces[1] - kToneTarget * kAces[4],
               qc = kAces[2] - kToneTarget * kAces[5];
  const double half = -0.5 * qb / qa, x_max = half + std::sqrt(half * half - qc / qa);
  const std::size_t pixels = std::size_t(width) * height;
  std::vector<double> y(pixels);
  for (std::size_t p = 0; p < pixels; ++p) y[p] = luminance(reference, p, channels);
  const double y_max = *std::max_element(y.begin(), y.end());
  std::nth_element(y.begin(), y.begin() + pixels / 2, y.end());
  const double y_median = y[pixels / 2];
  FlipExposures e;
  e.start = std::log2(x_max / std::max(y_max, double(FLT_EPSILON)));
  e.stop = std::log2(x_max / std::max(y_median, double(FLT_EPSILON)));
  e.count = std::uint32_t(std::max(2.0, std::ceil(e.stop - e.start)));
  return e;
}

FlipResult flip(const Device& device, const std::vector<float>& prediction, const std::vector<float>& reference,
                std::uint32_t width, std::uint32_t height, std::uint32_t channels, const FlipOptions& options) {
  check_images("metrics::flip", prediction, reference, width, height, channels);
  for (const auto* img : {&prediction, &reference})
    if (std::any_of(img->begin(), img->end(), [](float v) { return std::isnan(v); }))
      throw InvalidArgument(std::string("metrics::flip: the ") + (img == &prediction ? "prediction" : "reference") +
                            " contains NaN");
  const double ppd = options.pixels_per_degree;
  if (!(ppd > 0) || !std::isfinite(ppd))
    throw InvalidArgument("metrics::flip: pixels_per_degree must be a positive number, not " + std::to_string(ppd));

  FlipResult result;
  const bool hdr = options.range == FlipRange::hdr;
  if (hdr) {
    if (std::isnan(options.start_exposure) || std::isnan(options.stop_exposure))
      result.exposures = flip_exposures(reference, width, height, channels);
    if (!std::isnan(options.start_exposure)) result.exposures.start = options.start_exposure;
    if (!std::isnan(options.stop_exposure)) result.exposures.stop = options.stop_exposure;
    const auto& e = result.exposures;
    if (!std::isfinite(e.start) || !std::isfinite(e.stop) || e.start > e.stop)
      throw InvalidArgument("metrics::flip: the exposures must be finite with start <= stop, not start " +
                            std::to_string(e.start) + ", stop " + std::to_string(e.stop));
    result.exposures.count = options.exposures ? std::max<std::uint32_t>(options.exposures, 1)
                                               : std::uint32_t(std::max(2.0, std::ceil(e.stop - e.start)));
  } else {
    result.exposures = {0, 0, 1};
  }

  int radius = 0;
  const std::vector<float> taps = flip_taps(ppd, radius);
  const double cmax = flip_cmax();
  const std::size_t pixels = std::size_t(width) * height;
  Buffer<float> a(device, prediction), b(device, reference), t(device, taps);
  // kernels/flip.cl's planes, two images each: YCxCz (rows of span floats, the edges repeated radius times), then
  // filtered along x and along y (rows of pitch floats, whole chunks of FLIP_CHUNK).
  constexpr std::uint32_t kChunk = 16;
  const auto pitch = static_cast<std::uint32_t>(round_up(width, kChunk)), span = pitch + 2 * std::uint32_t(radius);
  const std::size_t pitched = std::size_t(pitch) * height;
  Buffer<float> ycc(device, 6 * std::size_t(span) * height), along_x(device, 14 * pitched),
      along_y(device, 14 * pitched), error(device, pitched);
  Kernel prepare = device.kernel("flip.cl", "flip_prepare");
  Kernel rows = device.kernel("flip.cl", "flip_rows");
  Kernel columns = device.kernel("flip.cl", "flip_columns");
  Kernel flip_error = device.kernel("flip.cl", "flip_error");
  rows.args(height, pitch, radius, t, ycc, along_x);
  columns.args(height, pitch, radius, t, along_x, along_y);
  flip_error.args(height, pitch, along_y, float(cmax), float(kPc * cmax), std::uint32_t(1), error);
  // Fixed work-group sizes: one compiled variant of each kernel for every image size.
  const cl::NDRange chunks(pitch / kChunk, round_up(height, 8)), chunk_group(1, 8);
  const auto& e = result.exposures;
  const double step = e.count > 1 ? (e.stop - e.start) / (e.count - 1) : 0.0;
  for (std::uint32_t i = 0; i < e.count; ++i) {
    const float scale = hdr ? float(std::exp2(e.start + i * step)) : 1.0f;
    prepare.args(width, height, span, radius, channels, scale, std::uint32_t(hdr), a, b, ycc)
        .launch(cl::NDRange(round_up(span, 16), height), cl::NDRange(16, 1));
    rows.launch(chunks, chunk_group);
    columns.launch(chunks, chunk_group);
    flip_error.arg(5, std::uint32_t(i == 0)).launch(chunks, chunk_group);
  }
  const std::vector<float> padded = error.read();
  result.error.resize(pixels);
  for (std::uint32_t y = 0; y < height; ++y)
    std::copy_n(padded.begin() + std::size_t(y) * pitch, width, result.error.begin() + std::size_t(y) * width);
  for (float v : result.error) result.mean += v;
  result.mean /= double(pixels);
  return result;
}

}  // namespace relit::metrics
