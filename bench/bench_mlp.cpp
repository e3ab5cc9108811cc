// bench_mlp: the fully fused MLP against the device's measured FMA peak and two peers on the same machine,
// in the same run: the same MLP as a CLBlast GEMM chain (+ bias/activation kernels) and as an Eigen chain
// (OpenMP). Every variant is verified against a double-precision reference before it is timed.
//
//   bench_mlp [--smoke] [--json out.json] [--device SELECTOR] [--reps N] [--variants fused,eigen,clblast]
//   bench_mlp --blockings "T,R,B,V,RJ,RK,ROWS[,F[,G[,S]]];..." [--variants w64,w128,w256] [--reps N]
//                                                                 (tuning: fused only; S 1: train_saved)
//   bench_mlp --workgroups "S,N,RJ,RS,KT,DWT,DWR,DWS,DWC;..." [--batch N] ...    (tuning: the work-group kernels)
//
// FLOPs: 2 per multiply-add; forward = 2 * sum(in * out) per sample; training step = 3 x forward
// (forward + dL/dinput + dL/dweights). Timings are medians over --reps runs, each ended by clFinish.
#include <relit/io/file.hpp>
#include <relit/verify/mlp_reference.hpp>
#include <relit/verify/peak_reference.hpp>

#include <relit/cl/program.hpp>
#include <relit/nn/fully_fused_mlp.hpp>
#include <relit/nn/registry.hpp>

#include <Eigen/Dense>
#include <omp.h>

#ifdef RELIT_HAVE_CLBLAST
#include <clblast.h>
#endif

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <functional>
#include <optional>
#include <iostream>
#include <random>
#include <string>
#include <thread>
#include <vector>

using namespace relit;
using namespace relit::nn;
using Clock = std::chrono::steady_clock;

namespace {

struct Options {
  bool smoke = false;
  std::string json, device, variants = "fused,eigen,clblast";
  std::string blockings;    // --blockings: tuning mode (SIMD kernels)
  std::string workgroups;   // --workgroups: tuning mode (work-group kernels)
  std::uint32_t batch = 0;  // --batch: samples per batch (0: 76800, relit's training batch of 1200 rays x 64)
  int reps = 7;
  bool wants(const std::string& v) const { return ("," + variants + ",").find("," + v + ",") != std::string::npos; }
};

double seconds_since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

double median_time(int reps, const std::function<void()>& run) {
  std::vector<double> t;
  for (int i = 0; i < reps; ++i) {
    const auto t0 = Clock::now();
    run();
    t.push_back(seconds_since(t0));
  }
  std::sort(t.begin(), t.end());
  return t[t.size() / 2];
}

using reference::random_vector;

int g_failures = 0;
void verify(const std::string& what, double worst) {
  const bool ok = worst <= 1.0;
  std::printf("  verify %-44s %s (worst error / tolerance = %.3g)\n", what.c_str(), ok ? "ok  " : "FAIL", worst);
  if (!ok) ++g_failures;
}

// The exit status: 1 and a message after the tables (stdout flushed first, so that a shared file or pipe keeps
// the order) if any verification failed.
int verdict() {
  if (!g_failures) return 0;
  std::fflush(stdout);
  std::fprintf(stderr, "bench_mlp: %d verification(s) failed\n", g_failures);
  return 1;
}

// ------------------------------------------------------------------------------------------------------
// Peak: kernels/peak.cl
// ------------------------------------------------------------------------------------------------------
struct PeakResult {
  std::string variant;
  double gflops = 0;
};

std::vector<PeakResult> measure_peak(const Device& device, const Options& o) {
  std::vector<PeakResult> out;
  const std::size_t items = o.smoke ? 64 : std::size_t(device.info().compute_units) * 256;
  Buffer<float> buf(device, items);
  for (const auto& [name, lanes] : reference::kPeakKernels) {
    reference::PeakKernel peak(device, name, lanes, items);
    peak.calibrate(device, buf, o.smoke ? 0.005 : 0.25);
    peak.launch(device, buf);
    verify(std::string(name) + " result", peak.verify(buf));
    const double t = median_time(o.smoke ? 1 : 5, [&] { peak.launch(device, buf); });
    out.push_back({name, peak.flops() / t * 1e-9});
    std::printf("  %-14s %8.1f GFLOP/s (%.0f ms a launch)\n", name, peak.flops() / t * 1e-9, t * 1e3);
  }
  return out;
}

// ------------------------------------------------------------------------------------------------------
// The MLP variants
// ------------------------------------------------------------------------------------------------------
struct NetSpec {
  std::string name;
  std::uint32_t n_in, width, n_hidden, n_out, batch;
};

struct Timing {
  std::string variant;
  double forward_s = 0, train_s = 0, first_call_s = 0;
};

// Eigen chain: samples as columns (column-major [features][batch]), the same flat parameter layout.
class EigenMLP {
 public:
  using Mat = Eigen::MatrixXf;
  using WMap =
      Eigen::Map<const Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>, 0, Eigen::OuterStride<>>;
  using GMap =
      Eigen::Map<Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>, 0, Eigen::OuterStride<>>;

