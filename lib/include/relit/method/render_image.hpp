// Relighting: a model's image from any camera under any point light (and the environment light of a model
// trained on 'env+point' data), in linear RGB (docs/method.md, "Relighting").
//
//   auto model = relit::method::load_model(device, "runs/cloud/checkpoint.relit");
//   relit::method::ImageRenderSettings settings;
//   settings.spp = 4;                                                    // 2 x 2 rays per pixel, averaged
//   relit::PointLight light{{3, -3, 2}, {800, 800, 800}};                // W/sr
//   relit::Image img = relit::method::render_image(*model, camera, light, settings);
#pragma once

#include <relit/io/image.hpp>
#include <relit/method/model.hpp>
#include <relit/progress.hpp>
#include <relit/scene/camera.hpp>
#include <relit/scene/light.hpp>

#include <cstdint>
#include <string>

namespace relit::method {

/// How render_image renders a model's image: tiles, rays per pixel, visibility, environment.
struct ImageRenderSettings {
  std::uint32_t tile_rays = 1024;  ///< rays per pass (small tiles stay in cache)
  std::uint32_t seed = 0;          ///< draws the indirect directions
  /// Rays per pixel, averaged: an n x n grid in each pixel (a box filter, as the path tracer's references;
  /// anti-aliases the medium's edges). A square: 1, 4, 9, 16, ... Each sample draws its own indirect directions.
  std::uint32_t spp = 1;
  /// "" uses the model's inference_visibility setting; "network" or "march" override it.
  std::string visibility;
  /// Light the scene with this environment map as well (a model trained on 'env+point' data; it is sampled
  /// in model/environment/n_dirs directions). Null: the point light alone.
  const EnvironmentLight* environment = nullptr;
  /// Also the alpha (1 - the camera ray's transmittance, averaged over the pixel's rays): RGBA out.
  bool alpha = false;
};

/// Renders `camera`'s image under `light` with the model: linear RGB (RGBA with settings.alpha), in tiles, with
/// progress counted in rays (pixels x spp).
Image render_image(const Model& model, const Camera& camera, const PointLight& light,
                   const ImageRenderSettings& settings = {}, const ProgressCallback& progress = {});

}  // namespace relit::method
