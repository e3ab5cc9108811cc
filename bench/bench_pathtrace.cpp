// bench_pathtrace: path-traced samples per second of the reference path tracer on the default cloud scene
// (built-in "cloud", 64^3 grid, one point light at distance 4, 128x128 view, unlimited bounces), after a
// correctness check (white furnace: an albedo-1 medium in a uniform environment must render its radiance).
// Writes JSON (stdout, or --out FILE).
//
//   bench_pathtrace [--smoke] [--device SEL] [--resolution R] [--spp N] [--reps N] [--out FILE]
// --smoke: tiny sizes, verification only (exit 1 on a wrong result), as run by the test suite.
#include <relit/io/file.hpp>
#include <relit/pathtrace.hpp>
#include <relit/relit.hpp>

#include <nlohmann/json.hpp>

#include <cstring>
#include <fstream>
#include <iostream>

using namespace relit;

namespace {

struct Args {
  bool smoke = false;
  std::string device, out;
  int resolution = 128;
  std::uint32_t spp = 16, reps = 5;
};

}  // namespace

int main(int argc, char** argv) try {
  Args a;
  for (int i = 1; i < argc; ++i) {
    auto next = [&]() -> std::string {
      if (i + 1 >= argc) throw InvalidArgument(std::string(argv[i]) + " needs a value");
      return argv[++i];
    };
    if (!std::strcmp(argv[i], "--smoke"))
      a.smoke = true;
    else if (!std::strcmp(argv[i], "--device"))
      a.device = next();
    else if (!std::strcmp(argv[i], "--resolution"))
      a.resolution = std::stoi(next());
    else if (!std::strcmp(argv[i], "--spp"))
      a.spp = std::stoul(next());
    else if (!std::strcmp(argv[i], "--reps"))
      a.reps = std::stoul(next());
    else if (!std::strcmp(argv[i], "--out"))
      a.out = next();
    else {
      std::cerr
          << "usage: bench_pathtrace [--smoke] [--device SEL] [--resolution R] [--spp N] [--reps N] [--out FILE]\n";
      return 2;
    }
  }
  if (a.smoke) a.resolution = 16, a.spp = 2, a.reps = 1;
  {
    const Device dev = Device::select(a.device);
    const PathTraceBenchmark b = benchmark_pathtracer(dev, a.resolution, a.spp, a.reps, a.smoke ? 16 : 64);
    nlohmann::json doc = {{"benchmark", "pathtrace"},
                          {"device", dev.info().description()},
                          {"scene", b.scene},
                          {"resolution", b.resolution},
                          {"spp", b.spp},
                          {"reps", b.reps},
                          {"warmup_seconds", b.warmup_seconds},
                          {"median_seconds", b.median_seconds},
                          {"samples_per_second", b.samples_per_second},
                          {"furnace_check_sigma", b.furnace_sigma},
                          {"smoke", a.smoke}};
    const double median = b.median_seconds, samples = double(b.resolution) * b.resolution * b.spp;
    if (a.out.empty())
      std::cout << doc.dump(2) << "\n";
    else
      relit::io::write_file_atomic(a.out, doc.dump(2) + "\n");
    std::cerr << "pathtrace: " << samples / median / 1e6 << " M samples/s (median of " << a.reps << ", " << a.resolution
              << "^2 x " << a.spp << " spp)\n";
    return 0;
  }
} catch (const std::exception& e) {
  std::cerr << "bench_pathtrace: " << e.what() << "\n";
  return 1;
}
