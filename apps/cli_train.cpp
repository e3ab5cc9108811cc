// relit train / relit render: fit a method (Ours or a baseline) to a dataset, and relight a trained run.
#include "cli.hpp"
#include "progress_bar.hpp"

#include <relit/cl/device.hpp>
#include <relit/dataset.hpp>
#include <relit/scene/scene.hpp>
#include <relit/error.hpp>
#include <relit/io/checkpoint.hpp>
#include <relit/io/file.hpp>
#include <relit/io/image.hpp>
#include <relit/method/evaluate.hpp>
#include <relit/method/model_io.hpp>
#include <relit/method/presets.hpp>
#include <relit/method/render_image.hpp>
#include <relit/method/trainer.hpp>
#include <relit/report.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <sstream>

namespace fs = std::filesystem;

namespace relit::cli {

namespace {

std::string fixed(double v, int digits) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*f", digits, v);
  return buf;
}

struct TrainOptions {
  std::string dataset, config = "fast", out, device, method;
  long long steps = -1, seed = -1;
  double minutes = 0;
  bool resume = false;
  unsigned profile = 0;
};

int run_train(const TrainOptions& o) {
  const std::string checkpoint = (fs::path(o.out) / "checkpoint.relit").string();
  Json config;
  if (o.resume) {
    if (!fs::exists(checkpoint)) throw IOError("--resume: " + checkpoint + " does not exist");
    config = Json::parse(io::read_file((fs::path(o.out) / "config.json").string()));
    config.erase("dataset");
  } else {
    if (fs::exists(checkpoint))
      throw IOError(o.out +
                    " already holds a run (checkpoint.relit); pass --resume to continue it or choose "
                    "another --out");
    config = method::load_run_config(method::config_for_method(o.config, o.method));
    method::set_method(config, o.method, o.config);
  }
  if (o.seed >= 0) config["training"]["seed"] = o.seed;
  const Device device = Device::select(o.device);
  method::Trainer trainer(device, o.dataset, config);
  if (o.profile) {
    std::cout << "per-stage time of one step (mean of " << o.profile << " steps, " << trainer.settings().batch_rays
              << " rays, method " << trainer.model().method() << ") on " << device.info().name << ":\n";
    double total = 0;
    for (const auto& [stage, ms] : trainer.profile(o.profile)) {
      std::cout << "  " << stage << std::string(stage.size() < 34 ? 34 - stage.size() : 1, ' ') << fixed(ms, 2)
                << " ms\n";
      total += ms;
    }
    std::cout << "  total" << std::string(29, ' ') << fixed(total, 2) << " ms\n";
    return 0;
  }
  trainer.set_output(o.out);
  if (o.resume) trainer.load_checkpoint(checkpoint);
  const std::uint64_t target = o.steps >= 0 ? std::uint64_t(o.steps) : trainer.settings().steps;
  std::cerr << "relit train: " << o.dataset << " → " << o.out << ", " << trainer.model().n_params() << " + "
            << trainer.model().n_vis_params() << " parameters, steps " << trainer.steps() << " → " << target << ", on "
            << device.info().name << "\n";
  ProgressBar bar("train");
  const auto start_step = trainer.steps();
  bool out_of_time = false;
  const auto stats = trainer.run_until(target, [&](const method::TrainStats& s) {
    if (o.minutes > 0 && s.elapsed >= 60.0 * o.minutes && s.step < target) out_of_time = true;
    Progress p;
    p.done = s.step - start_step;
    p.total = target - start_step;
    p.elapsed = s.elapsed;
    p.rate = s.steps_per_second;
    p.eta = s.eta;
    p.unit = "steps";
    p.message = "step " + std::to_string(s.step) + " loss " + fixed(s.loss, 5) +
                (std::isnan(s.val_psnr) ? std::string() : " val PSNR " + fixed(s.val_psnr, 2) + " dB");
    return bar(p) && !out_of_time;
  });
  bar.finish();
  if (out_of_time) {  // the time budget ended the run early (run_until() has written its checkpoint)
    std::cout << "stopped at step " << stats.step << " after the --minutes budget (" << fixed(o.minutes, 1)
              << " min)\n";
  }
  std::cout << "trained " << stats.step << " steps in " << fixed(stats.elapsed, 1) << " s ("
            << fixed(stats.steps_per_second, 2) << " steps/s); loss " << fixed(stats.loss, 6);
  if (!std::isnan(stats.val_psnr)) std::cout << ", validation PSNR " << fixed(stats.val_psnr, 2) << " dB";
  if (stats.skipped) std::cout << ", " << stats.skipped << " step(s) skipped (non-finite loss)";
  std::cout << "\nrun written to " << o.out << "\n";
  return 0;
}

std::vector<float> triple(const std::vector<float>& v, const char* what) {
  if (v.size() == 1) return {v[0], v[0], v[0]};
  if (v.size() == 3) return v;
  throw InvalidArgument(std::string(what) + " takes 1 or 3 values");
}

struct RenderOptions {
  std::string run, out, device, view, visibility, environment;
  float env_scale = 1.0f;
  bool env_visible = false;
  std::vector<float> eye{0, -4, 1}, target{0, 0, 0}, light{0, -3, 3}, intensity{600};
  int resolution = 0;  // 0: 128, or the view's
  float fov = 0.8f;
  std::uint32_t spp = 1;
};

int run_render(const RenderOptions& o) {
  const Device device = Device::select(o.device);
  const auto model = method::load_model(device, (fs::path(o.run) / "checkpoint.relit").string());
  Camera camera;
  PointLight light;
  std::shared_ptr<const EnvironmentLight> environment;  // --view of 'env+point' data: the dataset's
  if (!o.view.empty()) {
    // DATASET:SPLIT:INDEX — the camera and light of a dataset view.
    const auto a = o.view.rfind(':'), b = o.view.rfind(':', a - 1);
    if (a == std::string::npos || b == std::string::npos)
      throw InvalidArgument("--view takes DATASET:SPLIT:INDEX, got '" + o.view + "'");
    const auto desc = read_dataset(o.view.substr(0, b));
    const std::string split = o.view.substr(b + 1, a - b - 1);
    const auto it = desc.splits.find(split);
    const std::size_t index = std::stoul(o.view.substr(a + 1));
    if (it == desc.splits.end() || index >= it->second.size())
      throw InvalidArgument("--view: no view " + std::to_string(index) + " in split '" + split + "'");
    camera = it->second[index].camera;
    light = it->second[index].light;
    if (o.resolution > 0) {  // the view's camera at another resolution: same field of view and aspect
      camera.height = std::max(1, static_cast<int>(std::lround(double(camera.height) * o.resolution / camera.width)));
      camera.width = o.resolution;
    }
    if (model->has_environment()) environment = dataset_environment(o.view.substr(0, b));
  } else {
    const auto e = triple(o.eye, "--eye"), t = triple(o.target, "--target");
    const int res = o.resolution > 0 ? o.resolution : 128;
    camera = Camera::look_at({e[0], e[1], e[2]}, {t[0], t[1], t[2]}, {0, 0, 1}, o.fov, res, res);
  }
  if (o.view.empty() || o.light != std::vector<float>{0, -3, 3}) {
    const auto l = triple(o.light, "--light");
    light.position = {l[0], l[1], l[2]};
  }
  const auto i = triple(o.intensity, "--intensity");
  if (o.view.empty() || o.intensity != std::vector<float>{600}) light.intensity = {i[0], i[1], i[2]};
  if (o.environment == "none") {
    environment.reset();
  } else if (!o.environment.empty()) {
    environment =
        std::make_shared<const EnvironmentLight>(read_image(o.environment), o.env_scale, o.env_visible, o.environment);
  }
  ProgressBar bar("render");
  method::RenderSettings rs;
  rs.visibility = o.visibility;
  rs.environment = environment.get();
  rs.spp = o.spp;
  const Image img = method::render_image(*model, camera, light, rs, [&](const Progress& p) { return bar(p); });
  bar.finish();
  write_image(o.out, img);
  std::cout << "image written to " << o.out << "\n";
  return 0;
}

struct EvalOptions {
  std::string run, dataset, out, device, visibility;
  std::vector<std::string> splits;
  std::size_t max_views = 0;
  std::uint32_t spp = 1;
  bool no_images = false;
};

std::vector<std::string> default_splits(const std::string& dataset) {
  std::vector<std::string> out{"test"};
  for (const auto& [name, frames] : read_dataset(dataset).splits)
    if (name.rfind("test_", 0) == 0 && !frames.empty()) out.push_back(name);
  return out;
}

int run_eval(const EvalOptions& o) {
  const Device device = Device::select(o.device);
  const std::string checkpoint = (fs::path(o.run) / "checkpoint.relit").string();
  const auto model = method::load_model(device, checkpoint);
  std::string dataset = o.dataset;
  const Json header = io::load_checkpoint(checkpoint).header;
  if (dataset.empty()) dataset = header.at("config").value("dataset", std::string());
  if (dataset.empty()) throw InvalidArgument("the run does not record its dataset; pass --dataset");
  method::EvalOptions eo;
  eo.splits = o.splits.empty() ? default_splits(dataset) : o.splits;
  eo.max_views = o.max_views;
  eo.write_images = !o.no_images;
  eo.visibility = o.visibility;
  eo.spp = o.spp;
  const std::string out = o.out.empty() ? (fs::path(o.run) / "eval").string() : o.out;
  const Json meta{{"run", o.run},
                  {"dataset", dataset},
                  {"step", header.value("step", Json())},
                  {"device", device.info().name},
                  {"visibility", o.visibility.empty() ? model->inference_visibility() : o.visibility},
                  {"spp", o.spp}};
  ProgressBar bar("eval");
  const auto views = method::evaluate(*model, dataset, out, eo, meta, [&](const Progress& p) { return bar(p); });
  bar.finish();
  std::cout << report::format_summary_lines(views) << "report written to " << out
            << " (metrics.json, metrics.md, contact sheets)\n";
  return 0;
}

struct DemoOptions {
  std::string out = "demo", device;
  long long steps = -1;
};

int run_demo(const DemoOptions& o) {
  const Device device = Device::select(o.device);
  const std::string dataset = (fs::path(o.out) / "data" / "cloud").string();
  const std::string run = (fs::path(o.out) / "run").string();
  std::cerr << "relit demo: the default cloud, 'point' lighting, the fast preset, on " << device.info().name << "\n";
  if (!fs::exists(fs::path(dataset) / "transforms_train.json")) {
    std::cerr << "[1/3] generating the dataset (path tracing) → " << dataset << "\n";
    fs::create_directories(fs::path(dataset).parent_path());
    DatasetSettings s;
    // Clean references, so that the metric measures the model rather than the path tracer's noise: against
    // 256-spp references the same model scores 1.6 dB lower (docs/method.md, "Results").
    s.test_spp = 1024;
    s.generalization = true;
    s.generalization_views = 6;
    ProgressBar bar("generate");
    generate_dataset(device, Scene::builtin_or_file("cloud", s.seed, 64), dataset, s,
                     [&](const Progress& p) { return bar(p); });
    bar.finish();
  } else {
    std::cerr << "[1/3] dataset " << dataset << " exists, reusing it\n";
  }
  TrainOptions t;
  t.dataset = dataset;
  t.out = run;
  t.device = o.device;
  t.steps = o.steps;
  t.resume = fs::exists(fs::path(run) / "checkpoint.relit");
  std::cerr << "[2/3] training → " << run << (t.resume ? " (resuming)" : "") << "\n";
  run_train(t);
  std::cerr << "[3/3] relighting the test views → " << run << "/eval\n";
  EvalOptions e;
  e.run = run;
  e.device = o.device;
  return run_eval(e);
}

}  // namespace

