// Host reference of FLIP and HDR-FLIP (kernels/flip.cl, metrics::flip) in double precision, written from the
// papers' 2-D definitions (FLIP, HPG 2020; HDR-FLIP, Eurographics 2021) rather than the separated filters the
// kernels use: the contrast sensitivity filters are the normalised 2-D sums of Gaussians and the edge and point
// detectors the 2-D derivative-of-Gaussian kernels with their positive and negative weights normalised, so a
// test against it also checks the separation.
//
//   auto e = relit::reference::flip_exposures(reference, w, h, 3);
//   std::vector<double> map = relit::reference::flip_map(prediction, reference, w, h, 3, 67.02, true, e.start,
//                                                        e.stop, e.count);
#pragma once

#include <algorithm>
#include <array>
#include <cfloat>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <vector>

namespace relit::reference {

namespace flip_detail {

constexpr double kPi = 3.14159265358979323846;
using Colour = std::array<double, 3>;

inline Colour rgb_to_xyz(const Colour& c) {
  return {(10135552.0 * c[0] + 8788810.0 * c[1] + 4435075.0 * c[2]) / 24577794.0,
          (2613072.0 * c[0] + 8788810.0 * c[1] + 887015.0 * c[2]) / 12288897.0,
          (1425312.0 * c[0] + 8788810.0 * c[1] + 70074185.0 * c[2]) / 73733382.0};
}

// The inverse of rgb_to_xyz, to the nine digits FLIP states it with.
inline Colour xyz_to_rgb(const Colour& c) {
  return {3.241003275 * c[0] - 1.537398934 * c[1] - 0.498615861 * c[2],
          -0.969224334 * c[0] + 1.875930071 * c[1] + 0.041554224 * c[2],
          0.055639423 * c[0] - 0.204011202 * c[1] + 1.057148933 * c[2]};
}

constexpr Colour kWhite = {0.950428545, 1.0, 1.088900371};  // D65

inline Colour xyz_to_ycxcz(const Colour& c) {
  const double x = c[0] / kWhite[0], y = c[1], z = c[2] / kWhite[2];
  return {116 * y - 16, 500 * (x - y), 200 * (y - z)};
}

inline Colour ycxcz_to_xyz(const Colour& c) {
  const double y = (c[0] + 16) / 116;
  return {(y + c[1] / 500) * kWhite[0], y, (y - c[2] / 200) * kWhite[2]};
}

// CIE L*a*b* of linear RGB, Hunt-adjusted (a*, b* times L* / 100).
inline Colour hunt_lab(const Colour& rgb) {
  const Colour xyz = rgb_to_xyz(rgb);
  const double d = 6.0 / 29.0;
  double f[3];
  for (int i = 0; i < 3; ++i) {
    const double t = xyz[i] / kWhite[i];
    f[i] = t > d * d * d ? std::cbrt(t) : t / (3 * d * d) + 4.0 / 29.0;
  }
  const double l = 116 * f[1] - 16;
  return {l, 0.01 * l * 500 * (f[0] - f[1]), 0.01 * l * 200 * (f[1] - f[2])};
}

inline double hyab(const Colour& a, const Colour& b) {
  return std::fabs(a[0] - b[0]) + std::hypot(a[1] - b[1], a[2] - b[2]);
}

inline double aces(double x) {
  const double k[6] = {0.6 * 0.6 * 2.51, 0.6 * 0.03, 0.0, 0.6 * 0.6 * 2.43, 0.6 * 0.59, 0.14};
  return std::clamp((k[0] * x * x + k[1] * x + k[2]) / (k[3] * x * x + k[4] * x + k[5]), 0.0, 1.0);
}

// A (2r + 1)^2 kernel, row-major.
struct Kernel2d {
  int r = 0;
  std::vector<double> w;
  double at(int dx, int dy) const { return w[std::size_t(dy + r) * (2 * r + 1) + (dx + r)]; }
};

// FLIP's contrast sensitivity filter a1 sqrt(pi/b1) exp(-pi^2 d^2/b1) + a2 sqrt(pi/b2) exp(-pi^2 d^2/b2),
// d in degrees, normalised to sum 1.
inline Kernel2d csf(double ppd, int r, double a1, double b1, double a2, double b2) {
  Kernel2d k{r, {}};
  double sum = 0;
  for (int y = -r; y <= r; ++y)
    for (int x = -r; x <= r; ++x) {
      const double d2 = (double(x) * x + double(y) * y) / (ppd * ppd);
      double v = a1 * std::sqrt(kPi / b1) * std::exp(-kPi * kPi * d2 / b1);
      if (a2 != 0) v += a2 * std::sqrt(kPi / b2) * std::exp(-kPi * kPi * d2 / b2);
      k.w.push_back(v);
      sum += v;
    }
  for (double& v : k.w) v /= sum;
  return k;
}

// The edge (order 1: -x g) or point (order 2: (x^2/sd^2 - 1) g) detector along x; positive weights sum to 1,
// negative to -1.
inline Kernel2d feature(double ppd, int order) {
  const double sd = 0.5 * 0.082 * ppd;
  const int r = int(std::ceil(3 * sd));
  Kernel2d k{r, {}};
  double pos = 0, neg = 0;
  for (int y = -r; y <= r; ++y)
    for (int x = -r; x <= r; ++x) {
      const double g = std::exp(-(double(x) * x + double(y) * y) / (2 * sd * sd));
      const double v = order == 1 ? -x * g : (double(x) * x / (sd * sd) - 1) * g;
      k.w.push_back(v);
      (v > 0 ? pos : neg) += std::fabs(v);
    }
  for (double& v : k.w) v /= v > 0 ? pos : neg;
  return k;
}

// LDR-FLIP of two images already in [0, 1] linear RGB (3 doubles per pixel): the per-pixel error.
inline std::vector<double> ldr_flip(const std::vector<double>& test, const std::vector<double>& ref, int w, int h,
                                    double ppd) {
  const int rc = int(std::ceil(3 * std::sqrt(0.04 / (2 * kPi * kPi)) * ppd));
  const Kernel2d sy = csf(ppd, rc, 1, 0.0047, 0, 1), scx = csf(ppd, rc, 1, 0.0053, 0, 1),
                 scz = csf(ppd, rc, 34.1, 0.04, 13.5, 0.025);
  const Kernel2d edge = feature(ppd, 1), point = feature(ppd, 2);
  const std::size_t n = std::size_t(w) * h;
  std::vector<Colour> ycc[2];
  for (int i = 0; i < 2; ++i) {
    const auto& img = i ? ref : test;
    for (std::size_t p = 0; p < n; ++p)
      ycc[i].push_back(xyz_to_ycxcz(rgb_to_xyz({img[3 * p], img[3 * p + 1], img[3 * p + 2]})));
  }
  const auto clamped = [&](const std::vector<Colour>& img, int x, int y, int c) {
    return img[std::size_t(std::clamp(y, 0, h - 1)) * w + std::clamp(x, 0, w - 1)][c];
  };
  const Colour green = hunt_lab({0, 1, 0}), blue = hunt_lab({0, 0, 1});
  const double cmax = std::pow(hyab(green, blue), 0.7), pccmax = 0.4 * cmax;
  std::vector<double> out(n);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      Colour lab[2];
      double edges[2], points[2];
      for (int i = 0; i < 2; ++i) {
        Colour f = {0, 0, 0};
        for (int dy = -rc; dy <= rc; ++dy)
          for (int dx = -rc; dx <= rc; ++dx) {
            f[0] += sy.at(dx, dy) * clamped(ycc[i], x + dx, y + dy, 0);
            f[1] += scx.at(dx, dy) * clamped(ycc[i], x + dx, y + dy, 1);
            f[2] += scz.at(dx, dy) * clamped(ycc[i], x + dx, y + dy, 2);
          }
        Colour rgb = xyz_to_rgb(ycxcz_to_xyz(f));
        for (double& v : rgb) v = std::clamp(v, 0.0, 1.0);
        lab[i] = hunt_lab(rgb);
        double ex = 0, ey = 0, px = 0, py = 0;
        for (int dy = -edge.r; dy <= edge.r; ++dy)
          for (int dx = -edge.r; dx <= edge.r; ++dx) {
            const double gx = (clamped(ycc[i], x + dx, y + dy, 0) + 16) / 116;  // the detectors along x
            const double gy = (clamped(ycc[i], x + dy, y + dx, 0) + 16) / 116;  // transposed: along y
            ex += edge.at(dx, dy) * gx;
            ey += edge.at(dx, dy) * gy;
            px += point.at(dx, dy) * gx;
            py += point.at(dx, dy) * gy;
          }
        edges[i] = std::hypot(ex, ey);
        points[i] = std::hypot(px, py);
      }
      double colour = std::pow(hyab(lab[0], lab[1]), 0.7);
      colour = colour < pccmax ? colour * 0.95 / pccmax : 0.95 + (colour - pccmax) / (cmax - pccmax) * 0.05;
      const double feature_error =
          std::sqrt(std::max(std::fabs(edges[0] - edges[1]), std::fabs(points[0] - points[1])) / std::sqrt(2.0));
      out[std::size_t(y) * w + x] = std::pow(colour, 1 - feature_error);
    }
  return out;
}

// R, G, B of pixel p (grey from one channel).
inline Colour pixel(const std::vector<float>& img, std::size_t p, int channels) {
  const std::size_t i = p * channels;
  return channels >= 3 ? Colour{img[i], img[i + 1], img[i + 2]} : Colour{img[i], img[i], img[i]};
}

}  // namespace flip_detail

