// Evaluation of a trained model on a dataset's test splits (relit eval): renders every view, compares it with
// the dataset's image (PSNR/SSIM per view) and writes the report of relit/report.hpp into the output folder:
//
//   out/metrics.json               every view's psnr/ssim/mse, per-split and overall means, `meta`
//   out/metrics.md                 the same as Markdown tables
//   out/contact_sheet_<split>.png  up to 8 views per split, one row each: prediction | ground truth | error
//   out/<split>/<name>.png|.exr    every prediction (sRGB preview and linear EXR)
#pragma once

#include <relit/method/model.hpp>
#include <relit/progress.hpp>
#include <relit/report.hpp>

#include <string>
#include <vector>

namespace relit::method {

struct EvalOptions {
  std::vector<std::string> splits{"test"};  ///< dataset splits to render
  std::size_t max_views = 0;                ///< per split; 0 = all
  bool write_images = true;                 ///< each prediction as PNG + EXR
  std::string visibility;                   ///< "" (the model's setting), "network" or "march"
  std::uint32_t spp = 1;                    ///< rays per pixel (ImageRenderSettings::spp)
};

/// Renders every view of the splits with `model`, compares with the dataset's images, and writes the report
/// into `out_dir` (created; report::write_report). `meta` is stored in metrics.json. Progress counts views.
std::vector<report::ViewResult> evaluate(const Model& model, const std::string& dataset_dir, const std::string& out_dir,
                                         const EvalOptions& options = {}, const Json& meta = Json::object(),
                                         const ProgressCallback& progress = {});

}  // namespace relit::method