void add_eval_command(CLI::App& app) {
  auto o = std::make_shared<EvalOptions>();
  auto* cmd =
      app.add_subcommand("eval", "relight a run's test views and report PSNR/SSIM (JSON, Markdown, contact sheets)");
  cmd->add_option("run", o->run, "run folder written by relit train")->required();
  cmd->add_option("--dataset", o->dataset, "dataset folder (default: the run's)");
  cmd->add_option("--split", o->splits, "splits to evaluate (default: test and every test_* set)");
  cmd->add_option("--max-views", o->max_views, "at most this many views per split (0: all)")->capture_default_str();
  cmd->add_option("--out,-o", o->out, "report folder (default: RUN/eval)");
  cmd->add_flag("--no-images", o->no_images, "write only the metrics and contact sheets, not every prediction");
  cmd->add_option("--visibility", o->visibility, "network or march (default: the model's setting)")
      ->check(CLI::IsMember({"network", "march"}));
  cmd->add_option("--spp", o->spp, "rays per pixel, averaged over an n x n grid in the pixel (1, 4, 9, ...)")
      ->capture_default_str();
  cmd->add_option("--device,-d", o->device, "OpenCL device selector (index, platform:device, or name part)");
  cmd->final_callback([o] {
    if (const int code = run_eval(*o)) throw CLI::RuntimeError(code);
  });
}

