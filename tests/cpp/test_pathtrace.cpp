// The reference path tracer against known answers: HG and environment sampling (pdf = value, chi-square),
// transmittance (ratio and delta tracking vs exp(-int sigma)), single scattering vs numerical integration,
// multiple scattering at albedo < 1 (where Russian roulette fires) vs an independent analog random walk,
// the white furnace, determinism. Tolerances come from the sample variance (5-6 sigma) plus stated
// quadrature/float allowances; the seeds are fixed, so the tests are deterministic.
#include "test_support.hpp"

#include <relit/pathtrace.hpp>
#include <relit/render/environment.hpp>
#include <relit/scene/procedural.hpp>
#include <relit/verify/brdf_reference.hpp>

#include <array>
#include <cmath>
#include <iostream>
#include <random>
#include <utility>
#include <vector>

namespace relit {

namespace {

using test::kPi;

double hg(double cos_owi, double g) {
  const double d = 1 + g * g + 2 * g * cos_owi;
  return (1 - g * g) / (4 * kPi * d * std::sqrt(d));
}

// Writes actual/expected images to a folder that outlives the test, and says where.
std::string dump_images(const std::string& tag, const Image& actual, const Image& expected) {
  const auto dir = std::filesystem::temp_directory_path() / ("relit-failed-" + tag);
  std::filesystem::create_directories(dir);
  write_image((dir / "actual.exr").string(), actual);
  write_image((dir / "expected.exr").string(), expected);
  return " (images written to " + dir.string() + ")";
}

// Device buffers for the probe kernels' scene arguments.
struct ProbeScene {
  Buffer<float> density, majorant, env_pdf, env_marginal, env_conditional;
  Buffer<cl_float4> env;
  cl_int4 density_dims{{1, 1, 1, 0}}, majorant_dims{{1, 1, 1, 0}}, env_dims{{1, 1, 0, 0}};
  float scale = 0;

