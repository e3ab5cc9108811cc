// Rendering an image with a model: camera rays in tiles, n x n rays per pixel averaged, under a point light
// and optionally an environment light.
#include <relit/method/render_image.hpp>
#include <relit/render/environment.hpp>
#include <relit/render/rays.hpp>
#include <relit/render/volume_renderer.hpp>

#include <algorithm>
#include <array>

namespace relit::method {

Image render_image(const Model& model, const Camera& camera, const PointLight& light,
                   const ImageRenderSettings& settings, const ProgressCallback& progress) {
  camera.validate();
  light.validate();
  if (settings.tile_rays == 0) throw InvalidArgument("render_image: tile_rays must be positive");
  const std::uint32_t spp = settings.spp;
  std::vector<std::array<float, 2>> offsets{render::pixel_sample_offset(spp, 0)};  // throws unless spp is a square
  for (std::uint32_t s = 1; s < spp; ++s) offsets.push_back(render::pixel_sample_offset(spp, s));
  const std::string vis = settings.visibility.empty() ? model.inference_visibility() : settings.visibility;
  if (vis != "network" && vis != "march")
    throw InvalidArgument("render_image: visibility must be \"network\" or \"march\", got \"" + vis + "\"");
  const Device& device = model.device();
  const std::uint32_t total = static_cast<std::uint32_t>(camera.width) * camera.height;
  std::uint32_t tile = std::min(settings.tile_rays, total);
  std::unique_ptr<render::EnvironmentSamples> env;
  if (settings.environment) {
    if (!model.has_environment())
      throw InvalidArgument(
          "render_image: the model was trained without an environment light; render it under "
          "its point light alone (no environment)");
    env = std::make_unique<render::EnvironmentSamples>(device, *settings.environment, model.env_dirs());
  }
  // Keep a tile's network queries near 2^19 (N_e visibility queries per sample with an environment, ...).
  tile = std::min(tile, std::max<std::uint32_t>(16, (1u << 19) / model.queries_per_ray()));
  const auto pass = model.make_pass();
  Buffer<float> rays(device, std::size_t(tile) * render::kRayFloats);
  const int channels = settings.alpha ? 4 : 3;
  Image out(camera.width, camera.height, channels);
  std::vector<float> sample(std::size_t(tile) * 3), transmittance(settings.alpha ? tile : 0);
  const render::ImageRays image_rays(device, camera, light);
  ProgressTracker tracker(progress, std::uint64_t(total) * spp, "rays");
  for (std::uint32_t first = 0, k = 0; first < total; first += tile, ++k) {
    const std::uint32_t n = std::min(tile, total - first);
    float* dst = out.pixels.data() + std::size_t(first) * channels;
    for (std::uint32_t s = 0; s < spp; ++s) {
      const std::uint32_t iteration = k * spp + s;  // spp 1: the tile's index
      image_rays(first, n, rays, offsets[s]);
      if (env) {
        env->draw(settings.seed, iteration);
        env->fill_background(rays, n);
      }
      PassOptions o;
      o.seed = settings.seed;
      o.iteration = iteration;
      o.jitter_seed = settings.seed;
      o.march_visibility = vis == "march";
      o.env = env.get();
      model.render(*pass, rays, n, o);
      model.color(*pass, model.n_colors() - 1).read(sample.data(), 3 * std::size_t(n));
      if (settings.alpha) model.transmittance(*pass).read(transmittance.data(), n);
      for (std::size_t p = 0; p < n; ++p) {  // out starts at 0
        for (int c = 0; c < 3; ++c) dst[p * channels + c] += sample[p * 3 + c];
        if (settings.alpha) dst[p * 4 + 3] += 1.0f - transmittance[p];
      }
      tracker.update(std::uint64_t(first) * spp + std::uint64_t(n) * (s + 1));
    }
    for (std::size_t i = 0; i < std::size_t(channels) * n; ++i) dst[i] /= static_cast<float>(spp);
  }
  return out;
}

}  // namespace relit::method
