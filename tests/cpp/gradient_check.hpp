// Gradient checks of the method tests: an analytic gradient (a model's backward pass) against central
// differences of a scalar objective evaluated in double on the host, with a tolerance of its own for every
// checked parameter, and against the derivative along a random direction of the whole block.
//
//   test::GradientCheck check;                // the block [lo, hi) of θ, how many parameters of each kind
//   check.hi = theta.size();
//   test::check_gradient([&](const std::vector<float>& t) { ...; return objective; }, theta, grads, check);
//
// Per parameter i, central differences D(s) at the steps s = h, h/2 and h/4 (h = check.h max(1, |θ_i|), each step
// as the floats θ_i ± s actually differ) give the estimate D(h/2) and its own error bound:
//
//   tol_i = 2 |D(h) - D(h/2)|   truncation (O(h²): the error of D(h/2) is a third of the change)
//         + 2 K                 kinks: a clamp of the renderer that switches within the steps (second differences)
//         + 2 σ_f / (h/2)       rounding, σ_f the rounding noise of one evaluation of the objective (measured
//                               by fourth differences at tiny steps, four times their median)
//         + 1e-5 max_j |g_j|    the float rounding of the analytic gradient itself (a sum over many samples)
//
// A parameter whose truncation and kink terms exceed a fifth of |D(h/2)| (and 1e-3 max |g|) is retried with
// h / 4 and h / 16; one that no step resolves is not checked, and at most a quarter of the picks may be
// unresolved. The picks: the largest gradients, random parameters, and parameters with small analytic
// gradients (at most 2e-2 of the largest, zero included) whose difference is at least 1e-3 of the largest and
// resolved to better than half of itself: their sign must agree. Below 2e-2 of the largest gradient the former
// bound of these tests (2 % of the largest) let a zero or a flipped gradient pass. The directional check
// moves every parameter of the block along a random unit direction u (the most aligned with g of four) by
// ±ε, ±ε/2, ±ε/4 (ε = 1e-3) and compares the change with g · Δθ (Δθ as the floats moved), with the same
// tolerance terms; it must resolve g · u to a tenth.
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <functional>
#include <numeric>
#include <random>
#include <sstream>
#include <string>
#include <vector>

