// The neural volume renderer: forward against a double-precision reference of docs/design.md §4.2 on random inputs,
// backward against central finite differences of that reference, sampling, and known answers; the lighting and
// compositing for both kernel variants (SIMD and work-group), and the per-device choice between them.
#include <relit/verify/renderer_reference.hpp>
#include "test_support.hpp"

#include <relit/render/environment.hpp>
#include <relit/render/volume_renderer.hpp>
#include <relit/sh.hpp>

#include <Eigen/Core>

#include <cmath>
#include <cstdlib>
#include <functional>
#include <random>
#include <string>

namespace relit {

using nn::BatchMatrix;
using render::kRayFloats;
using render::VolumeRenderer;
using render::VolumeRendererSettings;
using Vec3 = Eigen::Vector3d;

namespace {

using reference::random_scene;
using reference::RayScene;
using reference::reference_color;

// The kernels run_device() uses: "auto" (the device's choice), or a variant forced by the RendererVariant
// fixture for the test it runs.
std::string g_variant = "auto";

// Forces the variant `g_variant` names: "workgroup" with 8 work-items per ray (so that 16 and 32 samples per
// ray make 2 and 4 segments of the compositing scan) and the shared directions in local memory, and
// "workgroup_unstaged" with 64 (lowered to the samples per ray: one segment) read from global memory.
void use_variant(VolumeRenderer& renderer) {
  if (g_variant == "simd") renderer.set_kernels(KernelVariant::Simd);
  if (g_variant == "workgroup")
    renderer.set_kernels(KernelVariant::WorkGroup, VolumeRenderer::WorkGroupParams{8, true});
  if (g_variant == "workgroup_unstaged")
    renderer.set_kernels(KernelVariant::WorkGroup, VolumeRenderer::WorkGroupParams{64, false});
  if (g_variant != "auto") {  // no silent fallback to the other variant
    EXPECT_EQ(kernel_variant_name(renderer.kernel_choice().variant), g_variant.substr(0, g_variant.find('_')));
  }
}

class RendererVariant : public ::testing::TestWithParam<std::string> {
 protected:
  void SetUp() override { g_variant = GetParam(); }
  void TearDown() override { g_variant = "auto"; }
};

struct DeviceRun {
  std::vector<float> color, transmittance, d_props;
};

DeviceRun run_device(const Device& dev, const RayScene& s, int lmax, const std::vector<float>& d_color,
                     bool closed_form = false, const render::EnvironmentSamples* env = nullptr,
                     bool visibility_gradient = false) {
  VolumeRenderer renderer(
      dev, {s.n_samples, lmax, s.n_dirs, closed_form, s.n_env, s.brdf ? "brdf" : "phase", visibility_gradient});
  use_variant(renderer);
  const std::uint32_t n = s.n_rays * s.n_samples;
  Buffer<float> rays(dev, s.rays), t(dev, n), delta(dev, n), color(dev, 3 * s.n_rays), trans(dev, s.n_rays),
      dcol(dev, d_color);
  BatchMatrix dirs(dev, s.n_dirs, 3), basis(dev, s.n_dirs, s.n_sh);
  dirs.upload_row_major(s.dirs);
  if (s.n_sh) basis.upload_row_major(s.basis);
  if (closed_form) renderer.view_basis(rays, s.n_rays, basis);
  BatchMatrix pos(dev, n, 3), props(dev, n, s.cols()), rad(dev, n, 3), drad(dev, n, 3), dprops(dev, n, s.cols());
  props.upload_row_major(std::vector<float>(s.props.begin(), s.props.end()));
  renderer.sample(rays, s.n_rays, false, 0, t, delta, pos);
  renderer.forward(rays, s.n_rays, t, delta, props, dirs, basis, rad, color, trans, env);
  renderer.backward(rays, s.n_rays, t, delta, props, dirs, basis, rad, color, dcol, drad, dprops, env);
  return {color.read(), trans.read(), dprops.download_row_major()};
}

// The colour of the scene with every sample's light contribution removed (what the background alone gives
// through the same densities): the difference shows how much a comparison is about the scattered light.
double mean_scattered(const RayScene& s) {
  RayScene dark = s;
  for (std::uint32_t i = 0; i < s.n_rays * s.n_samples; ++i) {
    double* p = &dark.props[i * s.cols()];
    for (int c = 1; c <= 3; ++c) p[c] = 0;  // no albedo: only the specular part remains in "brdf"
    p[render::kVisibility] = 0;
    for (std::uint32_t j = 0; j < s.n_env; ++j) p[s.env_col() + j] = 0;
    for (std::uint32_t j = 0; j < 3 * s.n_sh; ++j) p[6 + j] = 0;
    if (s.brdf) p[s.normal_col()] = p[s.normal_col() + 1] = p[s.normal_col() + 2] = 0;  // scatters nothing
  }
  const auto lit = reference_color(s, s.props), bg = reference_color(dark, dark.props);
  double sum = 0;
  for (std::size_t i = 0; i < lit.size(); ++i) sum += (lit[i] - bg[i]) / lit.size();
  return sum;
}

// Random weights w for the scalar loss L = sum w . colour.
std::vector<float> random_weights(std::size_t n, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-1, 1);
  std::vector<float> w(n);
  for (auto& v : w) v = u(rng);
  return w;
}

// Checks the device's dL/dproperties against central differences of the double reference, on every
// `stride`-th sample; every visibility column (point light and environment) must get exactly zero gradient,
// but with `visibility_gradient` the point light's is checked against the differences as well.
// In scattering "brdf" that covers albedo, roughness, SH coefficients, sigma and the raw normal.
// Returns the number of values checked.
int expect_gradients_match_finite_differences(const RayScene& s, const std::vector<float>& w,
                                              const std::vector<float>& d_props, bool closed_form, std::uint32_t stride,
                                              bool visibility_gradient = false) {
  auto loss = [&](const std::vector<double>& props) {
    const auto c = reference_color(s, props, closed_form);
    double l = 0;
    for (std::size_t i = 0; i < c.size(); ++i) l += w[i] * c[i];
    return l;
  };
  const std::uint32_t cols = s.cols();
  const double h = 1e-6;
  int checked = 0;
  for (std::uint32_t smp = 0; smp < s.n_rays * s.n_samples; smp += stride)
    for (std::uint32_t f = 0; f < cols; ++f) {
      auto plus = s.props, minus = s.props;
      plus[smp * cols + f] += h;
      minus[smp * cols + f] -= h;
      if ((f == render::kVisibility && !visibility_gradient) || (f >= s.env_col() && f < s.normal_col())) {
        EXPECT_EQ(d_props[smp * cols + f], 0.0f) << "sample " << smp << " visibility column " << f;
      } else {
        const double fd = (loss(plus) - loss(minus)) / (2 * h);
        EXPECT_NEAR(d_props[smp * cols + f], fd, 1e-4 * std::abs(fd) + 2e-5) << "sample " << smp << " column " << f;
      }
      ++checked;
    }
  return checked;
}

}  // namespace

