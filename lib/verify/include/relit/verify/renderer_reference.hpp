// Double-precision host reference of the neural volume renderer's forward pass (docs/design.md §4.2: stratum-centre
// samples, HG phase, point light, environment directions, the K-direction indirect sum with its clamp or the
// closed form, alpha compositing, background; and the "brdf" scattering of docs/design.md §4.4 with the BRDF of
// brdf_reference.hpp), with random scenes to run it on. Shared by the renderer's tests and by `relit bench`'s
// verification step.
#pragma once

#include "brdf_reference.hpp"

#include <relit/render/volume_renderer.hpp>
#include <relit/sh.hpp>

#include <Eigen/Core>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

namespace relit::reference {

using render::kRayFloats;
using Vec3 = Eigen::Vector3d;

constexpr double kPi = 3.14159265358979323846;

// The 3-vector field `f` of a ray record (render::RayField, kernels/layout.clh).
inline Vec3 field3(const float* ray, render::RayField f) { return Vec3(ray[f], ray[f + 1], ray[f + 2]); }

inline double hg(double g, double mu) { return (1 - g * g) / (4 * kPi * std::pow(1 + g * g + 2 * g * mu, 1.5)); }

struct RayScene {
  std::uint32_t n_rays, n_samples, n_sh, n_dirs, n_env = 0;
  std::vector<float> rays;    // kRayFloats per ray
  std::vector<double> props;  // row-major, n_rays * n_samples x (6 + 3 n_sh + n_env)
  std::vector<float> dirs, basis;
  std::vector<float> env_dirs, env_weights;  // n_env x 3 each, row-major
  bool brdf = false;  // scattering "brdf": column 4 is the roughness, the last three the raw normal
  std::uint32_t env_col() const { return 6 + 3 * n_sh; }
  std::uint32_t normal_col() const { return env_col() + n_env; }
  std::uint32_t cols() const { return normal_col() + (brdf ? 3 : 0); }
};

// With `brdf`, column 4 is a roughness in [0.1, 0.95] and each sample ends in a raw normal of length 0.3 to
// 2, mostly facing the camera (some face away and scatter nothing).
inline RayScene random_scene(std::uint32_t n_rays, std::uint32_t n_samples, int lmax, std::uint32_t n_dirs,
                             unsigned seed, std::uint32_t n_env = 0, bool brdf = false) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0, 1);
  RayScene s{n_rays, n_samples, lmax < 0 ? 0u : std::uint32_t((lmax + 1) * (lmax + 1)), n_dirs, n_env, {}, {}, {}, {},
             {},     {}};
  s.brdf = brdf;
  auto unit = [&] {
    Vec3 v(u(rng) * 2 - 1, u(rng) * 2 - 1, u(rng) * 2 - 1);
    while (v.norm() < 0.1 || v.norm() > 1) v = Vec3(u(rng) * 2 - 1, u(rng) * 2 - 1, u(rng) * 2 - 1);
    return Vec3(v.normalized());
  };
  for (std::uint32_t r = 0; r < n_rays; ++r) {
    const Vec3 o = 4.0 * unit();
    const Vec3 target(u(rng) - 0.5, u(rng) - 0.5, u(rng) - 0.5);
    const Vec3 d = (target - o).normalized();
    const Vec3 lp = (3 + 2 * u(rng)) * unit();
    const float i0 = float(300 + 600 * u(rng)), i1 = float(300 + 600 * u(rng)), i2 = float(300 + 600 * u(rng));
    const float b0 = float(u(rng)), b1 = float(u(rng)), b2 = float(u(rng));
    const auto rec =
        render::ray_record({float(o.x()), float(o.y()), float(o.z())}, {float(d.x()), float(d.y()), float(d.z())},
                           {float(lp.x()), float(lp.y()), float(lp.z())}, {i0, i1, i2}, {b0, b1, b2});
    s.rays.insert(s.rays.end(), rec.begin(), rec.end());
  }
  for (std::uint32_t i = 0; i < n_rays * n_samples; ++i) {
    s.props.push_back(3 * u(rng));                                                       // sigma
    for (int c = 0; c < 3; ++c) s.props.push_back(u(rng));                               // albedo
    s.props.push_back(brdf ? 0.1 + 0.85 * u(rng) : 1.8 * u(rng) - 0.9);                  // roughness or g
    s.props.push_back(u(rng));                                                           // visibility
    for (std::uint32_t j = 0; j < 3 * s.n_sh; ++j) s.props.push_back(2 * u(rng) - 0.7);  // SH, both signs
    for (std::uint32_t j = 0; j < n_env; ++j) s.props.push_back(u(rng));                 // environment visibility
    if (brdf) {
      const float* ray = &s.rays[(i / n_samples) * kRayFloats];
      const Vec3 wo = -field3(ray, render::kRayDirection);
      const Vec3 n = (unit() + 0.7 * wo).normalized() * (0.3 + 1.7 * u(rng));
      s.props.insert(s.props.end(), {n.x(), n.y(), n.z()});
    }
  }
  for (std::uint32_t k = 0; k < n_dirs; ++k) {
    const Vec3 w = unit();
    s.dirs.insert(s.dirs.end(), {float(w.x()), float(w.y()), float(w.z())});
    for (std::uint32_t j = 0; j < s.n_sh; ++j) s.basis.push_back(float(2 * u(rng) - 1));  // any basis values do
  }
  return s;
}

