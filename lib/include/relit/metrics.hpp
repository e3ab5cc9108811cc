// Image metrics (docs/evaluation.md), computed in OpenCL.
//
// Both images are linear float RGB(A), interleaved row-major (height x width x channels).
// - The paper's protocol, over the whole image: the images are clamped to [0, 1] and sRGB-encoded, so the numbers
//   describe what a person sees on a display, and match scikit-image's peak_signal_noise_ratio(data_range=1) and
//   structural_similarity(gaussian_weights=True, sigma=1.5, use_sample_covariance=False, data_range=1,
//   channel_axis=-1) on the encoded images.
// - Over the object: the same PSNR and SSIM over the pixels of a mask (object_mask(): the reference's or the
//   prediction's alpha above 0.01), and on the linear, unclamped images the relative MSE and the share of the
//   object's pixels that clip in the reference. Where most of an image is background, these say how well the
//   object itself is rendered; a clipped pixel shows no error in sRGB however wrong it is.
// - HDR-FLIP (flip()): NVIDIA's perceptual difference of the linear, unclamped images as a viewer sees them
//   over a range of exposures, per pixel in [0, 1]; its mean over the image and over the object.
//
//   auto mask = metrics::object_mask(reference_alpha, prediction_alpha, width * height);
//   auto m = metrics::compare(device, prediction, reference, width, height, 3, &mask);
//   m.psnr, m.flip, m.object.psnr, m.object.rel_mse, m.object.clipped, m.object.flip
//   auto f = metrics::flip(device, prediction, reference, width, height, 3);   // f.error: the per-pixel map
#pragma once

#include <relit/cl/buffer.hpp>

#include <cstdint>
#include <limits>
#include <vector>

