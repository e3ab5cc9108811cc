// The reference volumetric path tracer (docs/design.md §5): unbiased ground truth for media and solids.
//
//   relit::PathTracer pt(device, scene);                 // uploads grids, majorants, environment tables once
//   relit::PathTraceSettings rs; rs.spp = 64; rs.seed = 1;
//   relit::Image img = pt.render(camera, scene.lights, rs, progress).image;   // RGBA, linear
//
// Estimators: delta tracking against a majorant grid, next-event estimation to point lights with ratio
// tracking, environment importance sampling with MIS (power heuristic), HG sampling, Russian roulette,
// unlimited bounces; solids by sphere tracing an SDF grid with the GGX + Lambert BRDF (kernels/pathtrace.clh).
// The image is RGB radiance plus alpha = 1 - transmittance along the camera ray (box-filtered pixels).
// Sample s of pixel p draws from a random stream keyed by (seed, p, s): the same seed gives the same image
// bit for bit on a device, whatever the tiling; other devices agree within Monte Carlo/float tolerance.
#pragma once

#include <relit/cl/device.hpp>
#include <relit/io/image.hpp>
#include <relit/progress.hpp>
#include <relit/scene/scene.hpp>

#include <cstdint>
#include <memory>
#include <vector>

namespace relit {

/// How the reference path tracer renders an image (PathTracer::render, render_reference).
struct PathTraceSettings {
  std::uint32_t spp = 64;         ///< samples per pixel, >= 1
  std::uint32_t seed = 0;         ///< random seed
  std::uint32_t max_bounces = 0;  ///< scattering events gathered per path; 0 = unlimited (1 = single scattering)
  std::uint32_t rr_depth = 3;     ///< Russian roulette from this vertex on
  std::uint32_t samples_per_launch = 1u << 18;  ///< work per kernel launch: keeps launches short, progress flowing

  void validate() const;
};

struct RenderResult {
  Image image;     ///< RGBA mean over the samples
  Image variance;  ///< per-pixel variance of one sample's RGBA (divide by spp for the variance of the mean)
  std::uint32_t spp = 0;
};

class PathTracer {
 public:
  PathTracer(const Device& device, const Scene& scene);
  ~PathTracer();
  PathTracer(PathTracer&&) noexcept;
  PathTracer& operator=(PathTracer&&) noexcept;

  /// Renders `camera`'s view lit by `lights` (plus the scene's environment, if any).
  RenderResult render(const Camera& camera, const std::vector<PointLight>& lights, const PathTraceSettings& settings,
                      const ProgressCallback& progress = {}) const;
  const Device& device() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> m_impl;
};

/// One-call form: renders the scene's camera `camera_index` under the scene's own lights.
Image render_reference(const Device& device, const Scene& scene, std::size_t camera_index,
                       const PathTraceSettings& settings, const ProgressCallback& progress = {});

/// Throughput of the path tracer on the default cloud scene (built-in "cloud", 64^3 grid, one point light at
/// distance 4, unlimited bounces), measured after a correctness check. For `relit bench` and bench_pathtrace.
struct PathTraceBenchmark {
  std::string scene;
  int resolution = 0;
  std::uint32_t spp = 0, reps = 0;
  double warmup_seconds = 0;  ///< first render (kernel build and first launch)
  double median_seconds = 0;  ///< median over `reps` renders
  double samples_per_second = 0;
  double furnace_sigma = 0;  ///< white-furnace check: |mean - L| in standard errors (must be < 5)
};

/// Verifies (white furnace: throws DeviceError when the device renders it wrong), then times `reps` renders
/// of resolution^2 pixels at `spp` samples per pixel. `scene_resolution` is the cloud's grid size.
PathTraceBenchmark benchmark_pathtracer(const Device& device, int resolution = 128, std::uint32_t spp = 16,
                                        std::uint32_t reps = 5, int scene_resolution = 64);

}  // namespace relit