TEST_P(RendererVariant, ForwardMatchesDoubleReference) {
  for (const int lmax : {-1, 0, 2}) {
    const RayScene s = random_scene(7, 32, lmax, 16, 11 + lmax);
    const auto got = run_device(test::test_device(), s, lmax, std::vector<float>(3 * s.n_rays, 1.f));
    const auto ref = reference_color(s, s.props);
    for (std::size_t i = 0; i < ref.size(); ++i)
      EXPECT_NEAR(got.color[i], ref[i], 2e-5 * std::abs(ref[i]) + 1e-6) << "lmax " << lmax << " value " << i;
  }
}

TEST_P(RendererVariant, BackwardMatchesFiniteDifferencesOfTheReference) {
  const int lmax = 1;
  const RayScene s = random_scene(3, 16, lmax, 8, 5);
  const auto w = random_weights(3 * s.n_rays, 3);
  const auto got = run_device(test::test_device(), s, lmax, w);
  EXPECT_GT(expect_gradients_match_finite_differences(s, w, got.d_props, false, 5), 100);
}

// The shadow gradient's input (docs/baselines.md): dL/dV toward the point light, in both scattering models;
// the environment's columns stay zero.
TEST_P(RendererVariant, VisibilityGradientMatchesFiniteDifferences) {
  for (const bool brdf : {false, true}) {
    const int lmax = 1;
    const RayScene s = random_scene(3, 16, lmax, 8, 17, 0, brdf);
    const auto w = random_weights(3 * s.n_rays, 4);
    const auto got = run_device(test::test_device(), s, lmax, w, false, nullptr, true);
    EXPECT_GT(expect_gradients_match_finite_differences(s, w, got.d_props, false, 5, true), 100) << brdf;
    double norm = 0;
    for (std::uint32_t i = 0; i < s.n_rays * s.n_samples; ++i) norm += std::abs(got.d_props[i * s.cols() + 5]);
    EXPECT_GT(norm, 1e-3) << "dL/dV is zero everywhere (brdf " << brdf << ")";
  }
}

TEST_P(RendererVariant, ClosedFormIndirectMatchesReferenceAndFiniteDifferences) {
  const int lmax = 2;
  const RayScene s = random_scene(3, 16, lmax, 8, 21);
  const auto w = random_weights(3 * s.n_rays, 8);
  const auto got = run_device(test::test_device(), s, lmax, w, true);
  const auto ref = reference_color(s, s.props, true);
  for (std::size_t i = 0; i < ref.size(); ++i) EXPECT_NEAR(got.color[i], ref[i], 2e-5 * std::abs(ref[i]) + 1e-6) << i;
  EXPECT_GT(expect_gradients_match_finite_differences(s, w, got.d_props, true, 7), 100);
}