  ProbeScene(const Device& dev, const Grid* grid, float sigma_scale, const EnvironmentLight* envl) {
    if (grid) {
      density = Buffer<float>(dev, grid->values);
      density_dims = cl_int4{{grid->nx, grid->ny, grid->nz, 1}};
      const Grid m = majorant_grid(*grid, sigma_scale, std::max(1, grid->nx / 16));
      majorant = Buffer<float>(dev, m.values);
      majorant_dims = cl_int4{{m.nx, m.ny, m.nz, 1}};
      scale = sigma_scale;
    }
    if (envl) {
      std::vector<cl_float4> px(envl->image().pixels.size() / 4);
      for (std::size_t i = 0; i < px.size(); ++i)
        for (int c = 0; c < 4; ++c) px[i].s[c] = envl->image().pixels[i * 4 + c];
      env = Buffer<cl_float4>(dev, px);
      env_pdf = Buffer<float>(dev, envl->pdf_uv());
      env_marginal = Buffer<float>(dev, envl->marginal_cdf());
      env_conditional = Buffer<float>(dev, envl->conditional_cdf());
      env_dims = cl_int4{{envl->image().width, envl->image().height, 1, 0}};
    }
  }
  template <class... Before>
  void set(Kernel& k, const Before&... before) {
    k.args(before..., density, density_dims, scale, majorant, majorant_dims, env, env_pdf, env_marginal,
           env_conditional, env_dims);
  }
};

// Optical depth of scale * grid along o + t d over [t0, t1]: midpoint rule in double.
double optical_depth(const Grid& g, double scale, const double o[3], const double d[3], double t0, double t1,
                     int steps) {
  double sum = 0;
  const double dt = (t1 - t0) / steps;
  for (int i = 0; i < steps; ++i) {
    const double t = t0 + (i + 0.5) * dt;
    sum += g.sample(o[0] + t * d[0], o[1] + t * d[1], o[2] + t * d[2]);
  }
  return sum * dt * scale;
}

bool box_hit(const double o[3], const double d[3], double& t0, double& t1) {
  t0 = -1e30, t1 = 1e30;
  for (int a = 0; a < 3; ++a) {
    const double inv = 1.0 / d[a];
    double u = (-1 - o[a]) * inv, v = (1 - o[a]) * inv;
    if (u > v) std::swap(u, v);
    t0 = std::max(t0, u), t1 = std::min(t1, v);
  }
  return t1 > std::max(t0, 0.0);
}

}  // namespace

TEST(PathTraceSampling, HgSamplesHaveDensityEqualToThePhaseFunction) {
  const Device dev = test::test_device();
  Kernel k = dev.kernel("pathtrace_probe.cl", "probe_hg_sample");
  const cl_uint n = 160000;
  Buffer<cl_float4> out(dev, n);
  const double wo[3] = {0.3, -0.5, std::sqrt(1 - 0.34)};
  for (const double g : {-0.7, 0.0, 0.5, 0.9}) {
    k.args(n, cl_uint(11), cl_float4{{float(wo[0]), float(wo[1]), float(wo[2]), float(g)}}, out).launch(n, 64);
    const auto s = out.read();
    // Frame around the forward direction -wo for the azimuth.
    const double f[3] = {-wo[0], -wo[1], -wo[2]};
    double t[3] = {f[1], -f[0], 0};
    const double tl = std::sqrt(t[0] * t[0] + t[1] * t[1]);
    for (auto& x : t) x /= tl;
    const double b[3] = {f[1] * t[2] - f[2] * t[1], f[2] * t[0] - f[0] * t[2], f[0] * t[1] - f[1] * t[0]};
    const int bm = 20, bp = 8;
    std::vector<double> count(bm * bp, 0);
    double mean_cos = 0;
    for (const auto& v : s) {
      const double mu = std::clamp(v.s[0] * f[0] + v.s[1] * f[1] + v.s[2] * f[2], -1.0, 1.0);
      ASSERT_NEAR(v.s[3], hg(-mu, g), 2e-3 * hg(-mu, g) + 1e-6) << "pdf != phase value, g = " << g;
      mean_cos += mu;
      // Exact CDF of the HG cosine: bins of equal probability.
      const double cdf = std::abs(g) < 1e-3
                             ? (mu + 1) / 2
                             : (1 - g * g) / (2 * g) * (1 / std::sqrt(1 + g * g - 2 * g * mu) - 1 / (1 + g));
      const double phi =
          std::atan2(v.s[0] * b[0] + v.s[1] * b[1] + v.s[2] * b[2], v.s[0] * t[0] + v.s[1] * t[1] + v.s[2] * t[2]);
      const int i = std::min(int(cdf * bm), bm - 1), j = std::min(int((phi + kPi) / (2 * kPi) * bp), bp - 1);
      count[i * bp + j] += 1;
    }
    const double expected = double(n) / (bm * bp);
    double chi2 = 0;
    for (double c : count) chi2 += (c - expected) * (c - expected) / expected;
    const double dof = bm * bp - 1;
    EXPECT_LT(chi2, dof + 6 * std::sqrt(2 * dof)) << "g = " << g;
    EXPECT_NEAR(mean_cos / n, g, 5 * std::sqrt(1.0 / n)) << "mean cosine must equal g";
  }
}

TEST(PathTraceSampling, EnvironmentSamplerPdfIsConsistentAndMatchesTheMap) {
  const Device dev = test::test_device();
  const EnvironmentLight env(read_image(std::string(RELIT_TEST_DATA_DIR) + "/env_small.exr"), 1.0f, false);
  ProbeScene ps(dev, nullptr, 0, &env);
  Kernel k = dev.kernel("pathtrace_probe.cl", "probe_env_sample");
  const cl_uint n = 200000;
  Buffer<cl_float4> out(dev, n);
  Buffer<float> pdf_at(dev, n);
  ps.set(k, n, cl_uint(5));
  k.arg(12, out).arg(13, pdf_at).launch(n, 64);
  const auto s = out.read();
  const auto p = pdf_at.read();
  const int w = env.image().width, h = env.image().height;
  std::vector<double> count(std::size_t(w) * h, 0);
  int mismatched = 0;
  for (cl_uint i = 0; i < n; ++i) {
    const Float3 d{s[i].s[0], s[i].s[1], s[i].s[2]};
    const double host = env.pdf(d);
    if (std::abs(s[i].s[3] - host) > 1e-3 * host || std::abs(p[i] - host) > 1e-3 * host) ++mismatched;
    double phi = std::atan2(d[1], d[0]);
    if (phi < 0) phi += 2 * kPi;
    const int x = std::min(int(phi / (2 * kPi) * w), w - 1), y = std::min(int(std::acos(d[2]) / kPi * h), h - 1);
    count[std::size_t(y) * w + x] += 1;
  }
  EXPECT_LT(mismatched, int(n / 1000)) << "sampled pdf != pdf(direction) (texel-boundary rounding aside)";
  double chi2 = 0, pooled_c = 0, pooled_e = 0;
  int bins = 0;
  for (std::size_t t = 0; t < count.size(); ++t) {
    const double e = double(n) * env.pdf_uv()[t] / (w * h);
    if (e < 20) {
      pooled_c += count[t], pooled_e += e;
      continue;
    }
    chi2 += (count[t] - e) * (count[t] - e) / e;
    ++bins;
  }
  if (pooled_e > 0) chi2 += (pooled_c - pooled_e) * (pooled_c - pooled_e) / pooled_e, ++bins;
  EXPECT_LT(chi2, bins - 1 + 6 * std::sqrt(2.0 * (bins - 1)));
}

// The environment sampler against its documented distribution computed here from the raw map, without the
// library's tables or pdf: texel t = (x, y) is drawn with probability P_t = Y(t) sin(theta_y) / sum, Y the
// Rec. 709 luminance 0.2126 R + 0.7152 G + 0.0722 B, theta_y = (y + 1/2) pi / h the row's centre, and is
// uniform in (phi, theta) inside the texel, so the solid-angle pdf at d is P_t w h / (2 pi^2 sin theta(d)).
// Checked: the pdf the sampler reports and env_pdf(d) (the path tracer's MIS weights), a chi-square of the
// samples over half-texels (the texel probabilities and the uniformity inside a texel), and the weights
// E / (pdf N_e) of the neural renderer's environment directions.
TEST(PathTraceSampling, EnvironmentSamplerFollowsTheLuminanceOfTheRawMap) {
  const Device dev = test::test_device();
  // A map with saturated texels (the luminance weights of R, G and B differ by 10x), and the test fixture.
  Image vivid(24, 12, 3);
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> u(0.05f, 1.0f);
  for (float& v : vivid.pixels) v = u(rng);
  for (int x = 0; x < 24; x += 3) {  // pure red, green and blue texels in every other row
    for (int y = 1; y < 12; y += 2)
      for (int c = 0; c < 3; ++c) vivid.at(x + (y / 2) % 3, y, c) = c == (x / 3) % 3 ? 6.0f : 0.0f;
  }
  const std::pair<const char*, Image> maps[] = {
      {"saturated texels", vivid}, {"env_small.exr", read_image(std::string(RELIT_TEST_DATA_DIR) + "/env_small.exr")}};
  for (const auto& [name, raw] : maps) {
    const int w = raw.width, h = raw.height;
    std::vector<double> prob(std::size_t(w) * h);
    double total = 0;
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) {
        const double lum = 0.2126 * raw.at(x, y, 0) + 0.7152 * raw.at(x, y, 1) + 0.0722 * raw.at(x, y, 2);
        prob[std::size_t(y) * w + x] = lum * std::sin((y + 0.5) * kPi / h);
        total += prob[std::size_t(y) * w + x];
      }
    for (double& p : prob) p /= total;
    auto texel = [&](const double d[3], int& x, int& y, double& fx, double& fy) {
      double phi = std::atan2(d[1], d[0]);
      if (phi < 0) phi += 2 * kPi;
      const double px = phi / (2 * kPi) * w, py = std::acos(std::clamp(d[2], -1.0, 1.0)) / kPi * h;
      x = std::min(int(px), w - 1), y = std::min(int(py), h - 1);
      fx = px - x, fy = py - y;
    };
    auto expected_pdf = [&](const double d[3]) {
      int x, y;
      double fx, fy;
      texel(d, x, y, fx, fy);
      const double st = std::sqrt(std::max(0.0, 1 - d[2] * d[2]));
      return prob[std::size_t(y) * w + x] * w * h / (2 * kPi * kPi * st);
    };

    const EnvironmentLight env(raw, 1.0f, false);
    ProbeScene ps(dev, nullptr, 0, &env);
    Kernel k = dev.kernel("pathtrace_probe.cl", "probe_env_sample");
    const cl_uint n = 300000;
    Buffer<cl_float4> out(dev, n);
    Buffer<float> pdf_at(dev, n);
    ps.set(k, n, cl_uint(23));
    k.arg(12, out).arg(13, pdf_at).launch(n, 64);
    const auto s = out.read();
    const auto p = pdf_at.read();
    std::vector<double> count(std::size_t(w) * h * 4, 0);  // half-texels: 2 x 2 per texel
    int mismatched = 0;
    double inv_pdf = 0;
    for (cl_uint i = 0; i < n; ++i) {
      const double d[3] = {s[i].s[0], s[i].s[1], s[i].s[2]};
      const double e = expected_pdf(d);
      // A draw on a texel border may fall on either side in float and double; those are rare.
      if (!(std::abs(s[i].s[3] - e) <= 1e-3 * e) || !(std::abs(p[i] - e) <= 1e-3 * e)) ++mismatched;
      inv_pdf += 1 / e;
      int x, y;
      double fx, fy;
      texel(d, x, y, fx, fy);
      count[(std::size_t(y) * w + x) * 4 + (fy >= 0.5) * 2 + (fx >= 0.5)] += 1;
    }
    EXPECT_LT(mismatched, int(n / 1000)) << name << ": the sampler's pdf differs from the map's luminance pdf";
    // E[1 / pdf] over the samples is the sphere's area when the samples have that density.
    EXPECT_NEAR(inv_pdf / n, 4 * kPi, 0.05 * 4 * kPi) << name;
    double chi2 = 0, pooled_c = 0, pooled_e = 0;
    int bins = 0;
    for (std::size_t b = 0; b < count.size(); ++b) {
      const double e = n * prob[b / 4] / 4;
      if (e < 20) {
        pooled_c += count[b], pooled_e += e;
        continue;
      }
      chi2 += (count[b] - e) * (count[b] - e) / e;
      ++bins;
    }
    if (pooled_e > 0) chi2 += (pooled_c - pooled_e) * (pooled_c - pooled_e) / pooled_e, ++bins;
    std::cout << "[ env pdf  ] " << name << ": chi-square " << chi2 << " over " << bins << " bins, " << mismatched
              << " pdf mismatches in " << n << ", E[1/pdf] / 4 pi = " << inv_pdf / n / (4 * kPi) << "\n";
    ASSERT_GT(bins, 200) << name;
    EXPECT_LT(chi2, bins - 1 + 6 * std::sqrt(2.0 * (bins - 1))) << name << ": chi-square over " << bins << " bins";

    // The neural renderer's environment directions: weights E / (pdf N_e) with this pdf and the raw texel.
    render::EnvironmentSamples samples(dev, env, 64);
    int bad_weights = 0;
    for (std::uint32_t it = 0; it < 20; ++it) {
      samples.draw(2, it);
      const auto dirs = samples.dirs().download_row_major(), weights = samples.weights().download_row_major();
      for (std::uint32_t j = 0; j < 64; ++j) {
        const double d[3] = {dirs[3 * j], dirs[3 * j + 1], dirs[3 * j + 2]};
        int x, y;
        double fx, fy;
        texel(d, x, y, fx, fy);
        for (int c = 0; c < 3; ++c) {
          const double want = raw.at(x, y, c) / (expected_pdf(d) * 64);
          if (!(std::abs(weights[3 * j + c] - want) <= 1e-3 * want + 1e-7)) ++bad_weights;
        }
      }
    }
    EXPECT_LE(bad_weights, 6) << name << ": environment weights must be E / (pdf N_e)";
  }
}

