// relit bench: portable benchmarks across OpenCL devices. Every case is verified against a reference before it
// is timed (a wrong result is reported as a failure, never as a time); the first call (kernel builds + first
// launch), a warm-up and `repeats` timed runs are kept apart; results go to a table and to JSON, and
// `relit bench --compare a.json b.json` prints the ratios between two runs (e.g. two devices).
#include "cli.hpp"

#include <relit/verify/hashgrid_reference.hpp>  // the double-precision references, shared with the tests
#include <relit/verify/mlp_reference.hpp>
#include <relit/verify/peak_reference.hpp>
#include <relit/verify/renderer_reference.hpp>

#include <relit/cl/program.hpp>
#include <relit/dataset.hpp>
#include <relit/io/file.hpp>
#include <relit/log.hpp>
#include <relit/method/presets.hpp>
#include <relit/method/render_image.hpp>
#include <relit/method/trainer.hpp>
#include <relit/nn/encodings.hpp>
#include <relit/nn/optimizer.hpp>
#include <relit/nn/registry.hpp>
#include <relit/pathtrace.hpp>
#include <relit/render/volume_renderer.hpp>
#include <relit/scene/scene.hpp>
#include <relit/version.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <iostream>
#include <map>
#include <memory>
#include <optional>
#include <thread>
#include <unistd.h>

