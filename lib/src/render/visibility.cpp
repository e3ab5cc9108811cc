// Visibility targets by marching a density grid (kernels/visibility.cl).
#include <relit/cl/program.hpp>
#include <relit/render/visibility.hpp>

#include <algorithm>
#include <cmath>

namespace relit::render {

namespace {
void check_grid(const DensityGrid& grid, std::uint32_t steps, const char* what) {
  const std::size_t cells =
      std::size_t(std::max(grid.dims[0], 0)) * std::max(grid.dims[1], 0) * std::max(grid.dims[2], 0);
  if (grid.dims[0] < 1 || grid.dims[1] < 1 || grid.dims[2] < 1 || grid.sigma.size() != cells)
    throw InvalidArgument(std::string(what) + ": the density grid holds " + std::to_string(grid.sigma.size()) +
                          " values for " + std::to_string(grid.dims[0]) + "x" + std::to_string(grid.dims[1]) + "x" +
                          std::to_string(grid.dims[2]) + " voxels");
  if (steps < 1 || steps > 4096) throw InvalidArgument(std::string(what) + ": steps must be in [1, 4096]");
}
}  // namespace

void march_visibility(const Device& device, const Buffer<float>& rays, std::uint32_t n_rays, std::uint32_t n_samples,
                      const nn::BatchMatrix& positions, const DensityGrid& grid, std::uint32_t steps,
                      nn::BatchMatrix& visibility, float depth_scale) {
  const std::uint64_t n = std::uint64_t(n_rays) * n_samples;
  if (positions.batch() != n || positions.cols() != 3 || visibility.cols() == 0)
    throw InvalidArgument("march_visibility: expected " + std::to_string(n) +
                          " sample positions (3 columns) and a visibility matrix with a column");
  if (n_samples == 0 || n_samples % nn::kBatchTile != 0)
    throw InvalidArgument("march_visibility: samples per ray must be a positive multiple of 16, got " +
                          std::to_string(n_samples));
  check_grid(grid, steps, "march_visibility");
  if (!(depth_scale >= 0.0f) || !std::isfinite(depth_scale))
    throw InvalidArgument("march_visibility: the depth scale must be finite and >= 0");
  visibility.resize(static_cast<std::uint32_t>(n));
  device
      .kernel("visibility.cl", "march_to_light",
              {{"N_SAMPLES", std::to_string(n_samples)}, {"MARCH_STEPS", std::to_string(steps)}})
      .args(static_cast<std::uint32_t>(n / nn::kBatchTile), positions.data(), rays, grid.sigma, grid.dims[0],
            grid.dims[1], grid.dims[2], depth_scale, visibility.data(), visibility.cols())
      .launch(n / nn::kBatchTile, 16);
}

void march_visibility_directions(const Device& device, const nn::BatchMatrix& positions, const nn::BatchMatrix& dirs,
                                 const DensityGrid& grid, std::uint32_t steps, nn::BatchMatrix& out) {
  const std::uint32_t n = positions.batch(), n_dirs = dirs.batch();
  if (positions.cols() != 3 || dirs.cols() != 3 || n_dirs == 0)
    throw InvalidArgument("march_visibility_directions: positions (" + std::to_string(positions.cols()) +
                          " columns) and directions (" + std::to_string(n_dirs) + "x" + std::to_string(dirs.cols()) +
                          ") need 3 columns and at least one direction");
  if (out.cols() != n_dirs)
    throw InvalidArgument("march_visibility_directions: the output has " + std::to_string(out.cols()) +
                          " columns, one per direction (" + std::to_string(n_dirs) + ") expected");
  check_grid(grid, steps, "march_visibility_directions");
  out.resize(n);
  if (n == 0) return;
  const auto n_tiles = static_cast<std::uint32_t>(round_up(n, nn::kBatchTile) / nn::kBatchTile);
  device.kernel("visibility.cl", "march_directions", {{"MARCH_STEPS", std::to_string(steps)}})
      .args(n_tiles, n_dirs, positions.data(), dirs.data(), grid.sigma, grid.dims[0], grid.dims[1], grid.dims[2],
            out.data())
      .launch(std::size_t(n_tiles) * n_dirs, 16);
}

}  // namespace relit::render