TEST(PathTraceTransmittance, RatioAndDeltaTrackingMatchExpMinusOpticalDepth) {
  const Device dev = test::test_device();
  Kernel k = dev.kernel("pathtrace_probe.cl", "probe_transmittance");
  std::mt19937 rng(4);
  std::uniform_real_distribution<double> u(-1, 1);
  struct Case {
    const char* name;
    Grid grid;
    float scale;
  };
  std::vector<Case> cases = {{"homogeneous cube", Grid(8, 8, 8, 1, 1.0f), 1.5f},
                             {"cloud", make_cloud(24, 3).density, 6.0f}};
  const cl_uint rays = 48, samples = 4000;
  for (const auto& c : cases) {
    std::vector<cl_float4> data;
    std::vector<double> expected;
    for (cl_uint r = 0; r < rays; ++r) {
      // Rays from outside the box toward a random point inside it.
      double o[3] = {u(rng) * 3, u(rng) * 3, 2.5}, target[3] = {u(rng) * 0.5, u(rng) * 0.5, u(rng) * 0.5}, d[3];
      double len = 0;
      for (int a = 0; a < 3; ++a) d[a] = target[a] - o[a], len += d[a] * d[a];
      for (auto& x : d) x /= std::sqrt(len);
      double t0, t1;
      ASSERT_TRUE(box_hit(o, d, t0, t1));
      expected.push_back(std::exp(-optical_depth(c.grid, c.scale, o, d, t0, t1, 4000)));
      data.push_back(cl_float4{{float(o[0]), float(o[1]), float(o[2]), float(t0)}});
      data.push_back(cl_float4{{float(d[0]), float(d[1]), float(d[2]), float(t1)}});
    }
    Buffer<cl_float4> ray_buf(dev, data), out(dev, rays);
    ProbeScene ps(dev, &c.grid, c.scale, nullptr);
    ps.set(k, rays, cl_uint(9), samples, ray_buf);
    k.arg(14, out).launch(rays, 8);
    const auto res = out.read();
    for (cl_uint r = 0; r < rays; ++r) {
      const double T = expected[r];
      const double ratio_sd =
          std::sqrt(std::max(double(res[r].s[2]) - double(res[r].s[0]) * res[r].s[0], 1e-8) / samples);
      const double delta_sd = std::sqrt(std::max(T * (1 - T), 1e-8) / samples);
      EXPECT_NEAR(res[r].s[0], T, 5 * ratio_sd + 1e-3) << c.name << " ray " << r << ": ratio tracking";
      EXPECT_NEAR(res[r].s[1], T, 5 * delta_sd + 1e-3) << c.name << " ray " << r << ": delta tracking";
      EXPECT_NEAR(res[r].s[0], res[r].s[1], 5 * (ratio_sd + delta_sd) + 1e-3) << c.name << ": estimators disagree";
    }
  }
  // Straight through the homogeneous cube along x: exactly exp(-sigma * 2).
  EXPECT_NEAR(std::exp(-optical_depth(cases[0].grid, 1.5, std::array<double, 3>{-3, 0.1, 0.2}.data(),
                                      std::array<double, 3>{1, 0, 0}.data(), 2, 4, 100)),
              std::exp(-3.0), 1e-12);
}

