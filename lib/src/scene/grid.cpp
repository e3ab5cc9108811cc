// Grid lookups, majorant grids, and the validation of media and surfaces.
#include <relit/error.hpp>
#include <relit/scene/grid.hpp>
#include <relit/scene/medium.hpp>
#include <relit/scene/surface.hpp>

#include <algorithm>
#include <cmath>
#include <limits>

namespace relit {

double Grid::sample(double x, double y, double z, int c) const {
  const double p[3] = {x, y, z};
  const int n[3] = {nx, ny, nz};
  int i0[3], i1[3];
  double f[3];
  for (int a = 0; a < 3; ++a) {
    double u = (p[a] + 1.0) * 0.5 * n[a] - 0.5;
    u = std::clamp(u, 0.0, double(n[a] - 1));
    i0[a] = std::min(int(std::floor(u)), n[a] - 1);
    i1[a] = std::min(i0[a] + 1, n[a] - 1);
    f[a] = u - i0[a];
  }
  auto v = [&](int a, int b, int d) { return double(at(a, b, d, c)); };
  const double c00 = v(i0[0], i0[1], i0[2]) * (1 - f[0]) + v(i1[0], i0[1], i0[2]) * f[0];
  const double c10 = v(i0[0], i1[1], i0[2]) * (1 - f[0]) + v(i1[0], i1[1], i0[2]) * f[0];
  const double c01 = v(i0[0], i0[1], i1[2]) * (1 - f[0]) + v(i1[0], i0[1], i1[2]) * f[0];
  const double c11 = v(i0[0], i1[1], i1[2]) * (1 - f[0]) + v(i1[0], i1[1], i1[2]) * f[0];
  const double c0 = c00 * (1 - f[1]) + c10 * f[1];
  const double c1 = c01 * (1 - f[1]) + c11 * f[1];
  return c0 * (1 - f[2]) + c1 * f[2];
}

float Grid::max_value(int c) const {
  float m = -std::numeric_limits<float>::infinity();
  for (std::size_t i = c; i < values.size(); i += channels) m = std::max(m, values[i]);
  return m;
}

float Grid::min_value(int c) const {
  float m = std::numeric_limits<float>::infinity();
  for (std::size_t i = c; i < values.size(); i += channels) m = std::min(m, values[i]);
  return m;
}

Grid majorant_grid(const Grid& grid, float scale, int block) {
  block = std::max(block, 1);
  const int mx = (grid.nx + block - 1) / block, my = (grid.ny + block - 1) / block, mz = (grid.nz + block - 1) / block;
  Grid m(mx, my, mz, 1, 0.0f);
  // Cell c spans voxel coordinates [c*n/m - 0.5, (c+1)*n/m - 0.5] in lookup space; the trilinear lookups
  // there read voxels floor(lo) .. floor(hi) + 1. One extra voxel on each side absorbs float rounding in
  // the kernels' cell traversal.
  auto range = [](int c, int cells, int n, int& lo, int& hi) {
    const double a = double(c) * n / cells - 0.5, b = double(c + 1) * n / cells - 0.5;
    lo = std::max(int(std::floor(a)) - 1, 0);
    hi = std::min(int(std::floor(b)) + 2, n - 1);
  };
  for (int k = 0; k < mz; ++k)
    for (int j = 0; j < my; ++j)
      for (int i = 0; i < mx; ++i) {
        int i0, i1, j0, j1, k0, k1;
        range(i, mx, grid.nx, i0, i1);
        range(j, my, grid.ny, j0, j1);
        range(k, mz, grid.nz, k0, k1);
        float v = 0.0f;
        for (int c = k0; c <= k1; ++c)
          for (int b = j0; b <= j1; ++b)
            for (int a = i0; a <= i1; ++a) v = std::max(v, grid.at(a, b, c));
        m.at(i, j, k) = v * scale;
      }
  return m;
}

namespace {
void check_grid(const Grid& g, int channels, const char* what) {
  if (g.nx < 2 || g.ny < 2 || g.nz < 2 || g.nx > 1024 || g.ny > 1024 || g.nz > 1024)
    throw InvalidArgument(std::string(what) + " must be between 2 and 1024 voxels per side, got " +
                          std::to_string(g.nx) + "x" + std::to_string(g.ny) + "x" + std::to_string(g.nz));
  if (g.channels != channels || g.values.size() != g.voxels() * channels)
    throw InvalidArgument(std::string(what) + " must have " + std::to_string(channels) +
                          " channel(s) and matching data");
  for (float v : g.values)
    if (!std::isfinite(v)) throw InvalidArgument(std::string(what) + " contains NaN or infinite values");
}
}  // namespace

void Medium::validate() const {
  check_grid(density, 1, "the density grid");
  if (density.min_value() < 0.0f) throw InvalidArgument("the density grid has negative values; densities must be >= 0");
  if (!(density_scale >= 0.0f) || !std::isfinite(density_scale))
    throw InvalidArgument("density_scale must be a finite number >= 0");
  if (!(g > -1.0f && g < 1.0f))
    throw InvalidArgument("the Henyey-Greenstein g must lie in (-1, 1), got " + std::to_string(g));
  for (float a : albedo)
    if (!(a >= 0.0f && a <= 1.0f)) throw InvalidArgument("albedo values must lie in [0, 1]");
  if (!albedo_grid.empty()) {
    check_grid(albedo_grid, 3, "the albedo grid");
    if (albedo_grid.min_value(0) < 0 || albedo_grid.max_value(0) > 1 || albedo_grid.min_value(1) < 0 ||
        albedo_grid.max_value(1) > 1 || albedo_grid.min_value(2) < 0 || albedo_grid.max_value(2) > 1)
      throw InvalidArgument("albedo grid values must lie in [0, 1]");
  }
}

void Surface::validate() const {
  check_grid(sdf, 1, "the SDF grid");
  for (float a : base_color)
    if (!(a >= 0.0f && a <= 1.0f)) throw InvalidArgument("base_color values must lie in [0, 1]");
  if (!(roughness >= 0.02f && roughness <= 1.0f)) throw InvalidArgument("roughness must lie in [0.02, 1]");
}

}  // namespace relit
