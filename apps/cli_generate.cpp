// relit generate: render a dataset of a scene with the reference path tracer.
#include "cli.hpp"
#include "progress_bar.hpp"

#include <relit/cl/device.hpp>
#include <relit/dataset.hpp>
#include <relit/error.hpp>
#include <relit/parallel.hpp>

#include <iostream>

namespace relit::cli {

namespace {

struct GenerateOptions {
  std::string scene = "cloud", out, device;
  DatasetSettings settings;
  std::vector<float> intensity;
  std::vector<float> light_distance;
  int scene_resolution = 64;
};

int run_generate(GenerateOptions& o) {
  DatasetSettings& s = o.settings;
  if (o.intensity.size() == 1)
    s.intensity_min = s.intensity_max = o.intensity[0];
  else if (o.intensity.size() == 2)
    s.intensity_min = o.intensity[0], s.intensity_max = o.intensity[1];
  else if (!o.intensity.empty())
    throw InvalidArgument("--intensity takes one value (fixed) or two (a range)");
  if (o.light_distance.size() == 2)
    s.light_distance_min = o.light_distance[0], s.light_distance_max = o.light_distance[1];
  else if (!o.light_distance.empty())
    throw InvalidArgument("--light-distance takes two values (a range)");
  s.validate();
  const Device device = Device::select(o.device);
  const Scene scene = Scene::builtin_or_file(o.scene, s.seed, o.scene_resolution);
  std::size_t views = s.train + s.val + s.test + (s.generalization ? 8 * s.generalization_views : 0);
  if (parallel::rank() == 0)
    std::cerr << "relit generate: " << views << " views of '" << o.scene << "' at " << s.resolution << "x"
              << s.resolution << ", " << s.spp << " spp, lighting " << s.lighting << ", on " << device.info().name
              << "\n";
  ProgressBar bar("generate");
  generate_dataset(device, scene, o.out, s, [&](const Progress& p) { return bar(p); });
  bar.finish();
  std::cout << "dataset written to " << o.out << "\n";
  return 0;
}

}  // namespace

void add_generate_command(CLI::App& app) {
  auto o = std::make_shared<GenerateOptions>();
  DatasetSettings& s = o->settings;
  auto* cmd = app.add_subcommand("generate", "render a multi-view dataset of a scene with the reference path tracer");
  cmd->add_option("--scene", o->scene, "built-in scene (cloud, smoke, blobs, spheres, torus) or a scene .json file")
      ->capture_default_str();
  cmd->add_option("--out,-o", o->out, "output folder (must not exist unless --overwrite)")->required();
  cmd->add_option("--lighting", s.lighting, "lighting protocol: point, env+point")
      ->check(CLI::IsMember({"point", "env+point"}))
      ->capture_default_str();
  cmd->add_option("--seed", s.seed, "random seed (views, lights, path tracing, procedural scene)")
      ->check(integer_in(0, 4294967295LL))
      ->capture_default_str();
  cmd->add_option("--resolution", s.resolution, "image width and height in pixels")
      ->check(integer_in(4, 4096))
      ->capture_default_str();
  cmd->add_option("--train", s.train, "training views")->check(integer_in(0, 100000))->capture_default_str();
  cmd->add_option("--val", s.val, "validation views")->check(integer_in(0, 100000))->capture_default_str();
  cmd->add_option("--test", s.test, "test views")->check(integer_in(0, 100000))->capture_default_str();
  cmd->add_option("--spp", s.spp, "path-traced samples per pixel")->check(integer_in(1, 65536))->capture_default_str();
  cmd->add_option("--test-spp", s.test_spp,
                  "samples per pixel of the test splits (0: --spp); the references that "
                  "evaluation compares with")
      ->check(integer_in(0, 65536))
      ->capture_default_str();
  cmd->add_option("--max-bounces", s.max_bounces, "scattering events per path (0 = unlimited)")
      ->check(integer_in(0, 100000))
      ->capture_default_str();
  cmd->add_option("--intensity", o->intensity,
                  "point light intensity in W/sr: one value, or two for a range (default 600)")
      ->check(number_in(0, 1e9))
      ->expected(1, 2);
  cmd->add_option("--light-distance", o->light_distance, "range of light distances from the centre (default 3 5)")
      ->check(number_in(1.8, 1e6))
      ->expected(2);
  cmd->add_option("--camera-distance", s.camera_distance, "camera distance from the centre")
      ->check(number_in(1.8, 1e6))
      ->capture_default_str();
  cmd->add_option("--fov", s.camera_angle_x, "horizontal field of view, radians (camera_angle_x)")
      ->check(number_in(0.05, 3.0))
      ->capture_default_str();
  cmd->add_flag("--generalization", s.generalization,
                "also write test sets at light distances 3, 5, 7, 10 and intensities 400, 800, 1200, 1600 "
                "(2/3, 4/3, 2, 8/3 of --generalization-intensity)");
  cmd->add_option("--generalization-intensity", s.generalization_intensity,
                  "W/sr of the light-distance sets and the unit of the light-intensity sets")
      ->check(number_in(1e-3, 1e9))
      ->capture_default_str();
  cmd->add_option("--generalization-views", s.generalization_views, "views per generalisation test set")
      ->check(integer_in(1, 100000))
      ->capture_default_str();
  cmd->add_option("--env-scale", s.env_scale, "env+point: scale of the procedural sky (scenes may bring their own map)")
      ->check(number_in(0, 1e6))
      ->capture_default_str();
  cmd->add_flag("--env-visible", s.env_visible, "camera rays that miss the object see the environment");
  cmd->add_option("--scene-resolution", o->scene_resolution, "voxels per side of a built-in scene's grid")
      ->check(integer_in(8, 512))
      ->capture_default_str();
  cmd->add_flag("!--no-previews", s.previews, "skip the PNG previews");
  cmd->add_flag("--overwrite", s.overwrite, "replace an existing output folder once the new dataset is complete");
  add_device_option(cmd, o->device);
  on_parsed(cmd, o, run_generate);
}

}  // namespace relit::cli