  EigenMLP(const FullyFusedMLP& net, const std::vector<float>& params) : m_net(net), m_params(params) {}

  WMap w(std::uint32_t l) const {
    const std::uint32_t n_in = m_net.layer_inputs(l);
    return WMap(m_params.data() + m_net.layer_offset(l), m_net.layer_outputs(l), n_in, Eigen::OuterStride<>(n_in + 1));
  }
  Eigen::Map<const Eigen::VectorXf, 0, Eigen::InnerStride<>> b(std::uint32_t l) const {
    const std::uint32_t n_in = m_net.layer_inputs(l);
    return {m_params.data() + m_net.layer_offset(l) + n_in, m_net.layer_outputs(l), Eigen::InnerStride<>(n_in + 1)};
  }

  const Mat& forward(const Mat& x) {
    const std::uint32_t L = m_net.n_hidden_layers();
    m_h.resize(L + 1);
    for (std::uint32_t l = 0; l <= L; ++l) {
      const Mat& in = l == 0 ? x : m_h[l - 1];
      m_h[l].noalias() = w(l) * in;
      const Eigen::VectorXf bias = b(l);
      const bool relu = l < L;
      Mat& h = m_h[l];
#pragma omp parallel for schedule(static)
      for (Eigen::Index s = 0; s < h.cols(); ++s) {
        h.col(s) += bias;
        if (relu) h.col(s) = h.col(s).cwiseMax(0.0f);
      }
    }
    return m_h[L];
  }

  void backward(const Mat& x, const Mat& dy, std::vector<float>& grads, Mat& dx) {
    const std::uint32_t L = m_net.n_hidden_layers();
    Mat dz = dy, din;
    for (std::uint32_t l = L + 1; l-- > 0;) {
      const Mat& in = l == 0 ? x : m_h[l - 1];
      const std::uint32_t n_in = m_net.layer_inputs(l);
      GMap gw(grads.data() + m_net.layer_offset(l), m_net.layer_outputs(l), n_in, Eigen::OuterStride<>(n_in + 1));
      Eigen::Map<Eigen::VectorXf, 0, Eigen::InnerStride<>> gb(grads.data() + m_net.layer_offset(l) + n_in,
                                                              m_net.layer_outputs(l), Eigen::InnerStride<>(n_in + 1));
      // dW = dZ X^T sums over the long batch dimension, but Eigen parallelises a GEMM over output blocks only
      // and a 64x64 dW is a single block: split the batch across the threads and add their partial products.
      const int threads = omp_get_max_threads();
      std::vector<Mat> part_w(threads);
      std::vector<Eigen::VectorXf> part_b(threads);
#pragma omp parallel num_threads(threads)
      {
        const int t = omp_get_thread_num();
        const Eigen::Index chunk = (dz.cols() + threads - 1) / threads,
                           s0 = std::min<Eigen::Index>(t * chunk, dz.cols());
        const Eigen::Index n = std::min<Eigen::Index>(chunk, dz.cols() - s0);
        part_w[t].noalias() = dz.middleCols(s0, n) * in.middleCols(s0, n).transpose();
        part_b[t] = dz.middleCols(s0, n).rowwise().sum();
      }
      Mat sum_w = part_w[0];
      Eigen::VectorXf sum_b = part_b[0];
      for (int t = 1; t < threads; ++t) {
        sum_w += part_w[t];
        sum_b += part_b[t];
      }
      gw = sum_w;
      gb = sum_b;
      if (l == 0) {
        dx.noalias() = w(0).transpose() * dz;
      } else {
        din.noalias() = w(l).transpose() * dz;
        const Mat& h = m_h[l - 1];
#pragma omp parallel for schedule(static)
        for (Eigen::Index s = 0; s < din.cols(); ++s) din.col(s) = (h.col(s).array() > 0.0f).select(din.col(s), 0.0f);
        dz.swap(din);
      }
    }
  }