struct FlipExposureRange {
  double start = 0, stop = 0;
  int count = 2;
};

/// HDR-FLIP's exposures from the reference: ACES(x_max) = 0.85, start = log2(x_max / Y_max), stop =
/// log2(x_max / Y_median) (the element n/2 of the sorted luminances), both luminances at least FLT_EPSILON,
/// count = max(2, ceil(stop - start)).
inline FlipExposureRange flip_exposures(const std::vector<float>& reference, int w, int h, int channels) {
  const double k[6] = {0.6 * 0.6 * 2.51, 0.6 * 0.03, 0.0, 0.6 * 0.6 * 2.43, 0.6 * 0.59, 0.14}, t = 0.85;
  const double a = k[0] - t * k[3], b = k[1] - t * k[4], c = k[2] - t * k[5];
  const double x_max = (-b + std::sqrt(b * b - 4 * a * c)) / (2 * a);
  std::vector<double> y;
  for (std::size_t p = 0; p < std::size_t(w) * h; ++p) {
    const auto rgb = flip_detail::pixel(reference, p, channels);
    y.push_back(0.2126 * rgb[0] + 0.7152 * rgb[1] + 0.0722 * rgb[2]);
  }
  std::sort(y.begin(), y.end());
  FlipExposureRange e;
  e.start = std::log2(x_max / std::max(y.back(), double(FLT_EPSILON)));
  e.stop = std::log2(x_max / std::max(y[y.size() / 2], double(FLT_EPSILON)));
  e.count = int(std::max(2.0, std::ceil(e.stop - e.start)));
  return e;
}

