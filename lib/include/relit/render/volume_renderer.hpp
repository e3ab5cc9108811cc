// VolumeRenderer: the neural volume renderer of docs/design.md §4.2 (kernels/render.cl), forward and backward.
//
// The renderer does not know about networks: the method queries its networks at the sample positions the
// renderer places, packs the results into one BatchMatrix of per-sample properties, and the renderer turns
// them into pixel colours (and, backward, pixel-colour gradients into property gradients).
//
//   sample():   rays → t_near/t_far, stratified sample distances t, deltas, sample positions (BatchMatrix x 3)
//   forward():  properties → per-sample radiance a ⊙ (S_dir + S_env + S_ind) (scattering "phase"), or the
//               BRDF-weighted light of a solid's surface (scattering "brdf", docs/design.md §4.4) → composited colour
//               and transmittance
//   backward(): dL/dcolour → dL/dproperties (sigma, albedo, g or roughness, SH coefficients, the raw normal;
//               zero for every visibility column, whose network the render loss must not reach, unless
//               visibility_gradient asks for dL/dV toward the point light)
//
// Ray records are kRayFloats floats: origin, t_near, direction (unit), t_far, light position, light RGB
// intensity [W/sr], background radiance, at the offsets RayField names (both declared in kernels/layout.clh,
// which the kernels share). Sample s = ray * n_samples + i.
#pragma once

#include <relit/parallel.hpp>
#include <relit/cl/buffer.hpp>
#include <relit/cl/kernel_variant.hpp>
#include <relit/layout.clh>
#include <relit/nn/batch.hpp>
#include <relit/nn/module.hpp>

#include <memory>
#include <optional>
#include <string>

#include <cstdint>

namespace relit::render {

class EnvironmentSamples;

/// Columns of the per-sample property matrix: sigma, albedo (3), g (scattering "phase") or the roughness
/// (scattering "brdf"), V toward the point light, the SH coefficients channel-major (3 n_sh), then V toward
/// each of the N_e environment directions, and with scattering "brdf" the raw normal (3, any length).
enum PropColumn : std::uint32_t { kSigma = 0, kAlbedo = 1, kG = 4, kRoughness = 4, kVisibility = 5, kSH = 6 };

/// The first environment-visibility column, V(x, w_0): column kSH + 3 n_sh; V(x, w_j) is this + j.
constexpr std::uint32_t env_visibility_column(std::uint32_t n_sh) { return kSH + 3 * n_sh; }

/// The first of the three columns of the raw normal in scattering "brdf" (x, then y, z): after the N_e
/// environment-visibility columns, the last three of the matrix.
constexpr std::uint32_t normal_column(std::uint32_t n_sh, std::uint32_t n_env_dirs) {
  return env_visibility_column(n_sh) + n_env_dirs;
}

/// What a VolumeRenderer is built for: samples per ray, SH bands, indirect directions, scattering model, N_e.
struct VolumeRendererSettings {
  std::uint32_t n_samples = 64;  ///< samples per ray, a multiple of 16
  int sh_lmax = 5;               ///< SH bands 0..sh_lmax for indirect light; -1: no indirect light
  std::uint32_t n_dirs = 64;     ///< K, uniform directions of the indirect-light sum
  /// Replace the K-direction sum by its closed form sum_lm g^l c_lm Y_lm(-w_o) (exact when the max(0, .)
  /// clamp is inactive; an ablation and a fast preview). forward()/backward() then take the view basis
  /// (view_basis()) in place of the directions' basis, and ignore `dirs`. Scattering "phase" only.
  bool closed_form_indirect = false;
  /// N_e, importance-sampled environment directions of S_env (docs/design.md §4.2 uses 32); 0: no environment
  /// light. With N_e > 0 the property matrix ends in N_e visibility columns and forward()/backward() need
  /// the EnvironmentSamples of the iteration.
  std::uint32_t n_env_dirs = 0;
  /// How a sample scatters light toward the camera: "phase" (media, docs/design.md §4.2: radiance a ⊙ S with the HG
  /// phase function of column kG) or "brdf" (solids, "Ours + BRDF", docs/design.md §4.4: column kRoughness holds
  /// the roughness r in (0, 1), three more columns at normal_column() the raw normal n_raw, which the
  /// renderer normalises; each light term is f(w_o, w_i) max(0, n.w_i) times its incident light with f
  /// the BRDF of kernels/brdf.clh, the path tracer's). "brdf" has no closed-form indirect light.
  std::string scattering = "phase";
  /// backward() writes dL/dV toward the point light into column kVisibility instead of zero. The method
  /// decides what to do with it (the shadow gradient, relit/method/medium.hpp); the renderer still
  /// gives zero to the environment's visibility columns.
  bool visibility_gradient = false;
  /// Which kernels light and composite the samples: "auto" (the device's table row: SIMD kernels on CPUs,
  /// work-group kernels on GPUs), "simd" or "workgroup"; the environment variable RELIT_RENDER_VARIANT
  /// overrides it (docs/renderer.md, "Kernel variants").
  std::string kernel_variant = "auto";
};

class VolumeRenderer {
 public:
  VolumeRenderer(const Device& device, const VolumeRendererSettings& settings);