namespace relit::test {

/// The scalar whose gradient is checked, in double: sets the parameters to `theta` and evaluates it.
using Objective = std::function<double(const std::vector<float>& theta)>;

struct GradientCheck {
  std::size_t lo = 0, hi = 0;  ///< the checked block of parameters [lo, hi); outside it the gradient must be 0
  int n_largest = 8;           ///< the parameters with the largest |gradient|
  int n_random = 8;            ///< uniformly drawn parameters of [random_lo, hi)
  std::size_t random_lo = 0;   ///< where the random picks start (at least lo)
  int n_small = 6;             ///< parameters with |g| in [1e-3, 2e-2] max |g| (the sign is checked too)
  double h = 1e-2;             ///< first step of the per-parameter differences, relative to max(1, |θ_i|)
  double direction_step = 1e-3;
  std::uint32_t seed = 5;
};

struct GradientCheckReport {
  int checked = 0, unresolved = 0, small_checked = 0;
  double noise = 0;  ///< σ_f, the measured rounding noise of one evaluation of the objective
  double worst = 0;  ///< the largest |g_i - D_i| / tol_i over the checked parameters
};

namespace detail {

inline double sign(double x) { return x > 0 ? 1.0 : x < 0 ? -1.0 : 0.0; }

// The rounding noise of one evaluation of f: fourth differences (exact for cubics) at steps far below those of
// the checks, on the parameters with the largest gradients; their median, as a standard deviation (the fourth
// difference of independent noise has 70 times its variance), made conservative by a factor of 4.
inline double rounding_noise(const Objective& f, const std::vector<float>& theta, const std::vector<std::size_t>& at,
                             double f0) {
  std::vector<double> d4;
  std::vector<float> t = theta;
  for (std::size_t i : at) {
    const float p = theta[i];
    const double step = 1e-4 * std::max(1.0f, std::fabs(p));
    double v[5];
    for (int k = -2; k <= 2; ++k) {
      if (k == 0) {
        v[2] = f0;
        continue;
      }
      t[i] = static_cast<float>(p + k * step);
      v[k + 2] = f(t);
    }
    t[i] = p;
    d4.push_back(std::fabs(v[0] - 4 * v[1] + 6 * v[2] - 4 * v[3] + v[4]) / std::sqrt(70.0));
  }
  std::sort(d4.begin(), d4.end());
  return 4.0 * d4[d4.size() / 2];
}

struct Difference {
  bool resolved = false;
  double estimate = 0, tolerance = 0, step = 0;
  double coarse = 0;  // D(h), of the step pair that resolved it
};

// Central differences at steps h, h/2 and h/4, with the error estimate of D(h/2): 2 |D(h) - D(h/2)|
// (truncation: three times its O(h²) estimate), 2 K (kinks), 2 σ_f / (h/2) (rounding) and `floor`. A kink (a
// clamp of the renderer switching) at distance k < h/2 with slope change Δ moves D(h/2) by Δ (1 - 2k/h) / 2 and
// may move D(h) alike; it shows in the second differences c(s) = F+(s) - F-(s) (forward minus backward
// difference), which are f'' s on a smooth piece: K = max(|c(h) - 2 c(h/2)|, |c(h/2) - 2 c(h/4)|) is at least
// Δ / 3 for any k < h/4 and at least four times the error of D(h/2) for h/4 < k < h/2.
struct StepPair {
  double coarse = 0, fine = 0, step = 0, tolerance = 0, disagreement = 0;
};

// The steps of a 1-D function phi(s) (phi(0) = f0); `move(s, moved)` returns phi(s) and the step as the floats
// actually moved (`moved`).
template <class Move>
StepPair step_pair(const Move& move, double h, double f0, double noise, double floor) {
  auto at = [&](double step, double& central, double& second) {
    double up = 0, down = 0;
    const double fp = move(step, up), fm = move(-step, down);  // up > 0 > down
    central = (fp - fm) / (up - down);
    second = (fp - f0) / up - (f0 - fm) / -down;
    return (up - down) / 2;
  };
  StepPair r;
  double c1 = 0, c2 = 0, c4 = 0, d4 = 0;
  at(h, r.coarse, c1);
  r.step = at(h / 2, r.fine, c2);
  at(h / 4, d4, c4);
  const double kink = std::max(std::fabs(c1 - 2 * c2), std::fabs(c2 - 2 * c4));
  const double rounding = 2 * noise / r.step;
  r.tolerance = 2 * std::fabs(r.coarse - r.fine) + 2 * kink + rounding + floor;
  r.disagreement = r.tolerance - rounding - floor;
  return r;
}

// Central differences of f in parameter i, retried with smaller steps while their truncation and kink terms
// exceed a fifth of the estimate and `resolution`.
inline Difference difference(const Objective& f, std::vector<float>& t, std::size_t i, double h0, double f0,
                             double noise, double floor, double resolution) {
  const float p = t[i];
  auto move = [&](double step, double& moved) {
    t[i] = static_cast<float>(p + step);
    moved = double(t[i]) - double(p);
    const double v = f(t);
    t[i] = p;
    return v;
  };
  Difference d;
  for (double scale : {1.0, 0.25, 0.0625}) {
    const StepPair r = step_pair(move, h0 * scale * std::max(1.0f, std::fabs(p)), f0, noise, floor);
    d.estimate = r.fine;
    d.coarse = r.coarse;
    d.step = r.step;
    d.tolerance = r.tolerance;
    if (r.disagreement <= 0.2 * std::fabs(r.fine) || r.tolerance <= resolution) {
      d.resolved = true;
      return d;
    }
  }
  return d;
}

}  // namespace detail

/// Checks `grad` (the analytic gradient of f at `theta`) as the header describes; failures are gtest failures
/// naming the parameter, its difference and tolerance.
inline GradientCheckReport check_gradient(const Objective& f, const std::vector<float>& theta,
                                          const std::vector<float>& grad, const GradientCheck& c) {
  GradientCheckReport report;
  EXPECT_EQ(grad.size(), theta.size());
  EXPECT_LT(c.lo, c.hi);
  EXPECT_LE(c.hi, theta.size());
  if (grad.size() != theta.size() || c.lo >= c.hi || c.hi > theta.size()) return report;
  for (std::size_t i = 0; i < grad.size(); ++i)
    if (i < c.lo || i >= c.hi) {
      EXPECT_EQ(grad[i], 0.0f) << "parameter " << i << " outside the checked block";
    }
  double max_g = 0;
  for (std::size_t i = c.lo; i < c.hi; ++i) max_g = std::max(max_g, double(std::fabs(grad[i])));
  EXPECT_GT(max_g, 0.0) << "the gradient of the block is zero";
  if (!(max_g > 0)) return report;
  std::mt19937 rng(c.seed);
  std::vector<std::size_t> order(c.hi - c.lo);
  std::iota(order.begin(), order.end(), c.lo);
  std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
    return std::fabs(grad[a]) > std::fabs(grad[b]) || (std::fabs(grad[a]) == std::fabs(grad[b]) && a < b);
  });
  const std::size_t n_largest = std::min<std::size_t>(c.n_largest, order.size());
  std::vector<std::size_t> largest(order.begin(), order.begin() + n_largest);
  std::vector<std::size_t> random;
  const std::size_t random_lo = std::clamp(c.random_lo, c.lo, c.hi - 1);
  for (int k = 0; k < c.n_random; ++k) random.push_back(random_lo + rng() % (c.hi - random_lo));
  std::vector<std::size_t> small;
  for (std::size_t i : order)
    if (std::fabs(grad[i]) <= 2e-2 * max_g) small.push_back(i);
  std::shuffle(small.begin(), small.end(), rng);

  const double f0 = f(theta);
  report.noise = detail::rounding_noise(
      f, theta, std::vector<std::size_t>(largest.begin(), largest.begin() + std::min<std::size_t>(5, largest.size())),
      f0);
  const double floor = 1e-5 * max_g;
  std::vector<float> t = theta;
  auto check = [&](std::size_t i, const detail::Difference& d, const char* kind) {
    const double err = std::fabs(double(grad[i]) - d.estimate);
    report.worst = std::max(report.worst, err / d.tolerance);
    ++report.checked;
    EXPECT_LE(err, d.tolerance) << kind << " parameter " << i << ": gradient " << grad[i] << ", differences "
                                << d.estimate << " (step " << d.step << "; at twice the step " << d.coarse
                                << ", tolerance " << d.tolerance << "; largest gradient " << max_g << ")";
  };
  int unresolved = 0, picked = 0;
  for (const auto* picks : {&largest, &random}) {
    for (std::size_t i : *picks) {
      ++picked;
      const auto d = detail::difference(f, t, i, c.h, f0, report.noise, floor, 1e-3 * max_g);
      if (!d.resolved) {
        ++unresolved;
        continue;
      }
      check(i, d, picks == &largest ? "large" : "random");
    }
  }
  // Small gradients: parameters whose analytic gradient is at most 2e-2 of the largest (zero included, so that a
  // lost gradient is found) and whose difference is at least 1e-3 of it, resolved well enough to fix the sign,
  // which must agree. Candidates that do not qualify are replaced by the next ones.
  for (std::size_t k = 0; k < small.size() && report.small_checked < c.n_small && k < 8u * c.n_small; ++k) {
    const std::size_t i = small[k];
    const auto d = detail::difference(f, t, i, c.h, f0, report.noise, floor, 1e-3 * max_g);
    if (!d.resolved || std::fabs(d.estimate) < 1e-3 * max_g || d.tolerance >= 0.5 * std::fabs(d.estimate)) continue;
    check(i, d, "small");
    EXPECT_EQ(detail::sign(grad[i]), detail::sign(d.estimate))
        << "small parameter " << i << ": gradient " << grad[i] << " has the wrong sign, differences " << d.estimate;
    ++report.small_checked;
  }
  report.unresolved = unresolved;
  EXPECT_LE(4 * unresolved, picked) << unresolved << " of " << picked
                                    << " parameters unresolved by the differences (kinks?)";
  EXPECT_GE(report.small_checked, std::min<int>(c.n_small, int(small.size())))
      << "too few small gradients resolved (of " << small.size() << " candidates)";
  EXPECT_GT(report.small_checked, 0) << "no small gradient checked";

  // The derivative along a random unit direction u of the block: every parameter at once, phi(s) = f(θ + s u).
  // The analytic side is g · Δθ with Δθ as the floats moved, so the rounding of the moved parameters cancels.
  {
    // Of four random unit directions the one most aligned with g (a direction nearly orthogonal to g would
    // leave g · u too small to resolve).
    std::normal_distribution<double> normal;
    std::vector<double> u;
    double gnorm = 0, g_u = 0;
    for (std::size_t i = c.lo; i < c.hi; ++i) gnorm += double(grad[i]) * grad[i];
    gnorm = std::sqrt(gnorm);
    for (int k = 0; k < 4; ++k) {
      std::vector<double> w(theta.size(), 0.0);
      double norm = 0, g_w = 0;
      for (std::size_t i = c.lo; i < c.hi; ++i) w[i] = normal(rng), norm += w[i] * w[i];
      norm = std::sqrt(norm);
      for (std::size_t i = c.lo; i < c.hi; ++i) w[i] /= norm, g_w += grad[i] * w[i];
      if (std::fabs(g_w) > std::fabs(g_u)) u = w, g_u = g_w;
    }
    // The objective minus the analytic linear part: its central difference is the error D - g · u directly.
    auto move = [&](double step, double& moved) {
      std::vector<float> m = theta;
      double analytic = 0;
      for (std::size_t i = c.lo; i < c.hi; ++i) {
        m[i] = static_cast<float>(theta[i] + step * u[i]);
        analytic += double(grad[i]) * (double(m[i]) - double(theta[i]));
      }
      moved = step;
      return f(m) - analytic;
    };
    const detail::StepPair r = detail::step_pair(move, c.direction_step, f0, report.noise, 1e-5 * gnorm);
    EXPECT_LE(std::fabs(r.fine), r.tolerance)
        << "derivative along a random direction: g.u " << g_u << ", differences minus g.u " << r.fine
        << " (at twice the step " << r.coarse << ", tolerance " << r.tolerance << ", |g| " << gnorm << ")";
    EXPECT_LT(r.tolerance, 0.1 * std::fabs(g_u)) << "the directional differences are not resolved (g.u " << g_u << ")";
  }
  return report;
}

}  // namespace relit::test
