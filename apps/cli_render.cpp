// relit render: relight a trained run, rendering a camera under a point light (and an environment).
#include "cli.hpp"
#include "progress_bar.hpp"

#include <relit/parallel.hpp>
#include <relit/cl/device.hpp>
#include <relit/dataset.hpp>
#include <relit/error.hpp>
#include <relit/io/image.hpp>
#include <relit/method/evaluate.hpp>
#include <relit/method/model_io.hpp>
#include <relit/method/render_image.hpp>
#include <relit/method/render_video.hpp>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <iostream>
#include <optional>

namespace fs = std::filesystem;

namespace relit::cli {

namespace {

const std::vector<float> kDefaultLight{0, -3, 3}, kDefaultIntensity{600};

std::vector<float> triple(const std::vector<float>& v, const char* what) {
  if (v.size() == 1) return {v[0], v[0], v[0]};
  if (v.size() == 3) return v;
  throw InvalidArgument(std::string(what) + " takes 1 or 3 values");
}

struct RenderOptions {
  std::string run, out, device, view, visibility, environment;
  float env_scale = 1.0f;
  bool env_visible = false;
  std::vector<float> eye{0, -4, 1}, target{0, 0, 0};
  std::optional<std::vector<float>> light, intensity;  // unset: the view's, else kDefaultLight, kDefaultIntensity
  std::optional<int> resolution;                       // unset: 128, or the view's width
  float fov = 0.8f;
  std::uint32_t spp = 1;
  int orbit_camera = 0, orbit_light = 0, fps = 24;  // videos
  std::string path;
  bool no_mp4 = false;
};

// --orbit-camera, --orbit-light, --path: numbered frames and an MP4 next to --out (without its extension).
int run_video(const method::Model& model, const RenderOptions& o) {
  if ((o.orbit_camera > 0) + (o.orbit_light > 0) + !o.path.empty() > 1)
    throw InvalidArgument("give one of --orbit-camera, --orbit-light and --path");
  if (!o.view.empty()) throw InvalidArgument("--view makes one image; a video takes --eye, --target and --light");
  if (!o.environment.empty() && o.environment != "none")
    throw InvalidArgument("--environment: videos are rendered under the point light alone");
  method::Keyframe start;
  const auto e = triple(o.eye, "--eye"), t = triple(o.target, "--target");
  const auto l = triple(o.light.value_or(kDefaultLight), "--light");
  const auto i = triple(o.intensity.value_or(kDefaultIntensity), "--intensity");
  start.eye = {e[0], e[1], e[2]};
  start.target = {t[0], t[1], t[2]};
  start.light = {l[0], l[1], l[2]};
  start.intensity = {i[0], i[1], i[2]};
  const auto frames = o.orbit_camera  ? method::orbit_camera(start, o.orbit_camera)
                      : o.orbit_light ? method::orbit_light(start, o.orbit_light)
                                      : method::read_keyframes(o.path, start);
  method::VideoSettings vs;
  vs.width = vs.height = o.resolution.value_or(128);
  vs.fov = o.fov;
  vs.render.visibility = o.visibility;
  vs.render.spp = o.spp;
  vs.fps = o.fps;
  vs.mp4 = !o.no_mp4;
  const fs::path out(o.out);
  const std::string prefix = (out.parent_path() / out.stem()).string();
  ProgressBar bar("render");
  const auto paths = method::render_video(model, frames, prefix, vs, [&](const Progress& p) { return bar(p); });
  bar.finish();
  if (parallel::rank() != 0) return 0;  // the frames were shared out; rank 0 wrote them
  std::cout << paths.size() << " frames written to " << prefix << "_0000.png ... "
            << fs::path(paths.back()).filename().string() << (vs.mp4 ? ", video to " + prefix + ".mp4" : std::string())
            << "\n";
  return 0;
}

int run_render(const RenderOptions& o) {
  const Device device = Device::select(o.device);
  const auto model = method::load_model(device, (fs::path(o.run) / "checkpoint.relit").string());
  if (o.orbit_camera || o.orbit_light || !o.path.empty()) return run_video(*model, o);
  Camera camera;
  PointLight light;
  std::shared_ptr<const EnvironmentLight> environment;  // --view of 'env+point' data: the dataset's
  if (!o.view.empty()) {
    // DATASET:SPLIT:INDEX — the camera and light of a dataset view.
    const auto a = o.view.rfind(':'), b = a == 0 || a == std::string::npos ? a : o.view.rfind(':', a - 1);
    if (a == std::string::npos || b == std::string::npos || a == 0)
      throw InvalidArgument("--view takes DATASET:SPLIT:INDEX, got '" + o.view + "'");
    const auto desc = read_dataset(o.view.substr(0, b));
    const std::string split = o.view.substr(b + 1, a - b - 1);
    const auto it = desc.splits.find(split);
    const std::string index_text = o.view.substr(a + 1);
    if (index_text.empty() || index_text.size() > 9 || index_text.find_first_not_of("0123456789") != std::string::npos)
      throw InvalidArgument("--view: the view index must be a non-negative integer, got '" + index_text + "'");
    const std::size_t index = std::stoul(index_text);
    if (it == desc.splits.end() || index >= it->second.size())
      throw InvalidArgument("--view: no view " + std::to_string(index) + " in split '" + split + "'");
    camera = it->second[index].camera;
    light = it->second[index].light;
    if (o.resolution) {  // the view's camera at another resolution: same field of view and aspect
      camera.height = std::max(1, static_cast<int>(std::lround(double(camera.height) * *o.resolution / camera.width)));
      camera.width = *o.resolution;
    }
    if (model->has_environment()) environment = dataset_environment(o.view.substr(0, b));
  } else {
    const auto e = triple(o.eye, "--eye"), t = triple(o.target, "--target");
    const int res = o.resolution.value_or(128);
    camera = Camera::look_at({e[0], e[1], e[2]}, {t[0], t[1], t[2]}, {0, 0, 1}, o.fov, res, res);
  }
  // Without --view the defaults light the scene; with it, the view's light unless --light/--intensity are given.
  if (o.view.empty() || o.light) {
    const auto l = triple(o.light.value_or(kDefaultLight), "--light");
    light.position = {l[0], l[1], l[2]};
  }
  if (o.view.empty() || o.intensity) {
    const auto i = triple(o.intensity.value_or(kDefaultIntensity), "--intensity");
    light.intensity = {i[0], i[1], i[2]};
  }
  if (o.environment == "none") {
    environment.reset();
  } else if (!o.environment.empty()) {
    environment =
        std::make_shared<const EnvironmentLight>(read_image(o.environment), o.env_scale, o.env_visible, o.environment);
  }
  if (parallel::rank() != 0) return 0;  // one image: rank 0 renders it (video frames are shared out)
  ProgressBar bar("render");
  method::ImageRenderSettings rs;
  rs.visibility = o.visibility;
  rs.environment = environment.get();
  rs.spp = o.spp;
  const Image img = method::render_image(*model, camera, light, rs, [&](const Progress& p) { return bar(p); });
  bar.finish();
  write_image(o.out, img);
  std::cout << "image written to " << o.out << "\n";
  return 0;
}

}  // namespace

void add_render_command(CLI::App& app) {
  auto o = std::make_shared<RenderOptions>();
  auto* cmd = app.add_subcommand("render", "relight a trained run: render a camera under a point light");
  cmd->add_option("run", o->run, "run folder written by relit train")->required();
  cmd->add_option("--out,-o", o->out, "output image (.png: sRGB 8-bit, .exr: linear float)")->required();
  cmd->add_option("--view", o->view,
                  "use the camera (and light, unless --light/--intensity are given) of a dataset "
                  "view: DATASET:SPLIT:INDEX");
  cmd->add_option("--eye", o->eye, "camera position (x y z)")->check(number_in(-1e6, 1e6))->expected(3);
  cmd->add_option("--target", o->target, "point the camera looks at (x y z)")->check(number_in(-1e6, 1e6))->expected(3);
  cmd->add_option("--resolution", o->resolution,
                  "image width and height (default 128; with --view: the view's "
                  "width, the height keeping its aspect)")
      ->check(integer_in(1, 16384));
  cmd->add_option("--fov", o->fov, "horizontal field of view, radians")
      ->check(number_in(0.02, 3.0))
      ->capture_default_str();
  cmd->add_option("--light", o->light, "point light position (x y z; default 0 -3 3, or the --view's)")
      ->check(number_in(-1e6, 1e6))
      ->expected(3);
  cmd->add_option("--intensity", o->intensity,
                  "light intensity in W/sr: one value (white) or r g b (default 600, or the --view's)")
      ->check(number_in(0, 1e9))
      ->expected(1, 3);
  cmd->add_option("--visibility", o->visibility, "network or march (default: the model's setting)")
      ->check(CLI::IsMember({"network", "march"}));
  cmd->add_option("--environment", o->environment,
                  "light the scene with this lat-long map (.exr/.hdr) as well, or 'none' (default: the dataset's "
                  "map for --view of 'env+point' data); the model must have been trained on 'env+point' data");
  cmd->add_option("--env-scale", o->env_scale, "radiance scale of --environment")
      ->check(number_in(0, 1e6))
      ->capture_default_str();
  cmd->add_flag("--env-visible", o->env_visible, "camera rays that miss the medium see --environment");
  cmd->add_option("--spp", o->spp,
                  "rays per pixel, averaged over an n x n grid in the pixel (1, 4, 9, ...): "
                  "anti-aliased edges, like the path tracer's box filter")
      ->check(integer_in(1, 65536))
      ->capture_default_str();
  cmd->add_option("--orbit-camera", o->orbit_camera,
                  "a video: N frames of the camera going once around the vertical axis through --target, written "
                  "as OUT_0000.png ... and OUT.mp4 (OUT: --out without its extension)")
      ->check(integer_in(1, 100000));
  cmd->add_option("--orbit-light", o->orbit_light,
                  "a video: N frames of the light going once around the vertical axis (frames and MP4 as "
                  "--orbit-camera)")
      ->check(integer_in(1, 100000));
  cmd->add_option("--path", o->path,
                  "a video along keyframes: a JSON list of {\"eye\", \"target\", \"light\", \"intensity\"} "
                  "objects, one per frame (a key left out keeps the previous frame's)");
  cmd->add_option("--fps", o->fps, "frames per second of the video")->check(integer_in(1, 240))->capture_default_str();
  cmd->add_flag("--no-mp4", o->no_mp4, "write the video's frames only (no ffmpeg needed)");
  add_device_option(cmd, o->device);
  on_parsed(cmd, o, run_render);
}

}  // namespace relit::cli