// Scattering "brdf": the light one sample (properties p) sends toward w_o, sum over the light terms of
// f(w_o, w_i) max(0, n.w_i) L(w_i) with n = n_raw / |n_raw|; `to_light` = p_l - x, I the light's intensity.
inline Vec3 brdf_radiance(const RayScene& s, const double* p, const Vec3& wo, const Vec3& to_light, const Vec3& I) {
  const Vec3 m(p[s.normal_col()], p[s.normal_col() + 1], p[s.normal_col() + 2]);
  if (m.norm() == 0) return Vec3::Zero();
  const Dir3 n = {m.x() / m.norm(), m.y() / m.norm(), m.z() / m.norm()}, o = {wo.x(), wo.y(), wo.z()};
  Vec3 rad = Vec3::Zero();
  auto term = [&](const Vec3& wi, const Vec3& L) {
    const Dir3 w = {wi.x(), wi.y(), wi.z()};
    const double cos = std::max(0.0, dot3(n, w));
    for (int ch = 0; ch < 3; ++ch) rad[ch] += brdf(n, o, w, p[1 + ch], p[4]) * cos * L[ch];
  };
  term(to_light.normalized(), p[5] / to_light.squaredNorm() * I);
  for (std::uint32_t j = 0; j < s.n_env; ++j)
    term(Vec3(s.env_dirs[3 * j], s.env_dirs[3 * j + 1], s.env_dirs[3 * j + 2]),
         p[s.env_col() + j] * Vec3(s.env_weights[3 * j], s.env_weights[3 * j + 1], s.env_weights[3 * j + 2]));
  for (std::uint32_t k = 0; s.n_sh && k < s.n_dirs; ++k) {
    Vec3 L;
    for (int ch = 0; ch < 3; ++ch) {
      double l = 0;
      for (std::uint32_t j = 0; j < s.n_sh; ++j) l += p[6 + ch * s.n_sh + j] * s.basis[k * s.n_sh + j];
      L[ch] = 4 * kPi / s.n_dirs * std::max(0.0, l);
    }
    term(Vec3(s.dirs[3 * k], s.dirs[3 * k + 1], s.dirs[3 * k + 2]), L);
  }
  return rad;
}

// Double-precision reference of sample placement + radiance + compositing (stratum centres).
inline std::vector<double> reference_color(const RayScene& s, const std::vector<double>& props,
                                           bool closed_form = false) {
  std::vector<double> color;
  const std::uint32_t cols = s.cols();
  for (std::uint32_t r = 0; r < s.n_rays; ++r) {
    const float* ray = &s.rays[r * kRayFloats];
    const Vec3 o = field3(ray, render::kRayOrigin), d = field3(ray, render::kRayDirection),
               lp = field3(ray, render::kRayLightPosition);
    const Vec3 I = field3(ray, render::kRayLightIntensity), bg = field3(ray, render::kRayBackground);
    double tn = 0, tf = 1e30;
    for (int a = 0; a < 3; ++a) {
      const double t0 = (-1 - o[a]) / d[a], t1 = (1 - o[a]) / d[a];
      tn = std::max(tn, std::min(t0, t1));
      tf = std::min(tf, std::max(t0, t1));
    }
    if (!(tf > tn)) tn = tf = 0;
    const double step = (tf - tn) / s.n_samples;
    double T = 1;
    Vec3 c = Vec3::Zero();
    for (std::uint32_t i = 0; i < s.n_samples; ++i) {
      const double* p = &props[(std::size_t(r) * s.n_samples + i) * cols];
      const double t = tn + (i + 0.5) * step;
      const double delta = step;  // midpoint intervals of stratum centres
      const Vec3 x = o + t * d, wo = -d, tl = lp - x;
      const double alpha = 1 - std::exp(-p[0] * delta);
      if (s.brdf) {
        c += T * alpha * brdf_radiance(s, p, wo, tl, I);
        T *= 1 - alpha;
        continue;
      }
      const double g = p[4];
      Vec3 S = hg(g, wo.dot(tl.normalized())) * p[5] / tl.squaredNorm() * I;
      if (closed_form && s.n_sh) {
        // sum_l g^l sum_m c_lm Y_lm(-w_o), with -w_o = d.
        const int lmax = int(std::lround(std::sqrt(double(s.n_sh)))) - 1;
        const auto y = sh::eval(lmax, {d.x(), d.y(), d.z()});
        for (int ch = 0; ch < 3; ++ch)
          for (int l = 0, j = 0; l <= lmax; ++l)
            for (int m = -l; m <= l; ++m, ++j) S[ch] += std::pow(g, l) * p[6 + ch * s.n_sh + j] * y[j];
      }
      for (std::uint32_t j = 0; j < s.n_env; ++j) {
        const Vec3 wj(s.env_dirs[3 * j], s.env_dirs[3 * j + 1], s.env_dirs[3 * j + 2]);
        for (int ch = 0; ch < 3; ++ch) S[ch] += hg(g, wo.dot(wj)) * p[s.env_col() + j] * s.env_weights[3 * j + ch];
      }
      for (std::uint32_t k = 0; !closed_form && k < s.n_dirs; ++k) {
        const Vec3 wk(s.dirs[3 * k], s.dirs[3 * k + 1], s.dirs[3 * k + 2]);
        for (int ch = 0; ch < 3; ++ch) {
          double L = 0;
          for (std::uint32_t j = 0; j < s.n_sh; ++j) L += p[6 + ch * s.n_sh + j] * s.basis[k * s.n_sh + j];
          S[ch] += 4 * kPi / s.n_dirs * hg(g, wo.dot(wk)) * std::max(0.0, L);
        }
      }
      c += T * alpha * Vec3(p[1] * S[0], p[2] * S[1], p[3] * S[2]);
      T *= 1 - alpha;
    }
    c += T * bg;
    color.insert(color.end(), {c.x(), c.y(), c.z()});
  }
  return color;
}

}  // namespace relit::reference
