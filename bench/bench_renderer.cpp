// bench_renderer: the neural volume renderer's forward + backward pass (render.cl: per-sample light,
// compositing and their gradients) on one device, with and without the environment light, after checking
// the environment term (a renderer with every environment direction occluded renders exactly what the
// renderer without environment does; a uniform environment of radiance E gives S_env = E on average).
// Writes JSON (stdout, or --out FILE).
//
//   bench_renderer [--smoke] [--device SEL] [--rays N] [--reps N] [--out FILE]
//
// Target configuration: 1200 rays x 64 samples (a training batch), SH l_max 5 with K = 64 indirect
// directions, N_e = 0 and 32 environment directions; also the draw of the environment directions and the
// march of their visibility targets (64 steps through a 64^3 grid) for a quarter of the batch, the share the
// visibility network trains on. --smoke: tiny sizes, verification only (exit 1 on a wrong result).
#include <relit/io/file.hpp>
#include <relit/relit.hpp>
#include <relit/render/environment.hpp>
#include <relit/render/visibility.hpp>

#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <fstream>
#include <iostream>
#include <random>

using namespace relit;
using nn::BatchMatrix;
using Json = nlohmann::json;

namespace {

struct Args {
  bool smoke = false;
  std::string device, out;
  std::uint32_t rays = 1200, reps = 9;
};

// Median wall seconds of `reps` runs of f() + device.finish(), after one warm-up run.
template <class F>
double median_time(const Device& device, std::uint32_t reps, F f) {
  f();
  device.finish();
  std::vector<double> t;
  for (std::uint32_t i = 0; i < reps; ++i) {
    const auto t0 = std::chrono::steady_clock::now();
    f();
    device.finish();
    t.push_back(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
  }
  std::sort(t.begin(), t.end());
  return t[t.size() / 2];
}

// Rays from a sphere of radius 4 toward the box, a point light at distance 3..5.
std::vector<float> random_rays(std::uint32_t n, std::mt19937& rng) {
  std::normal_distribution<float> nd;
  std::uniform_real_distribution<float> u(-0.5f, 0.5f);
  auto unit = [&] {
    float v[3] = {nd(rng), nd(rng), nd(rng)};
    const float l = std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    return std::array<float, 3>{v[0] / l, v[1] / l, v[2] / l};
  };
  std::vector<float> rays;
  for (std::uint32_t r = 0; r < n; ++r) {
    const auto o = unit(), l = unit();
    float d[3] = {u(rng) - 4 * o[0], u(rng) - 4 * o[1], u(rng) - 4 * o[2]};
    const float len = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    const auto rec = render::ray_record({4 * o[0], 4 * o[1], 4 * o[2]}, {d[0] / len, d[1] / len, d[2] / len},
                                        {4 * l[0], 4 * l[1], 4 * l[2]}, {600, 600, 600});
    rays.insert(rays.end(), rec.begin(), rec.end());
  }
  return rays;
}

struct Batch {
  Buffer<float> rays, t, delta, color, trans, d_color;
  BatchMatrix pos, props, rad, d_rad, d_props;
};

Batch make_batch(const Device& dev, const render::VolumeRenderer& r, std::uint32_t n_rays, std::mt19937& rng) {
  const std::uint32_t n = n_rays * r.settings().n_samples, cols = r.prop_cols();
  Batch b{Buffer<float>(dev, random_rays(n_rays, rng)),
          Buffer<float>(dev, n),
          Buffer<float>(dev, n),
          Buffer<float>(dev, 3 * n_rays),
          Buffer<float>(dev, n_rays),
          Buffer<float>(dev, std::vector<float>(3 * n_rays, 1.0f)),
          BatchMatrix(dev, n, 3),
          BatchMatrix(dev, n, cols),
          BatchMatrix(dev, n, 3),
          BatchMatrix(dev, n, 3),
          BatchMatrix(dev, n, cols)};
  std::uniform_real_distribution<float> u(0, 1);
  std::vector<float> p(std::size_t(n) * cols);
  for (std::uint32_t s = 0; s < n; ++s) {
    float* row = &p[std::size_t(s) * cols];
    row[0] = 3 * u(rng);
    for (int c = 1; c < 4; ++c) row[c] = u(rng);
    row[4] = 1.8f * u(rng) - 0.9f;
    // visibilities in [0, 1], SH coefficients mostly positive
    for (std::uint32_t f = 5; f < cols; ++f)
      row[f] = f >= render::kSH && f < r.env_visibility_col() ? 0.2f * u(rng) - 0.05f : u(rng);
  }
  b.props.upload_row_major(p);
  r.sample(b.rays, n_rays, true, 1, b.t, b.delta, b.pos);
  return b;
}

bool check(bool ok, const std::string& what, double error, Json& report) {
  report["checks"].push_back({{"what", what}, {"max_error", error}, {"ok", ok}});
  if (!ok) std::cerr << "bench_renderer: WRONG RESULT: " << what << " (error " << error << ")\n";
  return ok;
}

bool verify(const Device& dev, Json& report) {
  bool ok = true;
  // 1. Every environment direction occluded: exactly the renderer without environment.
  {
    std::mt19937 rng(3);
    const std::uint32_t n_rays = 40, n_env = 32;
    render::VolumeRenderer with(dev, {64, 2, 16, false, n_env}), without(dev, {64, 2, 16});
    render::EnvironmentSamples env(dev, EnvironmentLight::sky(32, 16, 1, 1.0f, false), n_env);
    env.draw(1, 0);
    Batch b = make_batch(dev, with, n_rays, rng);
    auto p = b.props.download_row_major();
    std::vector<float> p0;
    for (std::uint32_t s = 0; s < b.props.batch(); ++s) {
      const float* row = &p[std::size_t(s) * with.prop_cols()];
      for (std::uint32_t j = 0; j < n_env; ++j)
        p[std::size_t(s) * with.prop_cols() + with.env_visibility_col() + j] = 0;
      p0.insert(p0.end(), row, row + without.prop_cols());
    }
    b.props.upload_row_major(p);
    BatchMatrix props0(dev, b.props.batch(), without.prop_cols()), dirs(dev, 16, 3), basis(dev, 16, 9);
    props0.upload_row_major(p0);
    Buffer<float> c0(dev, 3 * n_rays), t0(dev, n_rays);
    with.forward(b.rays, n_rays, b.t, b.delta, b.props, dirs, basis, b.rad, b.color, b.trans, &env);
    without.forward(b.rays, n_rays, b.t, b.delta, props0, dirs, basis, b.rad, c0, t0);
    const auto a = b.color.read(), z = c0.read();
    double err = 0;
    for (std::size_t i = 0; i < a.size(); ++i) err = std::max(err, double(std::abs(a[i] - z[i])));
    ok &= check(err == 0.0, "occluded environment adds nothing", err, report);
  }
  // 2. Uniform environment E, V = 1, no other light, albedo 1: S_env averages to E.
  {
    const std::uint32_t n_env = 32, n = 16, draws = 64;
    render::VolumeRenderer r(dev, {n, -1, 1, false, n_env});
    render::EnvironmentSamples env(dev, EnvironmentLight::uniform({2.0f, 2.0f, 2.0f}, false), n_env);
    const auto rec = render::ray_record({-3, 0, 0}, {1, 0, 0}, {0, 5, 0}, {1, 1, 1});
    Buffer<float> rays(dev, std::vector<float>(rec.begin(), rec.end())), t(dev, n), delta(dev, n), color(dev, 3),
        trans(dev, 1);
    BatchMatrix pos(dev, n, 3), props(dev, n, r.prop_cols()), rad(dev, n, 3), dirs(dev, 1, 3), basis(dev, 1, 0);
    std::vector<float> p(n * r.prop_cols(), 1.0f);
    for (std::uint32_t s = 0; s < n; ++s)
      p[s * r.prop_cols() + 4] = 0.5f * (s % 3) - 0.5f, p[s * r.prop_cols() + 5] = 0;
    props.upload_row_major(p);
    r.sample(rays, 1, false, 0, t, delta, pos);
    double mean = 0;
    for (std::uint32_t i = 0; i < draws; ++i) {
      env.draw(2, i);
      r.forward(rays, 1, t, delta, props, dirs, basis, rad, color, trans, &env);
      for (float v : rad.download_row_major()) mean += v / (3.0 * n * draws);
    }
    ok &=
        check(std::abs(mean / 2.0 - 1) < 0.03, "uniform environment: mean S_env = E", std::abs(mean / 2.0 - 1), report);
  }
  return ok;
}

}  // namespace

int main(int argc, char** argv) {
  Args a;
  for (int i = 1; i < argc; ++i) {
    const std::string s = argv[i];
    auto next = [&]() -> std::string {
      if (i + 1 >= argc) throw InvalidArgument(s + " needs a value");
      return argv[++i];
    };
    if (s == "--smoke")
      a.smoke = true;
    else if (s == "--device")
      a.device = next();
    else if (s == "--rays")
      a.rays = static_cast<std::uint32_t>(std::stoul(next()));
    else if (s == "--reps")
      a.reps = static_cast<std::uint32_t>(std::stoul(next()));
    else if (s == "--out")
      a.out = next();
    else {
      std::cerr << "usage: bench_renderer [--smoke] [--device SEL] [--rays N] [--reps N] [--out FILE]\n";
      return 2;
    }
  }
  if (a.smoke) a.rays = 20, a.reps = 1;
  if (a.rays < 1 || a.reps < 1) {
    std::cerr << "bench_renderer: --rays and --reps must be positive\n";
    return 2;
  }
  try {
    const Device dev = Device::select(a.device);
    Json report = {{"bench", "renderer"},   {"device", dev.info().description()},
                   {"smoke", a.smoke},      {"rays", a.rays},
                   {"samples_per_ray", 64}, {"sh_lmax", 5},
                   {"indirect_dirs", 64},   {"checks", Json::array()}};
    const bool ok = verify(dev, report);
    std::mt19937 rng(7);
    const EnvironmentLight sky = EnvironmentLight::sky(128, 64, 2, 1.0f, true);
    render::IndirectBasis indirect(dev, 64, 5);
    indirect.draw(1, 0);
    for (const std::uint32_t n_env : {0u, 32u}) {
      render::VolumeRenderer r(dev, {64, 5, 64, false, n_env});
      Batch b = make_batch(dev, r, a.rays, rng);
      std::unique_ptr<render::EnvironmentSamples> env;
      if (n_env) {
        env = std::make_unique<render::EnvironmentSamples>(dev, sky, n_env);
        env->draw(1, 0);
      }
      const double fwd = median_time(dev, a.reps, [&] {
        r.forward(b.rays, a.rays, b.t, b.delta, b.props, indirect.dirs(), indirect.basis(), b.rad, b.color, b.trans,
                  env.get());
      });
      const double bwd = median_time(dev, a.reps, [&] {
        r.backward(b.rays, a.rays, b.t, b.delta, b.props, indirect.dirs(), indirect.basis(), b.rad, b.color, b.d_color,
                   b.d_rad, b.d_props, env.get());
      });
      Json entry = {{"n_env_dirs", n_env},
                    {"forward_ms", 1e3 * fwd},
                    {"backward_ms", 1e3 * bwd},
                    {"forward_backward_ms", 1e3 * (fwd + bwd)}};
      if (env) {
        entry["draw_ms"] = 1e3 * median_time(dev, a.reps, [&] { env->draw(1, 1); });
        // Visibility targets toward the N_e directions for a quarter of the batch (64 steps, 64^3 grid).
        const int g = a.smoke ? 8 : 64;
        std::uniform_real_distribution<float> u(0, 2);
        std::vector<float> grid(std::size_t(g) * g * g);
        for (auto& v : grid) v = u(rng);
        const render::DensityGrid density{{g, g, g}, Buffer<float>(dev, grid)};
        const std::uint32_t quarter = (a.rays / 4 + 1) * 64;
        BatchMatrix pos(dev, quarter, 3), vis(dev, quarter, n_env);
        std::vector<float> xs(std::size_t(quarter) * 3);
        std::uniform_real_distribution<float> x(-1, 1);
        for (auto& v : xs) v = x(rng);
        pos.upload_row_major(xs);
        entry["march_quarter_batch_ms"] =
            1e3 * median_time(dev, a.reps,
                              [&] { render::march_visibility_directions(dev, pos, env->dirs(), density, 64, vis); });
        entry["march_samples"] = quarter;
      }
      report["timings"].push_back(entry);
      std::cerr << "renderer, N_e = " << n_env << ": forward " << 1e3 * fwd << " ms, backward " << 1e3 * bwd << " ms\n";
    }
    report["ok"] = ok;
    const std::string text = report.dump(2);
    if (a.out.empty())
      std::cout << text << "\n";
    else
      relit::io::write_file_atomic(a.out, text + "\n");
    return ok ? 0 : 1;
  } catch (const std::exception& e) {
    std::cerr << "bench_renderer: " << e.what() << "\n";
    return 1;
  }
}
