// The path tracer's benchmark: a white-furnace check, then timed renders of the default cloud.
#include <relit/error.hpp>
#include <relit/pathtrace.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>

namespace relit {

namespace {

double furnace_sigma(const Device& dev, int res) {
  const Json j = {{"medium",
                   {{"source", {{"type", "cloud"}, {"resolution", 24}, {"seed", 2}}},
                    {"density_scale", 8.0},
                    {"albedo", 1.0},
                    {"g", 0.5}}},
                  {"environment", {{"radiance", {0.5, 0.5, 0.5}}, {"visible", true}}}};
  const Scene scene = Scene::from_json(j);
  const Camera cam = Camera::look_at({0.3f, -3.0f, 0.4f}, {0, 0, 0}, {0, 0, 1}, 0.45f, res, res);
  PathTraceSettings rs;
  rs.spp = 32;
  rs.seed = 1;
  const RenderResult r = PathTracer(dev, scene).render(cam, {}, rs);
  double sum = 0, var = 0;
  const int n = res * res;
  for (int p = 0; p < n; ++p) sum += r.image.pixels[p * 4], var += r.variance.pixels[p * 4] / rs.spp;
  return std::abs(sum / n - 0.5) / (std::sqrt(var) / n + 1e-9);
}

}  // namespace

PathTraceBenchmark benchmark_pathtracer(const Device& device, int resolution, std::uint32_t spp, std::uint32_t reps,
                                        int scene_resolution) {
  if (resolution < 1 || reps < 1) throw InvalidArgument("benchmark resolution and reps must be >= 1");
  PathTraceBenchmark b;
  b.scene = "cloud (" + std::to_string(scene_resolution) +
            "^3, density_scale 20, albedo 0.96, g 0.4), point light at distance 4";
  b.resolution = resolution, b.spp = spp, b.reps = reps;
  b.furnace_sigma = furnace_sigma(device, std::min(resolution, 16));
  if (!(b.furnace_sigma < 5.0))
    throw DeviceError("path tracer verification failed on " + device.info().name + ": the white furnace is " +
                      std::to_string(b.furnace_sigma) + " standard errors off");
  const Scene scene = Scene::from_json(Scene::builtin_json("cloud", 0, scene_resolution));
  const Camera cam = Camera::look_at({0, -4, 0.5f}, {0, 0, 0}, {0, 0, 1}, 0.8f, resolution, resolution);
  PointLight light;
  light.position = {2.3f, -2.3f, 2.3f};
  const PathTracer pt(device, scene);
  PathTraceSettings rs;
  rs.spp = spp;
  auto seconds = [](auto t0) { return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(); };
  const auto w0 = std::chrono::steady_clock::now();
  pt.render(cam, {light}, rs);
  b.warmup_seconds = seconds(w0);
  std::vector<double> times;
  for (std::uint32_t r = 0; r < reps; ++r) {
    rs.seed = r + 1;
    const auto t0 = std::chrono::steady_clock::now();
    const RenderResult res = pt.render(cam, {light}, rs);
    times.push_back(seconds(t0));
    double lum = 0;
    for (std::size_t p = 0; p < res.image.pixels.size(); p += 4) lum += res.image.pixels[p];
    if (!(lum > 0)) throw DeviceError("path tracer benchmark: the lit cloud rendered black on " + device.info().name);
  }
  std::sort(times.begin(), times.end());
  b.median_seconds = times[times.size() / 2];
  b.samples_per_second = double(resolution) * resolution * spp / b.median_seconds;
  return b;
}

}  // namespace relit
