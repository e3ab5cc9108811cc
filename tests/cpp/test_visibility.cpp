// Visibility targets, toward the point light and toward environment directions: a homogeneous grid gives
// exp(-sigma d) exactly; a random grid matches a double-precision march with the same quadrature and trilinear
// lookup.
#include "test_support.hpp"

#include <relit/render/visibility.hpp>
#include <relit/render/volume_renderer.hpp>

#include <Eigen/Core>

#include <cmath>
#include <random>

namespace relit {

using nn::BatchMatrix;
using render::kRayFloats;
using V3 = Eigen::Vector3d;

namespace {

// The point light's position in a ray record.
V3 light_position(const float* ray) {
  const auto p = render::ray_field3(ray, render::kRayLightPosition);
  return V3(p[0], p[1], p[2]);
}

double lookup(const std::vector<float>& g, int n, const V3& p) {
  V3 u = ((p.array() + 1) * 0.5 * n - 0.5).matrix();
  for (int a = 0; a < 3; ++a) u[a] = std::min(std::max(u[a], 0.0), n - 1.0);
  int lo[3], hi[3];
  double f[3];
  for (int a = 0; a < 3; ++a) {
    lo[a] = std::min(int(std::floor(u[a])), n - 1);
    hi[a] = std::min(lo[a] + 1, n - 1);
    f[a] = u[a] - lo[a];
  }
  double v = 0;
  for (int c = 0; c < 8; ++c) {
    const int i = c & 1 ? hi[0] : lo[0], j = c & 2 ? hi[1] : lo[1], k = c & 4 ? hi[2] : lo[2];
    const double w = (c & 1 ? f[0] : 1 - f[0]) * (c & 2 ? f[1] : 1 - f[1]) * (c & 4 ? f[2] : 1 - f[2]);
    v += w * g[(std::size_t(k) * n + j) * n + i];
  }
  return v;
}

// Distance from x toward the light until the box is left (or the light reached).
std::pair<double, double> shadow_segment(const V3& x, const V3& light) {
  const V3 w = (light - x).normalized();
  double t0 = -1e30, t1 = 1e30;
  for (int a = 0; a < 3; ++a) {
    const double u = (-1 - x[a]) / w[a], v = (1 - x[a]) / w[a];
    t0 = std::max(t0, std::min(u, v));
    t1 = std::min(t1, std::max(u, v));
  }
  const double start = std::max(t0, 0.0), end = std::min(t1, (light - x).norm());
  return {start, std::max(end - start, 0.0)};
}

struct Setup {
  std::vector<float> rays;
  std::vector<float> positions, visibility;  // visibility: column 0 of the marched matrix
  std::vector<float> other_columns;          // its columns 1 .. cols - 1, filled with 7 before the march
};

Setup run(const Device& d, const std::vector<float>& grid, int n, std::uint32_t steps, float depth_scale = 1.0f,
          std::uint32_t cols = 1) {
  const std::uint32_t n_rays = 6, n_samples = 16;
  std::mt19937 rng(4);
  std::uniform_real_distribution<float> u(-1, 1);
  std::vector<float> rays;
  for (std::uint32_t r = 0; r < n_rays; ++r) {
    const V3 o = 4 * V3(u(rng), u(rng), u(rng)).normalized();
    const V3 dir = (V3(0.3 * u(rng), 0.3 * u(rng), 0.3 * u(rng)) - o).normalized();
    const V3 light = (3 + u(rng)) * V3(u(rng), u(rng), u(rng)).normalized();
    const auto rec =
        render::ray_record({float(o.x()), float(o.y()), float(o.z())}, {float(dir.x()), float(dir.y()), float(dir.z())},
                           {float(light.x()), float(light.y()), float(light.z())}, {1, 1, 1});
    rays.insert(rays.end(), rec.begin(), rec.end());
  }
  render::VolumeRenderer renderer(d, {n_samples, -1, 1});
  Buffer<float> r(d, rays), t(d, n_rays * n_samples), delta(d, n_rays * n_samples);
  BatchMatrix pos(d, n_rays * n_samples, 3), vis(d, n_rays * n_samples, cols);
  vis.upload_row_major(std::vector<float>(std::size_t(n_rays) * n_samples * cols, 7.0f));
  renderer.sample(r, n_rays, true, 3, t, delta, pos);
  render::DensityGrid g{{n, n, n}, Buffer<float>(d, grid)};
  render::march_visibility(d, r, n_rays, n_samples, pos, g, steps, vis, depth_scale);
  Setup s{rays, pos.download_row_major(), {}, {}};
  const auto all = vis.download_row_major();
  for (std::size_t i = 0; i < all.size(); ++i) (i % cols == 0 ? s.visibility : s.other_columns).push_back(all[i]);
  return s;
}

}  // namespace

TEST(Visibility, HomogeneousGridTransmitsExpMinusSigmaD) {
  const auto s = run(test::test_device(), std::vector<float>(8, 0.8f), 2, 32);
  for (std::size_t i = 0; i < s.visibility.size(); ++i) {
    const V3 x(s.positions[3 * i], s.positions[3 * i + 1], s.positions[3 * i + 2]);
    const float* ray = &s.rays[(i / 16) * kRayFloats];
    const double d = shadow_segment(x, light_position(ray)).second;
    EXPECT_NEAR(s.visibility[i], std::exp(-0.8 * d), 2e-6) << i;
  }
}

// A visibility net's output matrix (NeRV's V, D): the march writes V into column 0, the same values as into a
// one-column matrix, and leaves the other columns as they were.
TEST(Visibility, MarchWritesTheFirstColumnOfAWiderMatrix) {
  const Device d = test::test_device();
  const std::vector<float> grid(8, 0.8f);
  const auto one = run(d, grid, 2, 32), wide = run(d, grid, 2, 32, 1.0f, 3);
  EXPECT_EQ(wide.visibility, one.visibility);
  ASSERT_EQ(wide.other_columns.size(), 2 * one.visibility.size());
  for (const float v : wide.other_columns) ASSERT_EQ(v, 7.0f);
}

// The SH head's optical-depth input: exp(-k tau) for the same march.
TEST(Visibility, DepthScaleGivesExpMinusKTau) {
  for (const float k : {0.25f, 0.0f}) {
    const auto s = run(test::test_device(), std::vector<float>(8, 0.8f), 2, 32, k);
    for (std::size_t i = 0; i < s.visibility.size(); ++i) {
      const V3 x(s.positions[3 * i], s.positions[3 * i + 1], s.positions[3 * i + 2]);
      const float* ray = &s.rays[(i / 16) * kRayFloats];
      const double d = shadow_segment(x, light_position(ray)).second;
      EXPECT_NEAR(s.visibility[i], std::exp(-k * 0.8 * d), 2e-6) << i;
    }
  }
  EXPECT_THROW(run(test::test_device(), std::vector<float>(8, 0.8f), 2, 32, -1.0f), InvalidArgument);
}

TEST(Visibility, RandomGridMatchesDoublePrecisionMarch) {
  const int n = 8;
  const std::uint32_t steps = 48;
  std::mt19937 rng(9);
  std::uniform_real_distribution<float> u(0, 3);
  std::vector<float> grid(n * n * n);
  for (auto& v : grid) v = u(rng);
  const auto s = run(test::test_device(), grid, n, steps);
  for (std::size_t i = 0; i < s.visibility.size(); ++i) {
    const V3 x(s.positions[3 * i], s.positions[3 * i + 1], s.positions[3 * i + 2]);
    const float* ray = &s.rays[(i / 16) * kRayFloats];
    const V3 light = light_position(ray);
    const auto [start, d] = shadow_segment(x, light);
    const V3 w = (light - x).normalized();
    double tau = 0;
    for (std::uint32_t j = 0; j < steps; ++j) tau += lookup(grid, n, x + (start + (j + 0.5) * d / steps) * w);
    tau *= d / steps;
    EXPECT_NEAR(-std::log(s.visibility[i]), tau, 2e-5 * (1 + tau)) << i;
  }
}

namespace {

// Distance from x along unit w to where the ray leaves the box.
double exit_distance(const V3& x, const V3& w) {
  double t1 = 1e30;
  for (int a = 0; a < 3; ++a) t1 = std::min(t1, std::max((-1 - x[a]) / w[a], (1 - x[a]) / w[a]));
  return std::max(t1, 0.0);
}

struct DirectionSetup {
  std::vector<float> positions, dirs, visibility;  // row-major: n x 3, n_dirs x 3, n x n_dirs
};

DirectionSetup run_directions(const Device& d, const std::vector<float>& grid, int n, std::uint32_t steps,
                              std::uint32_t n_dirs) {
  const std::uint32_t n_pos = 75;  // a partial last tile
  std::mt19937 rng(12);
  std::normal_distribution<float> nd;
  std::uniform_real_distribution<float> u(-0.98f, 0.98f);
  std::vector<float> positions, dirs;
  for (std::uint32_t i = 0; i < n_pos; ++i) positions.insert(positions.end(), {u(rng), u(rng), u(rng)});
  for (std::uint32_t k = 0; k < n_dirs; ++k) {
    const V3 w = V3(nd(rng), nd(rng), nd(rng)).normalized();
    dirs.insert(dirs.end(), {float(w.x()), float(w.y()), float(w.z())});
  }
  BatchMatrix pos(d, n_pos, 3), dm(d, n_dirs, 3), vis(d, 1, n_dirs);
  pos.upload_row_major(positions);
  dm.upload_row_major(dirs);
  render::DensityGrid g{{n, n, n}, Buffer<float>(d, grid)};
  render::march_visibility_directions(d, pos, dm, g, steps, vis);
  EXPECT_EQ(vis.batch(), n_pos);
  return {positions, dirs, vis.download_row_major()};
}

}  // namespace

TEST(Visibility, DirectionsThroughAHomogeneousGridTransmitExpMinusSigmaD) {
  const std::uint32_t n_dirs = 20;  // not a multiple of 16: the directions' last tile is partial
  const auto s = run_directions(test::test_device(), std::vector<float>(8, 0.6f), 2, 16, n_dirs);
  for (std::size_t i = 0; i < s.positions.size() / 3; ++i)
    for (std::uint32_t k = 0; k < n_dirs; ++k) {
      const V3 x(s.positions[3 * i], s.positions[3 * i + 1], s.positions[3 * i + 2]);
      const V3 w(s.dirs[3 * k], s.dirs[3 * k + 1], s.dirs[3 * k + 2]);
      EXPECT_NEAR(s.visibility[i * n_dirs + k], std::exp(-0.6 * exit_distance(x, w)), 2e-6) << i << " " << k;
    }
}

TEST(Visibility, DirectionsThroughARandomGridMatchDoublePrecisionMarch) {
  const int n = 8;
  const std::uint32_t steps = 40, n_dirs = 32;
  std::mt19937 rng(10);
  std::uniform_real_distribution<float> u(0, 3);
  std::vector<float> grid(n * n * n);
  for (auto& v : grid) v = u(rng);
  const auto s = run_directions(test::test_device(), grid, n, steps, n_dirs);
  for (std::size_t i = 0; i < s.positions.size() / 3; ++i)
    for (std::uint32_t k = 0; k < n_dirs; ++k) {
      const V3 x(s.positions[3 * i], s.positions[3 * i + 1], s.positions[3 * i + 2]);
      const V3 w = V3(s.dirs[3 * k], s.dirs[3 * k + 1], s.dirs[3 * k + 2]);
      const double d = exit_distance(x, w);
      double tau = 0;
      for (std::uint32_t j = 0; j < steps; ++j) tau += lookup(grid, n, x + (j + 0.5) * d / steps * w);
      tau *= d / steps;
      EXPECT_NEAR(-std::log(s.visibility[i * n_dirs + k]), tau, 2e-5 * (1 + tau)) << i << " " << k;
    }
}

TEST(Visibility, BadShapesAreErrors) {
  const Device d = test::test_device();
  Buffer<float> rays(d, kRayFloats);
  BatchMatrix pos(d, 16, 3), vis(d, 16, 1);
  EXPECT_THROW(render::march_visibility(d, rays, 1, 16, pos, {{2, 2, 2}, Buffer<float>(d, 7)}, 8, vis),
               InvalidArgument);
  EXPECT_THROW(render::march_visibility(d, rays, 2, 16, pos, {{1, 1, 1}, Buffer<float>(d, 1)}, 8, vis),
               InvalidArgument);
  EXPECT_THROW(render::march_visibility(d, rays, 1, 16, pos, {{1, 1, 1}, Buffer<float>(d, 1)}, 0, vis),
               InvalidArgument);
  // A tile of 16 samples belongs to one ray.
  Buffer<float> two_rays(d, 2 * kRayFloats);
  EXPECT_THROW(render::march_visibility(d, two_rays, 2, 8, pos, {{1, 1, 1}, Buffer<float>(d, 1)}, 8, vis),
               InvalidArgument);
  BatchMatrix dirs(d, 4, 3), out(d, 16, 4), out3(d, 16, 3), dirs2(d, 4, 2);
  const render::DensityGrid ok{{1, 1, 1}, Buffer<float>(d, 1)};
  // The output needs one column per direction, the directions 3 columns, the grid its voxels, steps >= 1.
  EXPECT_THROW(render::march_visibility_directions(d, pos, dirs, ok, 8, out3), InvalidArgument);
  EXPECT_THROW(render::march_visibility_directions(d, pos, dirs2, ok, 8, out), InvalidArgument);
  EXPECT_THROW(render::march_visibility_directions(d, pos, dirs, {{2, 2, 2}, Buffer<float>(d, 7)}, 8, out),
               InvalidArgument);
  EXPECT_THROW(render::march_visibility_directions(d, pos, dirs, ok, 0, out), InvalidArgument);
  EXPECT_NO_THROW(render::march_visibility_directions(d, pos, dirs, ok, 8, out));
  d.finish();  // leave no work queued when the process exits
}

}  // namespace relit