  /// Parameters of the work-group kernels (kernels/render_wg.cl: one work-group per ray). Any valid set gives
  /// the same results up to float rounding; it only changes the speed.
  struct WorkGroupParams {
    std::uint32_t items = 64;  ///< RAY_ITEMS: work-items per ray, 1..1024 (lowered to a power of two that
                               ///< divides n_samples, within the device's limit)
    bool stage = true;         ///< STAGE_DIRS: stage the indirect and environment directions (and the SH basis)
                               ///< in local memory, where they fit in half of it
    bool operator==(const WorkGroupParams& o) const;
    std::string str() const;  ///< "N64 staged"
  };
  /// What runs: the variant, the work-group parameters, and where the choice came from.
  struct KernelChoice {
    KernelVariant variant = KernelVariant::Simd;
    WorkGroupParams workgroup;  ///< as lowered to fit (kernel_choice())
    bool tuned = false;         ///< the parameters were measured on such a device (false: a default)
    std::string source;         ///< "table: NVIDIA GPU", "RELIT_RENDER_VARIANT", "kernel_variant", ...
    std::string str() const;    ///< "workgroup N64 staged (table: NVIDIA GPU, untuned)"
  };
  /// The device's row of the renderer's tuning table (lib/src/render/render_tuning.cpp).
  static KernelChoice device_default(const DeviceInfo& info);
  /// device_default() with RELIT_RENDER_VARIANT (simd, workgroup or auto) applied: what a renderer whose
  /// kernel_variant is "auto" runs. Throws InvalidArgument on another value.
  static KernelChoice default_kernels(const DeviceInfo& info);
  /// What this renderer runs: set_kernels(), else RELIT_RENDER_VARIANT (read at construction), else the
  /// settings' kernel_variant, else the device's row; the parameters as lowered to fit. With scattering "brdf"
  /// the per-sample BRDF kernels of render.cl light the samples in either variant (they are one work-item per
  /// sample already); the variant chooses the compositing kernels.
  const KernelChoice& kernel_choice() const { return m_choice; }
  /// Runs `variant` (with `params`, else the device row's) whatever the settings and environment say (tests,
  /// benchmarks); std::nullopt restores the normal choice. Throws InvalidArgument on parameters out of range.
  void set_kernels(std::optional<KernelVariant> variant, std::optional<WorkGroupParams> params = std::nullopt);

  const VolumeRendererSettings& settings() const { return m_settings; }
  /// (sh_lmax + 1)^2, or 0 without indirect light.
  std::uint32_t n_sh() const { return m_n_sh; }
  /// Whether samples scatter with the BRDF (scattering "brdf") rather than the phase function.
  bool brdf() const { return m_brdf; }
  /// Columns of the property matrix: 6 + 3 n_sh + n_env_dirs, plus 3 for the normal with scattering "brdf".
  std::uint32_t prop_cols() const { return normal_col() + (m_brdf ? 3 : 0); }
  /// The column of V(x, w_0) toward the first environment direction.
  std::uint32_t env_visibility_col() const { return env_visibility_column(m_n_sh); }
  /// The first of the raw normal's three columns (scattering "brdf"; = prop_cols() in phase mode).
  std::uint32_t normal_col() const { return normal_column(m_n_sh, m_settings.n_env_dirs); }

  /// Intersects the rays with [-1, 1]^3 (writing t_near/t_far into the records) and places the samples.
  /// `jitter` draws each sample uniformly in its stratum from (seed, ray, sample); otherwise stratum centres.
  /// The ray index is the global one: rays share.first + share.stride r of a batch split over ranks.
  void sample(Buffer<float>& rays, std::uint32_t n_rays, bool jitter, std::uint32_t seed, Buffer<float>& t,
              Buffer<float>& delta, nn::BatchMatrix& positions, parallel::Share share = {}) const;

