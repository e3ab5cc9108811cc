// Point lights and the environment map with its importance-sampling tables.
#include <relit/error.hpp>
#include <relit/scene/light.hpp>

#include "shared.hpp"

#include <algorithm>
#include <cmath>

namespace relit {

namespace {
using ::relit::detail::kPi;
double luminance(double r, double g, double b) { return 0.2126 * r + 0.7152 * g + 0.0722 * b; }
}  // namespace

void PointLight::validate() const {
  for (float p : position)
    if (!std::isfinite(p) || std::abs(p) > 1e6f)
      throw InvalidArgument("point light position must be finite and within 1e6 of the origin, got " +
                            std::to_string(p));
  if (std::abs(position[0]) <= 1 && std::abs(position[1]) <= 1 && std::abs(position[2]) <= 1)
    throw InvalidArgument("a point light at (" + std::to_string(position[0]) + ", " + std::to_string(position[1]) +
                          ", " + std::to_string(position[2]) +
                          ") lies inside the scene box [-1, 1]^3; lights must be outside the medium");
  for (float i : intensity)
    if (!(i >= 0.0f) || !std::isfinite(i))
      throw InvalidArgument("point light intensity must be finite and >= 0 (W/sr per channel), got " +
                            std::to_string(i));
}

EnvironmentLight::EnvironmentLight(Image image, float scale, bool visible, std::string file)
    : m_scale(scale), m_visible(visible), m_file(std::move(file)) {
  if (image.empty() || image.width < 1 || image.height < 1) throw InvalidArgument("the environment image is empty");
  if (image.width > 16384 || image.height > 8192)
    throw InvalidArgument("the environment image is larger than 16384x8192");
  if (!(scale >= 0.0f) || !std::isfinite(scale)) throw InvalidArgument("environment scale must be finite and >= 0");
  // Keep RGBA so the kernels can read one float4 per texel.
  m_image = Image(image.width, image.height, 4, 0.0f);
  for (int y = 0; y < image.height; ++y)
    for (int x = 0; x < image.width; ++x) {
      for (int c = 0; c < 3; ++c) {
        const float v = image.at(x, y, std::min(c, image.channels - 1));
        if (!std::isfinite(v) || v < 0)
          throw InvalidArgument("the environment image has negative, NaN or infinite radiance");
        m_image.at(x, y, c) = v;
      }
      m_image.at(x, y, 3) = 1.0f;
    }
  build_tables();
}

EnvironmentLight EnvironmentLight::uniform(const Float3& radiance, bool visible) {
  // A constant image fine enough that sin(theta)-weighted sampling is close to uniform on the sphere.
  Image img(64, 32, 3);
  for (std::size_t i = 0; i < img.pixels.size(); i += 3)
    for (int c = 0; c < 3; ++c) img.pixels[i + c] = radiance[c];
  return EnvironmentLight(img, 1.0f, visible);
}

EnvironmentLight EnvironmentLight::sky(int width, int height, unsigned seed, float scale, bool visible) {
  Image img(width, height, 3);
  // The sun's direction depends on the seed: azimuth anywhere, elevation 20..60 degrees.
  const double a = (seed * 0.6180339887498949 - std::floor(seed * 0.6180339887498949)) * 2 * kPi;
  const double el = (20 + 40 * ((seed * 0.7548776662466927) - std::floor(seed * 0.7548776662466927))) * kPi / 180;
  const double sun[3] = {std::cos(el) * std::cos(a), std::cos(el) * std::sin(a), std::sin(el)};
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < width; ++x) {
      const double theta = (y + 0.5) / height * kPi, phi = (x + 0.5) / width * 2 * kPi;
      const double d[3] = {std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi), std::cos(theta)};
      const double up = d[2];
      const double cos_sun = d[0] * sun[0] + d[1] * sun[1] + d[2] * sun[2];
      double rgb[3];
      if (up >= 0) {  // sky: blue at the zenith, pale at the horizon
        const double t = std::pow(1 - up, 3);
        rgb[0] = 0.25 + 0.55 * t, rgb[1] = 0.45 + 0.45 * t, rgb[2] = 0.95 + 0.05 * t;
      } else {  // ground: dim, warm
        rgb[0] = 0.18, rgb[1] = 0.15, rgb[2] = 0.12;
      }
      const double glow = std::pow(std::max(cos_sun, 0.0), 64) * 4.0;
      const double disc = cos_sun > std::cos(3.0 * kPi / 180) ? 150.0 : 0.0;
      img.at(x, y, 0) = float(rgb[0] + (glow + disc) * 1.0);
      img.at(x, y, 1) = float(rgb[1] + (glow + disc) * 0.9);
      img.at(x, y, 2) = float(rgb[2] + (glow + disc) * 0.75);
    }
  return EnvironmentLight(img, scale, visible);
}

void EnvironmentLight::build_tables() {
  const int w = m_image.width, h = m_image.height;
  std::vector<double> f(std::size_t(w) * h);
  double total = 0;
  for (int y = 0; y < h; ++y) {
    const double s = std::sin((y + 0.5) / h * kPi);
    for (int x = 0; x < w; ++x) {
      f[std::size_t(y) * w + x] = luminance(m_image.at(x, y, 0), m_image.at(x, y, 1), m_image.at(x, y, 2)) * s;
      total += f[std::size_t(y) * w + x];
    }
  }
  if (!(total > 0))
    throw InvalidArgument("the environment image is black everywhere; leave the environment out instead");
  m_pdf_uv.resize(f.size());
  m_marginal.assign(h + 1, 0.0f);
  m_conditional.assign(std::size_t(h) * (w + 1), 0.0f);
  double row_acc = 0;
  for (int y = 0; y < h; ++y) {
    double row = 0;
    for (int x = 0; x < w; ++x) row += f[std::size_t(y) * w + x];
    double acc = 0;
    for (int x = 0; x < w; ++x) {
      m_pdf_uv[std::size_t(y) * w + x] = float(f[std::size_t(y) * w + x] / total * w * h);
      acc += f[std::size_t(y) * w + x];
      m_conditional[std::size_t(y) * (w + 1) + x + 1] = row > 0 ? float(acc / row) : float(x + 1) / w;
    }
    m_conditional[std::size_t(y) * (w + 1) + w] = 1.0f;
    row_acc += row;
    m_marginal[y + 1] = float(row_acc / total);
  }
  m_marginal[h] = 1.0f;
}

namespace {
void texel_of(const Float3& d, int w, int h, int& x, int& y, double& sin_theta) {
  const double z = std::clamp(double(d[2]), -1.0, 1.0);
  const double theta = std::acos(z);
  double phi = std::atan2(double(d[1]), double(d[0]));
  if (phi < 0) phi += 2 * kPi;
  x = std::min(int(phi / (2 * kPi) * w), w - 1);
  y = std::min(int(theta / kPi * h), h - 1);
  sin_theta = std::sqrt(std::max(0.0, 1 - z * z));
}
}  // namespace

Float3 EnvironmentLight::radiance(const Float3& d) const {
  int x, y;
  double s;
  texel_of(d, m_image.width, m_image.height, x, y, s);
  return {m_image.at(x, y, 0) * m_scale, m_image.at(x, y, 1) * m_scale, m_image.at(x, y, 2) * m_scale};
}

double EnvironmentLight::pdf(const Float3& d) const {
  int x, y;
  double s;
  texel_of(d, m_image.width, m_image.height, x, y, s);
  if (s <= 0) return 0;
  return m_pdf_uv[std::size_t(y) * m_image.width + x] / (2 * kPi * kPi * s);
}

}  // namespace relit
