// Visibility targets: the transmittance of a density grid from each renderer sample toward its ray's point
// light, or toward each environment direction (kernels/visibility.cl). The method trains its visibility
// network against these (docs/design.md §4.3).
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

/// Column 0 of visibility (n_rays * n_samples rows, any number of columns: a visibility net's outputs, of which
/// V is the first; the others are left as they are) = exp(-optical depth) from each sample position (as placed
/// by VolumeRenderer::sample) toward the point light of its ray, marched in `steps` midpoint steps. With
/// `depth_scale` k the result is exp(-k * optical depth) instead (k = 1: the visibility).
void march_visibility(const Device& device, const Buffer<float>& rays, std::uint32_t n_rays, std::uint32_t n_samples,
                      const nn::BatchMatrix& positions, const DensityGrid& grid, std::uint32_t steps,
                      nn::BatchMatrix& visibility, float depth_scale = 1.0f);

/// out (n_samples x N_e) = exp(-optical depth) from each sample position along each of the N_e unit
/// directions `dirs` (N_e x 3, e.g. EnvironmentSamples::dirs()) to where the ray leaves [-1, 1]^3, marched in
/// `steps` midpoint steps: the environment-visibility targets, V(x, w_j) in column j.
void march_visibility_directions(const Device& device, const nn::BatchMatrix& positions, const nn::BatchMatrix& dirs,
                                 const DensityGrid& grid, std::uint32_t steps, nn::BatchMatrix& out);

}  // namespace relit::render