 private:
  const FullyFusedMLP& m_net;
  const std::vector<float>& m_params;
  std::vector<Mat> m_h;
};

#ifdef RELIT_HAVE_CLBLAST
// CLBlast chain: row-major [batch][features] device matrices, one GEMM per layer plus element-wise kernels.
class ClblastMLP {
 public:
  ClblastMLP(const Device& device, const FullyFusedMLP& net, std::uint32_t batch)
      : m_device(device), m_net(net), m_batch(batch) {
    const std::uint32_t L = net.n_hidden_layers();
    for (std::uint32_t l = 0; l <= L; ++l) m_h.emplace_back(device, std::size_t(batch) * net.layer_outputs(l));
    m_g0 = Buffer<float>(device, std::size_t(batch) * std::max(net.width(), net.n_output_dims()));
    m_g1 = Buffer<float>(device, std::size_t(batch) * std::max(net.width(), net.n_output_dims()));
    m_bias_act = device.kernel("mlp_peers.cl", "bias_act");
    m_mask = device.kernel("mlp_peers.cl", "relu_mask");
    m_sums = device.kernel("mlp_peers.cl", "column_sums");
  }

  void gemm(clblast::Transpose ta, clblast::Transpose tb, std::size_t m, std::size_t n, std::size_t k,
            const Buffer<float>& a, std::size_t a_off, std::size_t lda, const Buffer<float>& b, std::size_t b_off,
            std::size_t ldb, Buffer<float>& c, std::size_t c_off, std::size_t ldc) {
    cl_command_queue q = m_device.queue()();
    const auto status = clblast::Gemm<float>(clblast::Layout::kRowMajor, ta, tb, m, n, k, 1.0f, a.handle()(), a_off,
                                             lda, b.handle()(), b_off, ldb, 0.0f, c.handle()(), c_off, ldc, &q);
    if (status != clblast::StatusCode::kSuccess)
      throw DeviceError("CLBlast Gemm failed with status " + std::to_string(static_cast<int>(status)));
  }

  const Buffer<float>& forward(const Buffer<float>& params, const Buffer<float>& x) {
    using T = clblast::Transpose;
    const std::uint32_t L = m_net.n_hidden_layers();
    for (std::uint32_t l = 0; l <= L; ++l) {
      const std::uint32_t n_in = m_net.layer_inputs(l), n_out = m_net.layer_outputs(l);
      const Buffer<float>& in = l == 0 ? x : m_h[l - 1];
      gemm(T::kNo, T::kYes, m_batch, n_out, n_in, in, 0, n_in, params, m_net.layer_offset(l), n_in + 1, m_h[l], 0,
           n_out);
      const std::uint32_t n = m_batch * n_out;
      m_bias_act.args(n, n_out, m_h[l], params, m_net.layer_offset(l) + n_in, n_in + 1, std::uint32_t(l < L ? 1 : 0));
      m_bias_act.launch(n, 64);
    }
    return m_h[L];
  }

  void backward(const Buffer<float>& params, const Buffer<float>& x, const Buffer<float>& dy, Buffer<float>& grads,
                Buffer<float>& dx) {
    using T = clblast::Transpose;
    const std::uint32_t L = m_net.n_hidden_layers();
    const Buffer<float>* dz = &dy;
    for (std::uint32_t l = L + 1; l-- > 0;) {
      const std::uint32_t n_in = m_net.layer_inputs(l), n_out = m_net.layer_outputs(l);
      const Buffer<float>& in = l == 0 ? x : m_h[l - 1];
      const std::uint32_t off = m_net.layer_offset(l);
      gemm(T::kYes, T::kNo, n_out, n_in, m_batch, *dz, 0, n_out, in, 0, n_in, grads, off, n_in + 1);
      m_sums.args(m_batch, n_out, *dz, grads, off + n_in, n_in + 1);
      m_sums.launch(n_out, 16);
      Buffer<float>& din = l == 0 ? dx : (dz == &m_g0 ? m_g1 : m_g0);
      gemm(T::kNo, T::kNo, m_batch, n_in, n_out, *dz, 0, n_out, params, off, n_in + 1, din, 0, n_in);
      if (l > 0) {
        const std::uint32_t n = m_batch * n_in;
        m_mask.args(n, din, m_h[l - 1]);
        m_mask.launch(n, 64);
        dz = &din;
      }
    }
  }