// With the max(0, .) clamp inactive, the closed form is the K-direction sum's limit (Funk-Hecke with the
// +2g phase convention of the paper, Zheng, Singh, Seidel, NeurIPS 2021, appendix A): both renderers agree within the
// Monte Carlo error of K = 4096 directions.
TEST(VolumeRenderer, ClosedFormIsTheLimitOfTheDirectionSum) {
  const Device dev = test::test_device();
  const int lmax = 2;
  const std::uint32_t k = 4096, n_rays = test::tiny_sizes() ? 1 : 4, n = n_rays * 16;
  RayScene s = random_scene(n_rays, 16, lmax, 1, 33);
  for (std::uint32_t i = 0; i < n; ++i) {
    double* p = &s.props[i * s.cols()];
    p[4] = 0.6 * p[4] / 0.9;  // g in [-0.6, 0.6]
    p[5] = 0;                 // no direct light: compare the indirect term alone
    for (int ch = 0; ch < 3; ++ch) {
      p[6 + ch * s.n_sh] = 3.0;  // a large constant band keeps the expansion positive everywhere
      for (std::uint32_t j = 1; j < s.n_sh; ++j) p[6 + ch * s.n_sh + j] *= 0.3;
    }
  }
  const std::vector<float> props(s.props.begin(), s.props.end());
  auto render_with = [&](bool closed_form) {
    VolumeRenderer renderer(dev, {16, lmax, k, closed_form});
    render::IndirectBasis basis(dev, k, lmax);
    basis.draw(1, 0);
    Buffer<float> rays(dev, s.rays), t(dev, n), delta(dev, n), color(dev, 3 * n_rays), trans(dev, n_rays);
    BatchMatrix pos(dev, n, 3), pm(dev, n, s.cols()), rad(dev, n, 3), view(dev, n_rays, renderer.n_sh());
    pm.upload_row_major(props);
    renderer.sample(rays, n_rays, false, 0, t, delta, pos);
    if (closed_form) renderer.view_basis(rays, n_rays, view);
    renderer.forward(rays, n_rays, t, delta, pm, basis.dirs(), closed_form ? view : basis.basis(), rad, color, trans);
    return color.read();
  };
  const auto mc = render_with(false), exact = render_with(true);
  for (std::size_t i = 0; i < mc.size(); ++i) {
    ASSERT_GT(exact[i], 0.05f);
    EXPECT_NEAR(mc[i], exact[i], 0.03 * exact[i]) << "value " << i;
  }
}

TEST_P(RendererVariant, AbsorbingSlabTransmitsExpMinusSigmaD) {
  // A ray along +x through the box (length 2) in a medium of sigma 0.7 and albedo 0: colour = T bg, T = e^-1.4.
  const Device dev = test::test_device();
  RayScene s = random_scene(1, 64, -1, 4, 1);
  const auto rec = render::ray_record({-3, 0.1f, -0.2f}, {1, 0, 0}, {0, 5, 0}, {100, 100, 100}, {0.5f, 1.0f, 2.0f});
  s.rays.assign(rec.begin(), rec.end());
  for (std::uint32_t i = 0; i < 64; ++i) {
    double* p = &s.props[i * s.cols()];
    p[0] = 0.7;
    p[1] = p[2] = p[3] = 0;
  }
  const auto got = run_device(dev, s, -1, {1, 1, 1});
  const double T = std::exp(-1.4);
  EXPECT_NEAR(got.transmittance[0], T, 1e-6);
  EXPECT_NEAR(got.color[0], 0.5 * T, 1e-6);
  EXPECT_NEAR(got.color[2], 2.0 * T, 1e-6);
}

TEST(VolumeRenderer, ScalesRgbBlocksByTheirRaysIntensity) {
  const Device d = test::test_device();
  const std::uint32_t spr = 16, n_rays = 3, n = spr * n_rays, per = 2;
  VolumeRenderer renderer(d, {spr, -1, 4});
  std::vector<float> rays(n_rays * kRayFloats, 0.0f);
  for (std::uint32_t r = 0; r < n_rays; ++r)
    for (int c = 0; c < 3; ++c) rays[r * kRayFloats + render::kRayLightIntensity + c] = float(10 * (r + 1) + c);
  std::vector<float> h(n * 3 * per);
  for (std::size_t i = 0; i < h.size(); ++i) h[i] = 0.5f + float(i % 7);
  BatchMatrix src(d, n, 3 * per), dst(d, n, 1 + 3 * per);
  src.upload_row_major(h);
  Buffer<float> rb(d, rays);
  renderer.scale_rgb_by_ray_intensity(rb, src, 0, dst, 1, per);
  const auto out = dst.download_row_major();
  for (std::uint32_t s = 0; s < n; ++s)
    for (std::uint32_t c = 0; c < 3 * per; ++c)
      EXPECT_EQ(out[s * (1 + 3 * per) + 1 + c],
                rays[(s / spr) * kRayFloats + render::kRayLightIntensity + c / per] * h[s * 3 * per + c])
          << s << " " << c;
  // Samples per ray are the renderer's, a multiple of 16 (its tiles belong to one ray each).
  EXPECT_THROW(VolumeRenderer(d, {24, -1, 4}), InvalidArgument);
  Buffer<float> too_few(d, 2 * kRayFloats);
  EXPECT_THROW(renderer.scale_rgb_by_ray_intensity(too_few, src, 0, dst, 1, per), InvalidArgument);
  EXPECT_THROW(renderer.scale_rgb_by_ray_intensity(rb, src, 0, dst, 2, per), InvalidArgument);
}

