// Real spherical harmonics in double (see relit/sh.hpp), by the same recurrences as kernels/enc_sh.cl.
#include <relit/error.hpp>
#include <relit/sh.hpp>

#include <cmath>
#include <string>

namespace relit::sh {

std::vector<double> eval(int l_max, const std::array<double, 3>& dir) {
  if (l_max < 0 || l_max > kMaxBand)
    throw InvalidArgument("sh::eval: l_max must be in [0, " + std::to_string(kMaxBand) + "], got " +
                          std::to_string(l_max));
  const double len = std::sqrt(dir[0] * dir[0] + dir[1] * dir[1] + dir[2] * dir[2]);
  if (!std::isfinite(len) || len == 0.0) throw InvalidArgument("sh::eval: the direction must be finite and non-zero");
  const double x = dir[0] / len, y = dir[1] / len, z = dir[2] / len;
  std::vector<double> out(n_coefficients(l_max));
  double cm = 1.0, sm = 0.0;  // Re, Im (x + i y)^m = sin^m(theta) cos(m phi), sin^m(theta) sin(m phi)
  double qmm = 1.0;           // (-1)^m (2m-1)!!
  for (int m = 0; m <= l_max; ++m) {
    if (m > 0) {
      const double c = x * cm - y * sm;
      sm = x * sm + y * cm;
      cm = c;
      qmm *= -(2.0 * m - 1.0);
    }
    // Normalisation sqrt((2l+1)/(4 pi) (l-m)!/(l+m)!), with the factorial ratio built up along l.
    double ratio = 1.0;  // (l-m)!/(l+m)! at l = m: 1/(2m)!
    for (int i = 2; i <= 2 * m; ++i) ratio /= i;
    double q2 = 0.0, q1 = 0.0;
    for (int l = m; l <= l_max; ++l) {
      double q;
      if (l == m)
        q = qmm;
      else if (l == m + 1)
        q = (2.0 * m + 1.0) * z * q1;
      else
        q = ((2.0 * l - 1.0) * z * q1 - (l + m - 1.0) * q2) / (l - m);
      if (l > m) ratio *= static_cast<double>(l - m) / static_cast<double>(l + m);
      q2 = q1;
      q1 = q;
      const double n = std::sqrt((2.0 * l + 1.0) / (4.0 * M_PI) * ratio);
      if (m == 0) {
        out[index(l, 0)] = n * q;
      } else {
        out[index(l, m)] = std::sqrt(2.0) * n * q * cm;
        out[index(l, -m)] = std::sqrt(2.0) * n * q * sm;
      }
    }
  }
  return out;
}

}  // namespace relit::sh
