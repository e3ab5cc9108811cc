// bench_encodings: throughput of the encodings on one device, results verified against double-precision
// host references before anything is timed. Writes JSON (stdout, or --out FILE).
//
//   bench_encodings [--smoke] [--device SEL] [--batch N] [--reps N] [--log2-hashmap-size K] [--hash-grid-only]
//                   [--out FILE]
//
// HashGrid target configuration (instant-ngp's NeRF grid, 3-D): 16 levels x 2 features, T = 2^19, base
// resolution 16, finest 2048 (per_level_scale 2^(7/15)), batch 76,800 = 1200 rays x 64 samples in ray order.
// --smoke: tiny sizes, verification only (exit 1 on a wrong result), as run by the test suite.
//
// First it measures the device's random-access rates (8-byte reads and read-modify-writes, kernels/
// random_access.cl: in a 256 KiB table, in one table of a hashed level's size (4 MiB at T = 2^19), in 16 such
// tables used in turn as the levels are, and in one 64 MiB table), and reports beside the hash grid's
// measured rate the bound those rates put on it: "hash_grid_roofline" (distinct cache lines per sample and
// level / rate).
#include <relit/io/file.hpp>
#include <relit/nn/encodings.hpp>
#include <relit/nn/registry.hpp>
#include <relit/relit.hpp>
#include <relit/sh.hpp>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <fstream>
#include <iostream>
#include <random>

using namespace relit;
using nn::BatchMatrix;
using nn::HashGridEncoding;

namespace {

struct Args {
  bool smoke = false, hash_grid_only = false;
  std::string device, out;
  std::uint32_t batch = 76800, reps = 15, log2_hashmap_size = 19;
};

// Samples along `batch / 64` random rays through the unit cube, 64 stratified samples each, in ray order
// (how a renderer produces them).
std::vector<float> ray_samples(std::uint32_t batch, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0, 1);
  std::vector<float> x(static_cast<std::size_t>(batch) * 3);
  const std::uint32_t per_ray = 64;
  for (std::uint32_t r = 0; r * per_ray < batch; ++r) {
    std::array<double, 3> a, b;
    for (int d = 0; d < 3; ++d) a[d] = u(rng), b[d] = u(rng);
    const int face = static_cast<int>(u(rng) * 3);  // start and end on opposite faces of the cube
    a[face] = 0.0;
    b[face] = 1.0;
    for (std::uint32_t i = 0; i < per_ray && r * per_ray + i < batch; ++i) {
      const double t = (i + u(rng)) / per_ray;
      for (int d = 0; d < 3; ++d) x[(r * per_ray + i) * 3 + d] = static_cast<float>(a[d] + t * (b[d] - a[d]));
    }
  }
  return x;
}

// Double reference of the hash grid (cells in float exactly as the kernel, weights and sums in double).
template <class Visit>
void grid_visit(const HashGridEncoding& enc, const float* x, Visit visit) {
  const std::uint32_t dims = enc.n_input_dims(), F = enc.options().n_features_per_level;
  for (std::uint32_t l = 0; l < enc.levels().size(); ++l) {
    const auto& L = enc.levels()[l];
    std::array<std::uint32_t, 3> cell{};
    std::array<double, 3> frac{};
    for (std::uint32_t d = 0; d < dims; ++d) {
      const float p = std::fma(std::fmin(std::fmax(x[d], 0.0f), 1.0f), L.scale, 0.5f), f = std::floor(p);
      cell[d] = static_cast<std::uint32_t>(f);
      frac[d] = p - f;
    }
    for (std::uint32_t c = 0; c < (1u << dims); ++c) {
      std::uint32_t index = 0, stride = 1;
      double w = 1;
      for (std::uint32_t d = 0; d < dims; ++d) {
        const std::uint32_t v = cell[d] + ((c >> d) & 1);
        if (L.hashed)
          index ^= v * HashGridEncoding::kPrimes[d];
        else
          index += v * stride;
        stride *= L.res;
        w *= ((c >> d) & 1) ? frac[d] : 1 - frac[d];
      }
      if (L.hashed) index &= L.size - 1;
      for (std::uint32_t f = 0; f < F; ++f) visit(l * F + f, L.offset + index * F + f, w);
    }
  }
}

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

