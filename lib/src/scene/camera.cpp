// Pinhole camera geometry (NeRF / Blender conventions).
#include <relit/error.hpp>
#include <relit/scene/camera.hpp>

#include <algorithm>
#include <cmath>

namespace relit {

namespace {
Float3 sub(const Float3& a, const Float3& b) { return {a[0] - b[0], a[1] - b[1], a[2] - b[2]}; }
Float3 cross(const Float3& a, const Float3& b) {
  return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}
Float3 normalised(const Float3& a) {
  const float n = std::sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]);
  return {a[0] / n, a[1] / n, a[2] / n};
}
}  // namespace

Camera Camera::look_at(const Float3& eye, const Float3& target, const Float3& up, float angle, int width, int height) {
  for (int k = 0; k < 3; ++k)
    if (!std::isfinite(eye[k]) || !std::isfinite(target[k]) || !std::isfinite(up[k]))
      throw InvalidArgument("look_at: eye, target and up must be finite");
  const Float3 view = sub(eye, target);
  if (std::sqrt(view[0] * view[0] + view[1] * view[1] + view[2] * view[2]) < 1e-6f)
    throw InvalidArgument("look_at: eye and target are the same point, so there is no view direction");
  const Float3 back = normalised(sub(eye, target));  // camera +z points away from what it looks at
  Float3 right = cross(up, back);
  if (std::sqrt(right[0] * right[0] + right[1] * right[1] + right[2] * right[2]) < 1e-6f)
    right = cross(std::abs(back[0]) < 0.9f ? Float3{1, 0, 0} : Float3{0, 1, 0}, back);  // up parallel to the view
  right = normalised(right);
  const Float3 cam_up = cross(back, right);
  Camera c;
  for (int r = 0; r < 3; ++r) c.transform[r] = {right[r], cam_up[r], back[r], eye[r]};
  c.transform[3] = {0, 0, 0, 1};
  c.camera_angle_x = angle;
  c.width = width;
  c.height = height;
  c.validate();
  return c;
}

float Camera::focal() const { return 0.5f * width / std::tan(0.5f * camera_angle_x); }

Float3 Camera::direction(double x, double y) const {
  const double f = focal();
  const double d[3] = {(x - 0.5 * width) / f, -(y - 0.5 * height) / f, -1.0};
  double w[3];
  for (int r = 0; r < 3; ++r) w[r] = transform[r][0] * d[0] + transform[r][1] * d[1] + transform[r][2] * d[2];
  const double n = std::sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2]);
  return {float(w[0] / n), float(w[1] / n), float(w[2] / n)};
}

void Camera::validate() const {
  if (!(camera_angle_x > 0.01f && camera_angle_x < 3.1f))
    throw InvalidArgument("camera_angle_x must lie in (0.01, 3.1) radians, got " + std::to_string(camera_angle_x));
  if (width < 1 || height < 1 || width > 16384 || height > 16384)
    throw InvalidArgument("camera resolution must be between 1 and 16384 pixels per side");
  for (const auto& row : transform)
    for (float v : row)
      if (!std::isfinite(v)) throw InvalidArgument("the camera transform contains NaN or infinite values");
  if (transform[3][0] != 0 || transform[3][1] != 0 || transform[3][2] != 0 || transform[3][3] != 1)
    throw InvalidArgument("the camera transform's bottom row must be 0 0 0 1 (a camera-to-world rigid transform)");
  // The upper 3x3 is the camera's right, up and back axes: a rotation. A zero, scaled or singular block
  // would give rays without a direction.
  double worst = 0;
  for (int a = 0; a < 3; ++a)
    for (int b = 0; b < 3; ++b) {
      double dot = 0;
      for (int r = 0; r < 3; ++r) dot += double(transform[r][a]) * transform[r][b];
      worst = std::max(worst, std::abs(dot - (a == b ? 1.0 : 0.0)));
    }
  if (worst > 1e-3)
    throw InvalidArgument(
        "the camera transform's upper 3x3 block must be a rotation (orthonormal columns: right, "
        "up, back), but its columns deviate by " +
        std::to_string(worst) + " (a zero, scaled or singular matrix?)");
  for (int r = 0; r < 3; ++r)
    if (std::abs(transform[r][3]) > 1e6f) throw InvalidArgument("the camera lies farther than 1e6 from the origin");
}

}  // namespace relit