TEST(PathTraceRender, WhiteFurnaceRendersTheEnvironmentRadianceEverywhere) {
  const Device dev = test::test_device();
  Json j = {{"medium",
             {{"source", {{"type", "cloud"}, {"resolution", 24}, {"seed", 2}}},
              {"density_scale", 8.0},
              {"albedo", 1.0},
              {"g", 0.5}}},
            {"environment", {{"radiance", {0.7, 0.7, 0.7}}, {"visible", true}}},
            {"cameras", {{{"position", {0.3, -3.0, 0.4}}, {"camera_angle_x", 0.45}, {"width", 12}, {"height", 12}}}}};
  const Scene scene = Scene::from_json(j);
  PathTraceSettings rs;
  rs.spp = 64;
  rs.seed = 3;
  const RenderResult r = PathTracer(dev, scene).render(scene.cameras[0], {}, rs);
  double sum = 0, var_sum = 0;
  int hit = 0;
  for (int p = 0; p < 144; ++p) {
    const double mean = r.image.pixels[p * 4], sd = std::sqrt(r.variance.pixels[p * 4] / rs.spp);
    EXPECT_NEAR(mean, 0.7, 6 * sd + 2e-4) << "pixel " << p << dump_images("furnace", r.image, Image(12, 12, 4, 0.7f));
    sum += mean, var_sum += r.variance.pixels[p * 4] / rs.spp;
    hit += r.image.pixels[p * 4 + 3] > 0;
  }
  EXPECT_NEAR(sum / 144, 0.7, 5 * std::sqrt(var_sum) / 144 + 1e-4);
  EXPECT_GT(hit, 40) << "the medium must cover a good part of the image for the test to mean anything";
}

TEST(PathTraceRender, SingleScatteringMatchesNumericalIntegration) {
  const Device dev = test::test_device();
  const float sigma = 1.2f;
  const Float3 albedo{0.9f, 0.6f, 0.3f};
  const float g = 0.4f;
  Json j = {{"medium",
             {{"source", {{"type", "sphere"}, {"resolution", 32}, {"radius", 0.7}}},
              {"density_scale", sigma},
              {"albedo", albedo},
              {"g", g}}},
            {"lights", {{{"position", {1.5, -2.0, 2.5}}, {"intensity", {40, 40, 40}}}}},
            {"cameras", {{{"position", {0.0, -4.0, 0.3}}, {"camera_angle_x", 0.55}, {"width", 8}, {"height", 8}}}}};
  const Scene scene = Scene::from_json(j);
  const Grid& grid = scene.medium->density;
  const Camera& cam = scene.cameras[0];
  const PointLight& light = scene.lights[0];
  PathTraceSettings rs;
  rs.spp = 1024;
  rs.max_bounces = 1;
  rs.seed = 8;
  const RenderResult r = PathTracer(dev, scene).render(cam, scene.lights, rs);

  Image expected(8, 8, 4);
  const int sub = 5, steps = 200;
  const Float3 eye = cam.position();
  for (int py = 0; py < 8; ++py)
    for (int px = 0; px < 8; ++px) {
      double acc = 0, alpha = 0;
      for (int sy = 0; sy < sub; ++sy)
        for (int sx = 0; sx < sub; ++sx) {
          const Float3 df = cam.direction(px + (sx + 0.5) / sub, py + (sy + 0.5) / sub);
          const double o[3] = {eye[0], eye[1], eye[2]}, d[3] = {df[0], df[1], df[2]};
          double t0, t1;
          if (!box_hit(o, d, t0, t1)) continue;
          t0 = std::max(t0, 0.0);
          const double dt = (t1 - t0) / steps;
          double tau = 0;  // optical depth from the camera to the current step
          for (int i = 0; i < steps; ++i) {
            const double t = t0 + (i + 0.5) * dt;
            const double x[3] = {o[0] + t * d[0], o[1] + t * d[1], o[2] + t * d[2]};
            const double s = sigma * grid.sample(x[0], x[1], x[2]);
            const double tau_mid = tau + 0.5 * s * dt;
            tau += s * dt;
            if (s <= 0) continue;
            double wl[3] = {light.position[0] - x[0], light.position[1] - x[1], light.position[2] - x[2]};
            const double dist = std::sqrt(wl[0] * wl[0] + wl[1] * wl[1] + wl[2] * wl[2]);
            for (auto& c : wl) c /= dist;
            double l0, l1;
            box_hit(x, wl, l0, l1);
            const double tau_l = optical_depth(grid, sigma, x, wl, 0.0, std::min(l1, dist), 100);
            const double cos_owi = -(d[0] * wl[0] + d[1] * wl[1] + d[2] * wl[2]);
            acc += std::exp(-tau_mid) * s * hg(cos_owi, g) * std::exp(-tau_l) * light.intensity[0] / (dist * dist) * dt;
          }
          alpha += 1 - std::exp(-tau);
        }
      for (int c = 0; c < 3; ++c) expected.at(px, py, c) = float(acc * albedo[c] / (sub * sub));
      expected.at(px, py, 3) = float(alpha / (sub * sub));
    }
  double total = 0;
  for (int p = 0; p < 64; ++p)
    for (int c = 0; c < 4; ++c) {
      const double e = expected.pixels[p * 4 + c], a = r.image.pixels[p * 4 + c];
      const double sd = std::sqrt(r.variance.pixels[p * 4 + c] / rs.spp);
      EXPECT_NEAR(a, e, 5 * sd + 0.01 * e + 1e-4)
          << "pixel " << p << " channel " << c << dump_images("single-scatter", r.image, expected);
      if (c == 0) total += e;
    }
  EXPECT_GT(total, 0.5) << "the reference image must not be black";
}

