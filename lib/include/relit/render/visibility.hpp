// Visibility targets: the transmittance of a density grid from each renderer sample toward its ray's point
// light (kernels/visibility.cl). The method trains its visibility network against these (DESIGN §4.3).
#pragma once

#include <relit/cl/buffer.hpp>
#include <relit/nn/batch.hpp>

#include <array>
#include <cstdint>

namespace relit::render {

/// A dense grid of extinction sigma over [-1, 1]^3 (x fastest, values at voxel centres, trilinear).
struct DensityGrid {
  std::array<int, 3> dims{};
  Buffer<float> sigma;
};

/// visibility (n_rays * n_samples x 1) = exp(-optical depth) from each sample position (as placed by
/// VolumeRenderer::sample) toward the point light of its ray, marched in `steps` midpoint steps.
void march_visibility(const Device& device, const Buffer<float>& rays, std::uint32_t n_rays, std::uint32_t n_samples,
                      const nn::BatchMatrix& positions, const DensityGrid& grid, std::uint32_t steps,
                      nn::BatchMatrix& visibility);

}  // namespace relit::render
