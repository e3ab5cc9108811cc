// Real spherical harmonics on the host, in double: the reference the renderer and the tests use.
//
// Y_l^m exactly as eq. 2 of Zheng et al. 2021 (Sloan's real SH; P_l^m includes the Condon-Shortley phase, so
// Y_1^-1 = -c y, Y_1^0 = c z, Y_1^1 = -c x with c = sqrt(3 / 4 pi), as tiny-cuda-nn), in the fixed world
// frame: z up, phi measured from +x. Coefficient index l*l + l + m, bands l = 0..l_max.
#pragma once

#include <array>
#include <vector>

namespace relit::sh {

constexpr int kMaxBand = 20;

/// Number of coefficients of bands 0..l_max: (l_max + 1)^2.
constexpr int n_coefficients(int l_max) { return (l_max + 1) * (l_max + 1); }
constexpr int index(int l, int m) { return l * l + l + m; }

/// Y_l^m(dir) for l = 0..l_max (0 <= l_max <= kMaxBand). `dir` is normalised first; a zero or non-finite
/// direction is an InvalidArgument.
std::vector<double> eval(int l_max, const std::array<double, 3>& dir);

}  // namespace relit::sh
