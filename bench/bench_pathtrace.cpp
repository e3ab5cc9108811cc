// bench_pathtrace: path-traced samples per second of the reference path tracer on the default cloud scene
// (built-in "cloud", 64^3 grid, one point light at distance 4, 128x128 view, unlimited bounces), after a
// correctness check (white furnace: an albedo-1 medium in a uniform environment must render its radiance).
// Writes JSON (stdout, or --out FILE).
//
//   bench_pathtrace [--smoke] [--device SEL] [--resolution R] [--spp N] [--reps N] [--out FILE]
// --smoke: tiny sizes, verification only (exit 1 on a wrong result), as run by the test suite.
#include <relit/pathtrace.hpp>
#include <relit/relit.hpp>

#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
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

// White furnace check; returns the worst |mean - L| in units of the image mean's standard error.
double furnace_z(const Device& dev, int res) {
  Json j = {{"medium", {{"source", {{"type", "cloud"}, {"resolution", 24}, {"seed", 2}}}, {"density_scale", 8.0},
                        {"albedo", 1.0}, {"g", 0.5}}},
            {"environment", {{"radiance", {0.5, 0.5, 0.5}}, {"visible", true}}}};
  const Scene scene = Scene::from_json(j);
  const Camera cam = Camera::look_at({0.3f, -3.0f, 0.4f}, {0, 0, 0}, {0, 0, 1}, 0.45f, res, res);
  RenderSettings rs;
  rs.spp = 32;
  rs.seed = 1;
  const RenderResult r = PathTracer(dev, scene).render(cam, {}, rs);
  double sum = 0, var = 0;
  const int n = res * res;
  for (int p = 0; p < n; ++p) sum += r.image.pixels[p * 4], var += r.variance.pixels[p * 4] / rs.spp;
  return std::abs(sum / n - 0.5) / (std::sqrt(var) / n + 1e-9);
}

}  // namespace

int main(int argc, char** argv) {
  Args a;
  for (int i = 1; i < argc; ++i) {
    auto next = [&]() -> std::string {
      if (i + 1 >= argc) throw InvalidArgument(std::string(argv[i]) + " needs a value");
      return argv[++i];
    };
    if (!std::strcmp(argv[i], "--smoke")) a.smoke = true;
    else if (!std::strcmp(argv[i], "--device")) a.device = next();
    else if (!std::strcmp(argv[i], "--resolution")) a.resolution = std::stoi(next());
    else if (!std::strcmp(argv[i], "--spp")) a.spp = std::stoul(next());
    else if (!std::strcmp(argv[i], "--reps")) a.reps = std::stoul(next());
    else if (!std::strcmp(argv[i], "--out")) a.out = next();
    else {
      std::cerr << "usage: bench_pathtrace [--smoke] [--device SEL] [--resolution R] [--spp N] [--reps N] [--out FILE]\n";
      return 2;
    }
  }
  if (a.smoke) a.resolution = 16, a.spp = 2, a.reps = 1;
  try {
    const Device dev = Device::select(a.device);
    const double z = furnace_z(dev, a.smoke ? 8 : 16);
    if (!(z < 5.0)) {
      std::cerr << "bench_pathtrace: white furnace check FAILED (" << z << " standard errors off)\n";
      return 1;
    }
    Scene scene = Scene::from_json(Scene::builtin_json("cloud", 0, a.smoke ? 16 : 64));
    const Camera cam = Camera::look_at({0, -4, 0.5f}, {0, 0, 0}, {0, 0, 1}, 0.8f, a.resolution, a.resolution);
    PointLight light;
    light.position = {2.3f, -2.3f, 2.3f};
    const PathTracer pt(dev, scene);
    RenderSettings rs;
    rs.spp = a.spp;
    const auto c0 = std::chrono::steady_clock::now();
    pt.render(cam, {light}, rs);  // warm-up: kernel build and first launch
    const double warm = std::chrono::duration<double>(std::chrono::steady_clock::now() - c0).count();
    std::vector<double> times;
    double luminance = 0;
    for (std::uint32_t r = 0; r < a.reps; ++r) {
      rs.seed = r + 1;
      const auto t0 = std::chrono::steady_clock::now();
      const RenderResult res = pt.render(cam, {light}, rs);
      times.push_back(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
      luminance = 0;
      for (std::size_t p = 0; p < res.image.pixels.size(); p += 4) luminance += res.image.pixels[p];
      if (!(luminance > 0)) {
        std::cerr << "bench_pathtrace: the lit cloud rendered black\n";
        return 1;
      }
    }
    std::sort(times.begin(), times.end());
    const double median = times[times.size() / 2];
    const double samples = double(a.resolution) * a.resolution * a.spp;
    nlohmann::json doc = {{"benchmark", "pathtrace"}, {"device", dev.info().description()},
                          {"scene", "cloud (64^3, density_scale 20, albedo 0.96, g 0.4), point light at distance 4"},
                          {"resolution", a.resolution}, {"spp", a.spp}, {"reps", a.reps},
                          {"warmup_seconds", warm}, {"median_seconds", median},
                          {"samples_per_second", samples / median}, {"furnace_check_sigma", z}, {"smoke", a.smoke}};
    if (a.out.empty()) std::cout << doc.dump(2) << "\n";
    else std::ofstream(a.out) << doc.dump(2) << "\n";
    std::cerr << "pathtrace: " << samples / median / 1e6 << " M samples/s (median of " << a.reps << ", "
              << a.resolution << "^2 x " << a.spp << " spp)\n";
    return 0;
  } catch (const std::exception& e) {
    std::cerr << "bench_pathtrace: " << e.what() << "\n";
    return 1;
  }
}