void add_demo_command(CLI::App& app) {
  auto o = std::make_shared<DemoOptions>();
  auto* cmd = app.add_subcommand("demo",
                                 "the main job: generate the default cloud, train the fast preset, relight the "
                                 "test views, print PSNR/SSIM and write images");
  cmd->add_option("--out,-o", o->out, "demo folder (data/cloud, run/, run/eval/); reruns reuse what is there")
      ->capture_default_str();
  cmd->add_option("--steps", o->steps, "training steps (default: the fast preset's)");
  cmd->add_option("--device,-d", o->device, "OpenCL device selector (index, platform:device, or name part)");
  cmd->final_callback([o] {
    if (const int code = run_demo(*o)) throw CLI::RuntimeError(code);
  });
}

void add_train_command(CLI::App& app) {
  auto o = std::make_shared<TrainOptions>();
  auto* cmd = app.add_subcommand("train", "train the relightable model on a dataset (writes a run folder)");
  cmd->add_option("dataset", o->dataset, "dataset folder (relit generate writes one)")->required();
  cmd->add_option("--config,-c", o->config, "preset (fast, paper) or a run config .json")->capture_default_str();
  cmd->add_option("--method,-m", o->method,
                  "ours, bi (Bi et al.) or nerv (NeRV); with a preset name, that method's preset (bi-fast, ...)");
  cmd->add_option("--minutes", o->minutes, "stop after this much training time (a checkpoint is written)");
  cmd->add_option("--out,-o", o->out, "run folder: config.json, log.jsonl, checkpoint.relit")->required();
  cmd->add_option("--steps", o->steps, "train until this step (default: the config's training.steps)");
  cmd->add_option("--seed", o->seed, "training seed (default: the config's training.seed)");
  cmd->add_flag("--resume", o->resume, "continue the run in --out from its checkpoint");
  cmd->add_option("--profile", o->profile, "time each stage over this many steps, print it and exit (nothing written)");
  cmd->add_option("--device,-d", o->device, "OpenCL device selector (index, platform:device, or name part)");
  cmd->final_callback([o] {
    if (const int code = run_train(*o)) throw CLI::RuntimeError(code);
  });
}