 private:
  Device m_device;
  const FullyFusedMLP& m_net;
  std::uint32_t m_batch;
  std::vector<Buffer<float>> m_h;
  Buffer<float> m_g0, m_g1;
  Kernel m_bias_act, m_mask, m_sums;
};
#endif

struct NetResult {
  NetSpec spec;
  double flops_fwd_per_sample = 0;
  std::vector<Timing> timings;
};

std::vector<float> to_row_major_batch(const Eigen::MatrixXf& m) {  // [features][batch] -> [batch][features]
  std::vector<float> v(std::size_t(m.size()));
  for (Eigen::Index s = 0; s < m.cols(); ++s)
    for (Eigen::Index f = 0; f < m.rows(); ++f) v[std::size_t(s) * m.rows() + f] = m(f, s);
  return v;
}

// A benchmark's inputs and the double reference of their first nv samples.
struct BenchData {
  std::vector<float> params, xh, dyh;  // parameters (non-zero biases), x and dL/dy of the whole batch
  std::vector<float> xv, dyv;          // the verification batch: the first nv samples
  std::vector<double> want_y, want_dp, want_dx;
  std::uint32_t n = 0, nv = 0;
};

BenchData bench_data(const FullyFusedMLP& net, const NetSpec& spec, std::uint32_t max_verify) {
  BenchData d;
  d.params.resize(net.n_params());
  net.initialize_params(d.params.data(), 1);
  {  // non-zero biases, so every variant's bias handling is verified
    auto r = random_vector(d.params.size(), 2, -0.1f, 0.1f);
    for (std::uint32_t l = 0; l <= net.n_hidden_layers(); ++l)
      for (std::uint32_t j = 0; j < net.layer_outputs(l); ++j) {
        const std::size_t i = net.layer_offset(l) + std::size_t(j) * (net.layer_inputs(l) + 1) + net.layer_inputs(l);
        d.params[i] = r[i];
      }
  }
  d.n = spec.batch;
  d.nv = std::min(d.n, max_verify);
  d.xh = random_vector(std::size_t(d.n) * spec.n_in, 3);
  d.dyh = random_vector(std::size_t(d.n) * spec.n_out, 4, -1e-3f, 1e-3f);
  reference::MlpReference ref(net, d.params);
  d.xv.assign(d.xh.begin(), d.xh.begin() + std::size_t(d.nv) * spec.n_in);
  d.dyv.assign(d.dyh.begin(), d.dyh.begin() + std::size_t(d.nv) * spec.n_out);
  const reference::Mat xm = reference::to_mat(d.xv, d.nv, spec.n_in);
  d.want_y = reference::flatten(ref.forward(xm));
  reference::Mat dxm;
  ref.backward(xm, reference::to_mat(d.dyv, d.nv, spec.n_out), d.want_dp, dxm);
  d.want_dx = reference::flatten(dxm);
  return d;
}

NetResult bench_net(const Device& device, const NetSpec& spec, const Options& o) {
  std::printf("\n%s: %u -> %u x %u -> %u, batch %u\n", spec.name.c_str(), spec.n_in, spec.n_hidden, spec.width,
              spec.n_out, spec.batch);
  auto base = create_network({{"n_neurons", spec.width}, {"n_hidden_layers", spec.n_hidden}}, spec.n_in, spec.n_out);
  const auto& net = dynamic_cast<const FullyFusedMLP&>(*base);
  NetResult result{spec, net.flops_per_sample(), {}};
  const BenchData data = bench_data(net, spec, o.smoke ? 200 : 1024);
  const auto& [params, xh, dyh, xv, dyv, want_y, want_dp, want_dx, n, nv] = data;

  Buffer<float> pbuf(device, params), gbuf(device, params.size());
  // ---- fused ----
  if (o.wants("fused")) {
    Timing t{"fused"};
    auto t0 = Clock::now();
    net.warm_up(device);
    BatchMatrix x(device, nv, spec.n_in), y(device, nv, spec.n_out), dy(device, nv, spec.n_out),
        dx(device, nv, spec.n_in);
    auto ws = net.make_workspace(device);
    x.upload_row_major(xv);
    dy.upload_row_major(dyv);
    net.forward(device, {&pbuf, 0}, x, y, *ws);
    net.backward(device, {&pbuf, 0}, x, y, dy, {&gbuf, 0}, false, &dx, *ws);
    device.finish();
    t.first_call_s = seconds_since(t0);
    verify("fused forward", reference::worst_ratio(y.download_row_major(), want_y, 1e-4));
    verify("fused dL/dparams", reference::worst_ratio(gbuf.read(), want_dp, 1e-3));
    verify("fused dL/dinput", reference::worst_ratio(dx.download_row_major(), want_dx, 1e-3));
    x.resize(n);
    y.resize(n);
    dy.resize(n);
    dx.resize(n);
    x.upload_row_major(xh);
    dy.upload_row_major(dyh);
    net.inference(device, {&pbuf, 0}, x, y);
    device.finish();
    auto yfull = y.download_row_major();
    yfull.resize(want_y.size());
    verify("fused inference at full batch (first samples)", reference::worst_ratio(yfull, want_y, 1e-4));
    t.forward_s = median_time(o.reps, [&] {
      net.inference(device, {&pbuf, 0}, x, y);
      device.finish();
    });
    t.train_s = median_time(o.reps, [&] {
      net.forward(device, {&pbuf, 0}, x, y, *ws);
      net.backward(device, {&pbuf, 0}, x, y, dy, {&gbuf, 0}, false, &dx, *ws);
      device.finish();
    });
    result.timings.push_back(t);
  }
  // ---- Eigen ----
  if (o.wants("eigen")) {
    Timing t{"eigen"};
    EigenMLP e(net, params);
    auto to_cols = [](const std::vector<float>& v, std::uint32_t rows, std::uint32_t cols) {
      Eigen::MatrixXf m(cols, rows);
      for (std::uint32_t s = 0; s < rows; ++s)
        for (std::uint32_t f = 0; f < cols; ++f) m(f, s) = v[std::size_t(s) * cols + f];
      return m;
    };
    std::vector<float> grads(params.size());
    Eigen::MatrixXf dx;
    {
      const auto x = to_cols(xv, nv, spec.n_in), dy = to_cols(dyv, nv, spec.n_out);
      auto t0 = Clock::now();
      const auto y = e.forward(x);
      e.backward(x, dy, grads, dx);
      t.first_call_s = seconds_since(t0);
      verify("eigen forward", reference::worst_ratio(to_row_major_batch(y), want_y, 1e-4));
      verify("eigen dL/dparams", reference::worst_ratio(grads, want_dp, 1e-3));
      verify("eigen dL/dinput", reference::worst_ratio(to_row_major_batch(dx), want_dx, 1e-3));
    }
    const auto x = to_cols(xh, n, spec.n_in), dy = to_cols(dyh, n, spec.n_out);
    t.forward_s = median_time(o.reps, [&] { e.forward(x); });
    t.train_s = median_time(o.reps, [&] {
      e.forward(x);
      e.backward(x, dy, grads, dx);
    });
    result.timings.push_back(t);
  }
#ifdef RELIT_HAVE_CLBLAST
  if (o.wants("clblast")) {
    Timing t{"clblast"};
    auto t0 = Clock::now();
    {
      ClblastMLP c(device, net, nv);
      Buffer<float> x(device, xv), dy(device, dyv), dx(device, std::size_t(nv) * spec.n_in);
      const auto& y = c.forward(pbuf, x);
      c.backward(pbuf, x, dy, gbuf, dx);
      device.finish();
      t.first_call_s = seconds_since(t0);
      verify("clblast forward", reference::worst_ratio(y.read(), want_y, 1e-4));
      verify("clblast dL/dparams", reference::worst_ratio(gbuf.read(), want_dp, 1e-3));
      verify("clblast dL/dinput", reference::worst_ratio(dx.read(), want_dx, 1e-3));
    }
    ClblastMLP c(device, net, n);
    Buffer<float> x(device, xh), dy(device, dyh), dx(device, std::size_t(n) * spec.n_in);
    c.forward(pbuf, x);  // shapes of the full batch may pick other kernels: warm them
    c.backward(pbuf, x, dy, gbuf, dx);
    device.finish();
    // A CLBlast training step of the paper net takes tens of seconds on a CPU: fewer repetitions.
    const int reps = spec.width >= 256 ? 1 : std::max(1, o.reps / 2);
    t.forward_s = median_time(reps, [&] {
      c.forward(pbuf, x);
      device.finish();
    });
    t.train_s = median_time(reps, [&] {
      c.forward(pbuf, x);
      c.backward(pbuf, x, dy, gbuf, dx);
      device.finish();
    });
    result.timings.push_back(t);
  }
#endif
  return result;
}

// ------------------------------------------------------------------------------------------------------
// Tuning modes (--blockings "T,R,B,V,RJ,RK,ROWS[,F[,G[,S]]];..." for the SIMD kernels, --workgroups
// "S,N,RJ,RS,KT,DWT,DWR,DWS,DWC;..." for the work-group kernels): the fused MLP with each setting (see
// FullyFusedMLP::Blocking and ::WorkGroupParams), verified, then timed round-robin (one forward and one training
// step of every setting per round) so that a loaded machine slows them all alike; medians over --reps rounds.
// ------------------------------------------------------------------------------------------------------
struct KernelSetting {
  std::optional<FullyFusedMLP::Blocking> blocking;
  std::optional<FullyFusedMLP::WorkGroupParams> workgroup;
  std::string str() const { return blocking ? blocking->str() : workgroup->str(); }
  void apply(FullyFusedMLP& net) const {
    if (blocking)
      net.set_blocking(blocking);
    else
      net.set_workgroup(workgroup);
  }
};

// The ';'-separated lists of at least `min` and at most `max` comma-separated unsigned numbers.
std::vector<std::vector<unsigned>> parse_lists(const std::string& list, int min, int max, const std::string& what) {
  std::vector<std::vector<unsigned>> out;
  std::size_t pos = 0;
  while (pos <= list.size()) {
    const std::size_t end = std::min(list.find(';', pos), list.size());
    const std::string item = list.substr(pos, end - pos);
    pos = end + 1;
    if (item.empty()) continue;
    std::vector<unsigned> v;
    std::size_t at = 0;
    while (at <= item.size()) {
      const std::size_t comma = std::min(item.find(',', at), item.size());
      const std::string field = item.substr(at, comma - at);
      at = comma + 1;
      if (field.empty() || field.find_first_not_of("0123456789") != std::string::npos)
        throw InvalidArgument(what + ": '" + item + "' holds '" + field + "', not an unsigned number");
      v.push_back(static_cast<unsigned>(std::stoul(field)));
    }
    if (int(v.size()) < min || int(v.size()) > max)
      throw InvalidArgument(what + ": '" + item + "' has " + std::to_string(v.size()) + " numbers, not " +
                            std::to_string(min) + (min == max ? "" : " to " + std::to_string(max)));
    out.push_back(v);
  }
  return out;
}

std::vector<KernelSetting> parse_settings(const Options& o) {
  std::vector<KernelSetting> out;
  for (auto v : parse_lists(o.blockings, 7, 10, "--blockings (T,R,B,V,RJ,RK,ROWS[,F[,G[,S]]])")) {
    if (v.size() < 8) v.push_back(0);   // F
    if (v.size() < 9) v.push_back(8);   // G
    if (v.size() < 10) v.push_back(0);  // S: the fused kernel reads the saved activations
    out.push_back({FullyFusedMLP::Blocking{v[0], v[1], v[2], v[3], v[4], v[5], v[6], v[7], v[8], v[9] != 0}, {}});
  }
  for (const auto& v : parse_lists(o.workgroups, 9, 9, "--workgroups (S,N,RJ,RS,KT,DWT,DWR,DWS,DWC)"))
    out.push_back({{}, FullyFusedMLP::WorkGroupParams{v[0], v[1], v[2], v[3], v[4], v[5], v[6], v[7], v[8]}});
  return out;
}

void tune_net(const Device& device, const NetSpec& spec, const Options& o, double peak) {
  const auto settings = parse_settings(o);
  std::printf("\n%s: %u -> %u x %u -> %u, batch %u\n", spec.name.c_str(), spec.n_in, spec.n_hidden, spec.width,
              spec.n_out, spec.batch);
  std::vector<std::unique_ptr<Network>> nets;
  for (const auto& setting : settings) {
    nets.push_back(
        create_network({{"n_neurons", spec.width}, {"n_hidden_layers", spec.n_hidden}}, spec.n_in, spec.n_out));
    setting.apply(dynamic_cast<FullyFusedMLP&>(*nets.back()));
  }
  const auto& net0 = dynamic_cast<const FullyFusedMLP&>(*nets[0]);
  const BenchData data = bench_data(net0, spec, 1024);
  const auto& [params, xh, dyh, xv, dyv, want_y, want_dp, want_dx, n, nv] = data;
  Buffer<float> pbuf(device, params), gbuf(device, params.size());
  BatchMatrix x(device, n, spec.n_in), y(device, n, spec.n_out), dy(device, n, spec.n_out), dx(device, n, spec.n_in);
  std::vector<std::unique_ptr<Workspace>> ws;
  for (std::size_t i = 0; i < nets.size(); ++i) {
    const auto& net = dynamic_cast<const FullyFusedMLP&>(*nets[i]);
    ws.push_back(net.make_workspace(device));
    x.resize(nv), y.resize(nv), dy.resize(nv), dx.resize(nv);
    x.upload_row_major(xv);
    dy.upload_row_major(dyv);
    net.forward(device, {&pbuf, 0}, x, y, *ws.back());
    net.backward(device, {&pbuf, 0}, x, y, dy, {&gbuf, 0}, false, &dx, *ws.back());
    device.finish();
    const std::string b = net.kernel_choice(device).str();
    verify(b + " forward", reference::worst_ratio(y.download_row_major(), want_y, 1e-4));
    verify(b + " dL/dparams", reference::worst_ratio(gbuf.read(), want_dp, 1e-3));
    verify(b + " dL/dinput", reference::worst_ratio(dx.download_row_major(), want_dx, 1e-3));
  }
  x.resize(n), y.resize(n), dy.resize(n), dx.resize(n);
  x.upload_row_major(xh);
  dy.upload_row_major(dyh);
  std::vector<std::vector<double>> tf(nets.size()), tt(nets.size());
  for (int rep = 0; rep < o.reps; ++rep)
    for (std::size_t i = 0; i < nets.size(); ++i) {
      const auto& net = dynamic_cast<const FullyFusedMLP&>(*nets[i]);
      auto t0 = Clock::now();
      net.inference(device, {&pbuf, 0}, x, y);
      device.finish();
      tf[i].push_back(seconds_since(t0));
      t0 = Clock::now();
      net.forward(device, {&pbuf, 0}, x, y, *ws[i]);
      net.backward(device, {&pbuf, 0}, x, y, dy, {&gbuf, 0}, false, &dx, *ws[i]);
      device.finish();
      tt[i].push_back(seconds_since(t0));
    }
  const double ff = net0.flops_per_sample() * n;
  std::printf("%-72s %10s %8s %10s %8s\n", "kernels (as lowered to fit the device)", "fwd ms", "fwd %pk", "train ms",
              "trn %pk");
  for (std::size_t i = 0; i < nets.size(); ++i) {
    auto med = [](std::vector<double> v) {
      std::sort(v.begin(), v.end());
      return v[v.size() / 2];
    };
    const double f = med(tf[i]), t = med(tt[i]);
    const auto& net = dynamic_cast<const FullyFusedMLP&>(*nets[i]);
    std::printf("%-72s %10.2f %7.1f%% %10.2f %7.1f%%\n", net.kernel_choice(device).str().c_str(), f * 1e3,
                100 * ff / f * 1e-9 / peak, t * 1e3, 100 * 3 * ff / t * 1e-9 / peak);
  }
}

}  // namespace

