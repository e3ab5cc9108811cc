// EnvironmentSamples: table upload and kernel launches (the sampler is in kernels/environment.clh).
#include <relit/cl/program.hpp>
#include <relit/render/environment.hpp>
#include <relit/render/volume_renderer.hpp>

namespace relit::render {

namespace {
constexpr std::uint32_t kMaxEnvDirs = 1024;
}

EnvironmentSamples::EnvironmentSamples(const Device& device, const EnvironmentLight& light, std::uint32_t n_env_dirs)
    : m_device(device) {
  if (n_env_dirs == 0 || n_env_dirs > kMaxEnvDirs)
    throw InvalidArgument("EnvironmentSamples: environment directions N_e must be in [1, " +
                          std::to_string(kMaxEnvDirs) + "], got " + std::to_string(n_env_dirs));
  if (light.empty())
    throw InvalidArgument(
        "EnvironmentSamples: the environment light has no image; give the scene an environment "
        "(a map file or a uniform radiance) or set n_env_dirs to 0");
  const Image& image = light.image();
  if (image.channels != 4)
    throw InvalidArgument("EnvironmentSamples: expected the environment's RGBA image, got " +
                          std::to_string(image.channels) + " channels");
  m_texels = Buffer<float>(device, image.pixels);
  m_pdf_uv = Buffer<float>(device, light.pdf_uv());
  m_marginal = Buffer<float>(device, light.marginal_cdf());
  m_conditional = Buffer<float>(device, light.conditional_cdf());
  m_width = image.width;
  m_height = image.height;
  m_scale = light.scale();
  m_visible = light.visible();
  m_dirs = nn::BatchMatrix(device, n_env_dirs, 3);
  m_weights = nn::BatchMatrix(device, n_env_dirs, 3);
}

void EnvironmentSamples::draw(std::uint32_t seed, std::uint32_t iteration) {
  const std::uint32_t n = size();
  m_device.kernel("environment.cl", "env_draw")
      .args(n, seed, iteration, m_texels, m_pdf_uv, m_marginal, m_conditional, m_width, m_height, m_scale,
            m_dirs.data(), m_weights.data())
      .launch(n, 16);
}

void EnvironmentSamples::fill_background(Buffer<float>& rays, std::uint32_t n_rays) const {
  if (rays.size() < std::size_t(n_rays) * kRayFloats)
    throw InvalidArgument("EnvironmentSamples::fill_background: the ray buffer holds " +
                          std::to_string(rays.size() / kRayFloats) + " records, " + std::to_string(n_rays) +
                          " requested");
  if (n_rays == 0) return;
  m_device.kernel("environment.cl", "env_background")
      .args(n_rays, std::uint32_t(m_visible), m_texels, m_width, m_height, m_scale, rays)
      .launch(n_rays, 16);
}

}  // namespace relit::render