  /// `dirs`: the n_dirs unit directions of the indirect sum (n_dirs x 3); `sh_basis`: Y_j(dir_k) (n_dirs x
  /// n_sh). IndirectBasis draws both on the device. With closed_form_indirect, `sh_basis` is view_basis()'s
  /// n_rays x n_sh matrix instead. `env`: the environment directions and weights of this iteration
  /// (EnvironmentSamples::draw()), required when n_env_dirs > 0 and null otherwise.
  void forward(const Buffer<float>& rays, std::uint32_t n_rays, const Buffer<float>& t, const Buffer<float>& delta,
               const nn::BatchMatrix& props, const nn::BatchMatrix& dirs, const nn::BatchMatrix& sh_basis,
               nn::BatchMatrix& radiance, Buffer<float>& color, Buffer<float>& transmittance,
               const EnvironmentSamples* env = nullptr) const;

  /// Y_j(-w_o) for every ray (n_rays x n_sh), the basis the closed-form indirect option needs.
  void view_basis(const Buffer<float>& rays, std::uint32_t n_rays, nn::BatchMatrix& out) const;

  /// For 3 channel-major blocks of `per_channel` columns: dst = I_ch(ray) * src, where sample s belongs to ray
  /// s / n_samples and I is the ray record's light intensity. Every value is also multiplied by `scale`. Its
  /// own adjoint: the gradient goes back through the same call. Indirect light is linear in the intensity, so a
  /// network can predict it per unit intensity.
  void scale_rgb_by_ray_intensity(const Buffer<float>& rays, const nn::BatchMatrix& src, std::uint32_t src_col,
                                  nn::BatchMatrix& dst, std::uint32_t dst_col, std::uint32_t per_channel,
                                  float scale = 1.0f) const;

  /// Uses `radiance` and `color` from the forward call and the same `env`. Overwrites every column of
  /// `d_props`; the visibility columns (point light and environment) get zero.
  void backward(const Buffer<float>& rays, std::uint32_t n_rays, const Buffer<float>& t, const Buffer<float>& delta,
                const nn::BatchMatrix& props, const nn::BatchMatrix& dirs, const nn::BatchMatrix& sh_basis,
                const nn::BatchMatrix& radiance, const Buffer<float>& color, const Buffer<float>& d_color,
                nn::BatchMatrix& d_radiance, nn::BatchMatrix& d_props, const EnvironmentSamples* env = nullptr) const;

 private:
  void check(std::uint32_t n_rays, const nn::BatchMatrix& props, const nn::BatchMatrix& dirs,
             const nn::BatchMatrix& sh_basis, const EnvironmentSamples* env, const char* what) const;
  KernelChoice choose(std::optional<KernelVariant> forced, std::optional<WorkGroupParams> params) const;
  Defines workgroup_defines(const WorkGroupParams& p) const;  ///< m_defines with the work-group parameters
  bool workgroup() const { return m_choice.variant == KernelVariant::WorkGroup; }
  Device m_device;
  VolumeRendererSettings m_settings;
  std::uint32_t m_n_sh;
  bool m_brdf;
  Defines m_defines;
  KernelChoice m_choice;
  Defines m_wg_defines;                 // m_defines with the work-group kernels' parameters
  std::shared_ptr<nn::Encoding> m_sh;   // evaluates view_basis(); absent without indirect light
  mutable nn::BatchMatrix m_view_dirs;  // view_basis() scratch, reused while the ray count does not grow
};

/// The K directions of the indirect-light sum, uniform on the sphere and drawn anew per iteration from
/// (seed, iteration) on the device, and their SH basis values, computed once and shared by the whole batch
/// (Zheng et al. 2021, appendix B).
class IndirectBasis {
 public:
  IndirectBasis(const Device& device, std::uint32_t n_dirs, int sh_lmax);
  /// Draws the directions of `iteration` and evaluates the basis; enqueued only.
  void draw(std::uint32_t seed, std::uint32_t iteration);
  const nn::BatchMatrix& dirs() const { return m_dirs; }
  const nn::BatchMatrix& basis() const { return m_basis; }

 private:
  Device m_device;
  nn::BatchMatrix m_dirs, m_basis;
  std::unique_ptr<nn::Encoding> m_sh;
};

}  // namespace relit::render