namespace relit::metrics {

/// Alpha above this marks an object pixel.
constexpr float kObjectAlpha = 0.01f;
/// object_mask()'s values: nonzero is the object; kMaskPredictionOnly marks pixels that only the prediction's
/// alpha puts there (floaters, or a haze in empty space), kMaskReference those of the reference's alpha.
constexpr std::uint8_t kMaskReference = 1;
constexpr std::uint8_t kMaskPredictionOnly = 2;
/// The relative MSE's (a - b)^2 / (b^2 + eps) regulariser (b: the reference), as in denoising papers: it keeps
/// near-black pixels from dominating.
constexpr double kRelMseEpsilon = 0.01;

/// Metrics over the pixels of an object mask. NaN (JSON null) when the mask is empty.
struct ObjectComparison {
  static constexpr double kNone = std::numeric_limits<double>::quiet_NaN();
  std::uint64_t pixels = 0;  ///< object pixels
  double fraction = 0;       ///< object pixels / all pixels
  double mse = kNone;        ///< mean squared error of the sRGB-encoded images over the object
  double psnr = kNone;       ///< 10 log10(1 / mse) dB
  double ssim = kNone;       ///< mean SSIM over the object's interior pixels (NaN when none is interior)
  double rel_mse = kNone;    ///< mean over the object and channels of (a - b)^2 / (b^2 + kRelMseEpsilon), linear
  double clipped = kNone;    ///< share of the object's pixels whose reference has a channel above 1
  double flip = kNone;       ///< mean HDR-FLIP over the object's pixels (the exposures are the whole image's)
  /// Share of the object's pixels that only the prediction's alpha marks (mask value kMaskPredictionOnly):
  /// floaters or a haze. Well above 0, the object metrics are averaged over that much empty space too. 0 when the
  /// mask does not say (a mask of 0 and 1 only).
  double prediction_only = kNone;
};

struct ImageComparison {
  double mse = 0;   ///< mean squared error of the sRGB-encoded images
  double psnr = 0;  ///< 10 log10(1 / mse) dB; +inf for identical images
  double ssim = 0;  ///< mean SSIM over interior pixels and channels (11x11 Gaussian window, sigma 1.5)
  /// Mean HDR-FLIP (flip() with the default FlipOptions), in [0, 1]; NaN when not computed (metrics given by hand).
  double flip = ObjectComparison::kNone;
  ObjectComparison object;  ///< over the mask given to compare(); pixels 0 and NaN metrics without one
};

/// The object's pixels (nonzero) of an image of `pixels` pixels: where the reference's alpha or the prediction's
/// exceeds kObjectAlpha; kMaskReference where the reference's does, kMaskPredictionOnly where only the
/// prediction's does. Either alpha may be empty (not known); both empty gives an empty mask (all 0).
std::vector<std::uint8_t> object_mask(const std::vector<float>& reference_alpha,
                                      const std::vector<float>& prediction_alpha, std::size_t pixels);

/// FLIP's observer: pixels per degree of visual angle. The default is NVIDIA's, a 0.7 m wide monitor of 3840
/// pixels seen from 0.7 m: 3840 pi / 180 = 67.02.
constexpr double kFlipPixelsPerDegree = 0.7 * (3840.0 / 0.7) * 3.14159265358979323846 / 180.0;

/// LDR-FLIP compares the images clamped to [0, 1] (what a display shows without tone mapping); HDR-FLIP compares
/// them at several exposures, each tone-mapped with ACES, and keeps each pixel's largest error.
enum class FlipRange { ldr, hdr };

/// The exposures of HDR-FLIP: `count` evenly spaced from `start` to `stop` (in stops, the image scaled by
/// 2^exposure before tone mapping).
struct FlipExposures {
  double start = 0, stop = 0;
  std::uint32_t count = 2;
};

struct FlipOptions {
  FlipRange range = FlipRange::hdr;
  double pixels_per_degree = kFlipPixelsPerDegree;
  /// HDR: NaN (the default) takes each from flip_exposures() of the reference.
  double start_exposure = std::numeric_limits<double>::quiet_NaN();
  double stop_exposure = std::numeric_limits<double>::quiet_NaN();
  /// HDR: 0 (the default) takes max(2, ceil(stop - start)).
  std::uint32_t exposures = 0;
};

/// The default exposure range of HDR-FLIP (Andersson, Nilsson, Shirley, Akenine-Möller, Eurographics 2021): with
/// x_max the input at which ACES reaches 0.85, start = log2(x_max / Y_max) brings the reference's brightest
/// luminance there and stop = log2(x_max / Y_median) its median, count = max(2, ceil(stop - start)). Luminance:
/// 0.2126 R + 0.7152 G + 0.0722 B of the linear reference; the median is the element n/2 of the sorted
/// luminances; Y_max and Y_median are at least FLT_EPSILON, as in NVIDIA's flip-evaluator 1.7, so a reference
/// that is mostly black (a median of 0) gets a stop exposure near 24 and an all-black one start = stop. One
/// channel: grey.
FlipExposures flip_exposures(const std::vector<float>& reference, std::uint32_t width, std::uint32_t height,
                             std::uint32_t channels);

struct FlipResult {
  std::vector<float> error;  ///< per pixel (height x width, row-major), in [0, 1]
  double mean = 0;           ///< the mean of `error`, added in double in row order
  FlipExposures exposures;   ///< those used (HDR); LDR: count 1
};

/// FLIP of `prediction` (the test image) against `reference`, both linear height x width x channels (R, G, B
/// from the first three channels; one channel is grey), computed in OpenCL (kernels/flip.cl). HDR-FLIP, the
/// default, expects non-negative radiance. Throws InvalidArgument for mismatched sizes, NaN, fewer than one pixel,
/// a non-positive pixels_per_degree or start > stop.
FlipResult flip(const Device& device, const std::vector<float>& prediction, const std::vector<float>& reference,
                std::uint32_t width, std::uint32_t height, std::uint32_t channels, const FlipOptions& options = {});

/// Compares `prediction` with `reference` (both linear, height x width x channels). The images must be at
/// least 11 x 11 pixels for SSIM. `mask`: height x width, nonzero for the object's pixels (object_mask()), or
/// null (ImageComparison::object stays empty).
ImageComparison compare(const Device& device, const std::vector<float>& prediction, const std::vector<float>& reference,
                        std::uint32_t width, std::uint32_t height, std::uint32_t channels,
                        const std::vector<std::uint8_t>* mask = nullptr);

}  // namespace relit::metrics
