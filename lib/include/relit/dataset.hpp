// Dataset generation (docs/design.md §5): multi-view renders of a scene under the lighting protocols of Zheng et al.
// 2021, written in the NeRF/NeRV-compatible format of docs/dataset-format.md:
//
//   out/transforms_{train,val,test}.json   camera_angle_x, w, h, environment, frames [{file_path,
//                                          preview_path, transform_matrix, light {type, position, intensity}}]
//   out/{train,val,test}/r_000.exr         linear float RGBA (alpha = 1 - transmittance of the camera ray)
//   out/{train,val,test}/r_000.png         8-bit sRGB previews, tone-mapped x/(1+x) (the EXR holds the data)
//   out/scene.json                         the generating scene (resolved); out/environment.exr for 'env+point'
//   out/transforms_test_distance_{3,5,7,10}.json, ..._intensity_{400,800,1200,1600}.json  (generalisation sets)
//
// Protocols: 'point' — a new point light per view, at distance U(3, 5) from the centre (stratified over the
// training views), intensity fixed or drawn from a range; 'env+point' — a fixed environment map plus the same
// per-view point light. Cameras lie on a sphere around the centre looking at it: training cameras on a
// randomly rotated Fibonacci sphere, validation and test cameras (and lights) drawn independently, so they
// are novel. Writing is atomic: everything goes to a temporary sibling folder that is renamed into place at
// the very end, so an interrupted run never leaves a dataset that looks complete, and an existing folder is
// only replaced when `overwrite` is set.
//
// Reading: read_dataset gives the transforms files back (cameras, lights, file paths), load_split a split with
// its images for training and evaluation.
#pragma once

#include <relit/cl/device.hpp>
#include <relit/pathtrace.hpp>
#include <relit/progress.hpp>
#include <relit/scene/scene.hpp>

#include <map>
#include <memory>
#include <string>
#include <vector>

namespace relit {

struct DatasetSettings {
  std::string lighting = "point";  ///< "point" or "env+point"
  std::uint32_t seed = 0;
  int resolution = 128;  ///< square images
  std::uint32_t train = 100, val = 20, test = 50;
  std::uint32_t spp = 64;
  std::uint32_t test_spp = 0;     ///< samples per pixel of the test and test_* splits (0: spp); cleaner references
  std::uint32_t max_bounces = 0;  ///< 0 = unlimited
  float camera_distance = 4.0f;   ///< the scene box [-1, 1]^3 nearly fills the view at the default field of view
  float camera_angle_x = 0.8f;
  float light_distance_min = 3.0f, light_distance_max = 5.0f;
  float intensity_min = 600.0f, intensity_max = 600.0f;  ///< W/sr (white); equal = fixed
  bool generalization = false;  ///< also write the light-distance and light-intensity test sets
  std::uint32_t generalization_views = 20;
  /// W/sr of the light-distance sets, and 3/2 of the first light-intensity set (generalization_intensities())
  float generalization_intensity = 600.0f;
  float env_scale = 1.0f;    ///< 'env+point' without an environment in the scene: procedural sky scale
  bool env_visible = false;  ///< whether camera rays that miss see the environment
  bool previews = true;      ///< write PNG previews
  bool overwrite = false;    ///< replace an existing output folder (only once the new one is complete)

  void validate() const;
};

/// The light intensities of the generalisation test sets (test_intensity_<value>) for a base intensity: 2/3,
/// 4/3, 2 and 8/3 of it, rounded to whole W/sr (400, 800, 1200, 1600 for 600).
std::vector<int> generalization_intensities(float base_intensity);

/// One view of a dataset split.
struct DatasetFrame {
  std::string file_path;  ///< relative to the dataset folder ("train/r_000.exr")
  Camera camera;
  PointLight light;
};

struct DatasetDescription {
  std::map<std::string, std::vector<DatasetFrame>> splits;  ///< "train", "val", "test", "test_distance_3", ...
  std::string lighting;
  Json environment;  ///< null, or {file, scale, visible}
};

/// The views a generation would render (cameras and lights), without rendering anything.
DatasetDescription plan_dataset(const DatasetSettings& settings);

/// Renders and writes the dataset to `out_dir`. Progress counts path samples over all views.
/// Throws IOError when `out_dir` exists (and overwrite is off) or cannot be written; Cancelled when the
/// callback cancels (nothing is left behind).
void generate_dataset(const Device& device, const Scene& scene, const std::string& out_dir,
                      const DatasetSettings& settings, const ProgressCallback& progress = {});

/// The path tracer seed of view `index` of `split`: any view can be re-rendered exactly.
std::uint32_t dataset_view_seed(std::uint32_t seed, const std::string& split, std::size_t index);

/// Reads the transforms files of a dataset folder back (cameras, lights, file paths).
DatasetDescription read_dataset(const std::string& dir);

/// One split of a dataset on the host: cameras, lights and linear RGB images (n x h x w x 3).
struct DatasetSplit {
  std::string split;
  std::vector<std::string> names;  ///< file stems ("r_012")
  std::vector<Camera> cameras;
  std::vector<PointLight> lights;
  std::vector<float> images;
  /// The images' alpha (n x h x w, the object's coverage) when every image of the split has one; else empty.
  std::vector<float> alphas;
  int width = 0, height = 0;
  /// The environment light of an 'env+point' dataset (every view is lit by it as well), or null.
  std::shared_ptr<const EnvironmentLight> environment;
  std::size_t size() const { return cameras.size(); }
  /// View i's image (h x w x 3).
  std::vector<float> image(std::size_t i) const;
  /// View i's alpha (h x w), or empty when the split's images have none.
  std::vector<float> alpha(std::size_t i) const;
};

/// Reads a split of a dataset folder (docs/dataset-format.md). `max_views` > 0 keeps that many views,
/// spread evenly over the split. Throws IOError naming the folder/file when something is missing or corrupt.
DatasetSplit load_split(const std::string& dataset_dir, const std::string& split, std::size_t max_views = 0);

/// The environment light of an 'env+point' dataset folder, or null for 'point' data.
std::shared_ptr<const EnvironmentLight> dataset_environment(const std::string& dataset_dir);

}  // namespace relit
