// Camera rays for the neural renderer: random training batches over a set of images, and image tiles.
//
// Cameras: pinhole, camera-to-world 4x4 in OpenGL/Blender axes (looks down -z, +y up), focal length and
// principal point in pixels. A training batch draws (image, pixel) pairs uniformly on the device from
// (seed, iteration, ray), so an iteration needs no host round trip and a run is reproducible.
#pragma once

#include <relit/cl/buffer.hpp>

#include <array>
#include <cstdint>
#include <vector>

namespace relit::render {

struct PinholeCamera {
  std::array<float, 16> camera_to_world{};  ///< row-major 4x4
  float fx = 0, fy = 0, cx = 0, cy = 0;       ///< pixels
  /// A camera of `width` pixels across with horizontal field of view `fov_x` (radians), centred.
  static PinholeCamera from_fov(const std::array<float, 16>& camera_to_world, float fov_x, std::uint32_t width,
                                std::uint32_t height);
  /// The 16-float device record: 3x4 matrix rows, fx, fy, cx, cy.
  std::array<float, 16> record() const;
};

struct PointLightRecord {
  std::array<float, 3> position{};
  std::array<float, 3> intensity{};  ///< RGB radiant intensity, W/sr
  std::array<float, 8> record() const {
    return {position[0], position[1], position[2], 0.f, intensity[0], intensity[1], intensity[2], 0.f};
  }
};

/// Images, cameras and lights of a training set, resident on the device.
class RaySource {
 public:
  /// `images`: n x height x width x 3 linear floats (one per camera/light pair).
  RaySource(const Device& device, std::uint32_t width, std::uint32_t height, const std::vector<PinholeCamera>& cameras,
            const std::vector<PointLightRecord>& lights, const std::vector<float>& images);

  std::uint32_t n_images() const { return m_n_images; }
  std::uint32_t width() const { return m_width; }
  std::uint32_t height() const { return m_height; }

  /// Fills `rays` (kRayFloats per ray), `targets` (3 per ray) and `pixel_ids` (image * W * H + pixel).
  void training_batch(std::uint32_t n_rays, std::uint32_t seed, std::uint32_t iteration, Buffer<float>& rays,
                      Buffer<float>& targets, Buffer<std::uint32_t>& pixel_ids) const;

 private:
  Device m_device;
  std::uint32_t m_width, m_height, m_n_images;
  Buffer<float> m_cameras, m_lights, m_images;
};

/// The rays of `n_rays` pixels of one image starting at pixel index `first` (row-major).
void image_rays(const Device& device, const PinholeCamera& camera, const PointLightRecord& light, std::uint32_t width,
                std::uint32_t first, std::uint32_t n_rays, Buffer<float>& rays);

}  // namespace relit::render
