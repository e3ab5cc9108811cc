// VolumeRenderer: argument checks and kernel launches (the math is in kernels/render.cl).
#include <relit/cl/program.hpp>
#include <relit/nn/registry.hpp>
#include <relit/render/environment.hpp>
#include <relit/render/volume_renderer.hpp>

#include <algorithm>

namespace relit::render {

namespace {
// Without environment light the kernels' environment arguments are unused: an empty buffer passes NULL.
const Buffer<float> kNoBuffer;
const Buffer<float>& env_dirs(const EnvironmentSamples* env) { return env ? env->dirs().data() : kNoBuffer; }
const Buffer<float>& env_weights(const EnvironmentSamples* env) { return env ? env->weights().data() : kNoBuffer; }
}  // namespace

VolumeRenderer::VolumeRenderer(const Device& device, const VolumeRendererSettings& settings)
    : m_device(device), m_settings(settings), m_brdf(settings.scattering == "brdf") {
  if (settings.scattering != "phase" && settings.scattering != "brdf")
    throw InvalidArgument("VolumeRendererSettings::scattering must be \"phase\" (media) or \"brdf\" (solids), got \"" +
                          settings.scattering + "\"");
  if (m_brdf && settings.closed_form_indirect)
    throw InvalidArgument(
        "VolumeRendererSettings: closed_form_indirect has no closed form with scattering \"brdf\" (the "
        "Funk-Hecke identity it uses holds for the HG phase function only); set "
        "closed_form_indirect = false to use the K-direction sum");
  if (settings.n_samples == 0 || settings.n_samples % nn::kBatchTile != 0 || settings.n_samples > 4096)
    throw InvalidArgument("samples per ray must be a positive multiple of 16 up to 4096, got " +
                          std::to_string(settings.n_samples));
  if (settings.sh_lmax < -1 || settings.sh_lmax > 9)
    throw InvalidArgument("sh_lmax must be in [-1, 9] (-1: no indirect light), got " +
                          std::to_string(settings.sh_lmax));
  if (settings.n_dirs == 0 || settings.n_dirs > 4096)
    throw InvalidArgument("indirect-light directions must be in [1, 4096], got " + std::to_string(settings.n_dirs));
  if (settings.n_env_dirs > 1024)
    throw InvalidArgument("environment directions n_env_dirs must be in [0, 1024] (0: no environment light), got " +
                          std::to_string(settings.n_env_dirs));
  m_n_sh = settings.sh_lmax < 0 ? 0 : static_cast<std::uint32_t>((settings.sh_lmax + 1) * (settings.sh_lmax + 1));
  m_defines = {{"N_SAMPLES", std::to_string(settings.n_samples)},
               {"N_SH", std::to_string(m_n_sh)},
               {"N_DIRS", std::to_string(settings.n_dirs)},
               {"INDIRECT_MODE", settings.closed_form_indirect ? "1" : "0"},
               {"N_ENV", std::to_string(settings.n_env_dirs)},
               {"SCATTERING_BRDF", m_brdf ? "1" : "0"},
               {"VISIBILITY_GRADIENT", settings.visibility_gradient ? "1" : "0"}};
  parse_kernel_variant(settings.kernel_variant, "VolumeRendererSettings::kernel_variant");
  if (m_n_sh) m_sh = nn::create_encoding({{"type", "SphericalHarmonics"}, {"degree", settings.sh_lmax + 1}}, 3);
  set_kernels(std::nullopt);
}

void VolumeRenderer::set_kernels(std::optional<KernelVariant> variant, std::optional<WorkGroupParams> params) {
  if (params && (params->items < 1 || params->items > 1024))
    throw InvalidArgument("VolumeRenderer::set_kernels: items must be in [1, 1024], got " +
                          std::to_string(params->items));
  m_choice = choose(variant, variant ? params : std::nullopt);
  m_wg_defines = workgroup_defines(m_choice.workgroup);
}

Defines VolumeRenderer::workgroup_defines(const WorkGroupParams& p) const {
  Defines d = m_defines;
  d["RAY_ITEMS"] = std::to_string(p.items);
  d["STAGE_DIRS"] = p.stage ? "1" : "0";
  return d;
}

VolumeRenderer::KernelChoice VolumeRenderer::choose(std::optional<KernelVariant> forced,
                                                    std::optional<WorkGroupParams> params) const {
  const DeviceInfo& info = m_device.info();
  KernelChoice c = resolve_kernel_choice(default_kernels(info), device_default(info), "RELIT_RENDER_VARIANT", forced,
                                         params, m_settings.kernel_variant);
  // Fit the device: a power of two of work-items that divides the samples of a ray (a multiple of 16, so 16
  // always does), within the device's limit; staging where the shared directions fit half the local memory.
  WorkGroupParams& p = c.workgroup;
  const std::uint32_t limit = static_cast<std::uint32_t>(std::min<std::size_t>(info.max_work_group_size, 1024));
  std::uint32_t items = 1;
  while (items * 2 <= std::min(p.items, limit) && m_settings.n_samples % (items * 2) == 0) items *= 2;
  p.items = items;
  const std::uint64_t indirect = m_settings.closed_form_indirect ? 0 : std::uint64_t(m_settings.n_dirs) * (3 + m_n_sh);
  const std::uint64_t staged = (indirect + 6ull * m_settings.n_env_dirs) * sizeof(float);
  p.stage = p.stage && staged <= info.local_memory / 2;
  if (c.variant == KernelVariant::Simd) return c;
  const Program program = m_device.program("render_wg.cl", workgroup_defines(p));
  std::string why;
  for (const char* name :
       {"render_wg_radiance", "render_wg_radiance_backward", "render_wg_composite", "render_wg_composite_backward"})
    if (program.kernel(name).max_work_group_size() < p.items)
      why = std::string("the compiled ") + name + " accepts fewer than " + std::to_string(p.items) + " work-items";
  if (!why.empty()) fall_back_to_simd(c, "VolumeRenderer", info.name, why, "RELIT_RENDER_VARIANT");
  return c;
}

void VolumeRenderer::view_basis(const Buffer<float>& rays, std::uint32_t n_rays, nn::BatchMatrix& out) const {
  if (out.cols() != m_n_sh) throw InvalidArgument("VolumeRenderer::view_basis: the output needs n_sh columns");
  out.resize(n_rays);
  if (!m_sh || n_rays == 0) return;
  // The SH encoding wants its input padded as its output: reallocate when the padding differs.
  if (m_view_dirs.cols() != 3 || m_view_dirs.padded() != out.padded())
    m_view_dirs = nn::BatchMatrix(m_device, n_rays, 3);
  m_view_dirs.resize(n_rays);
  m_device.kernel("render.cl", "view_directions", m_defines).args(n_rays, rays, m_view_dirs.data()).launch(n_rays, 16);
  m_sh->forward(m_device, {nullptr, 0}, m_view_dirs, out, 0, nullptr);
}

void VolumeRenderer::scale_rgb_by_ray_intensity(const Buffer<float>& rays, const nn::BatchMatrix& src,
                                                std::uint32_t src_col, nn::BatchMatrix& dst, std::uint32_t dst_col,
                                                std::uint32_t per_channel, float scale) const {
  const std::uint32_t count = 3 * per_channel;
  if (src.batch() != dst.batch() || src_col + count > src.cols() || dst_col + count > dst.cols())
    throw InvalidArgument("VolumeRenderer::scale_rgb_by_ray_intensity: columns [" + std::to_string(src_col) + ", " +
                          std::to_string(src_col + count) + ") of a " + std::to_string(src.batch()) + "x" +
                          std::to_string(src.cols()) + " matrix do not fit columns [" + std::to_string(dst_col) + ", " +
                          std::to_string(dst_col + count) + ") of a " + std::to_string(dst.batch()) + "x" +
                          std::to_string(dst.cols()) + " one");
  const std::uint32_t spr = m_settings.n_samples;
  const std::uint32_t n_tiles = (src.batch() + nn::kBatchTile - 1) / nn::kBatchTile;
  if (rays.size() < std::size_t((src.batch() + spr - 1) / spr) * kRayFloats)
    throw InvalidArgument("VolumeRenderer::scale_rgb_by_ray_intensity: fewer ray records than the samples need");
  m_device.kernel("render.cl", "scale_rgb_by_ray_intensity", m_defines)
      .args(n_tiles, per_channel, scale, rays, src.data(), src.cols(), src_col, dst.data(), dst.cols(), dst_col)
      .launch(n_tiles, 16);
}

void VolumeRenderer::check(std::uint32_t n_rays, const nn::BatchMatrix& props, const nn::BatchMatrix& dirs,
                           const nn::BatchMatrix& sh_basis, const EnvironmentSamples* env, const char* what) const {
  const std::uint32_t n_env = m_settings.n_env_dirs;
  if (n_env > 0 && !env)
    throw InvalidArgument(std::string("VolumeRenderer::") + what + ": n_env_dirs = " + std::to_string(n_env) +
                          " needs the environment samples of this iteration (EnvironmentSamples), got none");
  if (n_env == 0 && env)
    throw InvalidArgument(std::string("VolumeRenderer::") + what +
                          ": environment samples given to a renderer "
                          "without environment light; set VolumeRendererSettings::n_env_dirs to their count (" +
                          std::to_string(env->size()) + ")");
  if (env && env->size() != n_env)
    throw InvalidArgument(std::string("VolumeRenderer::") + what + ": the environment samples hold " +
                          std::to_string(env->size()) +
                          " directions, the renderer was built for n_env_dirs = " + std::to_string(n_env));
  if (m_settings.closed_form_indirect) {
    if (sh_basis.batch() != n_rays || sh_basis.cols() != m_n_sh)
      throw InvalidArgument(std::string("VolumeRenderer::") + what +
                            ": the closed-form indirect option needs the "
                            "view basis of every ray (" +
                            std::to_string(n_rays) + "x" + std::to_string(m_n_sh) + ", from view_basis())");
  } else if (dirs.batch() != m_settings.n_dirs || dirs.cols() != 3 || sh_basis.batch() != m_settings.n_dirs ||
             sh_basis.cols() != m_n_sh) {
    throw InvalidArgument(std::string("VolumeRenderer::") + what + ": need " + std::to_string(m_settings.n_dirs) +
                          " directions (x3) and their " + std::to_string(m_n_sh) + " SH basis values");
  }
  const std::uint64_t n = std::uint64_t(n_rays) * m_settings.n_samples;
  if (props.batch() != n || props.cols() != prop_cols())
    throw InvalidArgument(std::string("VolumeRenderer::") + what + ": properties are " + std::to_string(props.batch()) +
                          "x" + std::to_string(props.cols()) + ", expected " + std::to_string(n) + "x" +
                          std::to_string(prop_cols()) + " (rays x samples, 6 + 3 n_sh + n_env_dirs" +
                          (m_brdf ? " + 3 normal columns for scattering \"brdf\")" : ")"));
}

void VolumeRenderer::sample(Buffer<float>& rays, std::uint32_t n_rays, bool jitter, std::uint32_t seed,
                            Buffer<float>& t, Buffer<float>& delta, nn::BatchMatrix& positions,
                            parallel::Share share) const {
  const std::size_t n = std::size_t(n_rays) * m_settings.n_samples;
  if (rays.size() < std::size_t(n_rays) * kRayFloats || t.size() < n || delta.size() < n || positions.cols() != 3)
    throw InvalidArgument("VolumeRenderer::sample: buffers too small for " + std::to_string(n_rays) + " rays");
  positions.resize(static_cast<std::uint32_t>(n));
  m_device.kernel("render.cl", "sample_rays", m_defines)
      .args(n_rays, std::uint32_t(jitter), seed, rays, t, delta, positions.data(), share.first, share.stride)
      .launch(n_rays, 16);
}

void VolumeRenderer::forward(const Buffer<float>& rays, std::uint32_t n_rays, const Buffer<float>& t,
                             const Buffer<float>& delta, const nn::BatchMatrix& props, const nn::BatchMatrix& dirs,
                             const nn::BatchMatrix& sh_basis, nn::BatchMatrix& radiance, Buffer<float>& color,
                             Buffer<float>& transmittance, const EnvironmentSamples* env) const {
  check(n_rays, props, dirs, sh_basis, env, "forward");
  if (color.size() < 3 * std::size_t(n_rays) || transmittance.size() < n_rays || radiance.cols() != 3)
    throw InvalidArgument("VolumeRenderer::forward: output buffers too small");
  radiance.resize(props.batch());
  if (m_brdf) {  // one work-item per sample
    const std::uint32_t n = props.batch();
    m_device.kernel("render.cl", "render_radiance_brdf", m_defines)
        .args(n, rays, t, props.data(), dirs.data(), sh_basis.data(), env_dirs(env), env_weights(env), radiance.data())
        .launch(n, 64);
  } else if (workgroup()) {  // one work-group per ray
    m_device.kernel("render_wg.cl", "render_wg_radiance", m_wg_defines)
        .args(n_rays, rays, t, props.data(), dirs.data(), sh_basis.data(), env_dirs(env), env_weights(env),
              radiance.data())
        .launch(std::size_t(n_rays) * m_choice.workgroup.items, m_choice.workgroup.items);
  } else {  // one work-item per tile of 16 samples
    const auto n_tiles = static_cast<std::uint32_t>(props.batch() / nn::kBatchTile);
    m_device.kernel("render.cl", "render_radiance", m_defines)
        .args(n_tiles, rays, t, props.data(), dirs.data(), sh_basis.data(), env_dirs(env), env_weights(env),
              radiance.data())
        .launch(n_tiles, 16);
  }
  if (workgroup())
    m_device.kernel("render_wg.cl", "render_wg_composite", m_wg_defines)
        .args(n_rays, rays, delta, props.data(), radiance.data(), color, transmittance)
        .launch(std::size_t(n_rays) * m_choice.workgroup.items, m_choice.workgroup.items);
  else
    m_device.kernel("render.cl", "composite", m_defines)
        .args(n_rays, rays, delta, props.data(), radiance.data(), color, transmittance)
        .launch(n_rays, 16);
}

void VolumeRenderer::backward(const Buffer<float>& rays, std::uint32_t n_rays, const Buffer<float>& t,
                              const Buffer<float>& delta, const nn::BatchMatrix& props, const nn::BatchMatrix& dirs,
                              const nn::BatchMatrix& sh_basis, const nn::BatchMatrix& radiance,
                              const Buffer<float>& color, const Buffer<float>& d_color, nn::BatchMatrix& d_radiance,
                              nn::BatchMatrix& d_props, const EnvironmentSamples* env) const {
  check(n_rays, props, dirs, sh_basis, env, "backward");
  if (d_props.cols() != prop_cols() || d_radiance.cols() != 3 || d_color.size() < 3 * std::size_t(n_rays))
    throw InvalidArgument("VolumeRenderer::backward: gradient buffers have the wrong shape");
  d_props.resize(props.batch());
  d_radiance.resize(props.batch());
  if (workgroup()) {
    const std::size_t items = m_choice.workgroup.items;
    m_device.kernel("render_wg.cl", "render_wg_composite_backward", m_wg_defines)
        .args(n_rays, rays, delta, props.data(), radiance.data(), color, d_color, d_props.data(), d_radiance.data())
        .launch(n_rays * items, items);
    if (!m_brdf) {
      m_device.kernel("render_wg.cl", "render_wg_radiance_backward", m_wg_defines)
          .args(n_rays, rays, t, props.data(), dirs.data(), sh_basis.data(), env_dirs(env), env_weights(env),
                d_radiance.data(), d_props.data())
          .launch(n_rays * items, items);
      return;
    }
  } else {
    m_device.kernel("render.cl", "composite_backward", m_defines)
        .args(n_rays, rays, delta, props.data(), radiance.data(), color, d_color, d_props.data(), d_radiance.data())
        .launch(n_rays, 16);
  }
  const std::uint32_t n = m_brdf ? props.batch() : static_cast<std::uint32_t>(props.batch() / nn::kBatchTile);
  m_device.kernel("render.cl", m_brdf ? "render_radiance_brdf_backward" : "render_radiance_backward", m_defines)
      .args(n, rays, t, props.data(), dirs.data(), sh_basis.data(), env_dirs(env), env_weights(env), d_radiance.data(),
            d_props.data())
      .launch(n, m_brdf ? 64 : 16);
}

IndirectBasis::IndirectBasis(const Device& device, std::uint32_t n_dirs, int sh_lmax)
    : m_device(device),
      m_dirs(device, n_dirs, 3),
      m_basis(device, n_dirs, sh_lmax < 0 ? 0u : static_cast<std::uint32_t>((sh_lmax + 1) * (sh_lmax + 1))) {
  if (n_dirs == 0) throw InvalidArgument("IndirectBasis: need at least one direction");
  if (sh_lmax > 9) throw InvalidArgument("IndirectBasis: sh_lmax must be at most 9");
  if (sh_lmax >= 0) m_sh = nn::create_encoding({{"type", "SphericalHarmonics"}, {"degree", sh_lmax + 1}}, 3);
}

void IndirectBasis::draw(std::uint32_t seed, std::uint32_t iteration) {
  const std::uint32_t n = m_dirs.batch();
  m_device.kernel("rays.cl", "sphere_directions").args(n, seed, iteration, m_dirs.data()).launch(n, 16);
  if (m_sh) m_sh->forward(m_device, {nullptr, 0}, m_dirs, m_basis, 0, nullptr);
}

}  // namespace relit::render