namespace {

// An analog random walk in double through a homogeneous cube [-1, 1]^3 (extinction sigma, grey albedo a, HG g),
// written from the radiative transfer equation without any of the kernel's estimators: free paths drawn from
// exp(-sigma t) in closed form, absorption as an event of probability 1 - a (no throughput weights, no
// Russian roulette), HG directions by the textbook inverse CDF around the direction of travel, point lights
// by next-event estimation with the closed-form transmittance exp(-sigma * length inside the cube), the
// uniform environment only by escaping paths (no environment sampling, no MIS).
struct AnalogWalk {
  double sigma, albedo, g;
  std::array<double, 3> light_pos;
  double light_intensity, env_radiance;

  struct Result {
    double radiance;  // the path's estimate
    double multiple;  // the part of it gathered at the third scattering event or later
  };

  // A unit vector at cosine mu from unit d, azimuth phi.
  static std::array<double, 3> turn(const std::array<double, 3>& d, double mu, double phi) {
    std::array<double, 3> t =
        std::abs(d[0]) < 0.9 ? std::array<double, 3>{0, -d[2], d[1]} : std::array<double, 3>{d[2], 0, -d[0]};
    const double tl = std::sqrt(t[0] * t[0] + t[1] * t[1] + t[2] * t[2]);
    for (auto& v : t) v /= tl;
    const std::array<double, 3> b = {d[1] * t[2] - d[2] * t[1], d[2] * t[0] - d[0] * t[2], d[0] * t[1] - d[1] * t[0]};
    const double st = std::sqrt(std::max(0.0, 1 - mu * mu));
    std::array<double, 3> out;
    for (int a = 0; a < 3; ++a) out[a] = st * std::cos(phi) * t[a] + st * std::sin(phi) * b[a] + mu * d[a];
    return out;
  }

  Result trace(std::array<double, 3> o, std::array<double, 3> d, std::mt19937_64& rng) const {
    std::uniform_real_distribution<double> u(0, 1);
    Result r{0, 0};
    for (int collisions = 0;; ++collisions) {
      double t0, t1;
      if (!box_hit(o.data(), d.data(), t0, t1)) {  // (only the camera ray can miss; the environment is hidden)
        if (collisions > 0) r.radiance += env_radiance;
        break;
      }
      const double t = std::max(t0, 0.0) - std::log(1 - u(rng)) / sigma;
      if (t >= t1) {  // escaped: the environment's radiance (a hidden background for the camera ray)
        if (collisions > 0) r.radiance += env_radiance, r.multiple += collisions >= 3 ? env_radiance : 0;
        break;
      }
      const std::array<double, 3> x = {o[0] + t * d[0], o[1] + t * d[1], o[2] + t * d[2]};
      // The collision scatters with probability a: next-event estimation carries the factor a, and the walk
      // goes on with probability a.
      std::array<double, 3> wl = {light_pos[0] - x[0], light_pos[1] - x[1], light_pos[2] - x[2]};
      const double dist = std::sqrt(wl[0] * wl[0] + wl[1] * wl[1] + wl[2] * wl[2]);
      for (auto& v : wl) v /= dist;
      double l0, l1;
      box_hit(x.data(), wl.data(), l0, l1);
      const double cos_owl = -(d[0] * wl[0] + d[1] * wl[1] + d[2] * wl[2]);
      const double direct = albedo * hg(cos_owl, g) * std::exp(-sigma * l1) * light_intensity / (dist * dist);
      r.radiance += direct;
      if (collisions + 1 >= 3) r.multiple += direct;
      if (u(rng) >= albedo) break;  // absorbed
      // HG: the cosine between the old and the new direction of travel.
      const double v = u(rng);
      const double mu =
          std::abs(g) < 1e-6 ? 1 - 2 * v : (1 + g * g - std::pow((1 - g * g) / (1 - g + 2 * g * v), 2)) / (2 * g);
      d = turn(d, std::clamp(mu, -1.0, 1.0), 2 * kPi * u(rng));
      o = x;
    }
    return r;
  }
};

}  // namespace