TEST(VolumeRenderer, MissingRayShowsTheBackgroundAndJitterStaysInStrata) {
  const Device dev = test::test_device();
  VolumeRenderer renderer(dev, {16, -1, 4});
  // Ray 0 misses the box; ray 1 crosses it along the diagonal.
  const auto miss = render::ray_record({5, 5, 5}, {0, 0, 1}, {0, 0, 9}, {1, 1, 1}, {0.25f, 0.5f, 0.75f});
  const auto cross = render::ray_record({-3, -3, -3}, {0.57735027f, 0.57735027f, 0.57735027f}, {0, 0, 9}, {1, 1, 1});
  std::vector<float> rays(miss.begin(), miss.end());
  rays.insert(rays.end(), cross.begin(), cross.end());
  Buffer<float> r(dev, rays), t(dev, 32), delta(dev, 32);
  BatchMatrix pos(dev, 32, 3);
  renderer.sample(r, 2, true, 99, t, delta, pos);
  const auto rec = r.read(), tv = t.read(), dv = delta.read();
  EXPECT_EQ(rec[render::kRayTNear], 0.f);
  EXPECT_EQ(rec[render::kRayTFar], 0.f);
  const double tn = 2 * std::sqrt(3.0), tf = 4 * std::sqrt(3.0), step = (tf - tn) / 16;
  EXPECT_NEAR(rec[kRayFloats + render::kRayTNear], tn, 1e-5);
  EXPECT_NEAR(rec[kRayFloats + render::kRayTFar], tf, 1e-5);
  double total = 0;
  for (int i = 0; i < 16; ++i) {
    EXPECT_GE(tv[16 + i], tn + i * step - 1e-5);
    EXPECT_LE(tv[16 + i], tn + (i + 1) * step + 1e-5);
    total += dv[16 + i];
  }
  EXPECT_NEAR(total, tf - tn, 1e-5);  // the deltas tile [t_near, t_far]
  EXPECT_NEAR(dv[16], 0.5 * (tv[16] + tv[17]) - tn, 1e-5);
  const auto p = pos.download_row_major();
  EXPECT_NEAR(p[(16 + 3) * 3], -3 + tv[16 + 3] * 0.57735027, 1e-5);
  // The missing ray composites to its background with transmittance 1.
  BatchMatrix props(dev, 32, 6), rad(dev, 32, 3);
  std::vector<float> pv(32 * 6, 1.0f);
  props.upload_row_major(pv);
  Buffer<float> color(dev, 6), trans(dev, 2);
  BatchMatrix dirs(dev, 4, 3), basis(dev, 4, 0);
  dirs.upload_row_major(std::vector<float>(12, 0.5f));
  renderer.forward(r, 2, t, delta, props, dirs, basis, rad, color, trans);
  const auto c = color.read();
  EXPECT_EQ(trans.read()[0], 1.0f);
  EXPECT_FLOAT_EQ(c[0], 0.25f);
  EXPECT_FLOAT_EQ(c[2], 0.75f);
}

TEST(VolumeRenderer, BadSettingsAndShapesAreErrors) {
  const Device dev = test::test_device();
  EXPECT_THROW(VolumeRenderer(dev, {40, 2, 64}), InvalidArgument);
  EXPECT_THROW(VolumeRenderer(dev, {64, 10, 64}), InvalidArgument);
  VolumeRenderer renderer(dev, {16, 1, 4});
  Buffer<float> rays(dev, 20), t(dev, 16), delta(dev, 16), color(dev, 3), trans(dev, 1);
  BatchMatrix props(dev, 16, 7), rad(dev, 16, 3), dirs(dev, 4, 3), basis(dev, 4, 4);
  EXPECT_THROW(renderer.forward(rays, 1, t, delta, props, dirs, basis, rad, color, trans), InvalidArgument);
  BatchMatrix good(dev, 16, renderer.prop_cols()), few_dirs(dev, 3, 3);
  EXPECT_THROW(renderer.forward(rays, 1, t, delta, good, few_dirs, basis, rad, color, trans), InvalidArgument);
}

TEST(VolumeRenderer, IndirectBasisIsUniformOnTheSphereAndMatchesHostSH) {
  const Device dev = test::test_device();
  const std::uint32_t k = 4096;
  render::IndirectBasis basis(dev, k, 2);
  basis.draw(5, 17);
  const auto dirs = basis.dirs().download_row_major();
  const auto y = basis.basis().download_row_major();
  Vec3 mean = Vec3::Zero();
  for (std::uint32_t i = 0; i < k; ++i) {
    const Vec3 w(dirs[3 * i], dirs[3 * i + 1], dirs[3 * i + 2]);
    ASSERT_NEAR(w.norm(), 1.0, 1e-5);
    mean += w / k;
    const auto ref = sh::eval(2, {w.x(), w.y(), w.z()});
    for (std::size_t j = 0; j < 9; ++j) ASSERT_NEAR(y[i * 9 + j], ref[j], 2e-5) << i << " " << j;
  }
  EXPECT_LT(mean.norm(), 5 * std::sqrt(1.0 / k));  // E[w] = 0, each component has variance 1/3
  // A new iteration draws new directions; the same one draws the same.
  basis.draw(5, 18);
  EXPECT_NE(basis.dirs().download_row_major(), dirs);
  basis.draw(5, 17);
  EXPECT_EQ(basis.dirs().download_row_major(), dirs);
}

// ---- environment light (S_env) ---------------------------------------------------------------------------

namespace {

// A random environment: texels of independent RGB spread over two decades, so the importance weights
// E / (pdf N_e) differ per channel and per direction.
EnvironmentLight random_environment(int width, int height, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(0, 1);
  Image img(width, height, 3);
  for (auto& v : img.pixels) v = 0.05f * std::pow(10.0f, 2.0f * u(rng));
  return EnvironmentLight(img, 1.5f, false);
}

void attach(RayScene& s, const render::EnvironmentSamples& env) {
  s.env_dirs = env.dirs().download_row_major();
  s.env_weights = env.weights().download_row_major();
}

// The colour under an environment against the double reference; the environment must contribute visibly (the
// same scene with every environment direction occluded is darker), or the comparison would mean little.
void expect_environment_forward(const Device& dev, const RayScene& s, int lmax, const render::EnvironmentSamples& env) {
  const auto got = run_device(dev, s, lmax, std::vector<float>(3 * s.n_rays, 1.f), false, &env);
  const auto ref = reference_color(s, s.props);
  RayScene dark = s;
  for (std::uint32_t i = 0; i < s.n_rays * s.n_samples; ++i)
    for (std::uint32_t j = 0; j < s.n_env; ++j) dark.props[i * s.cols() + s.env_col() + j] = 0;
  const auto ref_dark = reference_color(dark, dark.props);
  double env_part = 0;
  for (std::size_t i = 0; i < ref.size(); ++i) {
    EXPECT_NEAR(got.color[i], ref[i], 2e-5 * std::abs(ref[i]) + 1e-6) << "lmax " << lmax << " value " << i;
    env_part += (ref[i] - ref_dark[i]) / ref.size();
  }
  EXPECT_GT(env_part, 0.05) << "the environment must contribute visibly for the comparison to mean something";
}

}  // namespace

