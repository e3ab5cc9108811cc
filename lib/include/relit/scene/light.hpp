// Lights: point lights and a lat-long environment map.
//
// Point light: RGB radiant intensity I [W/sr] at a position; irradiance-like falloff I / d^2.
// Environment: a lat-long HDR image in relit's world frame (z up, as Blender): direction
//   (sin(theta) cos(phi), sin(theta) sin(phi), cos(theta)) maps to u = phi / 2pi (phi from +x toward +y,
//   in [0, 2pi)), v = theta / pi (the top image row is +z). Radiance = scale * texel (nearest texel).
// The environment is importance sampled from a piecewise-constant distribution proportional to
// luminance * sin(theta); pdf(omega) = pdf_uv / (2 pi^2 sin(theta)), which integrates to 1 over the sphere.
#pragma once

#include <relit/io/image.hpp>
#include <relit/scene/grid.hpp>

#include <string>
#include <vector>

namespace relit {

struct PointLight {
  Float3 position{0.0f, 0.0f, 4.0f};
  Float3 intensity{600.0f, 600.0f, 600.0f};  ///< W/sr per channel, >= 0

  void validate() const;
};

class EnvironmentLight {
 public:
  EnvironmentLight() = default;
  /// `image` RGB(A) linear radiance; `file` is recorded for the scene JSON ("" for generated maps).
  EnvironmentLight(Image image, float scale, bool visible, std::string file = "");
  /// A uniform environment of radiance `radiance` (a constant image).
  static EnvironmentLight uniform(const Float3& radiance, bool visible);
  /// A procedural sky (gradient, horizon glow and a small bright sun), deterministic from `seed`.
  static EnvironmentLight sky(int width, int height, unsigned seed, float scale, bool visible);

  const Image& image() const { return m_image; }
  float scale() const { return m_scale; }
  bool visible() const { return m_visible; }
  const std::string& file() const { return m_file; }
  void set_file(std::string file) { m_file = std::move(file); }
  bool empty() const { return m_image.empty(); }

  /// Sampling tables (see the file comment): pdf_uv per texel (width*height), marginal CDF over rows
  /// (height+1) and conditional CDFs per row (height*(width+1)).
  const std::vector<float>& pdf_uv() const { return m_pdf_uv; }
  const std::vector<float>& marginal_cdf() const { return m_marginal; }
  const std::vector<float>& conditional_cdf() const { return m_conditional; }

  /// Host versions of what the kernels compute, for tests: radiance and pdf toward direction d (unit).
  Float3 radiance(const Float3& d) const;
  double pdf(const Float3& d) const;

 private:
  void build_tables();
  Image m_image;  // RGBA float
  float m_scale = 1.0f;
  bool m_visible = false;
  std::string m_file;
  std::vector<float> m_pdf_uv, m_marginal, m_conditional;
};

}  // namespace relit
