// Evaluation of a trained model on a dataset's test splits (relit eval): PSNR/SSIM per view and per split,
// written as metrics.json + metrics.md, with PNG contact sheets (prediction | ground truth | error).
//
//   out/metrics.json               every view's psnr/ssim/mse, per-split and overall means, `meta`
//   out/metrics.md                 the same as Markdown tables
//   out/contact_sheet_<split>.png  up to 8 views per split, one row each: prediction | ground truth | error
//   out/<split>/<name>.png|.exr    every prediction (sRGB preview and linear EXR)
//
// The error panel maps the mean absolute difference of the sRGB-encoded images through a perceptually
// ordered colour map (black → purple → orange → yellow), 0 → black and `error_scale` (default 0.25) → yellow.
// Every file is written atomically.
#pragma once

#include <relit/io/image.hpp>
#include <relit/method/ours.hpp>
#include <relit/metrics.hpp>
#include <relit/progress.hpp>

#include <string>
#include <vector>

namespace relit::method {

struct ViewResult {
  std::string split, name;
  int width = 0, height = 0;
  std::vector<float> prediction, reference;  ///< linear RGB, h x w x 3
  metrics::ImageComparison metrics;
};

struct SplitSummary {
  std::string split;  ///< "all" for the overall mean
  std::size_t n_views = 0;
  double psnr = 0, ssim = 0, mse = 0;  ///< means over the views (PSNR: mean of per-view PSNRs)
};

/// Per-split means in first-seen split order, then the overall mean ("all").
std::vector<SplitSummary> summarize(const std::vector<ViewResult>& views);

/// The contact sheet of `views` (at most `max_rows`, spread evenly): rows of prediction | reference | error.
Image contact_sheet(const std::vector<const ViewResult*>& views, std::size_t max_rows = 8, float error_scale = 0.25f);

struct EvalOptions {
  std::vector<std::string> splits{"test"};  ///< dataset splits to render
  std::size_t max_views = 0;                ///< per split; 0 = all
  bool write_images = true;                 ///< each prediction as PNG + EXR
  std::string visibility;                   ///< "" (the model's setting), "network" or "march"
};

/// Renders every view of the splits with `model`, compares with the dataset's images, and writes the report
/// into `out_dir` (created). `meta` is stored in metrics.json. Progress counts views.
std::vector<ViewResult> evaluate(const Ours& model, const std::string& dataset_dir, const std::string& out_dir,
                                 const EvalOptions& options = {}, const Json& meta = Json::object(),
                                 const ProgressCallback& progress = {});

/// Writes metrics.json, metrics.md and the contact sheets of `views` into `out_dir`.
void write_report(const std::string& out_dir, const std::vector<ViewResult>& views, const Json& meta);

/// The lines a program prints: one per split ("test: PSNR 31.23 dB  SSIM 0.9512 (50 views)"), then exactly
/// "PSNR <mean>" and "SSIM <mean>" over all views (for scripts).
std::string summary_lines(const std::vector<ViewResult>& views);

}  // namespace relit::method
