// Host reference of the calibrated FMA peak kernels (kernels/peak.cl), shared by bench_mlp and relit bench.
#pragma once

#include <cmath>
#include <cstddef>

namespace relit::reference {

/// Work-item `gid`'s result: 12 chains x `lanes` lanes of `iters` FMAs a = a * c + b, summed chain by chain, then
/// lane by lane (the kernel's order).
inline float peak_host(std::size_t gid, unsigned iters, float c, unsigned lanes) {
  float s = 0.0f;
  const float base = static_cast<float>(gid % 64u) * 0.001f;
  for (unsigned i = 0; i < 12; ++i)
    for (unsigned l = 0; l < lanes; ++l) {
      float a = std::fma(static_cast<float>(l), 0.01f, base + static_cast<float>(i) * 0.1f);
      const float b = std::fma(static_cast<float>(l), 0.001f, static_cast<float>(i) * 0.01f);
      for (unsigned it = 0; it < iters; ++it) a = std::fma(a, c, b);
      s += a;
    }
  return s;
}

}  // namespace relit::reference
