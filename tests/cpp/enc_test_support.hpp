// Helpers of the encoding tests: random batches, device round trips, comparisons and the loss used for
// finite differences (L = sum_ij w_ij * out_ij, so dL/dout = w).
#pragma once

#include "test_support.hpp"

#include <relit/nn/encodings.hpp>
#include <relit/nn/registry.hpp>

#include <Eigen/Dense>

#include <functional>
#include <random>

namespace relit::test {

using Matrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

inline Matrix random_matrix(std::uint32_t rows, std::uint32_t cols, double lo, double hi, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(static_cast<float>(lo), static_cast<float>(hi));
  Matrix m(rows, cols);
  for (Eigen::Index i = 0; i < m.size(); ++i) m.data()[i] = u(rng);  // float values: exactly what the device sees
  return m;
}

inline nn::BatchMatrix to_device(const Device& device, const Matrix& m) {
  nn::BatchMatrix b(device, static_cast<std::uint32_t>(m.rows()), static_cast<std::uint32_t>(m.cols()));
  std::vector<float> host(m.size());
  for (Eigen::Index i = 0; i < m.size(); ++i) host[i] = static_cast<float>(m.data()[i]);
  b.upload_row_major(host);
  return b;
}

inline Matrix to_host(const nn::BatchMatrix& b) {
  const std::vector<float> host = b.download_row_major();
  Matrix m(b.batch(), b.cols());
  for (Eigen::Index i = 0; i < m.size(); ++i) m.data()[i] = host[i];
  return m;
}

/// Largest |a - e| / (abs + rel * |e|); <= 1 means every element is within tolerance.
inline double worst_ratio(const Matrix& actual, const Matrix& expected, double rel, double abs) {
  EXPECT_EQ(actual.rows(), expected.rows());
  EXPECT_EQ(actual.cols(), expected.cols());
  double worst = 0.0;
  for (Eigen::Index i = 0; i < actual.size() && i < expected.size(); ++i) {
    const double e = expected.data()[i], a = actual.data()[i];
    const double r = std::abs(a - e) / (abs + rel * std::abs(e));
    if (!(r <= worst)) worst = std::isnan(r) ? INFINITY : r;
  }
  return worst;
}

inline double max_abs_error(const Matrix& actual, const Matrix& expected) {
  return (actual - expected).cwiseAbs().maxCoeff();
}

/// Central finite differences of L(x) = sum(w .* f(x)) with respect to every element of x.
inline Matrix finite_difference(const std::function<Matrix(const Matrix&)>& f, const Matrix& x, const Matrix& w,
                                double h) {
  Matrix g(x.rows(), x.cols());
  Matrix xp = x;
  for (Eigen::Index i = 0; i < x.size(); ++i) {
    const double x0 = xp.data()[i];
    xp.data()[i] = x0 + h;
    const double lp = f(xp).cwiseProduct(w).sum();
    xp.data()[i] = x0 - h;
    const double lm = f(xp).cwiseProduct(w).sum();
    xp.data()[i] = x0;
    g.data()[i] = (lp - lm) / (2.0 * h);
  }
  return g;
}

/// Runs `enc` forward on the device: input in columns [in_col, ...) of a matrix with in_cols columns, output
/// in columns [out_col, ...) of one with out_cols; returns exactly the encoded columns.
inline Matrix device_forward(const Device& device, const nn::Encoding& enc, const Buffer<float>* params,
                             const Matrix& x) {
  const auto in = to_device(device, x);
  nn::BatchMatrix out(device, static_cast<std::uint32_t>(x.rows()), enc.n_output_dims());
  enc.forward(device, {params, 0}, in, out, 0, nullptr);
  return to_host(out);
}

}  // namespace relit::test
