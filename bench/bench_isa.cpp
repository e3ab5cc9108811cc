// bench_isa: the multiply-add rates the host CPU offers at each precision, beside what its OpenCL device's
// compiler makes of them. It answers whether a lower-precision MLP could be faster than the float kernels on
// this machine: only an instruction with more multiply-adds per cycle than the float FMA can pay, and only if
// the device's compiler emits it.
//
//   bench_isa [--smoke] [--device SEL] [--seconds S] [--reps N] [--out FILE]   (--help: the options)
//
// Every probe runs about --seconds (0.3) a run, the best of --reps (5) runs counting. Host: one OpenMP thread
// per core, each running 12 independent chains of 512-bit registers and timing its own loop from a barrier:
//   fp32 FMA           vfmadd231ps   16 multiply-adds per instruction (AVX-512F)
//   bf16 dot product   vdpbf16ps     32 bf16 products accumulated in fp32 (AVX512_BF16)
//   fp16 FMA           vfmadd231ph   32 multiply-adds in fp16, fp16 accumulation (AVX512_FP16)
// Device: the float peak of kernels/peak.cl (as relit bench calibrates it) and bench/kernels/half_fma.cl (half16
// with cl_khr_fp16, Clang's _Float16 vectors without it).
// Every probe is first checked on a short run whose values stay exact integers (exit 1 on a wrong result);
// --smoke stops there with tiny timings, as the test suite runs it. Writes JSON (stdout, or --out FILE).
// FLOPs count 2 per multiply-add.
#include <relit/io/file.hpp>
#include <relit/relit.hpp>
#include <relit/verify/peak_reference.hpp>

#include <immintrin.h>
#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>
#include <omp.h>

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <functional>
#include <iostream>
#include <string>
#include <vector>

using namespace relit;
using Clock = std::chrono::steady_clock;

