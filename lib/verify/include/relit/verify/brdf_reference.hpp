// Double-precision host reference of the BRDF of kernels/brdf.clh (docs/design.md §4.4 with an energy-conserving
// diffuse term), written from the formulas and independent of the kernel code, except for the tabulated
// specular albedo, whose float values both sides read from kernels/brdf_albedo.clh. Also the quadrature that
// generates that table (scripts/brdf_albedo_table.cpp) and that the tests check it against.
//
//   f(wo, wi) = a (1 - E(n.wo)) (1 - E(n.wi)) / (pi (1 - E_avg))  +  D F G / (4 n.wi n.wo)
//   E(mu; r)  = int spec(wo, wi) n.wi dwi (the specular albedo), E_avg = 2 int_0^1 E(mu) mu dmu
#pragma once

#include <algorithm>
#include <array>
#include <cmath>

#ifndef RELIT_BRDF_TABLE_GENERATOR
#include "brdf_albedo.clh"  // kernels/, on relit::verify's include path
#endif

namespace relit::reference {

namespace brdf_detail {
constexpr double kPi = 3.14159265358979323846;
}

using Dir3 = std::array<double, 3>;

inline double dot3(const Dir3& a, const Dir3& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

// Schlick's Fresnel with F0 = 0.04 in UE4's spherical-Gaussian form.
inline double fresnel_sg(double v_h) { return 0.04 + 0.96 * std::pow(2.0, (-5.55473 * v_h - 6.98316) * v_h); }

// The specular (GGX) lobe without the cosine: D F G / (4 n.wi n.wo), alpha = r^2, Schlick-GGX G with
// k = (r+1)^2/8; zero unless both directions are above the surface.
inline double brdf_specular(const Dir3& n, const Dir3& wo, const Dir3& wi, double r) {
  using brdf_detail::kPi;
  const double nl = dot3(n, wi), nv = dot3(n, wo);
  if (nl <= 0 || nv <= 0) return 0;
  Dir3 h = {wo[0] + wi[0], wo[1] + wi[1], wo[2] + wi[2]};
  const double hl = std::sqrt(dot3(h, h));
  for (auto& x : h) x /= hl;
  const double nh = dot3(n, h), vh = dot3(wo, h);
  const double a2 = std::pow(r * r, 2), dd = nh * nh * (a2 - 1) + 1;
  const double D = a2 / (kPi * dd * dd);
  const double k = (r + 1) * (r + 1) / 8;
  const double G = nl / (nl * (1 - k) + k) * nv / (nv * (1 - k) + k);
  return D * fresnel_sg(vh) * G / (4 * nl * nv);
}

// E(mu; r) = int brdf_specular(wo, wi) n.wi dwi for n.wo = mu, by a midpoint rule over GGX-distributed half
// vectors (q x q in (u, phi), phi over half the circle by symmetry): the integrand F G v.h / (n.wo n.h) is
// smooth there, so q = 256 gives about 6 digits. mu = 0 is the limit n.wo -> 0+.
inline double specular_albedo(double mu, double r, int q = 256) {
  const double nv = std::max(mu, 0.0), wo[3] = {std::sqrt(std::max(0.0, 1 - nv * nv)), 0, nv};
  const double a2 = std::pow(r * r, 2), k = (r + 1) * (r + 1) / 8;
  double sum = 0;
  for (int i = 0; i < q; ++i)
    for (int j = 0; j < q; ++j) {
      const double u = (i + 0.5) / q, ph = (j + 0.5) / q * brdf_detail::kPi;
      const double ch = std::sqrt((1 - u) / (1 + (a2 - 1) * u)), sh = std::sqrt(std::max(0.0, 1 - ch * ch));
      const double h[3] = {sh * std::cos(ph), sh * std::sin(ph), ch};
      const double vh = wo[0] * h[0] + wo[1] * h[1] + wo[2] * h[2];
      if (vh <= 0) continue;
      const double nl = 2 * vh * h[2] - wo[2];
      if (nl <= 0) continue;
      // G / (4 nl nv) * (pdf change 4 vh / (D nh)) * D, with G1(nv)/nv written as 1/(nv (1-k) + k).
      sum += fresnel_sg(vh) * nl / (nl * (1 - k) + k) / (nv * (1 - k) + k) * vh / ch;
    }
  return sum / (double(q) * q);
}

#ifndef RELIT_BRDF_TABLE_GENERATOR

constexpr int kAlbedoN = RELIT_BRDF_ALBEDO_N;
constexpr float kAlbedoTable[] = {RELIT_BRDF_ALBEDO_TABLE};
constexpr float kAlbedoAverage[] = {RELIT_BRDF_ALBEDO_AVERAGE};

// The table's bilinear interpolant (rows r = i/(N-1), columns sqrt(mu) = j/(N-1)), as the kernels read it.
inline double tabulated_albedo(double mu, double r) {
  const double x = std::sqrt(std::clamp(mu, 0.0, 1.0)) * (kAlbedoN - 1), y = std::clamp(r, 0.0, 1.0) * (kAlbedoN - 1);
  const int j = std::min(int(x), kAlbedoN - 2), i = std::min(int(y), kAlbedoN - 2);
  const double fx = x - j, fy = y - i;
  auto at = [](int row, int col) { return double(kAlbedoTable[row * kAlbedoN + col]); };
  return (1 - fy) * ((1 - fx) * at(i, j) + fx * at(i, j + 1)) + fy * ((1 - fx) * at(i + 1, j) + fx * at(i + 1, j + 1));
}

inline double tabulated_average(double r) {
  const double y = std::clamp(r, 0.0, 1.0) * (kAlbedoN - 1);
  const int i = std::min(int(y), kAlbedoN - 2);
  return (1 - (y - i)) * kAlbedoAverage[i] + (y - i) * kAlbedoAverage[i + 1];
}

// The diffuse factor: f = albedo * brdf_diffuse + brdf_specular (unit n).
inline double brdf_diffuse(const Dir3& n, const Dir3& wo, const Dir3& wi, double r) {
  const double nl = dot3(n, wi), nv = dot3(n, wo);
  if (nl <= 0 || nv <= 0) return 0;
  return (1 - tabulated_albedo(nv, r)) * (1 - tabulated_albedo(nl, r)) /
         (brdf_detail::kPi * (1 - tabulated_average(r)));
}

// f(wo, wi) for one colour channel of albedo `a`; n must be a unit vector.
inline double brdf(const Dir3& n, const Dir3& wo, const Dir3& wi, double a, double r) {
  return a * brdf_diffuse(n, wo, wi, r) + brdf_specular(n, wo, wi, r);
}

#endif

}  // namespace relit::reference
