// Camera records and ray generation launches (kernels/rays.cl).
#include <relit/cl/program.hpp>
#include <relit/render/rays.hpp>
#include <relit/render/volume_renderer.hpp>

#include <cmath>

namespace relit::render {

PinholeCamera PinholeCamera::from_fov(const std::array<float, 16>& c2w, float fov_x, std::uint32_t width,
                                      std::uint32_t height) {
  if (!(fov_x > 0.0f && fov_x < 3.14159f)) throw InvalidArgument("field of view must be in (0, pi) radians");
  if (width == 0 || height == 0) throw InvalidArgument("camera resolution must be positive");
  PinholeCamera c;
  c.camera_to_world = c2w;
  c.fx = c.fy = 0.5f * width / std::tan(0.5f * fov_x);
  c.cx = 0.5f * width;
  c.cy = 0.5f * height;
  return c;
}

std::array<float, 16> PinholeCamera::record() const {
  std::array<float, 16> r{};
  for (int i = 0; i < 12; ++i) r[i] = camera_to_world[i];
  r[12] = fx;
  r[13] = fy;
  r[14] = cx;
  r[15] = cy;
  return r;
}

namespace {
template <class T, std::size_t N>
std::vector<float> flatten(const std::vector<T>& items) {
  std::vector<float> out;
  for (const auto& i : items) {
    const std::array<float, N> r = i.record();
    out.insert(out.end(), r.begin(), r.end());
  }
  return out;
}
}  // namespace

RaySource::RaySource(const Device& device, std::uint32_t width, std::uint32_t height,
                     const std::vector<PinholeCamera>& cameras, const std::vector<PointLightRecord>& lights,
                     const std::vector<float>& images)
    : m_device(device), m_width(width), m_height(height), m_n_images(static_cast<std::uint32_t>(cameras.size())) {
  if (cameras.empty() || lights.size() != cameras.size())
    throw InvalidArgument("RaySource: need one light per camera and at least one image (got " +
                          std::to_string(cameras.size()) + " cameras, " + std::to_string(lights.size()) + " lights)");
  if (images.size() != std::size_t(m_n_images) * width * height * 3)
    throw InvalidArgument("RaySource: " + std::to_string(images.size()) + " image values for " +
                          std::to_string(m_n_images) + " RGB images of " + std::to_string(width) + "x" +
                          std::to_string(height));
  m_cameras = Buffer<float>(device, flatten<PinholeCamera, 16>(cameras));
  m_lights = Buffer<float>(device, flatten<PointLightRecord, 8>(lights));
  m_images = Buffer<float>(device, images);
}

void RaySource::training_batch(std::uint32_t n_rays, std::uint32_t seed, std::uint32_t iteration, Buffer<float>& rays,
                               Buffer<float>& targets, Buffer<std::uint32_t>& pixel_ids) const {
  if (rays.size() < std::size_t(n_rays) * kRayFloats || targets.size() < 3 * std::size_t(n_rays) ||
      pixel_ids.size() < n_rays)
    throw InvalidArgument("RaySource::training_batch: buffers too small for " + std::to_string(n_rays) + " rays");
  m_device.kernel("rays.cl", "training_rays")
      .args(n_rays, seed, iteration, m_n_images, m_width, m_height, m_cameras, m_lights, m_images, rays, targets, pixel_ids)
      .launch(n_rays, 16);
}

void image_rays(const Device& device, const PinholeCamera& camera, const PointLightRecord& light, std::uint32_t width,
                std::uint32_t first, std::uint32_t n_rays, Buffer<float>& rays) {
  if (rays.size() < std::size_t(n_rays) * kRayFloats) throw InvalidArgument("image_rays: ray buffer too small");
  const auto c = camera.record();
  const auto l = light.record();
  Buffer<float> cam(device, std::vector<float>(c.begin(), c.end())), lig(device, std::vector<float>(l.begin(), l.end()));
  device.kernel("rays.cl", "image_rays").args(n_rays, first, width, cam, lig, rays).launch(n_rays, 16);
}

}  // namespace relit::render
