// Camera rays for the neural renderer: random training batches over a set of images, and image tiles.
//
// Cameras are relit::Camera (pinhole, camera-to-world in OpenGL/Blender axes: looks down -z, +y up) and
// lights relit::PointLight, as in scenes and datasets. A training batch draws (image, pixel) pairs uniformly on the
// device from (seed, iteration, ray), so an iteration needs no host round trip and a run is reproducible.
#pragma once

#include <relit/parallel.hpp>
#include <relit/cl/buffer.hpp>
#include <relit/layout.clh>
#include <relit/scene/camera.hpp>
#include <relit/scene/light.hpp>

#include <array>
#include <cstdint>
#include <vector>

namespace relit::render {

/// The device record of a camera (kernels/layout.clh): its 3x4 camera-to-world rows, fx, fy, cx, cy in pixels.
std::array<float, kCameraFloats> camera_record(const Camera& camera);
/// The device record of a point light (kernels/layout.clh): position and RGB intensity.
std::array<float, kLightFloats> light_record(const PointLight& light);

/// Images, cameras and lights of a training set, resident on the device.
class RaySource {
 public:
  /// `images`: n x height x width x 3 linear floats (one per camera/light pair).
  /// All cameras must have the same resolution.
  RaySource(const Device& device, const std::vector<Camera>& cameras, const std::vector<PointLight>& lights,
            const std::vector<float>& images);

  std::uint32_t n_images() const { return m_n_images; }
  std::uint32_t width() const { return m_width; }
  std::uint32_t height() const { return m_height; }

  /// Fills `rays` (kRayFloats per ray), `targets` (3 per ray) and `pixel_ids` (image * W * H + pixel). With a
  /// `share` of a global batch (relit/parallel.hpp), the n_rays rays are its rays share.first + share.stride j.
  void training_batch(std::uint32_t n_rays, std::uint32_t seed, std::uint32_t iteration, Buffer<float>& rays,
                      Buffer<float>& targets, Buffer<std::uint32_t>& pixel_ids, parallel::Share share = {}) const;

 private:
  Device m_device;
  std::uint32_t m_width, m_height, m_n_images;
  Buffer<float> m_cameras, m_lights, m_images;
};

/// The rays of one camera's image under one light, tile by tile: the camera and light are uploaded once.
class ImageRays {
 public:
  ImageRays(const Device& device, const Camera& camera, const PointLight& light);
  /// The rays of `n_rays` pixels starting at pixel index `first` (row-major), each through the point `offset`
  /// of its pixel (in pixels from its top-left corner; {0.5, 0.5}: the centre).
  void operator()(std::uint32_t first, std::uint32_t n_rays, Buffer<float>& rays,
                  std::array<float, 2> offset = {0.5f, 0.5f}) const;

 private:
  Device m_device;
  std::uint32_t m_width;
  Buffer<float> m_camera, m_light;
};

/// ImageRays for a single tile.
void image_rays(const Device& device, const Camera& camera, const PointLight& light, std::uint32_t first,
                std::uint32_t n_rays, Buffer<float>& rays, std::array<float, 2> offset = {0.5f, 0.5f});

/// Sample `s` of the n x n grid of points that `spp` = n^2 samples per pixel form in a pixel (row-major, each
/// at the centre of its cell; spp 1: the pixel's centre). Throws InvalidArgument unless spp is a square.
std::array<float, 2> pixel_sample_offset(std::uint32_t spp, std::uint32_t s);

}  // namespace relit::render