TEST_P(RendererVariant, EnvironmentForwardMatchesDoubleReference) {
  const Device dev = test::test_device();
  const EnvironmentLight light = random_environment(16, 8, 2);
  for (const int lmax : {-1, 2}) {
    RayScene s = random_scene(7, 32, lmax, 16, 40 + lmax, 32);
    render::EnvironmentSamples env(dev, light, 32);
    env.draw(7, 3);
    attach(s, env);
    if (lmax < 0)  // the environment alone: no point light
      for (std::uint32_t i = 0; i < s.n_rays * s.n_samples; ++i) s.props[i * s.cols() + render::kVisibility] = 0;
    expect_environment_forward(dev, s, lmax, env);
  }
}

namespace {

// The backward pass under an environment against finite differences (scene, environment and weights drawn
// from the seeds), and gradient isolation on every sample, not only the checked ones: all visibility columns
// are exactly zero, although the colour depends on them.
void expect_environment_backward(bool brdf, std::uint32_t scene_seed, std::uint32_t env_seed, std::uint32_t draw_seed,
                                 std::uint32_t draw_iteration, std::uint32_t weight_seed) {
  const Device dev = test::test_device();
  const int lmax = 1;
  RayScene s = random_scene(3, 16, lmax, 8, scene_seed, 8, brdf);
  render::EnvironmentSamples env(dev, random_environment(8, 4, env_seed), 8);
  env.draw(draw_seed, draw_iteration);
  attach(s, env);
  const auto w = random_weights(3 * s.n_rays, weight_seed);
  const auto got = run_device(dev, s, lmax, w, false, &env);
  EXPECT_GT(expect_gradients_match_finite_differences(s, w, got.d_props, false, 5), 200);
  for (std::uint32_t i = 0; i < s.n_rays * s.n_samples; ++i) {
    ASSERT_EQ(got.d_props[i * s.cols() + render::kVisibility], 0.0f) << i;
    for (std::uint32_t j = 0; j < s.n_env; ++j) ASSERT_EQ(got.d_props[i * s.cols() + s.env_col() + j], 0.0f) << i;
  }
}

}  // namespace

TEST_P(RendererVariant, EnvironmentBackwardMatchesFiniteDifferencesAndIsolatesVisibility) {
  expect_environment_backward(false, 6, 5, 1, 9, 4);
}

// Known answer: a uniform environment of radiance E, visibility 1 and no other light: S_env estimates
// int p(w_o, w; g) E dw = E for any g (the phase integrates to 1). Averaged over many draws (iterations),
// every sample's radiance (albedo 1) must be E within its standard error.
TEST(VolumeRendererEnvironment, UniformEnvironmentGivesItsRadianceForAnyG) {
  const Device dev = test::test_device();
  const std::uint32_t n_env = 32, n_draws = 2000, n = 16;
  const Vec3 E(0.7, 1.3, 2.1);
  render::EnvironmentSamples env(dev, EnvironmentLight::uniform({0.7f, 1.3f, 2.1f}, false), n_env);
  VolumeRenderer renderer(dev, {n, -1, 1, false, n_env});
  const auto rec = render::ray_record({-3, 0.2f, 0.1f}, {1, 0, 0}, {0, 5, 0}, {100, 100, 100});
  Buffer<float> rays(dev, std::vector<float>(rec.begin(), rec.end())), t(dev, n), delta(dev, n), color(dev, 3),
      trans(dev, 1);
  BatchMatrix pos(dev, n, 3), props(dev, n, renderer.prop_cols()), rad(dev, n, 3), none(dev, 1, 3), basis(dev, 1, 0);
  std::vector<float> pv(n * renderer.prop_cols(), 1.0f);  // sigma, albedo, V_env = 1
  for (std::uint32_t i = 0; i < n; ++i) {
    pv[i * renderer.prop_cols() + render::kG] = -0.8f + 1.6f * i / (n - 1);  // g from -0.8 to 0.8
    pv[i * renderer.prop_cols() + render::kVisibility] = 0.0f;               // no point light
  }
  props.upload_row_major(pv);
  renderer.sample(rays, 1, false, 0, t, delta, pos);
  std::vector<double> sum(3 * n, 0.0), sum_sq(3 * n, 0.0);
  for (std::uint32_t it = 0; it < n_draws; ++it) {
    env.draw(11, it);
    renderer.forward(rays, 1, t, delta, props, none, basis, rad, color, trans, &env);
    const auto r = rad.download_row_major();
    for (std::uint32_t i = 0; i < 3 * n; ++i) sum[i] += r[i], sum_sq[i] += double(r[i]) * r[i];
  }
  for (std::uint32_t i = 0; i < n; ++i)
    for (int ch = 0; ch < 3; ++ch) {
      const double mean = sum[3 * i + ch] / n_draws;
      const double se = std::sqrt(std::max(sum_sq[3 * i + ch] / n_draws - mean * mean, 0.0) / n_draws);
      EXPECT_NEAR(mean, E[ch], 4 * se + 1e-4 * E[ch]) << "g " << pv[i * renderer.prop_cols() + render::kG];
      EXPECT_LT(se, 0.02 * E[ch]) << "too noisy to tell: g " << pv[i * renderer.prop_cols() + render::kG];
    }
}