/// The FLIP error of every pixel (row-major) of `test` against `reference` (linear, `channels` per pixel).
/// hdr: the maximum over `count` exposures from start to stop of LDR-FLIP of ACES(2^exposure x); otherwise
/// LDR-FLIP of the images clamped to [0, 1].
inline std::vector<double> flip_map(const std::vector<float>& test, const std::vector<float>& reference, int w, int h,
                                    int channels, double ppd, bool hdr, double start = 0, double stop = 0,
                                    int count = 1) {
  using namespace flip_detail;
  const std::size_t n = std::size_t(w) * h;
  std::vector<double> best(n, 0.0);
  for (int i = 0; i < (hdr ? count : 1); ++i) {
    const double exposure = count > 1 ? start + i * (stop - start) / (count - 1) : start;
    std::vector<double> t(3 * n), r(3 * n);
    for (std::size_t p = 0; p < n; ++p) {
      const Colour ct = pixel(test, p, channels), cr = pixel(reference, p, channels);
      for (int c = 0; c < 3; ++c) {
        t[3 * p + c] = hdr ? aces(std::exp2(exposure) * ct[c]) : std::clamp(ct[c], 0.0, 1.0);
        r[3 * p + c] = hdr ? aces(std::exp2(exposure) * cr[c]) : std::clamp(cr[c], 0.0, 1.0);
      }
    }
    const auto e = ldr_flip(t, r, w, h, ppd);
    for (std::size_t p = 0; p < n; ++p) best[p] = std::max(best[p], e[p]);
  }
  return best;
}

}  // namespace relit::reference
