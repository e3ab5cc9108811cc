// relit train: fit a method (Ours or a baseline) to a dataset, writing a run folder.
#include "cli.hpp"
#include "cli_method.hpp"
#include "progress_bar.hpp"

#include <relit/cl/device.hpp>
#include <relit/error.hpp>
#include <relit/io/file.hpp>
#include <relit/method/model.hpp>
#include <relit/method/presets.hpp>
#include <relit/method/trainer.hpp>
#include <relit/parallel.hpp>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>

namespace fs = std::filesystem;

namespace relit::cli {

namespace {

std::string fixed(double v, int digits) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*f", digits, v);
  return buf;
}

}  // namespace

int run_train(const TrainOptions& o) {
  std::error_code ec;
  const bool out_exists = fs::exists(o.out, ec);
  if (ec) throw IOError("--out '" + o.out + "': " + ec.message());
  if (out_exists && !fs::is_directory(o.out, ec))
    throw IOError("--out '" + o.out + "' is an existing file; a run is written into a folder");
  for (fs::path up = fs::path(o.out).parent_path(); !out_exists && !up.empty(); up = up.parent_path()) {
    if (!fs::exists(up, ec)) continue;
    if (!fs::is_directory(up, ec))
      throw IOError("--out '" + o.out + "': '" + up.string() +
                    "' is a file (Not a directory), so no run folder can be made there");
    break;
  }
  const std::string checkpoint = (fs::path(o.out) / "checkpoint.relit").string();
  Json config;
  if (o.resume) {
    if (!fs::exists(checkpoint, ec)) throw IOError("--resume: " + checkpoint + " does not exist");
    const std::string config_path = (fs::path(o.out) / "config.json").string();
    config = parse_json(io::read_file(config_path), "the run's config '" + config_path + "'");
    if (!config.is_object()) throw ConfigError("", "the run's config '" + config_path + "' is not a JSON object");
    config.erase("dataset");
  } else {
    if (fs::exists(checkpoint, ec))
      throw IOError(o.out +
                    " already holds a run (checkpoint.relit); pass --resume to continue it or choose "
                    "another --out");
    config = method::load_run_config(method::config_for_method(o.config, o.method));
    method::set_method(config, o.method, o.config);
  }
  if (o.seed) config["training"]["seed"] = *o.seed;
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
  const std::uint64_t target = o.steps ? std::uint64_t(*o.steps) : trainer.settings().steps;
  if (parallel::rank() == 0)
    std::cerr << "relit train: " << o.dataset << " → " << o.out << ", " << trainer.model().n_params() << " + "
              << trainer.model().n_vis_params() << " parameters, steps " << trainer.steps() << " → " << target
              << ", on " << device.info().name << "\n";
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

void add_train_command(CLI::App& app) {
  auto o = std::make_shared<TrainOptions>();
  auto* cmd = app.add_subcommand("train", "train the relightable model on a dataset (writes a run folder)");
  cmd->add_option("dataset", o->dataset, "dataset folder (relit generate writes one)")->required();
  cmd->add_option("--config,-c", o->config, "preset (fast, paper) or a run config .json")->capture_default_str();
  std::string methods;
  for (const auto& m : method::method_names()) methods += (methods.empty() ? "" : ", ") + m;
  cmd->add_option("--method,-m", o->method, methods + "; with a preset name, that method's preset (bi-fast, ...)");
  cmd->add_option("--minutes", o->minutes, "stop after this much training time (a checkpoint is written)")
      ->check(number_in(0, 1e7));
  cmd->add_option("--out,-o", o->out, "run folder: config.json, log.jsonl, checkpoint.relit")->required();
  cmd->add_option("--steps", o->steps, "train until this step (default: the config's training.steps)")
      ->check(integer_in(0, 1000000000000LL));
  cmd->add_option("--seed", o->seed, "training seed (default: the config's training.seed)")
      ->check(integer_in(0, 4294967295LL));
  cmd->add_flag("--resume", o->resume, "continue the run in --out from its checkpoint");
  cmd->add_option("--profile", o->profile, "time each stage over this many steps, print it and exit (nothing written)")
      ->check(integer_in(1, 100000));
  add_device_option(cmd, o->device);
  on_parsed(cmd, o, run_train);
}

}  // namespace relit::cli