TEST(VolumeRendererEnvironment, EnvironmentSamplesAreRequiredExactlyWithEnvironmentDirections) {
  const Device dev = test::test_device();
  const EnvironmentLight light = EnvironmentLight::uniform({1, 1, 1}, false);
  render::EnvironmentSamples env4(dev, light, 4), env8(dev, light, 8);
  EXPECT_THROW(VolumeRenderer(dev, {16, -1, 4, false, 5000}), InvalidArgument);
  VolumeRenderer with_env(dev, {16, -1, 4, false, 4}), without(dev, {16, -1, 4});
  EXPECT_EQ(with_env.prop_cols(), 10u);
  EXPECT_EQ(with_env.env_visibility_col(), 6u);
  EXPECT_EQ(VolumeRenderer(dev, {16, 2, 4, false, 32}).env_visibility_col(), render::env_visibility_column(9));
  EXPECT_EQ(VolumeRenderer(dev, {16, 2, 4, false, 32}).prop_cols(), 6u + 27u + 32u);
  Buffer<float> rays(dev, kRayFloats), t(dev, 16), delta(dev, 16), color(dev, 3), trans(dev, 1), dcol(dev, 3);
  BatchMatrix props(dev, 16, 10), props6(dev, 16, 6), rad(dev, 16, 3), drad(dev, 16, 3), dprops(dev, 16, 10),
      dirs(dev, 4, 3), basis(dev, 4, 0);
  auto expect_message = [](auto&& call, const std::string& part) {
    try {
      call();
      ADD_FAILURE() << "expected InvalidArgument mentioning '" << part << "'";
    } catch (const InvalidArgument& e) {
      EXPECT_NE(std::string(e.what()).find(part), std::string::npos) << e.what();
    }
  };
  expect_message([&] { with_env.forward(rays, 1, t, delta, props, dirs, basis, rad, color, trans); },
                 "EnvironmentSamples");
  expect_message([&] { with_env.backward(rays, 1, t, delta, props, dirs, basis, rad, color, dcol, drad, dprops); },
                 "EnvironmentSamples");
  expect_message([&] { with_env.forward(rays, 1, t, delta, props, dirs, basis, rad, color, trans, &env8); },
                 "n_env_dirs = 4");
  expect_message([&] { without.forward(rays, 1, t, delta, props6, dirs, basis, rad, color, trans, &env4); },
                 "n_env_dirs");
  // The property matrix must carry the environment's visibility columns.
  expect_message([&] { with_env.forward(rays, 1, t, delta, props6, dirs, basis, rad, color, trans, &env4); },
                 "n_env_dirs");
  EXPECT_NO_THROW(with_env.forward(rays, 1, t, delta, props, dirs, basis, rad, color, trans, &env4));
  dev.finish();  // leave no work queued when the process exits
}

// ---- scattering "brdf" (solids, "Ours + BRDF", docs/design.md §4.4) -----------------------------------------------

namespace {

VolumeRendererSettings brdf_settings(std::uint32_t n_samples, int lmax, std::uint32_t n_dirs, std::uint32_t n_env = 0) {
  VolumeRendererSettings rs{n_samples, lmax, n_dirs, false, n_env};
  rs.scattering = "brdf";
  return rs;
}

void expect_invalid_argument(const std::function<void()>& call, const std::string& part) {
  try {
    call();
    ADD_FAILURE() << "expected InvalidArgument mentioning '" << part << "'";
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find(part), std::string::npos) << e.what();
  }
}

}  // namespace

TEST(VolumeRendererBrdf, PropertyColumnsEndWithTheRawNormal) {
  const Device dev = test::test_device();
  static_assert(render::normal_column(4, 8) == 6 + 12 + 8);
  static_assert(render::kRoughness == render::kG);
  const VolumeRenderer plain(dev, brdf_settings(16, 1, 8)), with_env(dev, brdf_settings(16, 1, 8, 8));
  EXPECT_TRUE(plain.brdf());
  EXPECT_EQ(plain.normal_col(), 6u + 12u);
  EXPECT_EQ(plain.prop_cols(), 6u + 12u + 3u);
  EXPECT_EQ(with_env.env_visibility_col(), 18u);
  EXPECT_EQ(with_env.normal_col(), render::normal_column(4, 8));
  EXPECT_EQ(with_env.prop_cols(), 18u + 8u + 3u);
  const VolumeRenderer phase(dev, {16, 1, 8, false, 8});
  EXPECT_FALSE(phase.brdf());
  EXPECT_EQ(phase.prop_cols(), phase.normal_col());  // no normal columns in phase mode
  // A property matrix without the normal's columns is an error that names them.
  Buffer<float> rays(dev, kRayFloats), t(dev, 16), delta(dev, 16), color(dev, 3), trans(dev, 1);
  BatchMatrix props(dev, 16, phase.prop_cols() - 8), rad(dev, 16, 3), dirs(dev, 8, 3), basis(dev, 8, 4);
  expect_invalid_argument([&] { plain.forward(rays, 1, t, delta, props, dirs, basis, rad, color, trans); },
                          "3 normal columns");
  dev.finish();
}