int main(int argc, char** argv) {
  Options o;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--smoke")
      o.smoke = true;
    else if (a == "--json" && i + 1 < argc)
      o.json = argv[++i];
    else if (a == "--device" && i + 1 < argc)
      o.device = argv[++i];
    else if (a == "--variants" && i + 1 < argc)
      o.variants = argv[++i];
    else if (a == "--reps" && i + 1 < argc)
      o.reps = std::max(1, std::atoi(argv[++i]));
    else if (a == "--blockings" && i + 1 < argc)
      o.blockings = argv[++i];
    else if (a == "--workgroups" && i + 1 < argc)
      o.workgroups = argv[++i];
    else if (a == "--batch" && i + 1 < argc)
      o.batch = static_cast<std::uint32_t>(std::max(16L, std::atol(argv[++i])));
    else {
      std::fprintf(
          stderr,
          "usage: bench_mlp [--smoke] [--json out.json] [--device SELECTOR] [--reps N] [--variants "
          "fused,eigen,clblast] "
          "[--blockings \"T,R,B,V,RJ,RK,ROWS[,F[,G[,S]]];...\"] [--workgroups \"S,N,RJ,RS,KT,DWT,DWR,DWS,DWC;...\"] "
          "[--batch N]\n");
      return 2;
    }
  }
  if (o.smoke) o.reps = 1;
  try {
    const Device device = Device::select(o.device);
    Eigen::setNbThreads(static_cast<int>(std::thread::hardware_concurrency()));
    std::printf("device: %s\nEigen threads: %d (OpenMP), %s\n", device.info().description().c_str(), Eigen::nbThreads(),
                o.smoke ? "smoke run (tiny sizes, results verified, timings meaningless)" : "full run");
#ifndef RELIT_HAVE_CLBLAST
    std::printf("CLBlast peer: not built (RELIT_WITH_CLBLAST=OFF)\n");
#endif
    std::printf("\npeak (calibrated FMA loop, kernels/peak.cl):\n");
    const auto peaks = measure_peak(device, o);
    double peak = 0;
    std::string peak_name;
    for (const auto& p : peaks)
      if (p.gflops > peak) peak = p.gflops, peak_name = p.variant;
    std::printf("  %% of peak below: of %s (%.1f GFLOP/s), the faster calibration\n", peak_name.c_str(), peak);

    const std::uint32_t batch = o.batch ? o.batch : o.smoke ? 1000 : 76800;
    std::vector<NetSpec> specs = {{"small (3x64)", 32, 64, 3, 16, batch},
                                  {"paper (8x256)", 64, 256, 8, 16, o.smoke ? 200 : batch}};
    if (!o.blockings.empty() || !o.workgroups.empty()) {
      // Tuning also covers relit bench's width-128 net (32 -> 4 x 128 -> 16), by name only (w128).
      specs.insert(specs.begin() + 1, NetSpec{"mid (4x128)", 32, 128, 4, 16, batch});
      for (const auto& s : specs)
        if (o.variants.find('w') == std::string::npos ? s.width != 128 : o.wants("w" + std::to_string(s.width)))
          tune_net(device, s, o, peak);
      return verdict();
    }
    std::vector<NetResult> results;
    for (const auto& s : specs) results.push_back(bench_net(device, s, o));

    // Table.
    std::printf("\n%-14s %-8s %10s %10s %8s %10s %10s %8s %10s\n", "net", "variant", "fwd ms", "fwd GF/s", "fwd %pk",
                "train ms", "train GF/s", "trn %pk", "first s");
    Json j = {
        {"device", device.info().description()}, {"smoke", o.smoke}, {"peak_gflops", peak}, {"nets", Json::array()}};
    for (const auto& p : peaks) j["peak"][p.variant] = p.gflops;
    for (const auto& r : results) {
      Json jn = {{"name", r.spec.name},
                 {"n_input", r.spec.n_in},
                 {"width", r.spec.width},
                 {"n_hidden", r.spec.n_hidden},
                 {"n_output", r.spec.n_out},
                 {"batch", r.spec.batch},
                 {"forward_flops_per_sample", r.flops_fwd_per_sample}};
      double fused_f = NAN, fused_t = NAN;
      for (const auto& t : r.timings) {
        const double ff = r.flops_fwd_per_sample * r.spec.batch, tf = 3 * ff;
        const double fg = ff / t.forward_s * 1e-9, tg = tf / t.train_s * 1e-9;
        if (t.variant == "fused") fused_f = t.forward_s, fused_t = t.train_s;
        std::printf("%-14s %-8s %10.2f %10.1f %7.1f%% %10.2f %10.1f %7.1f%% %10.2f\n", r.spec.name.c_str(),
                    t.variant.c_str(), t.forward_s * 1e3, fg, 100 * fg / peak, t.train_s * 1e3, tg, 100 * tg / peak,
                    t.first_call_s);
        jn["variants"][t.variant] = {
            {"forward_ms", t.forward_s * 1e3}, {"forward_gflops", fg}, {"forward_pct_peak", 100 * fg / peak},
            {"train_ms", t.train_s * 1e3},     {"train_gflops", tg},   {"train_pct_peak", 100 * tg / peak},
            {"first_call_s", t.first_call_s}};
      }
      for (const auto& t : r.timings)
        if (t.variant != "fused") {
          std::printf("%-14s fused vs %-8s forward %.2fx, training %.2fx\n", r.spec.name.c_str(), t.variant.c_str(),
                      t.forward_s / fused_f, t.train_s / fused_t);
          jn["speedup_vs_" + t.variant] = {{"forward", t.forward_s / fused_f}, {"train", t.train_s / fused_t}};
        }
      j["nets"].push_back(jn);
    }
    if (!o.json.empty()) relit::io::write_file_atomic(o.json, j.dump(2) + "\n");
    return verdict();
  } catch (const std::exception& e) {
    std::fflush(stdout);  // what ran before the error, then the error
    std::fprintf(stderr, "bench_mlp: %s\n", e.what());
    return 1;
  }
  return 0;
}
