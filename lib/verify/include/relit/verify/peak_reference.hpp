// The calibrated FMA peak (kernels/peak.cl), shared by bench_mlp and relit bench: its host reference and the
// calibration of its launch length.
#pragma once

#include <relit/cl/buffer.hpp>
#include <relit/cl/program.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <fstream>
#include <string>

namespace relit::reference {

/// The peak kernels of kernels/peak.cl and their vector lanes; each work-item runs kPeakChains chains per lane.
struct PeakKernelName {
  const char* name;
  unsigned lanes;
};
inline constexpr PeakKernelName kPeakKernels[] = {{"peak_fma_f16", 16}, {"peak_fma_f8", 8}};
inline constexpr unsigned kPeakChains = 12;  ///< PEAK_CHAINS of kernels/peak.cl

/// The start `a` and the constant term `b` of chain `chain`, lane `lane` of work-item `gid` (kernels/peak.cl sets
/// its chains up the same way). Every chain starts above 0 and has b > 0, so it moves monotonically towards its
/// fixed point b / (1 - c) >= 1 and never becomes subnormal: a chain with b = 0 decays towards 0 and, after
/// ~10^5 steps, stays at a subnormal fixed point, where every FMA on an Intel core takes a microcode assist
/// (one such lane in one of each work-item's 12 chains made the kernel ~19x slower on a 2-core Xeon: the
/// calibration, timing its growth steps past that point, chose 13 ms launches, and 5 s launches reported
/// 25 GFLOP/s against 475).
struct PeakChain {
  float a, b;
};
inline PeakChain peak_chain(std::size_t gid, unsigned chain, unsigned lane) {
  const float base = static_cast<float>(gid % 64u) * 0.001f + 0.001f;
  return {std::fma(static_cast<float>(lane), 0.01f, base + static_cast<float>(chain) * 0.1f),
          std::fma(static_cast<float>(lane), 0.001f, static_cast<float>(chain) * 0.01f + 0.001f)};
}

/// Chain (a, b) after `iters` FMAs a = a * c + b, with `visit(a)` called on its start and on every value it
/// takes. The recurrence reaches a float fixed point after a few thousand steps (0 < c < 1); from there on every
/// step returns it unchanged, so the loop stops there and a long calibration run need not be replayed step by step.
template <class Visit>
float peak_steps(PeakChain chain, float c, unsigned iters, Visit visit) {
  float a = chain.a;
  visit(a);
  for (unsigned it = 0; it < iters; ++it) {
    const float next = std::fma(a, c, chain.b);
    if (next == a) break;
    a = next;
    visit(a);
  }
  return a;
}

/// Work-item `gid`'s result: kPeakChains chains x `lanes` lanes of `iters` FMAs a = a * c + b, summed chain by
/// chain, then lane by lane (the kernel's order). `c` must be in (0, 1).
inline float peak_host(std::size_t gid, unsigned iters, float c, unsigned lanes) {
  float s = 0.0f;
  for (unsigned i = 0; i < kPeakChains; ++i)
    for (unsigned l = 0; l < lanes; ++l) s += peak_steps(peak_chain(gid, i, l), c, iters, [](float) {});
  return s;
}

/// The host CPU's model name ("model name" of /proc/cpuinfo, "unknown" without one), which the benchmarks
/// report beside the peaks they measure.
inline std::string host_cpu_model() {
  std::ifstream in("/proc/cpuinfo");
  for (std::string line; std::getline(in, line);)
    if (line.rfind("model name", 0) == 0) return line.substr(line.find(':') + 2);
  return "unknown";
}

/// The step count of a loop that runs about `target_seconds` (at least 1024, at most 2^30): `run(steps)` runs it
/// and returns its seconds. The count grows 8x from 1024 until one run takes a quarter of the target (the first
/// run, which may build code, is not timed), then is scaled to the target.
template <class Run>
std::uint32_t calibrated_iterations(double target_seconds, Run run) {
  std::uint32_t iters = 1024;
  run(iters);
  for (;;) {
    const double t = run(iters);
    if (t >= target_seconds / 4 || iters >= (1u << 27)) {
      const double scaled = double(iters) * target_seconds / std::max(t, 1e-9);
      return std::uint32_t(std::clamp(scaled, 1024.0, double(1u << 30)));
    }
    iters *= 8;
  }
}

/// One peak kernel (peak_fma_f16 or peak_fma_f8) sized so that a launch runs about `target_seconds`.
///
/// A launch of a few milliseconds measures the device's start-up as much as its arithmetic: on a 2-core AVX-512
/// CPU under PoCL, 4-7 ms launches gave 220-384 GFLOP/s in two runs against 444-457 sustained by a long loop.
/// The iteration count is therefore grown until one launch takes at least a quarter of the target, then scaled
/// to the target, so that thread wake-up, work distribution and clock ramps are a negligible share of the time.
struct PeakKernel {
  static constexpr float kFactor = 0.999f;  ///< the recurrence's c
  std::string name;
  unsigned lanes = 16;
  Kernel kernel;
  std::size_t items = 0, local = 1;
  std::uint32_t iters = 0;

  PeakKernel(const Device& device, std::string kernel_name, unsigned vector_lanes, std::size_t work_items)
      : name(std::move(kernel_name)),
        lanes(vector_lanes),
        kernel(device.kernel("peak.cl", name)),
        items(work_items),
        local(
            std::max<std::size_t>(1, std::min(kernel.preferred_work_group_multiple(), kernel.max_work_group_size()))) {}

  /// FLOPs of one launch (an FMA counts 2).
  double flops() const { return double(items) * kPeakChains * lanes * 2 * iters; }

  /// One launch with `iters` steps into `out` (items floats), waiting for it; returns its seconds.
  double launch(const Device& device, Buffer<float>& out) {
    kernel.args(iters, kFactor, out);
    const auto t0 = std::chrono::steady_clock::now();
    kernel.launch(items, local);
    device.finish();
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  }

  /// Chooses `iters` for launches of about `target_seconds` (at least 1024 steps, at most 2^30).
  void calibrate(const Device& device, Buffer<float>& out, double target_seconds) {
    iters = calibrated_iterations(target_seconds, [&](std::uint32_t n) {
      iters = n;
      return launch(device, out);
    });
  }

  /// The worst error over tolerance of the last launch's results (<= 1 passes), checked on `checks` items.
  double verify(const Buffer<float>& out, std::size_t checks = 8) const {
    const auto got = out.read();
    double worst = 0;
    for (std::size_t g = 0; g < items; g += std::max<std::size_t>(1, items / checks)) {
      const double want = peak_host(g, iters, kFactor, lanes);
      const double e = std::fabs(got[g] - want) / (1e-4 * (std::fabs(want) + 1));
      worst = std::max(worst, std::isfinite(e) ? e : 1e30);
    }
    return worst;
  }
};

}  // namespace relit::reference