// Multiple scattering at albedo < 1, where the path tracer's Russian roulette fires (from the third vertex
// on, with survival probability max(throughput) = a^k < 1): relit's path tracer against the analog walk
// above in a homogeneous cube of optical thickness 4 under a point light and a uniform environment. A
// roulette that forgot to divide by its survival probability, or a wrong albedo factor, transmittance or HG
// sampling, changes the image by many standard errors (z-tests with the variances of both sides).
TEST(PathTraceRender, MultipleScatteringBelowAlbedoOneMatchesAnAnalogWalk) {
  const Device dev = test::test_device();
  const int res = 4;  // pixels per side
  const double sigma = 2.0, env = 0.3, intensity = 25;
  const std::array<double, 3> light = {1.6, -2.4, 2.2};
  struct Case {
    double albedo, g;
  };
  for (const Case c : {Case{0.8, 0.0}, Case{0.95, 0.0}, Case{0.8, 0.6}, Case{0.95, 0.6}}) {
    Json j = {
        {"medium",
         {{"source", {{"type", "constant"}, {"resolution", 4}, {"value", 1.0}}},
          {"density_scale", sigma},
          {"albedo", c.albedo},
          {"g", c.g}}},
        {"lights", {{{"position", light}, {"intensity", intensity}}}},
        {"environment", {{"radiance", {env, env, env}}, {"visible", false}}},
        {"cameras", {{{"position", {0.4, -4.0, 0.7}}, {"camera_angle_x", 0.4}, {"width", res}, {"height", res}}}}};
    const Scene scene = Scene::from_json(j);
    const Camera& cam = scene.cameras[0];
    PathTraceSettings rs;
    rs.spp = 4096;
    rs.seed = 17;
    const RenderResult r = PathTracer(dev, scene).render(cam, scene.lights, rs);

    const AnalogWalk walk{sigma, c.albedo, c.g, light, intensity, env};
    std::mt19937_64 rng(99);
    std::uniform_real_distribution<double> u(0, 1);
    const int paths = 12000;
    const Float3 eye = cam.position();
    double sum_r = 0, var_r = 0, sum_h = 0, var_h = 0, multiple = 0, worst = 0;
    for (int p = 0; p < res * res; ++p) {
      double s = 0, s2 = 0;
      for (int k = 0; k < paths; ++k) {
        const Float3 d = cam.direction(p % res + u(rng), p / res + u(rng));
        const auto w = walk.trace({eye[0], eye[1], eye[2]}, {d[0], d[1], d[2]}, rng);
        s += w.radiance, s2 += w.radiance * w.radiance, multiple += w.multiple;
      }
      const double mean_h = s / paths, se2_h = std::max(s2 / paths - mean_h * mean_h, 0.0) / (paths - 1);
      const double mean_r = r.image.pixels[p * 4], se2_r = r.variance.pixels[p * 4] / rs.spp;
      const double z = (mean_r - mean_h) / std::sqrt(se2_r + se2_h);
      worst = std::max(worst, std::abs(z));
      EXPECT_LT(std::abs(z), 5.0) << "albedo " << c.albedo << ", g " << c.g << ", pixel " << p << ": relit " << mean_r
                                  << ", analog walk " << mean_h;
      sum_r += mean_r, var_r += se2_r, sum_h += mean_h, var_h += se2_h;
    }
    const double z_mean = (sum_r - sum_h) / std::sqrt(var_r + var_h);
    std::cout << "[ analog   ] albedo " << c.albedo << ", g " << c.g << ": image mean relit " << sum_r / (res * res)
              << ", analog walk " << sum_h / (res * res) << ", z = " << z_mean << ", worst pixel |z| = " << worst
              << ", share from the 3rd scattering on " << multiple / paths / sum_h << "\n";
    EXPECT_LT(std::abs(z_mean), 4.0) << "albedo " << c.albedo << ", g " << c.g << ": image means differ";
    EXPECT_GT(multiple / paths / sum_h, 0.15) << "the test needs paths long enough for the roulette to matter";
  }
}

TEST(PathTraceRender, SameSeedSameImageWhateverTheTilingOtherSeedsDiffer) {
  const auto devices = test::devices_under_test();
  Json j = Scene::builtin_json("blobs", 1, 24);
  j["lights"] = {{{"position", {2, -3, 2}}, {"intensity", 300}}};
  j["environment"] = {{"sky", 3}, {"visible", true}};
  j["cameras"] = {{{"position", {0, -4.5, 1}}, {"width", 10}, {"height", 8}}};
  const Scene scene = Scene::from_json(j);
  PathTraceSettings rs;
  rs.spp = 16;
  rs.seed = 42;
  const PathTracer pt(devices.front(), scene);
  const RenderResult a = pt.render(scene.cameras[0], scene.lights, rs);
  PathTraceSettings tiled = rs;
  tiled.samples_per_launch = 37;  // many small launches, passes of 1 sample
  EXPECT_EQ(pt.render(scene.cameras[0], scene.lights, tiled).image.pixels, a.image.pixels);
  PathTraceSettings other = rs;
  other.seed = 43;
  EXPECT_NE(pt.render(scene.cameras[0], scene.lights, other).image.pixels, a.image.pixels);
  // Other devices: the same image within Monte Carlo tolerance (streams are identical; floats may differ).
  for (std::size_t i = 1; i < devices.size(); ++i) {
    const RenderResult b = PathTracer(devices[i], scene).render(scene.cameras[0], scene.lights, rs);
    for (std::size_t p = 0; p < a.image.pixels.size(); ++p)
      EXPECT_NEAR(b.image.pixels[p], a.image.pixels[p], 6 * std::sqrt(2 * a.variance.pixels[p] / rs.spp) + 1e-3)
          << devices[i].info().name;
  }
}

TEST(PathTraceRender, ProgressIsReportedAndCancellationStops) {
  const Device dev = test::test_device();
  Json j = Scene::builtin_json("cloud", 0, 16);
  j["lights"] = {{{"position", {0, -3, 3}}, {"intensity", 100}}};
  j["cameras"] = {{{"width", 16}, {"height", 16}}};
  const Scene scene = Scene::from_json(j);
  PathTraceSettings rs;
  rs.spp = 8;
  rs.samples_per_launch = 256;
  std::vector<Progress> seen;
  PathTracer pt(dev, scene);
  pt.render(scene.cameras[0], scene.lights, rs, [&](const Progress& p) {
    seen.push_back(p);
    return true;
  });
  ASSERT_EQ(seen.size(), 8u);
  EXPECT_EQ(seen.back().done, 16u * 16u * 8u);
  EXPECT_EQ(seen.back().total, 16u * 16u * 8u);
  int calls = 0;
  EXPECT_THROW(pt.render(scene.cameras[0], scene.lights, rs, [&](const Progress&) { return ++calls < 2; }), Cancelled);
  EXPECT_EQ(calls, 2);
  rs.spp = 0;
  EXPECT_THROW(pt.render(scene.cameras[0], scene.lights, rs), InvalidArgument);
}

}  // namespace relit

