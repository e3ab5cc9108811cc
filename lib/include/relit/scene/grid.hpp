// Grid: a dense 3-D grid of values over the scene box [-1, 1]^3, read with trilinear interpolation.
//
// Values sit at voxel centres: voxel (i, j, k) of an nx*ny*nz grid is centred at
// (-1 + (i + 0.5) * 2/nx, ...). Lookups clamp to the edge voxels. Storage is x fastest, then y, then z,
// with `channels` values per voxel interleaved: value(i, j, k, c) = values[((k*ny + j)*nx + i)*channels + c].
// The kernels (kernels/geometry.clh) use the very same convention.
#pragma once

#include <array>
#include <cstddef>
#include <vector>

namespace relit {

using Float3 = std::array<float, 3>;

struct Grid {
  int nx = 0, ny = 0, nz = 0, channels = 1;
  std::vector<float> values;

  Grid() = default;
  Grid(int x, int y, int z, int c = 1, float fill = 0.0f)
      : nx(x), ny(y), nz(z), channels(c), values(std::size_t(x) * y * z * c, fill) {}

  bool empty() const { return values.empty(); }
  std::size_t voxels() const { return std::size_t(nx) * ny * nz; }
  float& at(int i, int j, int k, int c = 0) { return values[((std::size_t(k) * ny + j) * nx + i) * channels + c]; }
  float at(int i, int j, int k, int c = 0) const { return values[((std::size_t(k) * ny + j) * nx + i) * channels + c]; }
  /// World position of voxel (i, j, k)'s centre.
  Float3 centre(int i, int j, int k) const {
    return {-1.0f + (i + 0.5f) * 2.0f / nx, -1.0f + (j + 0.5f) * 2.0f / ny, -1.0f + (k + 0.5f) * 2.0f / nz};
  }
  /// Trilinear lookup at world position p (double precision: the host reference of the kernels' lookup).
  double sample(double x, double y, double z, int c = 0) const;
  float max_value(int c = 0) const;
  float min_value(int c = 0) const;
};

/// A coarse grid of upper bounds of `grid` (channel 0, times `scale`) over blocks of `block` voxels: each cell
/// bounds every trilinear lookup inside it. The path tracer's delta and ratio tracking step through it.
Grid majorant_grid(const Grid& grid, float scale, int block);

}  // namespace relit
