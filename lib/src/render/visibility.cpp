// Visibility targets by marching a density grid (kernels/visibility.cl).
#include <relit/cl/program.hpp>
#include <relit/render/visibility.hpp>

namespace relit::render {

void march_visibility(const Device& device, const Buffer<float>& rays, std::uint32_t n_rays, std::uint32_t n_samples,
                      const nn::BatchMatrix& positions, const DensityGrid& grid, std::uint32_t steps,
                      nn::BatchMatrix& visibility) {
  const std::uint64_t n = std::uint64_t(n_rays) * n_samples;
  if (positions.batch() != n || positions.cols() != 3 || visibility.cols() != 1)
    throw InvalidArgument("march_visibility: expected " + std::to_string(n) + " sample positions (3 columns) and a "
                          "1-column visibility matrix");
  const std::size_t cells = std::size_t(grid.dims[0]) * grid.dims[1] * grid.dims[2];
  if (grid.dims[0] < 1 || grid.dims[1] < 1 || grid.dims[2] < 1 || grid.sigma.size() != cells)
    throw InvalidArgument("march_visibility: the density grid holds " + std::to_string(grid.sigma.size()) +
                          " values for " + std::to_string(grid.dims[0]) + "x" + std::to_string(grid.dims[1]) + "x" +
                          std::to_string(grid.dims[2]) + " voxels");
  if (steps < 1 || steps > 4096) throw InvalidArgument("march_visibility: steps must be in [1, 4096]");
  visibility.resize(static_cast<std::uint32_t>(n));
  device
      .kernel("visibility.cl", "march_to_light",
              {{"N_SAMPLES", std::to_string(n_samples)}, {"MARCH_STEPS", std::to_string(steps)}})
      .args(static_cast<std::uint32_t>(n), positions.data(), rays, grid.sigma, grid.dims[0], grid.dims[1], grid.dims[2],
            visibility.data())
      .launch(n, 64);
}

}  // namespace relit::render
