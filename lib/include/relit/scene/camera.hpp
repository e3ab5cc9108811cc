// Camera: a pinhole camera with a camera-to-world matrix in OpenGL/Blender axes (the camera looks down its
// -z axis, +y is up, +x right), horizontal field of view `camera_angle_x` (radians, as NeRF's transforms
// JSON) and a resolution. Pixel (i, j) (j from the top row) looks along
//   d_cam = ((i + 0.5 - W/2) / f, -(j + 0.5 - H/2) / f, -1),  f = W / (2 tan(camera_angle_x / 2)).
#pragma once

#include <relit/scene/grid.hpp>

#include <array>

namespace relit {

using Matrix4 = std::array<std::array<float, 4>, 4>;  ///< row-major, [row][column]

struct Camera {
  Matrix4 transform{{{1, 0, 0, 0}, {0, 1, 0, 0}, {0, 0, 1, 4}, {0, 0, 0, 1}}};  ///< camera to world
  float camera_angle_x = 0.8f;
  int width = 128, height = 128;

  /// A camera at `eye` looking at `target`, with `up` as close to its +y as possible.
  static Camera look_at(const Float3& eye, const Float3& target, const Float3& up, float camera_angle_x, int width,
                        int height);
  Float3 position() const { return {transform[0][3], transform[1][3], transform[2][3]}; }
  float focal() const;
  /// Unit world direction through image position (x, y) in pixels (x right, y down; pixel centres at +0.5).
  Float3 direction(double x, double y) const;
  void validate() const;
};

}  // namespace relit
