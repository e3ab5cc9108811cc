// Identity, Frequency, SphericalHarmonics and Composite encodings against double-precision host references;
// gradients against central finite differences; SH orthonormality and the Funk-Hecke identity for the HG
// phase; config errors.
#include "enc_test_support.hpp"

#include <relit/sh.hpp>

#include <cmath>

namespace relit {

using test::Matrix;

namespace {

// --- references ---------------------------------------------------------------------------------------

Matrix frequency_reference(const Matrix& x, std::uint32_t n_freq, bool include_input) {
  const Eigen::Index d = x.cols();
  const Eigen::Index base = include_input ? d : 0;
  Matrix out(x.rows(), base + d * 2 * n_freq);
  for (Eigen::Index s = 0; s < x.rows(); ++s)
    for (Eigen::Index i = 0; i < d; ++i) {
      if (include_input) out(s, i) = x(s, i);
      for (std::uint32_t k = 0; k < n_freq; ++k) {
        const double a = std::ldexp(x(s, i), static_cast<int>(k)) * M_PI;
        out(s, base + i * 2 * n_freq + 2 * k) = std::sin(a);
        out(s, base + i * 2 * n_freq + 2 * k + 1) = std::cos(a);
      }
    }
  return out;
}

// The SH polynomials exactly as the kernel evaluates them (no renormalisation): Q_l^m(z) * Re/Im (x + iy)^m,
// written from the K_l^m of the paper (Zheng, Singh, Seidel, NeurIPS 2021; appendix B, eq. 2) with factorials,
// independently of relit::sh.
Matrix sh_polynomial_reference(const Matrix& dirs, int degree) {
  auto fact = [](int n) {
    double f = 1;
    for (int i = 2; i <= n; ++i) f *= i;
    return f;
  };
  Matrix out(dirs.rows(), degree * degree);
  for (Eigen::Index s = 0; s < dirs.rows(); ++s) {
    const double x = dirs(s, 0), y = dirs(s, 1), z = dirs(s, 2);
    for (int m = 0; m < degree; ++m) {
      std::complex<double> p = std::pow(std::complex<double>(x, y), m);
      double qmm = 1;
      for (int i = 1; i <= m; ++i) qmm *= -(2.0 * i - 1);
      double q2 = 0, q1 = 0;
      for (int l = m; l < degree; ++l) {
        const double q = l == m       ? qmm
                         : l == m + 1 ? (2 * m + 1) * z * q1
                                      : ((2 * l - 1) * z * q1 - (l + m - 1) * q2) / (l - m);
        q2 = q1;
        q1 = q;
        const double k = std::sqrt((2 * l + 1) / (4 * M_PI) * fact(l - m) / fact(l + m));
        if (m == 0)
          out(s, l * l + l) = k * q;
        else {
          out(s, l * l + l + m) = std::sqrt(2.0) * k * q * p.real();
          out(s, l * l + l - m) = std::sqrt(2.0) * k * q * p.imag();
        }
      }
    }
  }
  return out;
}

Matrix random_directions(std::uint32_t n, std::uint32_t seed) {
  Matrix d = test::random_matrix(n, 3, -1.0, 1.0, seed);
  for (Eigen::Index s = 0; s < d.rows(); ++s) {
    d.row(s).normalize();
    for (int i = 0; i < 3; ++i) d(s, i) = static_cast<float>(d(s, i));
  }
  return d;
}

// Gauss-Legendre nodes and weights on [-1, 1] (Newton on P_n).
void gauss_legendre(int n, std::vector<double>& nodes, std::vector<double>& weights) {
  nodes.resize(n);
  weights.resize(n);
  for (int i = 0; i < n; ++i) {
    double x = std::cos(M_PI * (i + 0.75) / (n + 0.5)), dp = 0;
    for (int it = 0; it < 100; ++it) {
      double p0 = 1, p1 = x;
      for (int k = 2; k <= n; ++k) {
        const double p2 = ((2 * k - 1) * x * p1 - (k - 1) * p0) / k;
        p0 = p1;
        p1 = p2;
      }
      dp = n * (x * p1 - p0) / (x * x - 1);
      const double dx = p1 / dp;
      x -= dx;
      if (std::abs(dx) < 1e-16) break;
    }
    nodes[i] = x;
    weights[i] = 2 / ((1 - x * x) * dp * dp);
  }
}

// Calls f(direction, weight) for a product quadrature of the sphere exact for polynomials of degree
// < min(2 n_mu, n_phi).
void sphere_quadrature(int n_mu, int n_phi, const std::function<void(const std::array<double, 3>&, double)>& f) {
  std::vector<double> mu, w;
  gauss_legendre(n_mu, mu, w);
  for (int i = 0; i < n_mu; ++i)
    for (int j = 0; j < n_phi; ++j) {
      const double phi = 2 * M_PI * (j + 0.5) / n_phi, st = std::sqrt(1 - mu[i] * mu[i]);
      f({st * std::cos(phi), st * std::sin(phi), mu[i]}, w[i] * 2 * M_PI / n_phi);
    }
}

// Encodes with the input in columns [2, 2 + d) of a wider matrix and the output at column 3 of a wider one,
// and checks that the columns around them are untouched (zero).
Matrix forward_at_offsets(const Device& device, const nn::Encoding& enc, const Buffer<float>* params, const Matrix& x) {
  Matrix wide = Matrix::Zero(x.rows(), x.cols() + 4);
  wide.middleCols(2, x.cols()) = x;
  const auto in = test::to_device(device, wide);
  nn::BatchMatrix out(device, static_cast<std::uint32_t>(x.rows()), enc.n_output_dims() + 5);
  enc.forward(device, {params, 0}, in, 2, out, 3, nullptr);
  const Matrix all = test::to_host(out);
  EXPECT_EQ(all.leftCols(3).cwiseAbs().maxCoeff(), 0.0);
  EXPECT_EQ(all.rightCols(2).cwiseAbs().maxCoeff(), 0.0);
  return all.middleCols(3, enc.n_output_dims());
}

// dL/dx from the device for L = sum(w .* enc(x)), with input at column 1 of a wider d_input.
Matrix device_input_gradient(const Device& device, const nn::Encoding& enc, const Buffer<float>* params,
                             const Matrix& x, const Matrix& w) {
  Matrix wide = Matrix::Zero(x.rows(), x.cols() + 2);
  wide.middleCols(1, x.cols()) = x;
  const auto in = test::to_device(device, wide);
  const auto d_out = test::to_device(device, w);
  nn::BatchMatrix d_in(device, static_cast<std::uint32_t>(x.rows()), x.cols() + 2);
  enc.backward(device, {params, 0}, in, 1, d_out, 0, {}, false, &d_in, nullptr);
  const Matrix all = test::to_host(d_in);
  EXPECT_EQ(all.col(0).cwiseAbs().maxCoeff(), 0.0);
  return all.middleCols(1, x.cols());
}

}  // namespace

// --- Identity --------------------------------------------------------------------------------------------

TEST(EncIdentity, ForwardAndGradient) {
  const Device device = test::test_device();
  auto enc = nn::create_encoding({{"type", "Identity"}, {"scale", 2.5}, {"offset", -0.5}}, 4);
  const Matrix x = test::random_matrix(300, 4, -3, 3, 1);
  const Matrix expected = (x.array() * 2.5 - 0.5).matrix();
  EXPECT_LE(test::worst_ratio(forward_at_offsets(device, *enc, nullptr, x), expected, 1e-6, 1e-6), 1.0);
  const Matrix w = test::random_matrix(300, 4, -1, 1, 2);
  EXPECT_LE(test::worst_ratio(device_input_gradient(device, *enc, nullptr, x, w), (w * 2.5).eval(), 1e-6, 1e-7), 1.0);
}

// --- Frequency -------------------------------------------------------------------------------------------

// Tolerance: values lie in [-1, 1]; the double-angle recurrence restarts from sinpi/cospi (exact argument
// reduction) every 3 octaves, so at most 2 doublings amplify the anchor's ~1 ulp error: 1e-5 absolute holds
// at every octave (measured worst 6.7e-7, see docs/encodings.md), where a float sin(2^k pi x) would already be off
// by 2^k * pi * |x| * 6e-8 ~ 1e-4 at k = 9.
TEST(EncFrequency, MatchesDoubleReferenceAtEveryOctave) {
  const Device device = test::test_device();
  for (const auto& [n_freq, include] : {std::pair<std::uint32_t, bool>{10, true}, {16, false}}) {
    auto enc = nn::create_encoding({{"type", "Frequency"}, {"n_frequencies", n_freq}, {"include_input", include}}, 3);
    ASSERT_EQ(enc->n_output_dims(), 3 * 2 * n_freq + (include ? 3 : 0));
    const Matrix x = test::random_matrix(1000, 3, -1, 1, 3 + n_freq);
    const Matrix got = forward_at_offsets(device, *enc, nullptr, x);
    const Matrix ref = frequency_reference(x, n_freq, include);
    EXPECT_LE(test::worst_ratio(got, ref, 0.0, 1e-5), 1.0)
        << "n_frequencies " << n_freq << ", max error " << test::max_abs_error(got, ref);
  }
}

TEST(EncFrequency, InputGradientMatchesFiniteDifferences) {
  const Device device = test::test_device();
  auto enc = nn::create_encoding({{"type", "Frequency"}, {"n_frequencies", 10}, {"include_input", true}}, 2);
  const Matrix x = test::random_matrix(200, 2, -1, 1, 5);
  const Matrix w = test::random_matrix(200, enc->n_output_dims(), -1, 1, 6);
  const Matrix got = device_input_gradient(device, *enc, nullptr, x, w);
  const Matrix fd =
      test::finite_difference([](const Matrix& p) { return frequency_reference(p, 10, true); }, x, w, 1e-7);
  // Gradients reach pi * 2^9 * 20 ~ 3e4: relative 1e-4 of the largest term's scale.
  const double scale = fd.cwiseAbs().maxCoeff();
  EXPECT_LE(test::worst_ratio(got, fd, 1e-4, 1e-5 * scale), 1.0) << "max error " << test::max_abs_error(got, fd);
}

// --- Spherical harmonics ---------------------------------------------------------------------------------

TEST(SphericalHarmonics, HostEvalMatchesAssociatedLegendre) {
  // Independent evaluation: theta, phi by trigonometry and std::assoc_legendre (which omits the
  // Condon-Shortley phase; eq. 2's P_l^m includes it, hence (-1)^m).
  auto fact = [](int n) {
    double f = 1;
    for (int i = 2; i <= n; ++i) f *= i;
    return f;
  };
  const Matrix dirs = random_directions(50, 7);
  for (int l_max : {0, 3, 9, 14}) {
    for (Eigen::Index s = 0; s < dirs.rows(); ++s) {
      const Eigen::Vector3d u = dirs.row(s).normalized();  // the float-rounded rows are unit only to 1e-7
      const std::array<double, 3> d = {u[0], u[1], u[2]};
      const std::vector<double> y = sh::eval(l_max, d);
      ASSERT_EQ(y.size(), static_cast<std::size_t>((l_max + 1) * (l_max + 1)));
      const double theta = std::acos(d[2]), phi = std::atan2(d[1], d[0]);
      for (int l = 0; l <= l_max; ++l)
        for (int m = -l; m <= l; ++m) {
          const int a = std::abs(m);
          const double k = std::sqrt((2 * l + 1) / (4 * M_PI) * fact(l - a) / fact(l + a));
          const double p = (a % 2 ? -1.0 : 1.0) * std::assoc_legendre(l, a, std::cos(theta));
          const double expected = m > 0    ? std::sqrt(2.0) * k * std::cos(m * phi) * p
                                  : m == 0 ? k * p
                                           : std::sqrt(2.0) * k * std::sin(-m * phi) * p;
          ASSERT_NEAR(y[sh::index(l, m)], expected, 1e-11 * (1 + std::abs(expected))) << "l " << l << " m " << m;
        }
    }
  }
  // The low bands in closed form (tiny-cuda-nn's signs): Y_1^-1 = -c y, Y_1^0 = c z, Y_1^1 = -c x.
  const auto y = sh::eval(1, {0.36, 0.48, 0.8});
  const double c = std::sqrt(3 / (4 * M_PI));
  EXPECT_NEAR(y[0], 0.5 / std::sqrt(M_PI), 1e-15);
  EXPECT_NEAR(y[1], -c * 0.48, 1e-15);
  EXPECT_NEAR(y[2], c * 0.8, 1e-15);
  EXPECT_NEAR(y[3], -c * 0.36, 1e-15);
  EXPECT_THROW(sh::eval(2, {0, 0, 0}), InvalidArgument);
  EXPECT_THROW(sh::eval(-1, {0, 0, 1}), InvalidArgument);
}

TEST(SphericalHarmonics, OrthonormalByQuadrature) {
  const int l_max = 9, n = sh::n_coefficients(l_max);
  Eigen::MatrixXd gram = Eigen::MatrixXd::Zero(n, n);
  sphere_quadrature(16, 32, [&](const std::array<double, 3>& w, double weight) {
    const auto y = sh::eval(l_max, w);
    const Eigen::Map<const Eigen::VectorXd> v(y.data(), n);
    gram += weight * v * v.transpose();
  });
  EXPECT_LE((gram - Eigen::MatrixXd::Identity(n, n)).cwiseAbs().maxCoeff(), 1e-12);
}

// Funk-Hecke for the paper's HG phase p(mu) = (1 - g^2) / (4 pi (1 + g^2 + 2 g mu)^1.5), mu = w . w', both
// directions pointing away from the scattering point. With the +2g, p(mu) = sum_l (2l+1)/(4 pi) (-g)^l P_l(mu),
// so   int p(w . w') Y_lm(w') dw' = (-g)^l Y_lm(w) = g^l Y_lm(-w).
// That is the sign verified here: the closed-form indirect term sum g^l c_lm Y_lm(-w_o) of docs/design.md §4.2 uses it.
TEST(SphericalHarmonics, FunkHeckeIdentityForHenyeyGreenstein) {
  const int l_max = 9, n = sh::n_coefficients(l_max);
  const Matrix dirs = random_directions(3, 11);
  for (double g : {0.5, -0.3}) {
    for (Eigen::Index s = 0; s < dirs.rows(); ++s) {
      const Eigen::Vector3d u = dirs.row(s).normalized();
      const std::array<double, 3> w = {u[0], u[1], u[2]};
      std::vector<double> integral(n, 0.0);
      double norm = 0;
      sphere_quadrature(96, 192, [&](const std::array<double, 3>& wp, double weight) {
        const double mu = w[0] * wp[0] + w[1] * wp[1] + w[2] * wp[2];
        const double p = (1 - g * g) / (4 * M_PI * std::pow(1 + g * g + 2 * g * mu, 1.5));
        norm += weight * p;
        const auto y = sh::eval(l_max, wp);
        for (int i = 0; i < n; ++i) integral[i] += weight * p * y[i];
      });
      EXPECT_NEAR(norm, 1.0, 1e-10);
      const auto y = sh::eval(l_max, w);
      const auto y_opposite = sh::eval(l_max, {-w[0], -w[1], -w[2]});
      for (int l = 0; l <= l_max; ++l)
        for (int m = -l; m <= l; ++m) {
          EXPECT_NEAR(integral[sh::index(l, m)], std::pow(-g, l) * y[sh::index(l, m)], 1e-9) << "g " << g << " l " << l;
          EXPECT_NEAR(integral[sh::index(l, m)], std::pow(g, l) * y_opposite[sh::index(l, m)], 1e-9);
        }
    }
  }
}

TEST(SphericalHarmonics, KernelMatchesHostReference) {
  const Device device = test::test_device();
  const Matrix dirs = random_directions(700, 13);
  for (std::uint32_t degree : {1u, 4u, 10u}) {
    auto enc = nn::create_encoding({{"type", "SphericalHarmonics"}, {"degree", degree}}, 3);
    ASSERT_EQ(enc->n_output_dims(), degree * degree);
    const Matrix got = forward_at_offsets(device, *enc, nullptr, dirs);
    Matrix ref(dirs.rows(), degree * degree);
    for (Eigen::Index s = 0; s < dirs.rows(); ++s) {
      const auto y = sh::eval(static_cast<int>(degree) - 1, {dirs(s, 0), dirs(s, 1), dirs(s, 2)});
      for (std::uint32_t i = 0; i < degree * degree; ++i) ref(s, i) = y[i];
    }
    // |Y| <= 1.3 for l < 10; float evaluation of the recurrences: 1e-5 relative to that scale.
    EXPECT_LE(test::worst_ratio(got, ref, 1e-5, 1e-5), 1.0)
        << "degree " << degree << ", max error " << test::max_abs_error(got, ref);
    // The polynomials (used for the gradient check) equal sh::eval on the sphere; the float-rounded
    // directions are unit only to ~1e-7, which the polynomials amplify by up to ~l^2.
    EXPECT_LE(test::max_abs_error(sh_polynomial_reference(dirs, static_cast<int>(degree)), ref), 1e-5);
  }
}

TEST(SphericalHarmonics, DirectionGradientMatchesFiniteDifferences) {
  const Device device = test::test_device();
  for (int degree : {3, 10}) {
    auto enc = nn::create_encoding({{"type", "SphericalHarmonics"}, {"degree", degree}}, 3);
    const Matrix dirs = random_directions(150, 17);
    const Matrix w = test::random_matrix(150, degree * degree, -1, 1, 19);
    const Matrix got = device_input_gradient(device, *enc, nullptr, dirs, w);
    const Matrix fd =
        test::finite_difference([&](const Matrix& d) { return sh_polynomial_reference(d, degree); }, dirs, w, 1e-6);
    const double scale = fd.cwiseAbs().maxCoeff();
    EXPECT_LE(test::worst_ratio(got, fd, 1e-4, 1e-4 * scale), 1.0)
        << "degree " << degree << ", max error " << test::max_abs_error(got, fd);
  }
}

// --- Composite -------------------------------------------------------------------------------------------

TEST(EncComposite, ConcatenatesNestedEncodingsAndTheirGradients) {
  const Device device = test::test_device();
  const Json cfg = {{"type", "Composite"},
                    {"nested",
                     {
                         {{"type", "Frequency"}, {"n_dims_to_encode", 2}, {"n_frequencies", 3}},
                         {{"otype", "SphericalHarmonics"}, {"degree", 3}},
                     }}};
  Json resolved;
  auto enc = nn::encodings().create(cfg, "/encoding", 5, &resolved);
  EXPECT_EQ(enc->n_input_dims(), 5u);
  EXPECT_EQ(enc->n_output_dims(), 2u * 6 + 9);
  EXPECT_EQ(resolved["nested"][1]["n_dims_to_encode"], 3);
  EXPECT_EQ(resolved["nested"][1]["type"], "SphericalHarmonics");
  EXPECT_EQ(enc->hyperparams(), resolved);
  EXPECT_NO_THROW(nn::create_encoding(resolved, 5));

  Matrix x(100, 5);
  x.leftCols(2) = test::random_matrix(100, 2, -1, 1, 23);
  x.rightCols(3) = random_directions(100, 29);
  const Matrix got = forward_at_offsets(device, *enc, nullptr, x);
  Matrix ref(100, 21);
  ref.leftCols(12) = frequency_reference(x.leftCols(2), 3, false);
  ref.rightCols(9) = sh_polynomial_reference(x.rightCols(3), 3);
  EXPECT_LE(test::worst_ratio(got, ref, 1e-5, 1e-5), 1.0);

  const Matrix w = test::random_matrix(100, 21, -1, 1, 31);
  const Matrix grad = device_input_gradient(device, *enc, nullptr, x, w);
  const Matrix fd = test::finite_difference(
      [](const Matrix& p) {
        Matrix o(p.rows(), 21);
        o.leftCols(12) = frequency_reference(p.leftCols(2), 3, false);
        o.rightCols(9) = sh_polynomial_reference(p.rightCols(3), 3);
        return o;
      },
      x, w, 1e-6);
  EXPECT_LE(test::worst_ratio(grad, fd, 1e-4, 1e-4 * fd.cwiseAbs().maxCoeff()), 1.0);
}

// --- Config ----------------------------------------------------------------------------------------------

namespace {
std::string config_error(const Json& j, std::uint32_t dims) {
  try {
    nn::encodings().create(j, "/encoding", dims);
  } catch (const ConfigError& e) {
    return e.pointer() + " | " + e.what();
  }
  return "no error";
}
}  // namespace

TEST(EncConfig, ErrorsNameTheJsonPointer) {
  auto starts = [](const std::string& s, const std::string& p) { return s.rfind(p, 0) == 0; };
  EXPECT_TRUE(starts(config_error({{"type", "Frequency"}, {"n_frequency", 4}}, 3), "/encoding/n_frequency | "));
  EXPECT_TRUE(starts(config_error({{"type", "Frequency"}, {"n_frequencies", 0}}, 3), "/encoding/n_frequencies | "));
  EXPECT_TRUE(starts(config_error({{"type", "SphericalHarmonics"}, {"degree", 11}}, 3), "/encoding/degree | "));
  EXPECT_TRUE(starts(config_error({{"type", "SphericalHarmonics"}}, 2), "/encoding | "));
  EXPECT_TRUE(starts(config_error({{"type", "HashGrid"}, {"n_features_per_level", 3}}, 3),
                     "/encoding/n_features_per_level | "));
  EXPECT_TRUE(
      starts(config_error({{"type", "HashGrid"}, {"log2_hashmap_size", 30}}, 3), "/encoding/log2_hashmap_size | "));
  EXPECT_TRUE(starts(config_error({{"type", "HashGrid"}}, 4), "/encoding | "));
  // A resolution beyond what float positions resolve is refused with the keys to change.
  const std::string fine = config_error({{"type", "HashGrid"}, {"n_levels", 32}, {"per_level_scale", 2.0}}, 3);
  EXPECT_TRUE(starts(fine, "/encoding | ")) << fine;
  EXPECT_NE(fine.find("per_level_scale"), std::string::npos) << fine;
  const Json bad_nested = {
      {"type", "Composite"},
      {"nested", {{{"type", "HashGrid"}, {"n_dims_to_encode", 3}, {"n_level", 8}}, {{"type", "Identity"}}}}};
  EXPECT_TRUE(starts(config_error(bad_nested, 4), "/encoding/nested/0/n_level | ")) << config_error(bad_nested, 4);
  EXPECT_TRUE(
      starts(config_error({{"type", "Composite"}, {"nested", {{{"type", "Identity"}, {"n_dims_to_encode", 5}}}}}, 4),
             "/encoding/nested/0/n_dims_to_encode | "));
  EXPECT_TRUE(
      starts(config_error({{"type", "Composite"}, {"nested", {{{"type", "Identity"}, {"n_dims_to_encode", 2}}}}}, 4),
             "/encoding/nested | "));
  EXPECT_TRUE(starts(config_error({{"type", "Composite"}, {"nested", Json::array()}}, 4), "/encoding/nested | "));
}

TEST(EncConfig, DefaultsAreResolvedAndRebuildable) {
  for (const char* type : {"Identity", "Frequency", "SphericalHarmonics", "HashGrid"}) {
    Json resolved;
    auto enc = nn::encodings().create({{"type", type}}, "", 3, &resolved);
    EXPECT_EQ(enc->hyperparams(), resolved) << type;
    Json again;
    nn::encodings().create(resolved, "", 3, &again);
    EXPECT_EQ(again, resolved) << type;
  }
  // The tiny-cuda-nn name of the key is accepted.
  EXPECT_EQ(nn::create_encoding({{"otype", "HashGrid"}, {"n_levels", 4}}, 2)->n_output_dims(), 8u);
}

}  // namespace relit
