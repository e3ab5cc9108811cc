// Image metrics (docs/design.md §6): PSNR and SSIM, computed in OpenCL on the clamped, sRGB-encoded images.
//
// Both images are linear float RGB(A), interleaved row-major (height x width x channels). They are clamped
// to [0, 1] and sRGB-encoded first, so the numbers describe what a person sees on a display, and match
// scikit-image's peak_signal_noise_ratio(data_range=1) and structural_similarity(gaussian_weights=True,
// sigma=1.5, use_sample_covariance=False, data_range=1, channel_axis=-1) on the encoded images.
#pragma once

#include <relit/cl/buffer.hpp>

#include <cstdint>
#include <vector>

namespace relit::metrics {

struct ImageComparison {
  double mse = 0;   ///< mean squared error of the sRGB-encoded images
  double psnr = 0;  ///< 10 log10(1 / mse) dB; +inf for identical images
  double ssim = 0;  ///< mean SSIM over interior pixels and channels (11x11 Gaussian window, sigma 1.5)
};

/// Compares `prediction` with `reference` (both linear, height x width x channels). The images must be at
/// least 11 x 11 pixels for SSIM.
ImageComparison compare(const Device& device, const std::vector<float>& prediction, const std::vector<float>& reference,
                        std::uint32_t width, std::uint32_t height, std::uint32_t channels);

}  // namespace relit::metrics