namespace {

constexpr int kChains = 12;        // independent accumulators per thread (covers a 4-6 cycle latency on 2 ports)
constexpr int kCheckSteps = 1000;  // the exact check's steps: every value stays an integer below 2048

struct Args {
  bool smoke = false;
  std::string device, out;
  double seconds = 0.3;
  int reps = 5;
};

// ---------------------------------------------------------------------------------------------------------
// Host probes. Each runs `steps` steps of its 12 chains and returns the sum of every lane of every chain.
// Lane l of chain i starts at i * lanes + l; each step adds `inc` (fp32 and fp16: a * 1 + 1; bf16: a + 1 * 1 +
// 1 * 1), so after n exact steps the sum is sum(start) + chains * lanes * inc * n.
// ---------------------------------------------------------------------------------------------------------
// The sum of every lane of every chain, chain by chain (doubles: every value is an integer).
__attribute__((target("avx512f"))) double lane_sum(const __m512 (&a)[kChains]) {
  double sum = 0;
  for (int i = 0; i < kChains; ++i) {
    alignas(64) float v[16];
    _mm512_store_ps(v, a[i]);
    for (float x : v) sum += double(x);
  }
  return sum;
}

// `steps` steps of the 12 chains a[i], each `update` (an expression of a[i]), the chains interleaved.
#define CHAIN_STEPS(steps, update) \
  for (long s_ = 0; s_ < (steps); ++s_) _Pragma("GCC unroll 12") for (int i = 0; i < kChains; ++i) update

// Lane l of chain i starts at i * 16 + l.
__attribute__((target("avx512f"))) void chain_starts(__m512 (&a)[kChains]) {
  for (int i = 0; i < kChains; ++i)
    a[i] = _mm512_add_ps(_mm512_set1_ps(float(i * 16)),
                         _mm512_setr_ps(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15));
}

__attribute__((target("avx512f"))) double fp32_fma(long steps, float one) {
  const __m512 c = _mm512_set1_ps(one), b = _mm512_set1_ps(one);
  __m512 a[kChains];
  chain_starts(a);
  CHAIN_STEPS(steps, a[i] = _mm512_fmadd_ps(a[i], c, b));
  return lane_sum(a);
}

__attribute__((target("avx512f,avx512bf16"))) double bf16_dot(long steps, float one) {
  const __m512bh x = _mm512_cvtne2ps_pbh(_mm512_set1_ps(one), _mm512_set1_ps(one));  // 32 bf16 ones
  __m512 a[kChains];
  chain_starts(a);
  CHAIN_STEPS(steps, a[i] = _mm512_dpbf16_ps(a[i], x, x));
  return lane_sum(a);
}

__attribute__((target("avx512f,avx512bw,avx512fp16"))) double fp16_fma(long steps, float one) {
  const __m512h c = _mm512_set1_ph(static_cast<_Float16>(one)), b = c;
  __m512h a[kChains];
  for (int i = 0; i < kChains; ++i) {
    alignas(64) _Float16 start[32];
    for (int l = 0; l < 32; ++l) start[l] = static_cast<_Float16>(i * 32 + l);
    a[i] = _mm512_load_ph(start);
  }
  CHAIN_STEPS(steps, a[i] = _mm512_fmadd_ph(a[i], c, b));
  double sum = 0;
  for (int i = 0; i < kChains; ++i) {
    alignas(64) _Float16 v[32];
    _mm512_store_ph(v, a[i]);
    for (int l = 0; l < 32; ++l) sum += double(v[l]);
  }
  return sum;
}

struct HostProbe {
  const char* name;
  const char* instruction;
  bool supported;
  int lanes;  // lanes per chain (the sum's starts)
  int macs;   // multiply-adds per instruction
  int inc;    // what one step adds to a lane
  double (*run)(long, float);
};

std::vector<HostProbe> host_probes() {
  __builtin_cpu_init();
  return {{"fp32 FMA", "vfmadd231ps", __builtin_cpu_supports("avx512f") != 0, 16, 16, 1, fp32_fma},
          {"bf16 dot product", "vdpbf16ps", __builtin_cpu_supports("avx512bf16") != 0, 16, 32, 2, bf16_dot},
          {"fp16 FMA", "vfmadd231ph", __builtin_cpu_supports("avx512fp16") != 0, 32, 32, 1, fp16_fma}};
}

// What a run of `steps` sums to when every step is exact (integers below 2048).
double exact_sum(int lanes, int inc, long steps) {
  const double n = double(kChains) * lanes;
  return n * (n - 1) / 2 + n * inc * double(steps);
}

// Seconds of one parallel run of `steps` steps on every thread: the slowest thread's own time from a barrier
// to the end of its loop, so that starting the parallel region (which can take milliseconds when an idle
// core must be woken) is not counted. The multiplier comes from a volatile, so the compiler cannot fold the
// chains.
volatile float g_one = 1.0f;
double host_seconds(const HostProbe& p, long steps) {
  double slowest = 0;
#pragma omp parallel reduction(max : slowest)
  {
#pragma omp barrier
    const auto t0 = Clock::now();
    volatile double sink = p.run(steps, g_one);
    (void)sink;
    slowest = std::chrono::duration<double>(Clock::now() - t0).count();
  }
  return slowest;
}

int g_failures = 0;
bool check(const std::string& what, double got, double want) {
  const bool ok = got == want;
  std::printf("  check %-34s %s (%.0f, exact %.0f)\n", what.c_str(), ok ? "ok  " : "FAIL", got, want);
  if (!ok) ++g_failures;
  return ok;
}

double best_of(int reps, const std::function<double()>& seconds) {
  double best = 1e30;
  for (int r = 0; r < reps; ++r) best = std::min(best, seconds());
  return best;
}

nlohmann::json run_host(const Args& a) {
  const int threads = omp_get_max_threads();
  std::printf("host: %s, %d threads\n", reference::host_cpu_model().c_str(), threads);
  nlohmann::json probes = nlohmann::json::array();
  for (const HostProbe& p : host_probes()) {
    nlohmann::json j = {{"name", p.name}, {"instruction", p.instruction}, {"supported", p.supported}};
    if (!p.supported) {
      std::printf("  %-18s %-12s not supported by this CPU\n", p.name, p.instruction);
      probes.push_back(j);
      continue;
    }
    j["verified"] = check(std::string(p.name) + " (" + p.instruction + ")", p.run(kCheckSteps, g_one),
                          exact_sum(p.lanes, p.inc, kCheckSteps));
    const std::uint32_t steps = reference::calibrated_iterations(a.smoke ? 0.002 : a.seconds,
                                                                 [&](std::uint32_t n) { return host_seconds(p, n); });
    const double t = best_of(a.smoke ? 1 : a.reps, [&] { return host_seconds(p, steps); });
    const double gflops = double(threads) * steps * kChains * p.macs * 2 / t * 1e-9;
    j["gflops"] = gflops;
    j["gflops_per_thread"] = gflops / threads;
    j["instructions_per_ns_per_thread"] = double(steps) * kChains / t * 1e-9;
    std::printf("  %-18s %-12s %8.1f GFLOP/s  (%.1f per thread, %.2f instructions/ns per thread)\n", p.name,
                p.instruction, gflops, gflops / threads, j["instructions_per_ns_per_thread"].get<double>());
    probes.push_back(j);
  }
  return {{"cpu", reference::host_cpu_model()}, {"threads", threads}, {"probes", probes}};
}

// ---------------------------------------------------------------------------------------------------------
// Device probes
// ---------------------------------------------------------------------------------------------------------
nlohmann::json device_float_peak(const Device& device, const Args& a) {
  const std::size_t items = a.smoke ? 64 : std::size_t(device.info().compute_units) * 256;
  Buffer<float> buf(device, items);
  reference::PeakKernel peak(device, "peak_fma_f16", 16, items);
  peak.calibrate(device, buf, a.smoke ? 0.005 : a.seconds);
  peak.launch(device, buf);
  const double worst = peak.verify(buf);
  std::printf("  check %-34s %s (worst error / tolerance = %.3g)\n", "float peak (peak_fma_f16)",
              worst <= 1 ? "ok  " : "FAIL", worst);
  if (worst > 1) ++g_failures;
  const double t = best_of(a.smoke ? 1 : a.reps, [&] { return peak.launch(device, buf); });
  const double gflops = peak.flops() / t * 1e-9;
  std::printf("  %-31s %8.1f GFLOP/s\n", "float FMA (kernels/peak.cl)", gflops);
  return {{"gflops", gflops}, {"verified", worst <= 1}};
}

nlohmann::json device_half(const Device& device, const Args& a) {
  nlohmann::json j = {{"cl_khr_fp16", device.info().has_extension("cl_khr_fp16")}};
  Kernel kernel, lanes_kernel;
  try {
    kernel = device.kernel("half_fma.cl", "half_fma");
    lanes_kernel = device.kernel("half_fma.cl", "half_lanes");
  } catch (const BuildError& e) {
    const std::string what = e.what();
    j["built"] = false;
    j["error"] = what.substr(0, what.find('\n'));
    std::printf("  %-31s not built by the device's compiler: %s\n", "half FMA", j["error"].get<std::string>().c_str());
    return j;
  }
  Buffer<std::uint32_t> lanes_buf(device, 1);
  lanes_kernel.arg(0, lanes_buf);
  lanes_kernel.launch(1, 1);
  const unsigned lanes = lanes_buf.read()[0];
  const std::size_t items = a.smoke ? 16 : std::size_t(device.info().compute_units) * 64;
  Buffer<float> out(device, items);
  std::uint32_t iters = kCheckSteps;
  auto launch = [&] {
    kernel.args(iters, 1.0f, 1.0f, out);
    const auto t0 = Clock::now();
    kernel.launch(items, 1);
    device.finish();
    return std::chrono::duration<double>(Clock::now() - t0).count();
  };
  launch();
  // Lane l of chain i of item g starts at (g % 8) * 64 + i * 32 + l (half_fma.cl) and gains 1 a step.
  auto want = [&](std::size_t g) {
    double sum = 0;
    for (int i = 0; i < kChains; ++i)
      for (unsigned l = 0; l < lanes; ++l) sum += double((g % 8) * 64 + i * 32 + l + kCheckSteps);
    return sum;
  };
  const std::vector<float> got = out.read();
  std::size_t shown = 0;  // the first wrong item, or item 0
  while (shown < items && got[shown] == want(shown)) ++shown;
  if (shown == items) shown = 0;
  const bool ok = check("half FMA (half_fma.cl)", got[shown], want(shown));
  iters = reference::calibrated_iterations(a.smoke ? 0.005 : a.seconds, [&](std::uint32_t n) {
    iters = n;
    return launch();
  });
  const double t = best_of(a.smoke ? 1 : a.reps, launch);
  const double gflops = double(items) * kChains * lanes * 2 * iters / t * 1e-9;
  std::printf("  %-31s %8.1f GFLOP/s (%u-lane vectors, %s)\n", "half FMA (half_fma.cl)", gflops, lanes,
              j["cl_khr_fp16"].get<bool>() ? "cl_khr_fp16" : "no cl_khr_fp16: Clang _Float16 vectors");
  j["built"] = true;
  j["lanes"] = lanes;
  j["gflops"] = gflops;
  j["verified"] = ok;
  return j;
}

}  // namespace