double process_cpu_seconds() {
  timespec ts{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return ts.tv_sec + 1e-9 * ts.tv_nsec;
}

// Median wall seconds of `reps` runs of f() + device.finish(); `cpu` gets the median process CPU time (all
// driver threads), which time-sharing with other processes inflates far less than wall time.
template <class F>
double median_time(const Device& device, std::uint32_t reps, F f, double* cpu = nullptr) {
  f();
  device.finish();  // warm (first launch compiles the work-group function)
  std::vector<double> t, c;
  for (std::uint32_t i = 0; i < reps; ++i) {
    const auto t0 = std::chrono::steady_clock::now();
    const double c0 = process_cpu_seconds();
    f();
    device.finish();
    t.push_back(seconds_since(t0));
    c.push_back(process_cpu_seconds() - c0);
  }
  std::sort(t.begin(), t.end());
  std::sort(c.begin(), c.end());
  if (cpu) *cpu = c[c.size() / 2];
  return t[t.size() / 2];
}

bool check(bool ok, const std::string& what, double error, Json& report) {
  report["checks"].push_back({{"what", what}, {"max_error", error}, {"ok", ok}});
  if (!ok) std::cerr << "bench_encodings: WRONG RESULT: " << what << " (max error " << error << ")\n";
  return ok;
}

// The memory roofline of the hash grid (bench/kernels/random_access.cl): the device's rate of independent random
// 8-byte reads and read-modify-writes in tables of `bytes`, one work-item per compute unit, as many misses in
// flight as the cores allow. `tables` > 1: that many tables used in turn, as the hash grid uses its levels'
// (reads: all work-items walk the same `tables` tables; read-modify-writes: the work-items share them out,
// each walking tables / work-items of its own, as the backward deals out the levels); `prefetch`: each table
// is prefetched sequentially while the one before it is in use (as the hash-grid kernels do on CPUs).
// Verified exactly (integer counts in float) before it is timed.
struct AccessRate {
  std::uint64_t bytes = 0;
  std::uint32_t tables = 1;
  bool prefetch = false;
  double read_per_s = 0, rmw_per_s = 0;
};

std::uint32_t ra_hash(std::uint32_t counter) {  // ra_index of random_access.cl, one lane
  std::uint32_t h = counter * 0x9E3779B1u;
  h ^= h >> 15;
  h *= 0x85EBCA77u;
  return h ^ (h >> 13);
}

AccessRate random_access_rate(const Device& device, std::uint64_t bytes, std::uint32_t tables, bool prefetch,
                              const Args& a, Json& report, bool& ok) {
  const std::uint32_t entries = static_cast<std::uint32_t>(bytes / 8), mask = entries - 1;
  const std::uint32_t items = std::max(1u, device.info().compute_units);
  const std::uint32_t iters = a.smoke ? 256 : (1u << 17);  // 2^21 accesses per work-item
  const std::uint64_t per_call = static_cast<std::uint64_t>(items) * iters * 16;
  const std::size_t floats = static_cast<std::size_t>(entries) * 2;  // one table
  Buffer<float> shared(device, std::vector<float>(floats * tables, 1.0f)), sums(device, items);
  Kernel read = device.kernel("random_access.cl", "random_read");
  read.args(iters, mask, tables, static_cast<std::uint32_t>(prefetch), shared, sums);
  read.launch(items, 1);
  double err = 0;
  for (float v : sums.read()) err = std::max(err, std::abs(v - 32.0 * iters));
  const std::uint32_t own = std::max(1u, tables / items);  // tables per work-item
  Buffer<float> owned(device, std::vector<float>(floats * own * items, 0.0f));
  Kernel rmw = device.kernel("random_access.cl", "random_rmw");
  rmw.args(iters, mask, own, static_cast<std::uint32_t>(prefetch), owned);
  rmw.launch(items, 1);
  // Replay the kernel's hash for the last work-item: each of its entries must hold its count of visits.
  std::vector<float> want(floats * own, 0.0f);
  for (std::uint32_t r = 0; r < iters; ++r)
    for (std::uint32_t l = 0; l < 16; ++l) {
      const std::size_t t = static_cast<std::uint64_t>(r) * own / iters;
      const std::size_t e = t * entries + (ra_hash(((items - 1) * iters + r) * 16u + l) & mask);
      want[e * 2] += 1.0f;
      want[e * 2 + 1] += 1.0f;
    }
  const std::vector<float> got = owned.read();
  for (std::size_t i = 0; i < want.size(); ++i)
    err = std::max(err, std::abs(got[(items - 1) * want.size() + i] - double(want[i])));
  const std::string what = std::to_string(bytes >> 10) + " KiB" +
                           (tables > 1 ? " x " + std::to_string(tables) + " in turn" : "") +
                           (prefetch ? ", next prefetched" : "");
  ok &= check(err == 0, "random access " + what + " (exact counts)", err, report);
  AccessRate r{bytes, tables, prefetch};
  if (!ok || a.smoke) return r;
  const double t_read = median_time(device, a.reps, [&] { read.launch(items, 1); });
  const double t_rmw = median_time(device, a.reps, [&] { rmw.launch(items, 1); });
  r.read_per_s = per_call / t_read;
  r.rmw_per_s = per_call / t_rmw;
  report["random_access"].push_back({{"table_bytes", bytes},
                                     {"tables_in_turn", tables},
                                     {"next_table_prefetched", prefetch},
                                     {"work_items", items},
                                     {"accesses", per_call},
                                     {"read_per_s", r.read_per_s},
                                     {"rmw_per_s", r.rmw_per_s}});
  return r;
}

// `rates`: the random-access rates (random_access_rate) for the roofline: in a 256 KiB table (cached), in
// one table of the grid's hashed-level size (`warm`), and in n_levels such tables in turn, each brought in
// by its random misses (`in_turn`) or prefetched while the one before it is used (`in_turn_prefetched`).
struct Rates {
  AccessRate cached, warm, in_turn, in_turn_prefetched;
};

bool bench_hash_grid(const Device& device, const Args& a, const Rates& rates, Json& report) {
  const Json cfg = {{"type", "HashGrid"},        {"n_levels", 16},
                    {"n_features_per_level", 2}, {"log2_hashmap_size", a.smoke ? 14 : a.log2_hashmap_size},
                    {"base_resolution", 16},     {"per_level_scale", std::exp2(7.0 / 15.0)}};
  auto base = nn::create_encoding(cfg, 3);
  const auto& enc = dynamic_cast<const HashGridEncoding&>(*base);
  std::vector<float> init(enc.n_params());
  enc.initialize_params(init.data(), 1);
  for (float& v : init) v *= 1e4f;  // O(1) values, so the check is meaningful
  Buffer<float> params(device, init), grads(device, enc.n_params());
  const std::vector<float> xs = ray_samples(a.batch, 2);
  BatchMatrix in(device, a.batch, 3), out(device, a.batch, enc.n_output_dims()),
      d_out(device, a.batch, enc.n_output_dims());
  in.upload_row_major(xs);
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> u(-1, 1);
  std::vector<float> g(static_cast<std::size_t>(a.batch) * enc.n_output_dims());
  for (float& v : g) v = u(rng);
  d_out.upload_row_major(g);

  // Verify: forward on every sample, gradient of every parameter.
  bool ok = true;
  enc.forward(device, {&params, 0}, in, out, 0, nullptr);
  enc.backward(device, {&params, 0}, in, d_out, 0, {&grads, 0}, false, nullptr, nullptr);
  const std::vector<float> got = out.download_row_major(), got_g = grads.read();
  std::vector<double> ref_out(got.size(), 0.0), ref_g(enc.n_params(), 0.0);
  const std::uint32_t cols = enc.n_output_dims();
  for (std::uint32_t s = 0; s < a.batch; ++s)
    grid_visit(enc, &xs[s * 3], [&](std::uint32_t col, std::uint32_t p, double w) {
      ref_out[s * cols + col] += w * init[p];
      ref_g[p] += w * g[s * cols + col];
    });
  double err = 0, gerr = 0, gscale = 0;
  for (double v : ref_g) gscale = std::max(gscale, std::abs(v));
  for (std::size_t i = 0; i < got.size(); ++i)
    err = std::max(err, std::abs(got[i] - ref_out[i]) / (1.0 + std::abs(ref_out[i])));  // table values are O(1)
  for (std::size_t i = 0; i < got_g.size(); ++i)
    gerr = std::max(gerr, std::abs(got_g[i] - ref_g[i]) / (std::abs(ref_g[i]) + 1e-3 * gscale));
  ok &= check(err <= 1e-5, "HashGrid forward (relative to 1 + |value|)", err, report);
  ok &= check(gerr <= 1e-4, "HashGrid parameter gradient (relative)", gerr, report);
  if (!ok || a.smoke) return ok;

  double fwd_cpu = 0, bwd_cpu = 0, both_cpu = 0;
  const double fwd = median_time(
      device, a.reps,
      [&] {
        enc.forward(device, {&params, 0}, in, out, 0, nullptr);
      },
      &fwd_cpu);
  const double bwd = median_time(
      device, a.reps,
      [&] {
        enc.backward(device, {&params, 0}, in, d_out, 0, {&grads, 0}, false, nullptr, nullptr);
      },
      &bwd_cpu);
  const double both = median_time(
      device, a.reps,
      [&] {
        enc.forward(device, {&params, 0}, in, out, 0, nullptr);
        enc.backward(device, {&params, 0}, in, d_out, 0, {&grads, 0}, false, nullptr, nullptr);
      },
      &both_cpu);
  // Same grid, samples in random order over the cube (no ray coherence), for comparison.
  std::vector<float> shuffled = xs;
  for (float& v : shuffled) v = (u(rng) + 1) / 2;
  BatchMatrix in_random(device, a.batch, 3);
  in_random.upload_row_major(shuffled);
  const double both_random = median_time(device, a.reps, [&] {
    enc.forward(device, {&params, 0}, in_random, out, 0, nullptr);
    enc.backward(device, {&params, 0}, in_random, d_out, 0, {&grads, 0}, false, nullptr, nullptr);
  });
  // Roofline: the distinct 64-byte lines each sample touches per level (x-neighbours mostly share one, as
  // prime_x = 1), each costing one random access at the measured rate: the cached rate for tables of at most
  // 256 KiB, else the rate of tables used in turn (the kernels' level-major order: each pass brings every
  // large table back from memory; the faster of with and without prefetching the next table), and, for
  // comparison, the rate if every table stayed cached (`warm`).
  // The kernels also compute, so these bound them from above.
  const std::size_t n_levels = enc.levels().size();
  std::vector<double> lines(n_levels, 0.0);
  for (std::uint32_t s = 0; s < a.batch; ++s) {
    std::vector<std::vector<std::uint32_t>> seen(n_levels);
    grid_visit(enc, &xs[s * 3], [&](std::uint32_t col, std::uint32_t p, double) {
      auto& v = seen[col / enc.options().n_features_per_level];
      if (std::find(v.begin(), v.end(), p / 16) == v.end()) v.push_back(p / 16);
    });
    for (std::size_t l = 0; l < n_levels; ++l) lines[l] += static_cast<double>(seen[l].size()) / a.batch;
  }
  double fwd_s = 0, bwd_s = 0, fwd_warm_s = 0, bwd_warm_s = 0, total_lines = 0;
  Json per_level = Json::array();
  for (std::size_t l = 0; l < n_levels; ++l) {
    const auto& L = enc.levels()[l];
    const std::uint64_t bytes = static_cast<std::uint64_t>(L.size) * enc.options().n_features_per_level * 4;
    const bool cached = bytes <= rates.cached.bytes;
    const AccessRate &t = rates.in_turn, &p = rates.in_turn_prefetched;
    const double read = cached ? rates.cached.read_per_s : std::max(t.read_per_s, p.read_per_s);
    const double rmw = cached ? rates.cached.rmw_per_s : std::max(t.rmw_per_s, p.rmw_per_s);
    const AccessRate& w = cached ? rates.cached : rates.warm;
    fwd_s += lines[l] / read;
    bwd_s += lines[l] / rmw;
    fwd_warm_s += lines[l] / w.read_per_s;
    bwd_warm_s += lines[l] / w.rmw_per_s;
    total_lines += lines[l];
    per_level.push_back({{"table_bytes", bytes}, {"hashed", L.hashed}, {"lines_per_sample", lines[l]}});
  }
  report["hash_grid_roofline"] = {
      {"lines_per_sample", total_lines},
      {"levels", per_level},
      {"forward_bound_samples_per_s", 1 / fwd_s},
      {"backward_params_bound_samples_per_s", 1 / bwd_s},
      {"forward_backward_bound_samples_per_s", 1 / (fwd_s + bwd_s)},
      {"forward_backward_fraction_of_bound", (fwd_s + bwd_s) / both * a.batch},
      {"forward_backward_bound_if_tables_stayed_cached_samples_per_s", 1 / (fwd_warm_s + bwd_warm_s)}};
  report["hash_grid"] = {{"config", enc.hyperparams()},
                         {"n_params", enc.n_params()},
                         {"batch", a.batch},
                         {"forward_samples_per_s", a.batch / fwd},
                         {"backward_params_samples_per_s", a.batch / bwd},
                         {"forward_backward_samples_per_s", a.batch / both},
                         {"forward_backward_uniform_random_samples_per_s", a.batch / both_random},
                         {"forward_ms", fwd * 1e3},
                         {"backward_ms", bwd * 1e3},
                         {"forward_backward_ms", both * 1e3},
                         {"forward_cpu_ms", fwd_cpu * 1e3},
                         {"backward_cpu_ms", bwd_cpu * 1e3},
                         {"forward_backward_cpu_ms", both_cpu * 1e3}};
  return ok;
}

bool bench_frequency_and_sh(const Device& device, const Args& a, Json& report) {
  bool ok = true;
  std::mt19937 rng(4);
  std::uniform_real_distribution<float> u(-1, 1);
  std::vector<float> pos(static_cast<std::size_t>(a.batch) * 3), dir(pos.size());
  for (float& v : pos) v = u(rng);
  for (std::uint32_t s = 0; s < a.batch; ++s) {
    double d[3] = {u(rng), u(rng), u(rng)};
    const double n = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]) + 1e-12;
    for (int i = 0; i < 3; ++i) dir[s * 3 + i] = static_cast<float>(d[i] / n);
  }
  BatchMatrix in_pos(device, a.batch, 3), in_dir(device, a.batch, 3), d_in(device, a.batch, 3);
  in_pos.upload_row_major(pos);
  in_dir.upload_row_major(dir);

  for (std::uint32_t n_freq : {10u, 16u}) {
    auto enc = nn::create_encoding({{"type", "Frequency"}, {"n_frequencies", n_freq}}, 3);
    BatchMatrix out(device, a.batch, enc->n_output_dims()), d_out(device, a.batch, enc->n_output_dims());
    enc->forward(device, {}, in_pos, out, 0, nullptr);
    const std::vector<float> got = out.download_row_major();
    double err = 0;
    for (std::uint32_t s = 0; s < a.batch; ++s)
      for (std::uint32_t d = 0; d < 3; ++d)
        for (std::uint32_t k = 0; k < n_freq; ++k) {
          const double arg = std::ldexp(static_cast<double>(pos[s * 3 + d]), static_cast<int>(k)) * M_PI;
          const std::size_t o = static_cast<std::size_t>(s) * enc->n_output_dims() + d * 2 * n_freq + 2 * k;
          err = std::max({err, std::abs(got[o] - std::sin(arg)), std::abs(got[o + 1] - std::cos(arg))});
        }
    ok &= check(err <= 1e-5, "Frequency n_frequencies=" + std::to_string(n_freq) + " (absolute)", err, report);
    if (!ok || a.smoke) continue;
    d_out.data().fill(1.0f);
    const double fwd = median_time(device, a.reps, [&] { enc->forward(device, {}, in_pos, out, 0, nullptr); });
    const double bwd =
        median_time(device, a.reps, [&] { enc->backward(device, {}, in_pos, d_out, 0, {}, false, &d_in, nullptr); });
    report["frequency"].push_back({{"n_frequencies", n_freq},
                                   {"n_input_dims", 3},
                                   {"batch", a.batch},
                                   {"forward_samples_per_s", a.batch / fwd},
                                   {"backward_input_samples_per_s", a.batch / bwd},
                                   {"max_abs_error_vs_double", err}});
  }
  for (std::uint32_t degree : {4u, 10u}) {
    auto enc = nn::create_encoding({{"type", "SphericalHarmonics"}, {"degree", degree}}, 3);
    BatchMatrix out(device, a.batch, enc->n_output_dims()), d_out(device, a.batch, enc->n_output_dims());
    enc->forward(device, {}, in_dir, out, 0, nullptr);
    const std::vector<float> got = out.download_row_major();
    double err = 0;
    for (std::uint32_t s = 0; s < a.batch; s += 7) {
      const auto y = sh::eval(static_cast<int>(degree) - 1, {dir[s * 3], dir[s * 3 + 1], dir[s * 3 + 2]});
      for (std::uint32_t i = 0; i < degree * degree; ++i)
        err = std::max(err, std::abs(got[static_cast<std::size_t>(s) * degree * degree + i] - y[i]));
    }
    ok &= check(err <= 1e-5, "SphericalHarmonics degree=" + std::to_string(degree) + " (absolute)", err, report);
    if (!ok || a.smoke) continue;
    d_out.data().fill(1.0f);
    const double fwd = median_time(device, a.reps, [&] { enc->forward(device, {}, in_dir, out, 0, nullptr); });
    const double bwd =
        median_time(device, a.reps, [&] { enc->backward(device, {}, in_dir, d_out, 0, {}, false, &d_in, nullptr); });
    report["spherical_harmonics"].push_back({{"degree", degree},
                                             {"batch", a.batch},
                                             {"forward_samples_per_s", a.batch / fwd},
                                             {"backward_input_samples_per_s", a.batch / bwd}});
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
    else if (s == "--batch")
      a.batch = static_cast<std::uint32_t>(std::stoul(next()));
    else if (s == "--reps")
      a.reps = static_cast<std::uint32_t>(std::stoul(next()));
    else if (s == "--out")
      a.out = next();
    else if (s == "--hash-grid-only")
      a.hash_grid_only = true;
    else if (s == "--log2-hashmap-size")
      a.log2_hashmap_size = static_cast<std::uint32_t>(std::stoul(next()));
    else {
      std::cerr << "usage: bench_encodings [--smoke] [--device SEL] [--batch N] [--reps N] [--log2-hashmap-size K] "
                   "[--hash-grid-only] [--out FILE]\n";
      return 2;
    }
  }
  if (a.smoke) a.batch = 2048 + 77;  // not a multiple of the batch granularity
  if (a.batch < 1 || a.reps < 1) {
    std::cerr << "bench_encodings: --batch and --reps must be positive\n";
    return 2;
  }
  try {
    const Device device = Device::select(a.device);
    Json report = {
        {"bench", "encodings"}, {"device", device.info().description()}, {"smoke", a.smoke}, {"checks", Json::array()}};
    bool ok = true;
    Rates rates;
    const std::uint64_t table = 8ull << (a.smoke ? 14 : a.log2_hashmap_size);  // a hashed level's, 2 features
    rates.cached = random_access_rate(device, a.smoke ? 64 << 10 : 256 << 10, 1, false, a, report, ok);
    rates.warm = random_access_rate(device, table, 1, false, a, report, ok);
    rates.in_turn = random_access_rate(device, table, 16, false, a, report, ok);
    rates.in_turn_prefetched = random_access_rate(device, table, 16, true, a, report, ok);
    if (!a.smoke) random_access_rate(device, 64 << 20, 1, false, a, report, ok);  // every level's table at once
    ok &= bench_hash_grid(device, a, rates, report);
    if (!a.hash_grid_only) ok &= bench_frequency_and_sh(device, a, report);
    report["ok"] = ok;
    const std::string text = report.dump(2);
    if (a.out.empty())
      std::cout << text << "\n";
    else
      relit::io::write_file_atomic(a.out, text + "\n");
    return ok ? 0 : 1;
  } catch (const std::exception& e) {
    std::cerr << "bench_encodings: " << e.what() << "\n";
    return 1;
  }
}