namespace relit {

namespace {

// The double reference of the BRDF (relit/verify/brdf_reference.hpp) with n = +z.
double brdf_ref(const double wo[3], const double wi[3], double base, double r) {
  return reference::brdf({0, 0, 1}, {wo[0], wo[1], wo[2]}, {wi[0], wi[1], wi[2]}, base, r);
}

}  // namespace

TEST(PathTraceSampling, BrdfMatchesReferenceAndItsSamplerIsUnbiased) {
  const Device dev = test::test_device();
  Kernel k = dev.kernel("pathtrace_probe.cl", "probe_brdf_sample");
  const cl_uint n = 200000;
  Buffer<cl_float4> out(dev, n), out_f(dev, n);
  const double wo[3] = {0.5, 0.2, std::sqrt(1 - 0.29)};
  for (const double r : {0.2, 0.5, 0.9}) {
    const double base = 0.6;
    k.args(n, cl_uint(21), cl_float4{{float(wo[0]), float(wo[1]), float(wo[2]), float(r)}},
           cl_float4{{float(base), float(base), float(base), 0}}, out, out_f)
        .launch(n, 64);
    const auto s = out.read(), f = out_f.read();
    // Estimators of int f cos and of the hemisphere's area (2 pi) from the sampler's own pdf.
    double est = 0, est2 = 0, area = 0, area2 = 0;
    int checked = 0;
    for (cl_uint i = 0; i < n; ++i) {
      const double wi[3] = {s[i].s[0], s[i].s[1], s[i].s[2]};
      const double pdf = s[i].s[3];
      if (wi[2] <= 0 || pdf <= 0) continue;  // below the surface: contributes 0
      const double ref = brdf_ref(wo, wi, base, r) * wi[2];
      if (checked++ < 2000) {
        ASSERT_NEAR(f[i].s[0], ref, 2e-3 * ref + 1e-6) << "BRDF value, r = " << r;
      }
      est += ref / pdf, est2 += (ref / pdf) * (ref / pdf);
      area += 1 / pdf, area2 += 1 / (pdf * pdf);
    }
    // Host quadrature of int f cos over the hemisphere.
    double integral = 0;
    const int nt = 800, np = 800;
    for (int a = 0; a < nt; ++a)
      for (int b = 0; b < np; ++b) {
        const double th = (a + 0.5) / nt * kPi / 2, ph = (b + 0.5) / np * 2 * kPi;
        const double wi[3] = {std::sin(th) * std::cos(ph), std::sin(th) * std::sin(ph), std::cos(th)};
        integral += brdf_ref(wo, wi, base, r) * wi[2] * std::sin(th) * (kPi / 2 / nt) * (2 * kPi / np);
      }
    const double mean = est / n, sd = std::sqrt(std::max(est2 / n - mean * mean, 0.0) / n);
    EXPECT_NEAR(mean, integral, 5 * sd + 2e-3 * integral) << "E[f cos / pdf] != int f cos, r = " << r;
    const double am = area / n, asd = std::sqrt(std::max(area2 / n - am * am, 0.0) / n);
    EXPECT_NEAR(am, 2 * kPi, 5 * asd + 1e-3) << "the sampler's pdf must be its density, r = " << r;
  }
}

TEST(PathTraceSampling, BrdfIsReciprocal) {
  // The GGX + Lambert BRDF the solids use: f(wo, wi) = f(wi, wo), evaluated with the device's brdf_eval on
  // random pairs of directions and roughnesses.
  const Device dev = test::test_device();
  Kernel k = dev.kernel("pathtrace_probe.cl", "probe_brdf_eval");
  std::mt19937 rng(4);
  std::uniform_real_distribution<double> u(0, 1);
  auto upper = [&] {
    const double z = u(rng) * 0.98 + 0.02, ph = 2 * kPi * u(rng), s = std::sqrt(1 - z * z);
    return std::array<double, 3>{s * std::cos(ph), s * std::sin(ph), z};
  };
  const cl_uint n = 4000;
  std::vector<cl_float4> pairs;
  std::vector<double> rough;
  for (cl_uint i = 0; i < n; ++i) {
    const auto a = upper(), b = upper();
    const double r = 0.05 + 0.95 * u(rng);
    rough.push_back(r);
    pairs.push_back({{float(a[0]), float(a[1]), float(a[2]), float(r)}});
    pairs.push_back({{float(b[0]), float(b[1]), float(b[2]), 0}});
  }
  std::vector<cl_float4> swapped(pairs.size());
  for (cl_uint i = 0; i < n; ++i) {
    swapped[2 * i] = pairs[2 * i + 1];
    swapped[2 * i].s[3] = pairs[2 * i].s[3];
    swapped[2 * i + 1] = pairs[2 * i];
  }
  const cl_float4 white{{1, 1, 1, 0}};
  Buffer<cl_float4> in(dev, pairs), in_swapped(dev, swapped), f(dev, n), g(dev, n);
  k.args(n, in, white, f).launch(n, 64);
  k.args(n, in_swapped, white, g).launch(n, 64);
  const auto fa = f.read(), fb = g.read();
  for (cl_uint i = 0; i < n; ++i)
    ASSERT_NEAR(fa[i].s[0], fb[i].s[0], 1e-4f * (1 + fa[i].s[0])) << "pair " << i << ", roughness " << rough[i];
}

// The white furnace of a surface: at albedo 1 the BRDF reflects no more energy than it receives, for every
// roughness and view angle down to grazing, and (its diffuse lobe takes what the specular one leaves) about
// all of it. Computed on the device with the path tracer's own brdf_eval, brdf_sample and brdf_pdf. Plain
// Lambert a/pi + GGX (without the energy-conserving diffuse term of docs/design.md §4.4) fails here: up to 1.15
// at r = 0.02-0.05, 80 degrees.
TEST(PathTraceSampling, BrdfWhiteFurnaceReflectsAllTheEnergyAndNoMore) {
  const Device dev = test::test_device();
  Kernel k = dev.kernel("pathtrace_probe.cl", "probe_brdf_albedo");
  const double roughness[] = {0.02, 0.05, 0.1, 0.2, 0.35, 0.5, 0.75, 1.0};
  const double degrees[] = {0, 30, 60, 70, 75, 80, 85, 88};
  std::vector<cl_float4> cases;
  for (const double r : roughness)
    for (const double deg : degrees) {
      const double th = deg * kPi / 180;
      cases.push_back({{float(std::sin(th)), 0.0f, float(std::cos(th)), float(r)}});
    }
  const auto n = cl_uint(cases.size());
  Buffer<cl_float4> in(dev, cases);
  Buffer<float> out(dev, n);
  k.args(n, in, cl_uint(256), out).launch(n, 16);
  const auto albedo = out.read();
  // Tolerance: the table's interpolation error (|E - E_table| < 1e-3); the quadrature adds < 1e-4.
  double lowest = 2, highest = 0;
  for (cl_uint i = 0; i < n; ++i) {
    const double r = cases[i].s[3], deg = std::acos(double(cases[i].s[2])) * 180 / kPi;
    EXPECT_LE(albedo[i], 1.0 + 1.5e-3) << "creates energy: roughness " << r << ", view angle " << deg << " degrees";
    EXPECT_GE(albedo[i], 1.0 - 1.5e-3) << "loses energy: roughness " << r << ", view angle " << deg << " degrees";
    lowest = std::min(lowest, double(albedo[i])), highest = std::max(highest, double(albedo[i]));
  }
  std::cout << "[ furnace  ] directional albedo at albedo 1 in [" << lowest << ", " << highest << "]\n";
}

// kernels/brdf_albedo.clh holds the directional albedo of brdf.clh's specular lobe and its cosine-weighted
// mean: checked against the host quadrature (regenerate it with scripts/brdf_albedo_table.cpp after
// changing the lobe).
TEST(PathTraceSampling, BrdfAlbedoTableIsTheSpecularLobesAlbedo) {
  const int n = reference::kAlbedoN;
  std::mt19937 rng(7);
  std::uniform_int_distribution<int> index(0, n - 1);
  std::vector<std::pair<int, int>> entries = {{0, 0}, {0, n - 1}, {n - 1, 0}, {n - 1, n - 1}, {1, 3}};
  for (int e = 0; e < 40; ++e) entries.push_back({index(rng), index(rng)});
  for (const auto& [i, j] : entries) {
    const double r = double(i) / (n - 1), x = double(j) / (n - 1);
    EXPECT_NEAR(reference::kAlbedoTable[i * n + j], reference::specular_albedo(x * x, r), 1e-4)
        << "E(mu = " << x * x << "; r = " << r << ")";
  }
  for (int i = 0; i < n; i += 5) {
    const double r = double(i) / (n - 1);
    const int steps = 200000;
    double mean = 0;
    for (int s = 0; s < steps; ++s) {
      const double mu = (s + 0.5) / steps;
      mean += 2 * reference::tabulated_albedo(mu, r) * mu / steps;
    }
    EXPECT_NEAR(reference::kAlbedoAverage[i], mean, 1e-6) << "E_avg(r = " << r << ")";
  }
}

TEST(PathTraceRender, SolidSphereUnderAPointLightMatchesTheAnalyticShading) {
  const Device dev = test::test_device();
  const double radius = 0.6, base = 0.7, rough = 0.5, inten = 20;
  Json j = {{"solid",
             {{"source", {{"type", "sphere"}, {"resolution", 64}, {"radius", radius}}},
              {"base_color", base},
              {"roughness", rough}}},
            {"lights", {{{"position", {2.0, -2.0, 3.0}}, {"intensity", inten}}}},
            {"cameras", {{{"position", {0, -4, 0}}, {"camera_angle_x", 0.18}, {"width", 8}, {"height", 8}}}}};
  const Scene scene = Scene::from_json(j);
  PathTraceSettings rs;
  rs.spp = 256;
  rs.seed = 2;
  const RenderResult r = PathTracer(dev, scene).render(scene.cameras[0], scene.lights, rs);
  const Camera& cam = scene.cameras[0];
  const Float3 eye = cam.position();
  const double lp[3] = {2, -2, 3};
  Image expected(8, 8, 4);
  const int sub = 6;
  for (int py = 0; py < 8; ++py)
    for (int px = 0; px < 8; ++px) {
      double acc = 0;
      for (int sy = 0; sy < sub; ++sy)
        for (int sx = 0; sx < sub; ++sx) {
          const Float3 df = cam.direction(px + (sx + 0.5) / sub, py + (sy + 0.5) / sub);
          const double o[3] = {eye[0], eye[1], eye[2]}, d[3] = {df[0], df[1], df[2]};
          const double b = o[0] * d[0] + o[1] * d[1] + o[2] * d[2];
          const double c = o[0] * o[0] + o[1] * o[1] + o[2] * o[2] - radius * radius;
          ASSERT_GT(b * b - c, 0) << "every pixel must see the sphere";
          const double t = -b - std::sqrt(b * b - c);
          const double x[3] = {o[0] + t * d[0], o[1] + t * d[1], o[2] + t * d[2]};
          const double nrm[3] = {x[0] / radius, x[1] / radius, x[2] / radius};
          double l[3] = {lp[0] - x[0], lp[1] - x[1], lp[2] - x[2]};
          const double dist = std::sqrt(l[0] * l[0] + l[1] * l[1] + l[2] * l[2]);
          for (auto& v : l) v /= dist;
          // Shade in a frame where n = +z.
          double t1[3] = {nrm[1], -nrm[0], 0};
          double tl = std::sqrt(t1[0] * t1[0] + t1[1] * t1[1]);
          if (tl < 1e-9) t1[0] = 1, t1[1] = 0, tl = 1;
          for (auto& v : t1) v /= tl;
          const double t2[3] = {nrm[1] * t1[2] - nrm[2] * t1[1], nrm[2] * t1[0] - nrm[0] * t1[2],
                                nrm[0] * t1[1] - nrm[1] * t1[0]};
          auto local = [&](const double v[3], double out[3]) {
            out[0] = v[0] * t1[0] + v[1] * t1[1] + v[2] * t1[2];
            out[1] = v[0] * t2[0] + v[1] * t2[1] + v[2] * t2[2];
            out[2] = v[0] * nrm[0] + v[1] * nrm[1] + v[2] * nrm[2];
          };
          const double wov[3] = {-d[0], -d[1], -d[2]};
          double wo_l[3], wi_l[3];
          local(wov, wo_l);
          local(l, wi_l);
          if (wi_l[2] > 0) acc += brdf_ref(wo_l, wi_l, base, rough) * wi_l[2] * inten / (dist * dist);
        }
      for (int ch = 0; ch < 3; ++ch) expected.at(px, py, ch) = float(acc / (sub * sub));
      expected.at(px, py, 3) = 1.0f;
    }
  for (int p = 0; p < 64; ++p)
    for (int ch = 0; ch < 4; ch += 3) {
      const double e = expected.pixels[p * 4 + ch], a = r.image.pixels[p * 4 + ch];
      const double sd = std::sqrt(r.variance.pixels[p * 4 + ch] / rs.spp);
      EXPECT_NEAR(a, e, 5 * sd + 0.03 * e + 1e-3)
          << "pixel " << p << " channel " << ch << dump_images("solid", r.image, expected);
    }
}

}  // namespace relit
