// Scene: what the reference path tracer renders, described by JSON (unknown keys are errors).
//
// {
//   "medium":  {"source": {"type": "cloud", "resolution": 64, "seed": 1},   // or smoke, blobs, constant,
//                                                                            // sphere, vdb {file, grid}
//               "density_scale": 20, "albedo": [0.95, 0.95, 0.95], "g": 0.3},
//   "solid":   {"source": {"type": "torus", "resolution": 64, "seed": 1},   // or spheres
//               "base_color": [0.8, 0.5, 0.3], "roughness": 0.3},
//   "lights":  [{"type": "point", "position": [0, 0, 4], "intensity": [600, 600, 600]}],
//   "environment": {"file": "sky.exr", "scale": 1, "visible": false},      // or {"radiance": [r, g, b]}
//                                                                          // or {"sky": seed}
//   "cameras": [{"position": [0, -4.5, 1], "target": [0, 0, 0], "up": [0, 0, 1],  // or "transform_matrix"
//                "camera_angle_x": 0.8, "width": 128, "height": 128}]
// }
// See docs/scenes.md for every key. File paths are relative to the scene file's folder.
#pragma once

#include <relit/config.hpp>
#include <relit/scene/camera.hpp>
#include <relit/scene/light.hpp>
#include <relit/scene/medium.hpp>
#include <relit/scene/surface.hpp>

#include <optional>
#include <string>
#include <vector>

namespace relit {

struct Scene {
  std::optional<Medium> medium;
  std::optional<Surface> solid;
  std::vector<PointLight> lights;
  std::optional<EnvironmentLight> environment;
  std::vector<Camera> cameras;
  Json description;  ///< the resolved JSON this scene was built from (every default filled in)

  /// Builds a scene from JSON; `base_dir` resolves relative file paths. Throws ConfigError (with the JSON
  /// pointer) for bad values and IOError for unreadable files.
  static Scene from_json(const Json& json, const std::string& base_dir = ".");
  /// Reads a scene JSON file, or the medium of a .vdb file (vdb_json()).
  static Scene load(const std::string& path);
  /// The JSON of a built-in scene: "cloud", "smoke", "blobs" (media), "spheres", "torus" (solids).
  static Json builtin_json(const std::string& name, unsigned seed = 0, int resolution = 64);
  /// The JSON of a scene of the medium in a .vdb file. One that relit export wrote (metadata relit_units): a
  /// "vdb" source with placement "world" at the file's own resolution, density_scale 1, its "albedo" grid and
  /// the σ-weighted mean g of its metadata (relit_mean_g). Any other: a "vdb" source fitted into the box, with
  /// the medium's defaults.
  static Json vdb_json(const std::string& path);
  /// A built-in scene by name, a path to a scene JSON file when `name_or_path` ends in .json, or a .vdb file
  /// (vdb_json()).
  static Scene builtin_or_file(const std::string& name_or_path, unsigned seed = 0, int resolution = 64);
  static const std::vector<std::string>& builtin_names();
};

}  // namespace relit