int main(int argc, char** argv) try {
  Args a;
  CLI::App app{"bench_isa: the CPU's multiply-add rates per precision beside the OpenCL device's float and half rates"};
  app.add_flag("--smoke", a.smoke, "check every probe, time each briefly (as the test suite runs it)");
  app.add_option("--device", a.device, "the OpenCL device (relit's selector syntax)");
  app.add_option("--seconds", a.seconds, "length of one timed run of each probe, host and device")
      ->check(CLI::Range(1e-3, 60.0));
  app.add_option("--reps", a.reps, "timed runs per probe (the best counts)")->check(CLI::Range(1, 100));
  app.add_option("--out", a.out, "write the JSON here (atomically) instead of to stdout");
  CLI11_PARSE(app, argc, argv);
  nlohmann::json doc = {{"benchmark", "isa"}, {"host", run_host(a)}};
  const Device dev = Device::select(a.device);
  std::printf("device: %s\n", dev.info().description().c_str());
  doc["device"] = {{"name", dev.info().name}, {"float", device_float_peak(dev, a)}, {"half", device_half(dev, a)}};
  if (doc["device"]["half"].value("built", false)) {
    const double ratio = doc["device"]["half"]["gflops"].get<double>() / doc["device"]["float"]["gflops"].get<double>();
    doc["device"]["half_over_float"] = ratio;
    std::printf("  half / float on this device: %.2fx\n", ratio);
  }
  const std::string text = doc.dump(2) + "\n";
  if (a.out.empty())
    std::cout << text;
  else
    io::write_file_atomic(a.out, text);
  if (g_failures) {
    std::fflush(stdout);
    std::fprintf(stderr, "bench_isa: %d check(s) failed\n", g_failures);
    return 1;
  }
  return 0;
} catch (const std::exception& e) {
  std::cerr << "bench_isa: " << e.what() << "\n";
  return 1;
}
