// relit eval: relight a run's test views and report their metrics (metrics.json, metrics.md, contact sheets), or
// compare two folders of images the same way.
#include "cli.hpp"
#include "cli_method.hpp"
#include "progress_bar.hpp"

#include <relit/cl/device.hpp>
#include <relit/dataset.hpp>
#include <relit/error.hpp>
#include <relit/io/checkpoint.hpp>
#include <relit/method/evaluate.hpp>
#include <relit/method/model_io.hpp>
#include <relit/parallel.hpp>
#include <relit/report.hpp>

#include <filesystem>
#include <iostream>

namespace fs = std::filesystem;

namespace relit::cli {

namespace {

std::vector<std::string> default_splits(const std::string& dataset) {
  std::vector<std::string> out{"test"};
  for (const auto& [name, frames] : read_dataset(dataset).splits)
    if (name.rfind("test_", 0) == 0 && !frames.empty()) out.push_back(name);
  return out;
}

}  // namespace

// relit eval --predictions DIR --references DIR: another renderer's images against references, the same report.
int run_compare_folders(const EvalOptions& o) {
  if (o.out.empty()) throw InvalidArgument("eval --predictions needs --out DIR: the folder to write the report into");
  const Device device = Device::select(o.device);
  ProgressBar bar("eval");
  const auto result =
      report::compare_folders(device, o.predictions, o.references, o.splits, [&](const Progress& p) { return bar(p); });
  bar.finish();
  if (!result.unmatched_predictions.empty())
    std::cerr << "relit: " << result.unmatched_predictions.size() << " image"
              << (result.unmatched_predictions.size() == 1 ? "" : "s") << " under " << o.predictions
              << " match no reference and are not compared (e.g. " << result.unmatched_predictions.front() << ")\n";
  report::ReportOptions ro;
  ro.meta = Json{{"predictions", o.predictions}, {"references", o.references}, {"device", device.info().name}};
  report::write_report(o.out, result.views, ro);
  std::cout << report::format_summary_lines(result.views) << "report written to " << o.out
            << " (metrics.json, metrics.md, contact sheets)\n";
  return 0;
}

int run_eval(const EvalOptions& o) {
  if (!o.predictions.empty() || !o.references.empty()) {
    if (o.predictions.empty() || o.references.empty())
      throw InvalidArgument("eval: give both --predictions DIR and --references DIR (or a run folder)");
    if (!o.run.empty()) throw InvalidArgument("eval: give a run folder or --predictions/--references, not both");
    return run_compare_folders(o);
  }
  if (o.run.empty()) throw InvalidArgument("eval: give a run folder (or --predictions DIR --references DIR)");
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
  if (parallel::rank() != 0) return 0;  // rank 0 holds the views and wrote the report
  std::cout << report::format_summary_lines(views) << "report written to " << out
            << " (metrics.json, metrics.md, contact sheets)\n";
  return 0;
}

void add_eval_command(CLI::App& app) {
  auto o = std::make_shared<EvalOptions>();
  auto* cmd = app.add_subcommand("eval",
                                 "relight a run's test views (or compare any renderer's images) and report PSNR, "
                                 "SSIM, HDR-FLIP and the object's metrics (JSON, Markdown, contact sheets)");
  cmd->add_option("run", o->run, "run folder written by relit train");
  cmd->add_option("--predictions", o->predictions,
                  "compare this folder's images with --references instead of rendering a run (any renderer's; "
                  "paired by split folder and file name)");
  cmd->add_option("--references", o->references, "reference images: a relit dataset folder or any folder of images");
  cmd->add_option("--dataset", o->dataset, "dataset folder (default: the run's)");
  cmd->add_option("--split", o->splits,
                  "splits to evaluate (default: test and every test_* set; with --predictions: every split of the "
                  "references)");
  cmd->add_option("--max-views", o->max_views, "at most this many views per split (0: all)")
      ->check(integer_in(0, 1000000))
      ->capture_default_str();
  cmd->add_option("--out,-o", o->out, "report folder (default: RUN/eval)");
  cmd->add_flag("--no-images", o->no_images, "write only the metrics and contact sheets, not every prediction");
  cmd->add_option("--visibility", o->visibility, "network or march (default: the model's setting)")
      ->check(CLI::IsMember({"network", "march"}));
  cmd->add_option("--spp", o->spp, "rays per pixel, averaged over an n x n grid in the pixel (1, 4, 9, ...)")
      ->check(integer_in(1, 65536))
      ->capture_default_str();
  add_device_option(cmd, o->device);
  on_parsed(cmd, o, run_eval);
}

}  // namespace relit::cli