void add_render_command(CLI::App& app) {
  auto o = std::make_shared<RenderOptions>();
  auto* cmd = app.add_subcommand("render", "relight a trained run: render a camera under a point light");
  cmd->add_option("run", o->run, "run folder written by relit train")->required();
  cmd->add_option("--out,-o", o->out, "output image (.png: sRGB 8-bit, .exr: linear float)")->required();
  cmd->add_option("--view", o->view,
                  "use the camera (and light, unless --light/--intensity are given) of a dataset "
                  "view: DATASET:SPLIT:INDEX");
  cmd->add_option("--eye", o->eye, "camera position (x y z)")->expected(3);
  cmd->add_option("--target", o->target, "point the camera looks at (x y z)")->expected(3);
  cmd->add_option("--resolution", o->resolution,
                  "image width and height (default 128; with --view: the view's "
                  "width, the height keeping its aspect)");
  cmd->add_option("--fov", o->fov, "horizontal field of view, radians")->capture_default_str();
  cmd->add_option("--light", o->light, "point light position (x y z)")->expected(3);
  cmd->add_option("--intensity", o->intensity, "light intensity in W/sr: one value (white) or r g b")->expected(1, 3);
  cmd->add_option("--visibility", o->visibility, "network or march (default: the model's setting)")
      ->check(CLI::IsMember({"network", "march"}));
  cmd->add_option("--environment", o->environment,
                  "light the scene with this lat-long map (.exr/.hdr) as well, or 'none' (default: the dataset's "
                  "map for --view of 'env+point' data); the model must have been trained on 'env+point' data");
  cmd->add_option("--env-scale", o->env_scale, "radiance scale of --environment")->capture_default_str();
  cmd->add_flag("--env-visible", o->env_visible, "camera rays that miss the medium see --environment");
  cmd->add_option("--spp", o->spp,
                  "rays per pixel, averaged over an n x n grid in the pixel (1, 4, 9, ...): "
                  "anti-aliased edges, like the path tracer's box filter")
      ->capture_default_str();
  cmd->add_option("--device,-d", o->device, "OpenCL device selector (index, platform:device, or name part)");
  cmd->final_callback([o] {
    if (const int code = run_render(*o)) throw CLI::RuntimeError(code);
  });
}

}  // namespace relit::cli
