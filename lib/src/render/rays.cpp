// Camera records and ray generation launches (kernels/rays.cl).
#include <relit/cl/program.hpp>
#include <relit/render/rays.hpp>
#include <relit/render/volume_renderer.hpp>

#include <string>

namespace relit::render {

std::array<float, kCameraFloats> camera_record(const Camera& camera) {
  camera.validate();
  std::array<float, kCameraFloats> r{};
  for (int row = 0; row < 3; ++row)
    for (int col = 0; col < 4; ++col) r[kCameraToWorld + row * 4 + col] = camera.transform[row][col];
  r[kCameraFocal] = r[kCameraFocal + 1] = camera.focal();
  r[kCameraCentre] = 0.5f * camera.width;
  r[kCameraCentre + 1] = 0.5f * camera.height;
  return r;
}

std::array<float, kLightFloats> light_record(const PointLight& light) {
  light.validate();
  std::array<float, kLightFloats> r{};
  for (int i = 0; i < 3; ++i) {
    r[kLightPosition + i] = light.position[i];
    r[kLightIntensity + i] = light.intensity[i];
  }
  return r;
}

namespace {
template <class T, class Record>
std::vector<float> flatten(const std::vector<T>& items, Record record) {
  std::vector<float> out;
  for (const auto& i : items) {
    const auto r = record(i);
    out.insert(out.end(), r.begin(), r.end());
  }
  return out;
}
}  // namespace

RaySource::RaySource(const Device& device, const std::vector<Camera>& cameras, const std::vector<PointLight>& lights,
                     const std::vector<float>& images)
    : m_device(device), m_n_images(static_cast<std::uint32_t>(cameras.size())) {
  if (cameras.empty() || lights.size() != cameras.size())
    throw InvalidArgument("RaySource: need one light per camera and at least one image (got " +
                          std::to_string(cameras.size()) + " cameras, " + std::to_string(lights.size()) + " lights)");
  m_width = static_cast<std::uint32_t>(cameras[0].width);
  m_height = static_cast<std::uint32_t>(cameras[0].height);
  for (const auto& c : cameras)
    if (c.width != cameras[0].width || c.height != cameras[0].height)
      throw InvalidArgument("RaySource: all cameras must have the same resolution");
  const std::uint32_t width = m_width, height = m_height;
  if (images.size() != std::size_t(m_n_images) * width * height * 3)
    throw InvalidArgument("RaySource: " + std::to_string(images.size()) + " image values for " +
                          std::to_string(m_n_images) + " RGB images of " + std::to_string(width) + "x" +
                          std::to_string(height));
  m_cameras = Buffer<float>(device, flatten(cameras, camera_record));
  m_lights = Buffer<float>(device, flatten(lights, light_record));
  m_images = Buffer<float>(device, images);
}

void RaySource::training_batch(std::uint32_t n_rays, std::uint32_t seed, std::uint32_t iteration, Buffer<float>& rays,
                               Buffer<float>& targets, Buffer<std::uint32_t>& pixel_ids, parallel::Share share) const {
  if (rays.size() < std::size_t(n_rays) * kRayFloats || targets.size() < 3 * std::size_t(n_rays) ||
      pixel_ids.size() < n_rays)
    throw InvalidArgument("RaySource::training_batch: buffers too small for " + std::to_string(n_rays) + " rays");
  m_device.kernel("rays.cl", "training_rays")
      .args(n_rays, seed, iteration, m_n_images, m_width, m_height, m_cameras, m_lights, m_images, rays, targets,
            pixel_ids, share.first, share.stride)
      .launch(n_rays, 16);
}

namespace {
template <std::size_t N>
std::vector<float> to_vector(const std::array<float, N>& a) {
  return {a.begin(), a.end()};
}
}  // namespace

ImageRays::ImageRays(const Device& device, const Camera& camera, const PointLight& light)
    : m_device(device),
      m_width(static_cast<std::uint32_t>(camera.width)),
      m_camera(device, to_vector(camera_record(camera))),
      m_light(device, to_vector(light_record(light))) {}

void ImageRays::operator()(std::uint32_t first, std::uint32_t n_rays, Buffer<float>& rays,
                           std::array<float, 2> offset) const {
  if (rays.size() < std::size_t(n_rays) * kRayFloats) throw InvalidArgument("image_rays: ray buffer too small");
  if (!(offset[0] >= 0.0f && offset[0] <= 1.0f && offset[1] >= 0.0f && offset[1] <= 1.0f))
    throw InvalidArgument("image_rays: the offset in the pixel must lie in [0, 1]^2");
  m_device.kernel("rays.cl", "image_rays")
      .args(n_rays, first, m_width, offset[0], offset[1], m_camera, m_light, rays)
      .launch(n_rays, 16);
}

void image_rays(const Device& device, const Camera& camera, const PointLight& light, std::uint32_t first,
                std::uint32_t n_rays, Buffer<float>& rays, std::array<float, 2> offset) {
  ImageRays(device, camera, light)(first, n_rays, rays, offset);
}

std::array<float, 2> pixel_sample_offset(std::uint32_t spp, std::uint32_t s) {
  if (spp > 65536)
    throw InvalidArgument("samples per pixel must be at most 65536 (a 256 x 256 grid in each pixel), got " +
                          std::to_string(spp));
  std::uint32_t n = 1;
  while (n * n < spp) ++n;
  if (spp == 0 || n * n != spp)
    throw InvalidArgument(
        "samples per pixel must be a square (1, 4, 9, 16, ...): they form an n x n grid in each "
        "pixel; got " +
        std::to_string(spp));
  if (s >= spp)
    throw InvalidArgument("pixel_sample_offset: sample " + std::to_string(s) + " of " + std::to_string(spp));
  return {(static_cast<float>(s % n) + 0.5f) / static_cast<float>(n),
          (static_cast<float>(s / n) + 0.5f) / static_cast<float>(n)};
}

}  // namespace relit::render