namespace relit::cli {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

double seconds(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

struct BenchOptions {
  std::string device, suite = "all", json;
  std::vector<std::string> compare;
  std::uint32_t repeats = 5;
  bool quick = false;
  std::string inject_error;             // a case whose result is corrupted before verification (tests the failure path)
  std::string filter;                   // run only the cases whose name contains this
  std::string mlp_variant = "auto";     // the MLP kernels: auto (the device's choice), simd, workgroup or all
  std::string kernel_variant = "auto";  // the hash-grid and renderer kernels: the same choices
  double peak_seconds = 0;              // length of one peak launch; 0: 0.25 s (0.05 s with --quick)
};

// One benchmark case. run() does one unit of work and waits for the device; verify() checks the results of the
// last run() against a reference and returns the worst error over its tolerance (<= 1 passes).
struct Case {
  std::string name, family;
  double flops = 0;  // per run, 0 when not meaningful
  double work = 0;   // units per run (samples, rays, steps...)
  std::string unit;  // "samples", ...
  std::function<void()> run;
  std::function<double()> verify;
  std::function<void()> corrupt;  // makes the last result wrong (--inject-error)
  std::function<Json()> kernels;  // which kernels ran (after run()), for the report; may be empty
};

struct Result {
  std::string name, family, unit, status = "ok", error;
  Json kernels;
  double worst = 0, first_call = 0, warmup = 0, median = 0, min = 0, max = 0, flops = 0, work = 0;
  std::uint32_t repeats = 0;
};

Result measure(const Case& c, const BenchOptions& o) {
  Result r;
  r.name = c.name;
  r.family = c.family;
  r.unit = c.unit;
  r.flops = c.flops;
  r.work = c.work;
  try {
    auto t0 = Clock::now();
    c.run();  // kernel builds (unless cached) and first launch
    r.first_call = seconds(t0);
    if (c.kernels) r.kernels = c.kernels();
    if (o.inject_error == c.name && c.corrupt) c.corrupt();
    r.worst = c.verify();
    if (!(r.worst <= 1.0)) {
      r.status = "failed";
      r.error = "result differs from the reference (worst error / tolerance = " + std::to_string(r.worst) + ")";
      return r;
    }
    t0 = Clock::now();
    c.run();
    r.warmup = seconds(t0);
    std::vector<double> t;
    for (std::uint32_t i = 0; i < o.repeats; ++i) {
      t0 = Clock::now();
      c.run();
      t.push_back(seconds(t0));
    }
    std::sort(t.begin(), t.end());
    r.repeats = o.repeats;
    r.median = t[t.size() / 2];
    r.min = t.front();
    r.max = t.back();
  } catch (const std::exception& e) {
    r.status = "failed";
    r.error = e.what();
  }
  return r;
}

// ---- verification helpers ----------------------------------------------------------------------------------

std::vector<float> random_floats(std::size_t n, std::uint32_t seed, float lo = -1.0f, float hi = 1.0f) {
  return reference::random_vector(n, seed, lo, hi);
}

// max_i |got_i - want_i| / (rtol * (|want_i| + scale)) with `scale` the mean magnitude of `want`.
template <class Got, class Want>
double worst_ratio(const Got& got, const Want& want, double rtol) {
  double scale = 0;
  for (double w : want) scale += std::fabs(w);
  scale = scale / std::max<std::size_t>(1, want.size()) + 1e-30;
  double worst = 0;
  for (std::size_t i = 0; i < want.size(); ++i) {
    const double e = std::fabs(double(got[i]) - double(want[i])) / (rtol * (std::fabs(double(want[i])) + scale));
    worst = std::max(worst, std::isfinite(e) ? e : 1e30);
  }
  return worst;
}

reference::Mat rows_of(const std::vector<float>& row_major, std::uint32_t rows, std::uint32_t cols) {
  reference::Mat m(rows, cols);
  for (std::uint32_t s = 0; s < rows; ++s)
    for (std::uint32_t f = 0; f < cols; ++f) m(s, f) = row_major[std::size_t(s) * cols + f];
  return m;
}

// ---- kernel cases ------------------------------------------------------------------------------------------

// The calibrated FMA peak (kernels/peak.cl): independent accumulator chains, lane-varying data, result stored,
// each launch sized to run --peak-seconds (reference::PeakKernel says why a short launch under-reports).
void add_peak(std::vector<Case>& cases, const Device& device, const BenchOptions& o) {
  const double target = o.peak_seconds > 0 ? o.peak_seconds : (o.quick ? 0.05 : 0.25);
  for (const auto& [name, lanes] : reference::kPeakKernels) {
    const std::size_t items = std::size_t(std::max(1u, device.info().compute_units)) * 256;
    auto buf = std::make_shared<Buffer<float>>(device, items);
    auto peak = std::make_shared<reference::PeakKernel>(device, name, lanes, items);
    peak->calibrate(device, *buf, target);
    Case c;
    c.name = name;
    c.family = "peak";
    c.flops = peak->flops();
    c.run = [=] { peak->launch(device, *buf); };
    c.verify = [=] { return peak->verify(*buf); };
    c.corrupt = [=] { buf->fill(-1.0f); };
    cases.push_back(c);
  }
}

// Fused MLPs of the method: width 64 (32→64³→16), 128 (32→128⁴→16), 256 (the paper trunk: 63→256⁸→16, skip at 4).
struct MlpSpec {
  std::string name;
  std::uint32_t n_in, width, hidden, n_out, skip;
};

// `variant`: "auto" (the device's choice; the cases keep their plain names), "simd" or "workgroup" (that
// variant with the device's parameters for it; with `suffix`, the cases are named mlp_w64_forward_simd /
// _wg).
void add_mlp(std::vector<Case>& cases, const Device& device, bool quick, const std::string& variant, bool suffix) {
  const std::uint32_t batch = quick ? 2048 : 76800, check_rows = 128;
  const std::string tag = !suffix ? "" : variant == "simd" ? "_simd" : "_wg";
  for (const MlpSpec& spec :
       {MlpSpec{"w64", 32, 64, 3, 16, 0}, MlpSpec{"w128", 32, 128, 4, 16, 0}, MlpSpec{"w256", 63, 256, 8, 16, 4}}) {
    Json cfg = {{"type", "FullyFusedMLP"}, {"n_neurons", spec.width}, {"n_hidden_layers", spec.hidden}};
    if (spec.skip) cfg["skip_layers"] = {spec.skip};
    std::shared_ptr<nn::Network> net = nn::create_network(cfg, spec.n_in, spec.n_out);
    auto* mlp = dynamic_cast<nn::FullyFusedMLP*>(net.get());
    const auto row = nn::FullyFusedMLP::device_default(device.info());
    if (variant == "simd") mlp->set_blocking(row.blocking);
    if (variant == "workgroup") mlp->set_workgroup(row.workgroup);
    auto kernels = [net, device] {
      const auto c = dynamic_cast<const nn::FullyFusedMLP&>(*net).kernel_choice(device);
      const bool simd = c.variant == nn::FullyFusedMLP::Variant::Simd;
      return Json{{"variant", nn::FullyFusedMLP::variant_name(c.variant)},
                  {"parameters", simd ? c.blocking.str() : c.workgroup.str()},
                  {"source", c.source},
                  {"tuned", c.tuned}};
    };
    std::vector<float> host_params(net->n_params());
    net->initialize_params(host_params.data(), 7);
    auto params = std::make_shared<Buffer<float>>(device, host_params);
    auto grads = std::make_shared<Buffer<float>>(device, net->n_params());
    const auto x_host = random_floats(std::size_t(batch) * spec.n_in, 3);
    auto x = std::make_shared<nn::BatchMatrix>(device, batch, spec.n_in);
    x->upload_row_major(x_host);
    auto y = std::make_shared<nn::BatchMatrix>(device, batch, spec.n_out);
    auto dy = std::make_shared<nn::BatchMatrix>(device, batch, spec.n_out);
    const auto dy_host = random_floats(std::size_t(batch) * spec.n_out, 4);
    dy->upload_row_major(dy_host);
    auto dx = std::make_shared<nn::BatchMatrix>(device, batch, spec.n_in);
    std::shared_ptr<nn::Workspace> ws = net->make_workspace(device);
    double flops = 0;
    for (std::uint32_t l = 0; l <= mlp->n_hidden_layers(); ++l)
      flops += 2.0 * mlp->layer_inputs(l) * mlp->layer_outputs(l);
    flops *= batch;

    Case f;
    f.name = "mlp_" + spec.name + "_forward" + tag;
    f.family = "mlp";
    f.flops = flops;
    f.work = batch;
    f.unit = "samples";
    f.run = [=] {
      net->inference(device, {params.get(), 0}, *x, *y);
      device.finish();
    };
    f.verify = [=] {
      reference::MlpReference ref(*mlp, host_params);
      const auto want = ref.forward(rows_of(x_host, check_rows, spec.n_in));
      const auto got = y->download_row_major();
      std::vector<double> w(want.size());
      for (std::uint32_t s = 0; s < check_rows; ++s)
        for (std::uint32_t j = 0; j < spec.n_out; ++j) w[s * spec.n_out + j] = want(s, j);
      return worst_ratio(got, w, 1e-4);
    };
    f.corrupt = [=] { y->data().fill(0.5f); };
    f.kernels = kernels;
    cases.push_back(f);

    // Training step: forward with saved activations, dL/dinput and dL/dweights. Verified on a 256-sample batch
    // through the same kernels: the weight gradient sums over every sample, and on large batches of deep ReLU
    // nets a pre-activation within float rounding of 0 takes the other side of the ReLU in the double
    // reference now and then (one sample's whole term moves), which says nothing about the kernels.
    Case t;
    t.name = "mlp_" + spec.name + "_train" + tag;
    t.family = "mlp";
    t.flops = 3 * flops;
    t.work = batch;
    t.unit = "samples";
    t.run = [=] {
      net->forward(device, {params.get(), 0}, *x, *y, *ws);
      net->backward(device, {params.get(), 0}, *x, *y, *dy, {grads.get(), 0}, false, dx.get(), *ws);
      device.finish();
    };
    t.verify = [=] {
      const std::uint32_t rows = std::min<std::uint32_t>(batch, 256);
      if (rows != batch) {
        nn::BatchMatrix xs(device, rows, spec.n_in), ys(device, rows, spec.n_out), dys(device, rows, spec.n_out),
            dxs(device, rows, spec.n_in);
        xs.upload_row_major(std::vector<float>(x_host.begin(), x_host.begin() + std::size_t(rows) * spec.n_in));
        dys.upload_row_major(std::vector<float>(dy_host.begin(), dy_host.begin() + std::size_t(rows) * spec.n_out));
        auto w2 = net->make_workspace(device);
        net->forward(device, {params.get(), 0}, xs, ys, *w2);
        net->backward(device, {params.get(), 0}, xs, ys, dys, {grads.get(), 0}, false, &dxs, *w2);
      }
      reference::MlpReference ref(*mlp, host_params);
      const auto xr = rows_of(x_host, rows, spec.n_in);
      ref.forward(xr);
      std::vector<double> want;
      reference::Mat dxr;
      ref.backward(xr, rows_of(dy_host, rows, spec.n_out), want, dxr);
      return worst_ratio(grads->read(), want, 1e-3);
    };
    t.corrupt = [=] { grads->fill(1.0f); };
    t.kernels = kernels;
    cases.push_back(t);
  }
}

// The variant `variant` names ("auto": none forced), and the suffix of its cases' names when both run.
std::optional<KernelVariant> forced_variant(const std::string& variant) {
  return variant == "auto" ? std::nullopt : parse_kernel_variant(variant, "--kernel-variant");
}
std::string variant_tag(const std::string& variant, bool suffix) {
  return !suffix ? "" : variant == "simd" ? "_simd" : "_wg";
}

void add_hashgrid(std::vector<Case>& cases, const Device& device, bool quick, const std::string& variant, bool suffix) {
  // The issue's grid: 16 levels x 2 features, 2^19 entries per level, 3-D positions.
  const Json cfg = {{"type", "HashGrid"},      {"n_levels", 16},        {"n_features_per_level", 2},
                    {"log2_hashmap_size", 19}, {"base_resolution", 16}, {"per_level_scale", 1.5}};
  std::shared_ptr<nn::Encoding> enc = nn::create_encoding(cfg, 3);
  auto* grid = dynamic_cast<nn::HashGridEncoding*>(enc.get());
  grid->set_kernels(forced_variant(variant));
  const std::uint32_t batch = quick ? 4096 : 76800, check_rows = 256;
  std::vector<float> host_params(enc->n_params());
  enc->initialize_params(host_params.data(), 5);
  for (float& p : host_params) p *= 1e4f;  // O(1) outputs
  auto params = std::make_shared<Buffer<float>>(device, host_params);
  auto grads = std::make_shared<Buffer<float>>(device, enc->n_params());
  const auto x_host = random_floats(std::size_t(batch) * 3, 9, 0.0f, 1.0f);
  auto x = std::make_shared<nn::BatchMatrix>(device, batch, 3);
  x->upload_row_major(x_host);
  auto y = std::make_shared<nn::BatchMatrix>(device, batch, enc->n_output_dims());
  auto dy = std::make_shared<nn::BatchMatrix>(device, batch, enc->n_output_dims());
  const auto dy_host = random_floats(std::size_t(batch) * enc->n_output_dims(), 10);
  dy->upload_row_major(dy_host);
  std::shared_ptr<nn::Workspace> ws = enc->make_workspace(device);
  Case c;
  c.name = "hashgrid_forward_backward" + variant_tag(variant, suffix);
  c.family = "encodings";
  c.work = batch;
  c.unit = "samples";
  c.run = [=] {
    enc->forward(device, {params.get(), 0}, *x, 0, *y, 0, ws.get());
    enc->backward(device, {params.get(), 0}, *x, 0, *dy, 0, {grads.get(), 0}, false, nullptr, ws.get());
    device.finish();
  };
  c.verify = [=] {
    const std::uint32_t cols = enc->n_output_dims();
    reference::RowMat xr(check_rows, 3);
    for (std::uint32_t s = 0; s < check_rows; ++s)
      for (int d = 0; d < 3; ++d) xr(s, d) = x_host[s * 3 + d];
    const auto want = reference::reference_forward(*grid, host_params, xr);
    const auto got = y->download_row_major();
    std::vector<double> w(std::size_t(check_rows) * cols);
    for (std::uint32_t s = 0; s < check_rows; ++s)
      for (std::uint32_t j = 0; j < cols; ++j) w[s * cols + j] = want(s, j);
    double worst = worst_ratio(got, w, 1e-5);
    if (quick) {  // the full-batch parameter gradient (the reference walks every sample)
      reference::RowMat xa(batch, 3), da(batch, cols);
      for (std::uint32_t s = 0; s < batch; ++s) {
        for (int d = 0; d < 3; ++d) xa(s, d) = x_host[s * 3 + d];
        for (std::uint32_t j = 0; j < cols; ++j) da(s, j) = dy_host[std::size_t(s) * cols + j];
      }
      worst = std::max(worst, worst_ratio(grads->read(), reference::reference_param_gradient(*grid, xa, da), 1e-4));
    }
    return worst;
  };
  c.corrupt = [=] { y->data().fill(0.0f); };
  c.kernels = [enc, device] {
    const auto& grid = dynamic_cast<const nn::HashGridEncoding&>(*enc);
    const auto k = grid.kernel_choice(device);
    return Json{
        {"of", "HashGrid"},
        {"variant", kernel_variant_name(k.variant)},
        {"parameters", k.variant == KernelVariant::WorkGroup ? k.workgroup.str()
                                                             : "R" + std::to_string(grid.gradient_ranges(device))},
        {"source", k.source},
        {"tuned", k.tuned}};
  };
  cases.push_back(c);
}

void add_adam(std::vector<Case>& cases, const Device& device, bool quick) {
  const std::size_t n = quick ? 100000 : 4000000;  // about the size of the fast preset's θ and ψ
  std::shared_ptr<nn::Optimizer> adam =
      nn::create_optimizer({{"type", "Adam"}, {"learning_rate", 1e-2}, {"epsilon", 1e-15}}, "/optimizer");
  adam->allocate(device, n);
  const auto p0 = random_floats(n, 11), g = random_floats(n, 12);
  auto params = std::make_shared<Buffer<float>>(device, p0);
  auto grads = std::make_shared<Buffer<float>>(device, g);
  Case c;
  c.name = "adam_step";
  c.family = "optimizer";
  c.work = double(n);
  c.unit = "params";
  c.run = [=] {
    adam->step(*params, *grads);
    device.finish();
  };
  // After the first step from zero moments, the bias-corrected update is lr g / (|g| + eps) = lr sign(g).
  c.verify = [=] {
    const auto got = params->read();
    std::vector<double> want(n);
    for (std::size_t i = 0; i < n; ++i)
      want[i] = double(p0[i]) - 1e-2 * double(g[i]) / (std::fabs(double(g[i])) + 1e-15);
    return worst_ratio(got, want, 1e-5);
  };
  c.corrupt = [=] { params->fill(0.0f); };
  cases.push_back(c);
}

// The neural renderer's lighting and compositing (docs/design.md §4.2: HG phase, point light, K = 64 direction SH
// indirect sum with l_max = 5, alpha compositing), forward and backward, on 1200 rays x 64 samples of random
// properties. Verified on a 32-ray scene through the same renderer: colours against the double reference, and
// the backward pass as a directional derivative <dL/dprops, v> against a central difference of the reference.
struct RenderRun {
  std::shared_ptr<render::VolumeRenderer> renderer;
  std::shared_ptr<Buffer<float>> rays, t, delta, color, trans, dcol;
  std::shared_ptr<nn::BatchMatrix> dirs, basis, pos, props, rad, drad, dprops;
  std::uint32_t n_rays = 0;
  RenderRun(const Device& dev, const reference::RayScene& s, std::optional<KernelVariant> variant) : n_rays(s.n_rays) {
    renderer = std::make_shared<render::VolumeRenderer>(
        dev, render::VolumeRendererSettings{s.n_samples, int(std::lround(std::sqrt(double(s.n_sh)))) - 1, s.n_dirs});
    renderer->set_kernels(variant);
    const std::uint32_t n = s.n_rays * s.n_samples;
    rays = std::make_shared<Buffer<float>>(dev, s.rays);
    t = std::make_shared<Buffer<float>>(dev, n);
    delta = std::make_shared<Buffer<float>>(dev, n);
    color = std::make_shared<Buffer<float>>(dev, 3 * s.n_rays);
    trans = std::make_shared<Buffer<float>>(dev, s.n_rays);
    dcol = std::make_shared<Buffer<float>>(dev, random_floats(3 * s.n_rays, 21));
    dirs = std::make_shared<nn::BatchMatrix>(dev, s.n_dirs, 3);
    basis = std::make_shared<nn::BatchMatrix>(dev, s.n_dirs, s.n_sh);
    dirs->upload_row_major(s.dirs);
    basis->upload_row_major(s.basis);
    pos = std::make_shared<nn::BatchMatrix>(dev, n, 3);
    props = std::make_shared<nn::BatchMatrix>(dev, n, s.cols());
    props->upload_row_major(std::vector<float>(s.props.begin(), s.props.end()));
    rad = std::make_shared<nn::BatchMatrix>(dev, n, 3);
    drad = std::make_shared<nn::BatchMatrix>(dev, n, 3);
    dprops = std::make_shared<nn::BatchMatrix>(dev, n, s.cols());
  }
  void run(const Device& dev) const {
    renderer->sample(*rays, n_rays, false, 0, *t, *delta, *pos);
    renderer->forward(*rays, n_rays, *t, *delta, *props, *dirs, *basis, *rad, *color, *trans);
    renderer->backward(*rays, n_rays, *t, *delta, *props, *dirs, *basis, *rad, *color, *dcol, *drad, *dprops);
    dev.finish();
  }
};

void add_renderer(std::vector<Case>& cases, const Device& device, bool quick, const std::string& variant, bool suffix) {
  const std::uint32_t n_rays = quick ? 64 : 1200;
  const std::optional<KernelVariant> forced = forced_variant(variant);
  auto big = std::make_shared<RenderRun>(device, reference::random_scene(n_rays, 64, 5, 64, 1), forced);
  auto small_scene = std::make_shared<reference::RayScene>(reference::random_scene(32, 64, 5, 64, 2));
  auto bad = std::make_shared<bool>(false);
  Case c;
  c.name = "render_forward_backward" + variant_tag(variant, suffix);
  c.family = "renderer";
  c.work = double(n_rays) * 64;
  c.unit = "samples";
  c.run = [=] { big->run(device); };
  c.verify = [=] {
    const reference::RayScene& s = *small_scene;
    RenderRun small(device, s, forced);
    small.run(device);
    const auto want = reference::reference_color(s, s.props);
    double worst = worst_ratio(small.color->read(), want, 1e-4);
    // <dL/dprops, v> for L = w . colour against (L(p + h v) - L(p - h v)) / 2h of the reference; v is zero on
    // the visibility columns, which get no gradient by design.
    const auto w = small.dcol->read();
    const auto dp = small.dprops->download_row_major();
    auto v = random_floats(s.props.size(), 22);
    for (std::size_t i = 0; i < v.size(); ++i)
      if (i % s.cols() == render::kVisibility) v[i] = 0.0f;
    double analytic = 0;
    for (std::size_t i = 0; i < v.size(); ++i) analytic += double(dp[i]) * v[i];
    const double h = 1e-4;
    auto loss = [&](double sign) {
      std::vector<double> p = s.props;
      for (std::size_t i = 0; i < p.size(); ++i) p[i] += sign * h * v[i];
      const auto col = reference::reference_color(s, p);
      double l = 0;
      for (std::size_t i = 0; i < col.size(); ++i) l += w[i] * col[i];
      return l;
    };
    const double fd = (loss(1) - loss(-1)) / (2 * h);
    worst = std::max(worst, std::fabs(analytic - fd) / (1e-3 * (std::fabs(fd) + 1e-3)));
    return *bad ? 1e9 : worst;
  };
  c.corrupt = [=] { *bad = true; };
  c.kernels = [big] {
    const auto& k = big->renderer->kernel_choice();
    return Json{{"of", "renderer"},
                {"variant", kernel_variant_name(k.variant)},
                {"parameters", k.variant == KernelVariant::WorkGroup ? k.workgroup.str() : "T16"},
                {"source", k.source},
                {"tuned", k.tuned}};
  };
  cases.push_back(c);
}

void add_pathtracer(std::vector<Case>& cases, const Device& device, bool quick) {
  // benchmark_pathtracer verifies a white furnace (throws when wrong) and times renders of the default cloud.
  auto last = std::make_shared<PathTraceBenchmark>();
  const int res = quick ? 32 : 128;
  const std::uint32_t spp = quick ? 2 : 16;
  Case c;
  c.name = "pathtrace_cloud";
  c.family = "pathtracer";
  c.work = double(res) * res * spp;
  c.unit = "paths";
  c.run = [=] { *last = benchmark_pathtracer(device, res, spp, 1, quick ? 16 : 64); };
  c.verify = [=] { return last->furnace_sigma / 5.0; };
  c.corrupt = [=] { last->furnace_sigma = 99; };
  cases.push_back(c);
}

// ---- end-to-end cases --------------------------------------------------------------------------------------

// One training iteration of a preset (1200 rays x 64 samples; the baselines' fast presets too) and one relit
// frame (128^2), on a small generated dataset (the cost of a step does not depend on the images' size). Verified: the
// step's losses are finite and a second trainer from the same seed reproduces them exactly (training is deterministic).
void add_e2e(std::vector<Case>& cases, const Device& device, bool quick, const std::string& data_dir) {
  for (const std::string preset : {"fast", "paper", "bi-fast", "nerv-fast", "ours_brdf-fast"}) {
    Json cfg = method::preset(preset);
    cfg["training"]["validate_every"] = 0;
    cfg["training"]["checkpoint_every"] = 0;
    if (quick) {
      cfg["training"]["batch_rays"] = 64;
      cfg["model"]["renderer"]["n_samples"] = 16;
      if (cfg["method"] == "bi") cfg["model"]["renderer"]["n_fine_samples"] = 16;
      if (cfg["method"] == "nerv") cfg["model"]["bounce"]["n_dirs"] = 4;
    }
    auto trainer = std::make_shared<method::Trainer>(device, data_dir, cfg);
    Case c;
    c.name = "train_step_" + preset;
    std::replace(c.name.begin(), c.name.end(), '-', '_');
    c.family = "e2e";
    c.work = double(cfg["training"]["batch_rays"].get<std::uint32_t>());
    c.unit = "rays";
    c.run = [=] {
      trainer->step();
      device.finish();
    };
    auto bad = std::make_shared<bool>(false);
    c.verify = [=] {
      const auto s = trainer->stats();
      method::Trainer again(device, data_dir, cfg);
      again.step();
      const auto s2 = again.stats();
      if (*bad) return 1e9;
      if (!std::isfinite(s.loss) || !std::isfinite(s.visibility_loss)) return 1e9;
      return (s.loss == s2.loss && s.visibility_loss == s2.visibility_loss) ? 0.0 : 1e9;
    };
    c.corrupt = [=] { *bad = true; };
    cases.push_back(c);
    if (preset != "fast") continue;
    const int res = quick ? 32 : 128;
    const Camera cam = Camera::look_at({0, -4, 1}, {0, 0, 0}, {0, 0, 1}, 0.8f, res, res);
    const PointLight light{{3, -3, 2}, {800, 800, 800}};
    auto image = std::make_shared<Image>();
    Case f;
    f.name = "relit_frame_fast";
    f.family = "e2e";
    f.work = double(res) * res;
    f.unit = "rays";
    f.run = [=] { *image = method::render_image(trainer->model(), cam, light); };
    f.verify = [=] {
      const Image again = method::render_image(trainer->model(), cam, light);
      std::vector<double> want(again.pixels.begin(), again.pixels.end());
      return worst_ratio(image->pixels, want, 1e-6);
    };
    f.corrupt = [=] { image->pixels.assign(image->pixels.size(), -1.0f); };
    cases.push_back(f);
  }
}

// ---- reporting ---------------------------------------------------------------------------------------------

Json result_json(const Result& r, double peak) {
  Json j = {{"name", r.name}, {"family", r.family}, {"status", r.status}};
  if (r.status != "ok") {
    j["error"] = r.error;
    return j;
  }
  if (!r.kernels.is_null()) j["kernels"] = r.kernels;
  j["verify_worst_over_tolerance"] = r.worst;
  j["first_call_s"] = r.first_call;
  j["compile_s"] = std::max(0.0, r.first_call - r.median);
  j["warmup_s"] = r.warmup;
  j["median_s"] = r.median;
  j["min_s"] = r.min;
  j["max_s"] = r.max;
  j["repeats"] = r.repeats;
  if (r.flops > 0) {
    j["gflops"] = r.flops / r.median * 1e-9;
    if (peak > 0 && r.family != "peak") j["percent_of_peak"] = 100.0 * r.flops / r.median * 1e-9 / peak;
  }
  if (r.work > 0) j["throughput"] = {{"value", r.work / r.median}, {"unit", r.unit + "/s"}};
  return j;
}

void print_table(const std::string& device, const std::vector<Json>& rows) {
  std::printf("\n%s\n", device.c_str());
  std::printf("  %-28s %-7s %10s %11s %19s %9s %7s %16s\n", "case", "status", "first [s]", "median [ms]", "spread [ms]",
              "GFLOP/s", "% peak", "throughput");
  for (const Json& j : rows) {
    if (j["status"] != "ok") {
      std::printf("  %-28s FAILED  %s\n", j["name"].get<std::string>().c_str(), j["error"].get<std::string>().c_str());
      continue;
    }
    char spread[64], gf[32] = "", pct[32] = "", thr[48] = "";
    std::snprintf(spread, sizeof spread, "%.2f-%.2f", j["min_s"].get<double>() * 1e3, j["max_s"].get<double>() * 1e3);
    if (j.contains("gflops")) std::snprintf(gf, sizeof gf, "%.1f", j["gflops"].get<double>());
    if (j.contains("percent_of_peak")) std::snprintf(pct, sizeof pct, "%.0f", j["percent_of_peak"].get<double>());
    if (j.contains("throughput"))
      std::snprintf(thr, sizeof thr, "%.3g %s", j["throughput"]["value"].get<double>(),
                    j["throughput"]["unit"].get<std::string>().c_str());
    std::printf("  %-28s %-7s %10.3f %11.3f %19s %9s %7s %16s\n", j["name"].get<std::string>().c_str(), "ok",
                j["first_call_s"].get<double>(), j["median_s"].get<double>() * 1e3, spread, gf, pct, thr);
  }
}

int run_compare(const std::vector<std::string>& files) {
  const Json a = parse_json(io::read_file(files[0]), "bench report '" + files[0] + "'"),
             b = parse_json(io::read_file(files[1]), "bench report '" + files[1] + "'");
  auto index = [](const Json& doc, std::size_t d) {
    std::map<std::string, Json> m;
    for (const Json& r : doc.at("devices").at(d).at("results")) m[r.at("name").get<std::string>()] = r;
    return m;
  };
  const std::size_t n = std::min(a.at("devices").size(), b.at("devices").size());
  if (n == 0) throw InvalidArgument("--compare: the files hold no device results");
  for (std::size_t d = 0; d < n; ++d) {
    std::printf("%s  vs  %s\n", a["devices"][d]["device"].get<std::string>().c_str(),
                b["devices"][d]["device"].get<std::string>().c_str());
    std::printf("  %-28s %12s %12s %10s\n", "case", "A [ms]", "B [ms]", "A / B");
    const auto ra = index(a, d), rb = index(b, d);
    for (const auto& [name, x] : ra) {
      auto it = rb.find(name);
      if (it == rb.end()) continue;
      const Json& y = it->second;
      if (x["status"] != "ok" || y["status"] != "ok") {
        std::printf("  %-28s %12s %12s %10s\n", name.c_str(), x["status"] == "ok" ? "" : "failed",
                    y["status"] == "ok" ? "" : "failed", "-");
        continue;
      }
      const double ta = x["median_s"].get<double>(), tb = y["median_s"].get<double>();
      std::printf("  %-28s %12.3f %12.3f %10.2f\n", name.c_str(), ta * 1e3, tb * 1e3, ta / tb);
    }
  }
  return 0;
}

int run_bench(const BenchOptions& o) {
  if (!o.compare.empty()) {
    try {
      return run_compare(o.compare);
    } catch (const Json::exception& e) {  // valid JSON of another layout
      throw InvalidArgument("--compare: " + o.compare[0] + " and " + o.compare[1] +
                            " must be reports of relit bench --json (devices[].results[] with name, status, "
                            "median_s): " +
                            e.what());
    }
  }
  if (o.suite != "kernels" && o.suite != "e2e" && o.suite != "all")
    throw InvalidArgument("--suite must be kernels, e2e or all, got '" + o.suite + "'");
  if (o.repeats == 0) throw InvalidArgument("--repeats must be at least 1");
  const std::vector<Device> devices =
      o.device.empty() ? std::vector<Device>{Device::select()} : Device::select_all(o.device);
  Json doc = {
      {"format", "relit-bench"},
      {"version", 1},
      {"relit_version", relit::version()},
      {"suite", o.suite},
      {"quick", o.quick},
      {"repeats", o.repeats},
      {"machine", {{"cpu", reference::host_cpu_model()}, {"hardware_threads", std::thread::hardware_concurrency()}}},
      {"devices", Json::array()}};
  char host[256] = "";
  if (gethostname(host, sizeof host - 1) == 0) doc["machine"]["hostname"] = host;
  int failures = 0;
  const fs::path tmp = fs::temp_directory_path() / ("relit-bench-" + std::to_string(::getpid()));
  for (const Device& device : devices) {
    const auto& info = device.info();
    std::vector<Case> cases;
    const auto t_setup = Clock::now();
    if (o.suite != "e2e") {
      add_peak(cases, device, o);
      if (o.mlp_variant == "all") {
        add_mlp(cases, device, o.quick, "simd", true);
        add_mlp(cases, device, o.quick, "workgroup", true);
      } else {
        add_mlp(cases, device, o.quick, o.mlp_variant, false);
      }
      for (const std::string& v : o.kernel_variant == "all" ? std::vector<std::string>{"simd", "workgroup"}
                                                            : std::vector<std::string>{o.kernel_variant}) {
        add_hashgrid(cases, device, o.quick, v, o.kernel_variant == "all");
        add_renderer(cases, device, o.quick, v, o.kernel_variant == "all");
      }
      add_adam(cases, device, o.quick);
      add_pathtracer(cases, device, o.quick);
    }
    if (o.suite != "kernels") {
      const std::string data = (tmp / "data").string();
      if (!fs::exists(data)) {
        fs::create_directories(tmp);
        DatasetSettings s;
        s.resolution = 16;
        s.train = 4;
        s.val = 1;
        s.test = 1;
        s.spp = 2;
        generate_dataset(device, Scene::from_json(Scene::builtin_json("cloud", 0, 32)), data, s);
      }
      add_e2e(cases, device, o.quick, data);
    }
    const double setup_s = seconds(t_setup);
    std::vector<Json> rows;
    double peak = 0, compile = 0;
    for (const Case& c : cases) {
      // The peak calibration runs whatever the filter: "% of peak" is against the same run's peak.
      if (!o.filter.empty() && c.family != "peak" && c.name.find(o.filter) == std::string::npos) continue;
      const Result r = measure(c, o);
      if (r.status != "ok") ++failures;
      // A peak is the best the device gives: its fastest run (the calibration kernel runs a few ms, and one
      // timer interrupt or frequency dip in the median run would lower every "% of peak" below).
      if (r.family == "peak" && r.status == "ok") peak = std::max(peak, r.flops / r.min * 1e-9);
      rows.push_back(result_json(r, peak));
      if (r.status == "ok") compile += std::max(0.0, r.first_call - r.median);
      std::fprintf(stderr, "[relit] bench %s: %s\n", c.name.c_str(), r.status.c_str());
    }
    print_table(info.description(), rows);
    for (const Json& j : rows)
      if (j.contains("kernels"))
        std::printf(
            "  %-28s %s kernels: %s %s (%s%s)\n", j["name"].get<std::string>().c_str(),
            j["kernels"].value("of", std::string("MLP")).c_str(), j["kernels"]["variant"].get<std::string>().c_str(),
            j["kernels"]["parameters"].get<std::string>().c_str(), j["kernels"]["source"].get<std::string>().c_str(),
            j["kernels"]["tuned"].get<bool>() ? "" : ", untuned");
    std::printf("  kernel builds and first launches: %.2f s (setup %.2f s); measured peak %.1f GFLOP/s\n", compile,
                setup_s, peak);
    doc["devices"].push_back({{"device", info.description()},
                              {"name", info.name},
                              {"platform", info.platform_name},
                              {"driver", info.driver_version},
                              {"opencl", info.version},
                              {"compute_units", info.compute_units},
                              {"peak_gflops", peak},
                              {"compile_and_first_call_s", compile},
                              {"setup_s", setup_s},
                              {"results", rows}});
  }
  std::error_code ec;
  fs::remove_all(tmp, ec);
  if (!o.json.empty()) {
    io::write_file_atomic(o.json, doc.dump(2) + "\n");
    std::printf("results written to %s\n", o.json.c_str());
  }
  if (failures) std::fprintf(stderr, "relit: error: %d case(s) failed verification or did not run\n", failures);
  return failures ? 1 : 0;
}

}  // namespace

void add_bench_command(CLI::App& app) {
  auto o = std::make_shared<BenchOptions>();
  auto* cmd = app.add_subcommand("bench",
                                 "benchmark relit's kernels and end-to-end steps on OpenCL devices "
                                 "(each result verified before it is timed)");
  cmd->add_option("--device,-d", o->device, "device selector, or 'all' (default: relit's choice)");
  cmd->add_option("--suite", o->suite, "kernels, e2e or all")
      ->capture_default_str()
      ->check(CLI::IsMember({"kernels", "e2e", "all"}));
  cmd->add_option("--json", o->json, "write every number to this JSON file");
  cmd->add_option("--repeats", o->repeats, "timed runs per case (median and spread)")
      ->check(integer_in(1, 100000))
      ->capture_default_str();
  cmd->add_option("--filter", o->filter, "run only the cases whose name contains this text (and the peak calibration)");
  cmd->add_option("--peak-seconds", o->peak_seconds,
                  "length of one launch of the peak calibration (default 0.25 s, 0.05 s with --quick); a "
                  "longer one checks that the default is within noise of the sustained rate")
      ->check(CLI::Range(0.001, 600.0));
  cmd->add_option("--mlp-variant", o->mlp_variant,
                  "MLP kernels: auto (the device's choice), simd, workgroup, or all (each MLP case with both "
                  "variants, named ..._simd and ..._wg)")
      ->capture_default_str()
      ->check(CLI::IsMember({"auto", "simd", "workgroup", "all"}));
  cmd->add_option("--kernel-variant", o->kernel_variant,
                  "hash-grid and renderer kernels: auto (the device's choice), simd, workgroup, or all (each of "
                  "those cases with both variants, named ..._simd and ..._wg)")
      ->capture_default_str()
      ->check(CLI::IsMember({"auto", "simd", "workgroup", "all"}));
  cmd->add_flag("--quick", o->quick, "small sizes: checks that everything runs and verifies (seconds)");
  cmd->add_option("--compare", o->compare,
                  "print the ratios between two result files A B (A / B of the median "
                  "times: > 1 means B is faster)")
      ->expected(2);
  cmd->add_option("--inject-error", o->inject_error,
                  "corrupt this case's result before verification (tests the "
                  "failure path)")
      ->group("");
  on_parsed(cmd, o, run_bench);
}

}  // namespace relit::cli
