// Double-precision host reference of the HashGrid encoding (forward and parameter gradient), shared by its
// tests and by `relit bench`'s verification step.
#pragma once

#include <relit/nn/encodings.hpp>

#include <Eigen/Dense>

#include <array>
#include <cmath>
#include <stdexcept>
#include <vector>

namespace relit::reference {

using nn::HashGridEncoding;
using RowMat = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;  // samples as rows

struct Corner {
  std::uint32_t index;  // entry within the level
  double weight;
  std::array<double, 3> d_weight;  // d weight / d x_d
};

// The 2^d corners of sample `x` at `level`. With float_positions, the cell and in-cell position are computed
// in float exactly as the kernel does (so indices agree bit for bit); otherwise in double (smooth in x, for
// finite differences).
inline std::vector<Corner> corners(const HashGridEncoding& enc, std::uint32_t level, const double* x,
                                   bool float_positions) {
  const auto& L = enc.levels()[level];
  const std::uint32_t dims = enc.n_input_dims();
  std::array<std::uint32_t, 3> cell{};
  std::array<double, 3> frac{}, dfrac{};
  for (std::uint32_t d = 0; d < dims; ++d) {
    if (float_positions) {
      const float xf = std::fmin(std::fmax(static_cast<float>(x[d]), 0.0f), 1.0f);
      const float p = std::fma(xf, L.scale, 0.5f), f = std::floor(p);
      cell[d] = static_cast<std::uint32_t>(f);
      frac[d] = p - f;
    } else {
      const double p = std::min(std::max(x[d], 0.0), 1.0) * L.scale + 0.5, f = std::floor(p);
      cell[d] = static_cast<std::uint32_t>(f);
      frac[d] = p - f;
    }
    dfrac[d] = (x[d] > 0.0 && x[d] < 1.0) ? L.scale : 0.0;
  }
  std::vector<Corner> out;
  for (std::uint32_t c = 0; c < (1u << dims); ++c) {
    std::uint32_t index = 0, stride = 1;
    Corner k{0, 1.0, {0, 0, 0}};
    for (std::uint32_t d = 0; d < dims; ++d) {
      const std::uint32_t v = cell[d] + ((c >> d) & 1);
      if (L.hashed)
        index ^= v * HashGridEncoding::kPrimes[d];
      else
        index += v * stride;
      stride *= L.res;
      k.weight *= ((c >> d) & 1) ? frac[d] : 1.0 - frac[d];
    }
    for (std::uint32_t d = 0; d < dims; ++d) {
      double dw = ((c >> d) & 1) ? dfrac[d] : -dfrac[d];
      for (std::uint32_t e = 0; e < dims; ++e)
        if (e != d) dw *= ((c >> e) & 1) ? frac[e] : 1.0 - frac[e];
      k.d_weight[d] = dw;
    }
    k.index = L.hashed ? (index & (L.size - 1)) : index;
    if (k.index >= L.size) throw std::logic_error("hash grid reference: entry out of range");
    out.push_back(k);
  }
  return out;
}

inline RowMat reference_forward(const HashGridEncoding& enc, const std::vector<float>& params, const RowMat& x,
                                bool float_positions = true) {
  const std::uint32_t F = enc.options().n_features_per_level;
  RowMat out = RowMat::Zero(x.rows(), enc.n_output_dims());
  for (Eigen::Index s = 0; s < x.rows(); ++s)
    for (std::uint32_t l = 0; l < enc.levels().size(); ++l)
      for (const Corner& c : corners(enc, l, x.row(s).data(), float_positions))
        for (std::uint32_t f = 0; f < F; ++f)
          out(s, l * F + f) += c.weight * params[enc.levels()[l].offset + c.index * F + f];
  return out;
}

inline std::vector<double> reference_param_gradient(const HashGridEncoding& enc, const RowMat& x, const RowMat& d_out) {
  const std::uint32_t F = enc.options().n_features_per_level;
  std::vector<double> g(enc.n_params(), 0.0);
  for (Eigen::Index s = 0; s < x.rows(); ++s)
    for (std::uint32_t l = 0; l < enc.levels().size(); ++l)
      for (const Corner& c : corners(enc, l, x.row(s).data(), true))
        for (std::uint32_t f = 0; f < F; ++f)
          g[enc.levels()[l].offset + c.index * F + f] += c.weight * d_out(s, l * F + f);
  return g;
}

}  // namespace relit::reference
