// Procedural media and SDFs. Every random choice comes from a seeded std::mt19937 or a hash of integer
// lattice points, so a (generator, resolution, seed) triple gives the same grid everywhere.
#include <relit/error.hpp>
#include <relit/scene/procedural.hpp>

#include "shared.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>

namespace relit {

namespace {

using ::relit::detail::kPi;

std::uint32_t hash3(int x, int y, int z, unsigned seed) {
  std::uint32_t h = seed * 0x9E3779B9u;
  for (std::uint32_t v : {std::uint32_t(x), std::uint32_t(y), std::uint32_t(z)}) {
    h ^= v + 0x7F4A7C15u + (h << 6) + (h >> 2);
    h *= 0x85EBCA6Bu;
    h ^= h >> 13;
  }
  h *= 0xC2B2AE35u;
  return h ^ (h >> 16);
}

double lattice(int x, int y, int z, unsigned seed) { return hash3(x, y, z, seed) * (1.0 / 4294967296.0); }

double value_noise(double x, double y, double z, unsigned seed) {
  const int xi = int(std::floor(x)), yi = int(std::floor(y)), zi = int(std::floor(z));
  auto fade = [](double t) { return t * t * t * (t * (t * 6 - 15) + 10); };
  const double fx = fade(x - xi), fy = fade(y - yi), fz = fade(z - zi);
  double r = 0;
  for (int c = 0; c < 8; ++c) {
    const int dx = c & 1, dy = (c >> 1) & 1, dz = c >> 2;
    r += lattice(xi + dx, yi + dy, zi + dz, seed) * (dx ? fx : 1 - fx) * (dy ? fy : 1 - fy) * (dz ? fz : 1 - fz);
  }
  return r;
}

double smoothstep(double a, double b, double x) {
  const double t = std::clamp((x - a) / (b - a), 0.0, 1.0);
  return t * t * (3 - 2 * t);
}

// Fades a density to zero over the outer 8 % of the box, so nothing is cut by the box faces.
double box_fade(double x, double y, double z) {
  const double m = std::max({std::abs(x), std::abs(y), std::abs(z)});
  return 1.0 - smoothstep(0.88, 0.98, m);
}

void check_resolution(int r) {
  if (r < 8 || r > 512)
    throw InvalidArgument("procedural grid resolution must lie in [8, 512], got " + std::to_string(r));
}

template <class F>
void fill(Grid& g, F f) {
  for (int k = 0; k < g.nz; ++k)
    for (int j = 0; j < g.ny; ++j)
      for (int i = 0; i < g.nx; ++i) {
        const Float3 p = g.centre(i, j, k);
        f(i, j, k, double(p[0]), double(p[1]), double(p[2]));
      }
}

struct Blob {
  double x, y, z, r;
};

}  // namespace

double fbm_noise(double x, double y, double z, unsigned seed, int octaves) {
  double sum = 0, amp = 0.5, norm = 0;
  for (int o = 0; o < octaves; ++o) {
    sum += amp * value_noise(x, y, z, seed + 1013u * o);
    norm += amp;
    x *= 2.03, y *= 2.03, z *= 2.03;
    amp *= 0.5;
  }
  return sum / norm;
}

ProceduralMedium make_cloud(int res, unsigned seed) {
  check_resolution(res);
  std::mt19937 rng(seed * 7919u + 1u);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  // A cumulus: a wide base row of blobs and smaller, higher ones piled on top.
  std::vector<Blob> blobs;
  const int n = 16;
  for (int b = 0; b < n; ++b) {
    const double a = u(rng) * 2 * kPi, rad = std::sqrt(u(rng));
    const double height = u(rng);
    const double spread = 0.6 * (1.0 - 0.5 * height);
    blobs.push_back({spread * rad * std::cos(a), spread * rad * std::sin(a), -0.35 + 0.6 * height,
                     (0.26 + 0.16 * u(rng)) * (1.0 - 0.35 * height)});
  }
  ProceduralMedium m{Grid(res, res, res, 1), Grid()};
  fill(m.density, [&](int i, int j, int k, double x, double y, double z) {
    double field = -1e9;  // negative outside every blob, so noise cannot grow fog far away
    for (const auto& b : blobs) {
      const double d = std::sqrt((x - b.x) * (x - b.x) + (y - b.y) * (y - b.y) + (z - b.z) * (z - b.z)) / b.r;
      field = std::max(field, 1.0 - d);
    }
    // fBm erodes and billows the surface of the blob union; the core stays dense.
    const double noise = fbm_noise(x * 3.5 + 11, y * 3.5 + 7, z * 3.5 + 3, seed, 5);
    const double v = field + 0.4 * (noise - 0.55);
    double dens = smoothstep(0.0, 0.35, v);
    dens *= smoothstep(-0.62, -0.48, z);  // the flat base of a cumulus
    m.density.at(i, j, k) = float(dens * box_fade(x, y, z));
  });
  return m;
}

ProceduralMedium make_smoke(int res, unsigned seed) {
  check_resolution(res);
  std::mt19937 rng(seed * 104729u + 3u);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  const double phase = u(rng) * 2 * kPi, freq = 2.0 + 1.5 * u(rng);
  ProceduralMedium m{Grid(res, res, res, 1), Grid()};
  fill(m.density, [&](int i, int j, int k, double x, double y, double z) {
    const double h = (z + 0.9) / 1.8;  // 0 at the source, 1 at the top
    const double cx = 0.25 * h * std::sin(freq * z + phase), cy = 0.2 * h * std::cos(0.7 * freq * z + phase);
    const double radius = 0.06 + 0.3 * h;
    const double r2 = ((x - cx) * (x - cx) + (y - cy) * (y - cy)) / (radius * radius);
    const double noise = fbm_noise(x * 5 + 1, y * 5 + 2, z * 3 - 2 * h, seed, 5);
    double dens = std::exp(-2.5 * r2) * std::max(0.0, 1.6 * noise - 0.25) * (1.0 - 0.5 * h);
    dens *= smoothstep(-0.9, -0.8, z);
    m.density.at(i, j, k) = float(std::clamp(dens, 0.0, 1.0) * box_fade(x, y, z));
  });
  return m;
}

ProceduralMedium make_blobs(int res, unsigned seed) {
  check_resolution(res);
  std::mt19937 rng(seed * 15485863u + 5u);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  const int n = 5;
  std::vector<Blob> blobs;
  std::vector<Float3> colours;
  for (int b = 0; b < n; ++b) {
    const double a = 2 * kPi * b / n + 0.3 * u(rng);
    blobs.push_back({0.45 * std::cos(a), 0.45 * std::sin(a), 0.3 * (u(rng) - 0.5), 0.3 + 0.12 * u(rng)});
    // Saturated, distinct albedos: each blob scatters one colour more than the others.
    Float3 c{float(0.3 + 0.3 * u(rng)), float(0.3 + 0.3 * u(rng)), float(0.3 + 0.3 * u(rng))};
    c[b % 3] = 0.98f;
    colours.push_back(c);
  }
  ProceduralMedium m{Grid(res, res, res, 1), Grid(res, res, res, 3)};
  fill(m.density, [&](int i, int j, int k, double x, double y, double z) {
    double total = 0, w_sum = 1e-9, rgb[3] = {0, 0, 0};
    for (int b = 0; b < n; ++b) {
      const auto& q = blobs[b];
      const double d2 = ((x - q.x) * (x - q.x) + (y - q.y) * (y - q.y) + (z - q.z) * (z - q.z)) / (q.r * q.r);
      const double w = std::exp(-3.0 * d2);
      total += w;
      w_sum += w;
      for (int c = 0; c < 3; ++c) rgb[c] += w * colours[b][c];
    }
    const double noise = fbm_noise(x * 4 + 5, y * 4, z * 4, seed, 4);
    m.density.at(i, j, k) = float(std::clamp(total * (0.6 + 0.8 * noise), 0.0, 1.0) * box_fade(x, y, z));
    for (int c = 0; c < 3; ++c) m.albedo.at(i, j, k, c) = float(w_sum > 1e-6 ? rgb[c] / w_sum : 0.9);
  });
  return m;
}

Grid make_spheres_sdf(int res, unsigned seed) {
  check_resolution(res);
  std::mt19937 rng(seed * 32452843u + 7u);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<Blob> spheres = {{0, 0, -0.15, 0.45}};
  for (int s = 0; s < 3; ++s) {
    const double a = 2 * kPi * s / 3 + u(rng);
    spheres.push_back({0.55 * std::cos(a), 0.55 * std::sin(a), -0.25 + 0.5 * u(rng), 0.18 + 0.12 * u(rng)});
  }
  Grid g(res, res, res, 1);
  fill(g, [&](int i, int j, int k, double x, double y, double z) {
    double d = 1e9;
    for (const auto& s : spheres)
      d = std::min(d, std::sqrt((x - s.x) * (x - s.x) + (y - s.y) * (y - s.y) + (z - s.z) * (z - s.z)) - s.r);
    g.at(i, j, k) = float(d);
  });
  return g;
}

Grid make_torus_sdf(int res, unsigned seed) {
  check_resolution(res);
  std::mt19937 rng(seed * 49979687u + 11u);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  const double tilt = 0.3 + 0.5 * u(rng), yaw = 2 * kPi * u(rng);
  const double R = 0.55, r = 0.22;
  Grid g(res, res, res, 1);
  fill(g, [&](int i, int j, int k, double x, double y, double z) {
    // Rotate the point into the torus frame: yaw about z, then tilt about x.
    const double x1 = std::cos(yaw) * x + std::sin(yaw) * y, y1 = -std::sin(yaw) * x + std::cos(yaw) * y;
    const double y2 = std::cos(tilt) * y1 + std::sin(tilt) * z, z2 = -std::sin(tilt) * y1 + std::cos(tilt) * z;
    const double q = std::sqrt(x1 * x1 + y2 * y2) - R;
    g.at(i, j, k) = float(std::sqrt(q * q + z2 * z2) - r);
  });
  return g;
}

const std::vector<std::string>& procedural_media() {
  static const std::vector<std::string> names = {"cloud", "smoke", "blobs"};
  return names;
}

const std::vector<std::string>& procedural_solids() {
  static const std::vector<std::string> names = {"spheres", "torus"};
  return names;
}

}  // namespace relit
