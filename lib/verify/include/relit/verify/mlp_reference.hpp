// Double-precision host reference of the FullyFusedMLP (Eigen), shared by its tests and its benchmark's
// verification step. It reads the network's flat parameter layout, so it checks that layout too.
#pragma once

#include <relit/nn/fully_fused_mlp.hpp>

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

namespace relit::reference {

using Mat = Eigen::MatrixXd;  // samples as rows

// The reference network, in double precision, read from the same flat parameter layout.
class MlpReference {
 public:
  MlpReference(const nn::FullyFusedMLP& net, const std::vector<float>& params, std::size_t offset = 0) : m_net(net) {
    const std::uint32_t b = net.has_bias() ? 1 : 0;
    for (std::uint32_t l = 0; l <= net.n_hidden_layers(); ++l) {
      const std::uint32_t n_in = net.layer_inputs(l), n_out = net.layer_outputs(l);
      Mat w(n_out, n_in);
      Eigen::VectorXd bias = Eigen::VectorXd::Zero(n_out);
      const float* p = params.data() + offset + net.layer_offset(l);
      for (std::uint32_t j = 0; j < n_out; ++j) {
        for (std::uint32_t k = 0; k < n_in; ++k) w(j, k) = p[j * (n_in + b) + k];
        if (b) bias(j) = p[j * (n_in + b) + n_in];
      }
      m_w.push_back(w);
      m_b.push_back(bias);
    }
  }

  /// Output for row-major input x (batch x n_in).
  Mat forward(const Mat& x) {
    m_in.clear();
    m_h.clear();
    Mat h = x;
    const std::uint32_t L = m_net.n_hidden_layers();
    for (std::uint32_t l = 0; l <= L; ++l) {
      Mat in = layer_input(l, h, x);
      Mat z = (in * m_w[l].transpose()).rowwise() + m_b[l].transpose();
      m_in.push_back(in);
      if (l < L) {
        h = z.unaryExpr([&](double v) { return nn::apply_activation(m_net.hidden_activation(), v); });
        m_h.push_back(h);
      } else {
        for (Eigen::Index j = 0; j < z.cols(); ++j)
          z.col(j) =
              z.col(j).unaryExpr([&](double v) { return nn::apply_activation(m_net.output_activations()[j], v); });
        m_y = z;
      }
    }
    return m_y;
  }

  /// After forward(): gradients of sum(dy .* y) w.r.t. the parameters (flat layout) and the input.
  void backward(const Mat& x, const Mat& dy, std::vector<double>& dparams, Mat& dx) const {
    const std::uint32_t L = m_net.n_hidden_layers(), b = m_net.has_bias() ? 1 : 0;
    dparams.assign(m_net.n_params(), 0.0);
    dx = Mat::Zero(x.rows(), x.cols());
    Mat dz = dy;
    for (Eigen::Index j = 0; j < dz.cols(); ++j)
      for (Eigen::Index s = 0; s < dz.rows(); ++s) dz(s, j) *= act_grad(m_net.output_activations()[j], m_y(s, j));
    for (std::uint32_t l = L + 1; l-- > 0;) {
      const Mat dw = dz.transpose() * m_in[l];
      const Eigen::VectorXd db = dz.colwise().sum().transpose();
      const std::uint32_t n_in = m_net.layer_inputs(l);
      for (Eigen::Index j = 0; j < dw.rows(); ++j) {
        for (std::uint32_t k = 0; k < n_in; ++k) dparams[m_net.layer_offset(l) + j * (n_in + b) + k] = dw(j, k);
        if (b) dparams[m_net.layer_offset(l) + j * (n_in + b) + n_in] = db(j);
      }
      const Mat din = dz * m_w[l];
      if (l == 0) {
        dx += din;
      } else {
        const std::uint32_t w = m_net.width();
        if (m_net.has_skip(l)) dx += din.rightCols(x.cols());
        dz = din.leftCols(w);
        for (Eigen::Index k = 0; k < dz.cols(); ++k)
          for (Eigen::Index s = 0; s < dz.rows(); ++s)
            dz(s, k) *= act_grad(m_net.hidden_activation(), m_h[l - 1](s, k));
      }
    }
  }

 private:
  static double act_grad(nn::Activation a, double y) {
    switch (a) {
      case nn::Activation::ReLU: return y > 0 ? 1.0 : 0.0;
      case nn::Activation::Sigmoid: return y * (1 - y);
      case nn::Activation::Softplus: return -std::expm1(-y);
      case nn::Activation::Tanh: return 1 - y * y;
      case nn::Activation::None: break;
    }
    return 1.0;
  }
  Mat layer_input(std::uint32_t l, const Mat& h, const Mat& x) const {
    if (l == 0) return x;
    if (!m_net.has_skip(l)) return h;
    Mat in(h.rows(), h.cols() + x.cols());
    in << h, x;
    return in;
  }

  const nn::FullyFusedMLP& m_net;
  std::vector<Mat> m_w;
  std::vector<Eigen::VectorXd> m_b;
  std::vector<Mat> m_in, m_h;
  Mat m_y;
};

/// n uniform floats in [lo, hi) from `seed`.
inline std::vector<float> random_vector(std::size_t n, std::uint32_t seed, float lo = -1.0f, float hi = 1.0f) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(lo, hi);
  std::vector<float> v(n);
  for (auto& x : v) x = u(rng);
  return v;
}

inline Mat to_mat(const std::vector<float>& v, std::uint32_t rows, std::uint32_t cols) {
  Mat m(rows, cols);
  for (std::uint32_t s = 0; s < rows; ++s)
    for (std::uint32_t f = 0; f < cols; ++f) m(s, f) = v[std::size_t(s) * cols + f];
  return m;
}

// |got - want| <= rtol * (|want| + rms(want)): relative where values are large, absolute (at the data's
// own scale) where they cancel to near zero. Returns the worst ratio error / allowed (<= 1 passes).
template <class Got>
double worst_ratio(const Got& got, const std::vector<double>& want, double rtol) {
  double rms = 0.0;
  for (double w : want) rms += w * w;
  rms = std::sqrt(rms / std::max<std::size_t>(1, want.size())) + 1e-30;
  double worst = 0.0;
  for (std::size_t i = 0; i < want.size(); ++i) {
    const double e = std::abs(double(got[i]) - want[i]);
    if (!std::isfinite(double(got[i]))) return INFINITY;
    worst = std::max(worst, e / (rtol * (std::abs(want[i]) + rms)));
  }
  return worst;
}

inline std::vector<double> flatten(const Mat& m) {
  std::vector<double> v(std::size_t(m.rows()) * m.cols());
  for (Eigen::Index s = 0; s < m.rows(); ++s)
    for (Eigen::Index f = 0; f < m.cols(); ++f) v[std::size_t(s) * m.cols() + f] = m(s, f);
  return v;
}

}  // namespace relit::reference