TEST(VolumeRendererBrdf, ClosedFormIndirectAndUnknownScatteringAreErrors) {
  const Device dev = test::test_device();
  VolumeRendererSettings rs = brdf_settings(16, 1, 8);
  rs.closed_form_indirect = true;
  expect_invalid_argument([&] { VolumeRenderer(dev, rs); }, "closed_form_indirect");
  rs.closed_form_indirect = false;
  rs.scattering = "BRDF";
  expect_invalid_argument([&] { VolumeRenderer(dev, rs); }, "\"phase\" (media) or \"brdf\" (solids)");
}

TEST_P(RendererVariant, BrdfForwardMatchesDoubleReference) {
  for (const int lmax : {-1, 1}) {
    const RayScene s = random_scene(7, 32, lmax, 16, 61 + lmax, 0, true);
    const auto got = run_device(test::test_device(), s, lmax, std::vector<float>(3 * s.n_rays, 1.f));
    const auto ref = reference_color(s, s.props);
    for (std::size_t i = 0; i < ref.size(); ++i)
      EXPECT_NEAR(got.color[i], ref[i], 2e-5 * std::abs(ref[i]) + 1e-6) << "lmax " << lmax << " value " << i;
    EXPECT_GT(mean_scattered(s), 0.5) << "the scattered light must show for the comparison to mean something";
  }
}

TEST_P(RendererVariant, BrdfForwardWithEnvironmentMatchesDoubleReference) {
  const Device dev = test::test_device();
  const EnvironmentLight light = random_environment(16, 8, 3);
  for (const int lmax : {-1, 1}) {
    RayScene s = random_scene(7, 32, lmax, 16, 71 + lmax, 32, true);
    render::EnvironmentSamples env(dev, light, 32);
    env.draw(8, 2);
    attach(s, env);
    expect_environment_forward(dev, s, lmax, env);
  }
}

TEST_P(RendererVariant, BrdfBackwardMatchesFiniteDifferencesOfTheReference) {
  const int lmax = 1;
  const RayScene s = random_scene(3, 16, lmax, 8, 15, 0, true);
  const auto w = random_weights(3 * s.n_rays, 13);
  const auto got = run_device(test::test_device(), s, lmax, w);
  EXPECT_GT(expect_gradients_match_finite_differences(s, w, got.d_props, false, 3), 200);
  // The checks must be about something: the roughness and the normal get gradient on most samples.
  int rough = 0, normal = 0;
  for (std::uint32_t i = 0; i < s.n_rays * s.n_samples; ++i) {
    rough += got.d_props[i * s.cols() + render::kRoughness] != 0.0f;
    normal += got.d_props[i * s.cols() + s.normal_col()] != 0.0f;
  }
  EXPECT_GT(rough, 24);
  EXPECT_GT(normal, 24);
}

TEST_P(RendererVariant, BrdfBackwardWithEnvironmentMatchesFiniteDifferencesAndIsolatesVisibility) {
  expect_environment_backward(true, 16, 6, 2, 5, 14);
}

// The renderer's "brdf" mode and the path tracer shade with the same BRDF: each sample's radiance under a
// point light equals the path tracer's f(w_o, w_l) max(0, n.w_l) (probe kernel) times V I / |p_l - x|^2.
TEST(VolumeRendererBrdf, RadianceMatchesThePathTracersBrdf) {
  const Device dev = test::test_device();
  const RayScene s = random_scene(8, 16, -1, 4, 81, 0, true);
  const std::uint32_t n = s.n_rays * s.n_samples;
  VolumeRenderer renderer(dev, brdf_settings(16, -1, 4));
  Buffer<float> rays(dev, s.rays), t(dev, n), delta(dev, n), color(dev, 3 * s.n_rays), trans(dev, s.n_rays);
  BatchMatrix pos(dev, n, 3), props(dev, n, s.cols()), rad(dev, n, 3), dirs(dev, 4, 3), basis(dev, 4, 0);
  props.upload_row_major(std::vector<float>(s.props.begin(), s.props.end()));
  renderer.sample(rays, s.n_rays, false, 0, t, delta, pos);
  renderer.forward(rays, s.n_rays, t, delta, props, dirs, basis, rad, color, trans);
  const auto x = pos.download_row_major(), radiance = rad.download_row_major();
  std::vector<cl_float4> records;
  std::vector<Vec3> light;  // V I / |p_l - x|^2 per sample
  for (std::uint32_t i = 0; i < n; ++i) {
    const float* ray = &s.rays[(i / s.n_samples) * kRayFloats];
    const double* p = &s.props[i * s.cols()];
    const Vec3 to_light =
        reference::field3(ray, render::kRayLightPosition) - Vec3(x[3 * i], x[3 * i + 1], x[3 * i + 2]);
    const Vec3 nrm = Vec3(p[s.normal_col()], p[s.normal_col() + 1], p[s.normal_col() + 2]).normalized();
    const Vec3 wl = to_light.normalized();
    records.push_back({{float(nrm.x()), float(nrm.y()), float(nrm.z()), float(p[render::kRoughness])}});
    records.push_back(
        {{-ray[render::kRayDirection], -ray[render::kRayDirection + 1], -ray[render::kRayDirection + 2], 0}});
    records.push_back({{float(wl.x()), float(wl.y()), float(wl.z()), 0}});
    records.push_back({{float(p[1]), float(p[2]), float(p[3]), 0}});
    light.push_back(p[render::kVisibility] / to_light.squaredNorm() *
                    reference::field3(ray, render::kRayLightIntensity));
  }
  Buffer<cl_float4> in(dev, records), out(dev, n);
  dev.kernel("pathtrace_probe.cl", "probe_brdf_cos").args(cl_uint(n), in, out).launch(n, 16);
  const auto f_cos = out.read();
  int lit = 0;
  for (std::uint32_t i = 0; i < n; ++i)
    for (int ch = 0; ch < 3; ++ch) {
      const double expected = f_cos[i].s[ch] * light[i][ch];
      EXPECT_NEAR(radiance[3 * i + ch], expected, 1e-4 * std::abs(expected) + 1e-6)
          << "sample " << i << " channel " << ch;
      lit += ch == 0 && expected > 1e-3;
    }
  EXPECT_GT(lit, int(n / 3)) << "many samples must face both the camera and the light";
}

