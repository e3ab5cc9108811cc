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
//
//   auto mask = metrics::object_mask(reference_alpha, prediction_alpha, width * height);
//   auto m = metrics::compare(device, prediction, reference, width, height, 3, &mask);
//   m.psnr, m.object.psnr, m.object.rel_mse, m.object.clipped
#pragma once

#include <relit/cl/buffer.hpp>

#include <cstdint>
#include <limits>
#include <vector>

namespace relit::metrics {

/// Alpha above this marks an object pixel.
constexpr float kObjectAlpha = 0.01f;
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
};

struct ImageComparison {
  double mse = 0;           ///< mean squared error of the sRGB-encoded images
  double psnr = 0;          ///< 10 log10(1 / mse) dB; +inf for identical images
  double ssim = 0;          ///< mean SSIM over interior pixels and channels (11x11 Gaussian window, sigma 1.5)
  ObjectComparison object;  ///< over the mask given to compare(); pixels 0 and NaN metrics without one
};

/// The object's pixels (1) of an image of `pixels` pixels: where the reference's alpha or the prediction's
/// exceeds kObjectAlpha. Either alpha may be empty (not known); both empty gives an empty mask (all 0).
std::vector<std::uint8_t> object_mask(const std::vector<float>& reference_alpha,
                                      const std::vector<float>& prediction_alpha, std::size_t pixels);

/// Compares `prediction` with `reference` (both linear, height x width x channels). The images must be at
/// least 11 x 11 pixels for SSIM. `mask`: height x width, nonzero for the object's pixels (object_mask()), or
/// null (ImageComparison::object stays empty).
ImageComparison compare(const Device& device, const std::vector<float>& prediction, const std::vector<float>& reference,
                        std::uint32_t width, std::uint32_t height, std::uint32_t channels,
                        const std::vector<std::uint8_t>* mask = nullptr);

}  // namespace relit::metrics
