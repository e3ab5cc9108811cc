// Double-precision host reference of the FullyFusedMLP for the benchmarks' verification step (Eigen).
#pragma once

#include <relit/nn/fully_fused_mlp.hpp>

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <vector>

namespace relit::bench {

class MlpReference {
 public:
  using Mat = Eigen::MatrixXd;  // samples as rows

  MlpReference(const nn::FullyFusedMLP& net, const std::vector<float>& params) : m_net(net) {
    const std::uint32_t b = net.has_bias() ? 1 : 0;
    for (std::uint32_t l = 0; l <= net.n_hidden_layers(); ++l) {
      const std::uint32_t n_in = net.layer_inputs(l), n_out = net.layer_outputs(l);
      Mat w(n_out, n_in);
      Eigen::VectorXd bias = Eigen::VectorXd::Zero(n_out);
      const float* p = params.data() + net.layer_offset(l);
      for (std::uint32_t j = 0; j < n_out; ++j) {
        for (std::uint32_t k = 0; k < n_in; ++k) w(j, k) = p[j * (n_in + b) + k];
        if (b) bias(j) = p[j * (n_in + b) + n_in];
      }
      m_w.push_back(w);
      m_b.push_back(bias);
    }
  }

  /// Row-major output for row-major input (n samples).
  std::vector<double> forward(const std::vector<float>& x, std::uint32_t n) {
    m_x = Mat(n, m_net.n_input_dims());
    for (std::uint32_t s = 0; s < n; ++s)
      for (std::uint32_t f = 0; f < m_net.n_input_dims(); ++f) m_x(s, f) = x[std::size_t(s) * m_net.n_input_dims() + f];
    const std::uint32_t L = m_net.n_hidden_layers();
    m_in.clear();
    m_h.clear();
    Mat h = m_x;
    for (std::uint32_t l = 0; l <= L; ++l) {
      Mat in = h;
      if (l > 0 && m_net.has_skip(l)) {
        in = Mat(n, h.cols() + m_x.cols());
        in << h, m_x;
      }
      Mat z = (in * m_w[l].transpose()).rowwise() + m_b[l].transpose();
      m_in.push_back(in);
      if (l < L) {
        h = z.unaryExpr([&](double v) { return nn::apply_activation(m_net.hidden_activation(), v); });
        m_h.push_back(h);
      } else {
        for (Eigen::Index j = 0; j < z.cols(); ++j)
          z.col(j) = z.col(j).unaryExpr([&](double v) { return nn::apply_activation(m_net.output_activations()[j], v); });
        m_y = z;
      }
    }
    return flatten(m_y);
  }

  /// After forward(): gradients of sum(dy .* y) (networks with ReLU/None hidden and None outputs).
  void backward(const std::vector<float>& dy, std::vector<double>& dparams, std::vector<double>& dx_out) const {
    const std::uint32_t L = m_net.n_hidden_layers(), b = m_net.has_bias() ? 1 : 0;
    Mat dz(m_y.rows(), m_y.cols());
    for (Eigen::Index s = 0; s < dz.rows(); ++s)
      for (Eigen::Index j = 0; j < dz.cols(); ++j) dz(s, j) = dy[std::size_t(s) * dz.cols() + j];
    dparams.assign(m_net.n_params(), 0.0);
    Mat dx = Mat::Zero(m_x.rows(), m_x.cols());
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
        if (m_net.has_skip(l)) dx += din.rightCols(m_x.cols());
        dz = din.leftCols(m_net.width());
        if (m_net.hidden_activation() == nn::Activation::ReLU)
          dz = (m_h[l - 1].array() > 0.0).select(dz, 0.0);
      }
    }
    dx_out = flatten(dx);
  }

 private:
  static std::vector<double> flatten(const Mat& m) {
    std::vector<double> v(std::size_t(m.rows()) * m.cols());
    for (Eigen::Index s = 0; s < m.rows(); ++s)
      for (Eigen::Index f = 0; f < m.cols(); ++f) v[std::size_t(s) * m.cols() + f] = m(s, f);
    return v;
  }
  const nn::FullyFusedMLP& m_net;
  std::vector<Mat> m_w;
  std::vector<Eigen::VectorXd> m_b;
  std::vector<Mat> m_in, m_h;
  Mat m_x, m_y;
};

/// Worst |got - want| / (rtol * (|want| + rms(want))) over the arrays (<= 1 passes; inf on NaN or size mismatch).
template <class Got>
double worst_ratio(const Got& got, const std::vector<double>& want, double rtol) {
  if (got.size() != want.size()) return INFINITY;
  double rms = 0.0;
  for (double w : want) rms += w * w;
  rms = std::sqrt(rms / std::max<std::size_t>(1, want.size())) + 1e-30;
  double worst = 0.0;
  for (std::size_t i = 0; i < want.size(); ++i) {
    if (!std::isfinite(double(got[i]))) return INFINITY;
    worst = std::max(worst, std::abs(double(got[i]) - want[i]) / (rtol * (std::abs(want[i]) + rms)));
  }
  return worst;
}

}  // namespace relit::bench