INSTANTIATE_TEST_SUITE_P(VolumeRenderer, RendererVariant, ::testing::Values("simd", "workgroup", "workgroup_unstaged"),
                         [](const ::testing::TestParamInfo<std::string>& info) { return info.param; });

// Every sum of the work-group kernels has one order: two runs give the same bits.
TEST(VolumeRenderer, WorkGroupKernelsAreBitForBitDeterministic) {
  const int lmax = 1;
  const RayScene s = random_scene(5, 32, lmax, 8, 91);
  const auto w = random_weights(3 * s.n_rays, 92);
  g_variant = "workgroup";
  const auto a = run_device(test::test_device(), s, lmax, w), b = run_device(test::test_device(), s, lmax, w);
  g_variant = "auto";
  EXPECT_EQ(a.color, b.color);
  EXPECT_EQ(a.transmittance, b.transmittance);
  EXPECT_EQ(a.d_props, b.d_props);
}

TEST(VolumeRenderer, KernelVariantFollowsTheTableSettingsAndEnvironment) {
  // The test sets RELIT_RENDER_VARIANT itself; a value the suite runs under is put back at the end (ScopedEnv).
  std::optional<test::ScopedEnv> env;
  env.emplace("RELIT_RENDER_VARIANT", std::nullopt);
  const test::TableDevices d;
  const DeviceInfo &cpu = d.cpu, &nvidia = d.nvidia, &amd = d.amd, &intel = d.intel, &other = d.other;
  EXPECT_EQ(VolumeRenderer::device_default(cpu).variant, KernelVariant::Simd);
  EXPECT_TRUE(VolumeRenderer::device_default(cpu).tuned);
  for (const DeviceInfo* gpu : {&nvidia, &amd, &intel, &other}) {
    const auto g = VolumeRenderer::device_default(*gpu);
    EXPECT_EQ(g.variant, KernelVariant::WorkGroup) << gpu->vendor;
    EXPECT_FALSE(g.tuned) << gpu->vendor;  // no GPU was measured
  }
  EXPECT_NE(VolumeRenderer::device_default(amd).source.find("AMD"), std::string::npos);
  EXPECT_EQ(VolumeRenderer::device_default(intel).workgroup.items, 32u);

  // The settings' kernel_variant, then RELIT_RENDER_VARIANT over it, then set_kernels() over both.
  const Device dev = test::test_device();
  VolumeRendererSettings simd_settings{48, 1, 8}, wg_settings{48, 1, 8};
  simd_settings.kernel_variant = "simd";
  wg_settings.kernel_variant = "workgroup";
  EXPECT_EQ(VolumeRenderer(dev, simd_settings).kernel_choice().variant, KernelVariant::Simd);
  const VolumeRenderer wg(dev, wg_settings);
  EXPECT_EQ(wg.kernel_choice().variant, KernelVariant::WorkGroup);
  EXPECT_EQ(wg.kernel_choice().source, "kernel_variant");
  EXPECT_EQ(wg.kernel_choice().workgroup.items, 16u) << "a power of two that divides 48 samples";
  EXPECT_EQ(VolumeRenderer(dev, {48, 1, 8}).kernel_choice().variant,
            VolumeRenderer::default_kernels(dev.info()).variant);
  ::setenv("RELIT_RENDER_VARIANT", "workgroup", 1);
  VolumeRenderer forced(dev, simd_settings);
  EXPECT_EQ(forced.kernel_choice().variant, KernelVariant::WorkGroup);
  EXPECT_EQ(forced.kernel_choice().source, "RELIT_RENDER_VARIANT");
  EXPECT_FALSE(VolumeRenderer::default_kernels(cpu).tuned);
  forced.set_kernels(KernelVariant::Simd);
  EXPECT_EQ(forced.kernel_choice().variant, KernelVariant::Simd);
  EXPECT_EQ(forced.kernel_choice().source, "set_kernels()");
  ::setenv("RELIT_RENDER_VARIANT", "gpu", 1);
  EXPECT_THROW(VolumeRenderer::default_kernels(cpu), InvalidArgument);
  env.reset();

  EXPECT_THROW(forced.set_kernels(KernelVariant::WorkGroup, VolumeRenderer::WorkGroupParams{0, true}), InvalidArgument);
  VolumeRendererSettings bad{16, 1, 8};
  bad.kernel_variant = "gpu";
  EXPECT_THROW(VolumeRenderer(dev, bad), InvalidArgument);
}

}  // namespace relit
