// Evaluation reports (docs/design.md §6): per-view PSNR/SSIM/HDR-FLIP of rendered test views against their
// references, their means per split and overall, written as files a person reads and a script parses.
//
//   dir/metrics.json               every view's psnr/ssim/mse/flip, per-split means, the overall mean, `meta`
//   dir/metrics.md                 a summary table and one table per split (PSNR 2 decimals, SSIM and FLIP 4)
//   dir/contact_sheet_<split>.png  up to 8 views of the split, one row each: prediction | reference | error
//   dir/<split>/<name>.png|.exr    optionally, every prediction (sRGB preview, linear float)
//
//   std::vector<report::ViewResult> views = ...;   // images + metrics::compare() of each view
//   report::ReportOptions options;
//   options.meta = {{"method", "ours"}, {"steps", 3000}};
//   report::write_report("runs/cloud/eval", views, options);
//   std::cout << report::format_summary_lines(views);   // "test: PSNR 31.23 dB  SSIM 0.9512 (50 views)", ...
//                                                       // then "PSNR 31.2345" and "SSIM 0.9512" for scripts
//
// Means are plain averages over the views; the PSNR mean is the mean of the per-view PSNRs (as NeRF papers
// report it), not the PSNR of the mean MSE. A view whose prediction equals its reference has PSNR +inf, which
// makes its split's mean +inf too; JSON has no infinity, so metrics.json stores such values as null.
#pragma once

#include <relit/config.hpp>
#include <relit/io/image.hpp>
#include <relit/metrics.hpp>
#include <relit/progress.hpp>

#include <array>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace relit::report {

/// One rendered view and how it compares with its reference.
struct ViewResult {
  std::string split;  ///< "test", "test_intensity_800", ...; names contact_sheet_<split>.png and a folder
  std::string name;   ///< unique within the split ("r_012"); names <split>/<name>.png
  std::uint32_t width = 0, height = 0;
  std::vector<float> prediction, reference;  ///< linear RGB, height x width x 3, row-major from the top
  /// The prediction's alpha (height x width) or empty: the EXR of the prediction then carries it as its A channel,
  /// so that comparing the written folder again (compare_folders) finds the same object mask.
  std::vector<float> prediction_alpha;
  metrics::ImageComparison metrics;  ///< usually metrics::compare(device, prediction, reference, w, h, 3)
};

/// Means over the views of a split (or of all views: split "all").
struct SplitSummary {
  std::string split;
  std::size_t n_views = 0;
  double psnr = 0, ssim = 0, mse = 0;  ///< PSNR: the mean of the per-view PSNRs in dB
  double flip = 0;                     ///< mean HDR-FLIP over the views that have it (NaN when none has)
  /// The object metrics' means over the views that have them (an object mask with pixels), NaN when none has:
  /// ObjectComparison's psnr, ssim, rel_mse, clipped, fraction, flip and prediction_only.
  double object_psnr = 0, object_ssim = 0, object_rel_mse = 0, object_clipped = 0, object_fraction = 0, object_flip = 0,
         object_prediction_only = 0;
};

/// Checks what the report relies on and throws InvalidArgument naming the view (split/name, index) and the
/// problem: no views; an empty split or name, or one that is not a plain file name ('/', "..", control
/// characters); the same name twice in a split; a zero size; images whose length is not width x height x 3;
/// a NaN or infinite pixel (with its position); NaN metrics (or infinite mse/ssim) of the whole image (the object
/// metrics may be NaN: no object pixels; FLIP may be NaN: not computed, and is otherwise in [0, 1]).
void validate(const std::vector<ViewResult>& views);

/// The means of every split, in the order the splits first appear in `views`.
std::vector<SplitSummary> summarize(const std::vector<ViewResult>& views);

/// The means over all views, with split "all". Throws InvalidArgument when `views` is empty.
SplitSummary overall(const std::vector<ViewResult>& views);

/// The rows a contact sheet shows of `n_views` views when it has at most `max_rows`: all of them when they
/// fit, otherwise `max_rows` indices spread evenly from the first view to the last.
std::vector<std::size_t> select_rows(std::size_t n_views, std::size_t max_rows);

/// The error colour map ('inferno', 33 control points interpolated linearly) at t, clamped to [0, 1]: sRGB
/// values, from near-black (0.0015, 0.0005, 0.0139) at 0 through purple and orange to pale yellow at 1.
std::array<float, 3> error_colour(float t);

struct ContactSheetOptions {
  std::size_t max_rows = 8;   ///< more views than this: select_rows() picks which
  float error_scale = 0.25f;  ///< the mean absolute sRGB difference shown as the top of the colour map
  int gutter = 4;             ///< pixels of dark grey around and between the panels
  /// Column titles, a caption under each row (the view's name, PSNR and object PSNR) and a colour bar of the
  /// error map at the bottom. Off: the panels and gutters alone.
  bool labels = true;
};

/// A contact sheet of `views`: one row per selected view, three panels per row, prediction | reference |
/// error. Panels are views' own size, top-left aligned in cells as large as the largest view (with labels at
/// least 72 pixels wide, a 15-pixel text band above the panels and under each row, and an 8-pixel colour bar
/// under the error column). The image is
/// linear (write_image() encodes a .png as sRGB): prediction and reference are clamped to [0, 1]; the
/// error panel shows, per pixel, the mean over R, G, B of |sRGB(prediction) - sRGB(reference)| (both
/// clamped) divided by error_scale, through error_colour(), so that the PNG shows the colour map's sRGB
/// values. Throws InvalidArgument for no views, a null view, a non-positive error_scale, a negative gutter
/// or a view that fails validate()'s image checks.
Image contact_sheet(const std::vector<const ViewResult*>& views, const ContactSheetOptions& options = {});

struct ReportOptions {
  Json meta = Json::object();      ///< stored as metrics.json's "meta" (method, config, steps, time, ...)
  ContactSheetOptions sheet;       ///< for every contact_sheet_<split>.png
  bool write_predictions = false;  ///< also dir/<split>/<name>.png for every view
  bool write_exr = false;          ///< also dir/<split>/<name>.exr (linear float) for every view
};

/// The content of metrics.json (docs/evaluation.md): {"format", "version", "meta", "mean": the overall means,
/// "splits": {split: its means and contact sheet} in first-seen order, "views": [...]}. Validates `views` and
/// options.meta first.
std::string metrics_json(const std::vector<ViewResult>& views, const ReportOptions& options = {});

/// The content of metrics.md: the meta's top-level entries, a summary table (one row per split and the
/// mean), then per split its contact sheet and a table of its views. Validates `views` first.
std::string metrics_markdown(const std::vector<ViewResult>& views, const ReportOptions& options = {});

/// Writes the report of `views` into `dir` (created when missing; see the top of this file). Everything is
/// validated and rendered in memory before the first file is touched, so bad input changes nothing. Every
/// file is written atomically (a temporary file in the same folder, renamed over the old one), so a file is
/// either its old self or complete, and metrics.json is written last: when it is new, so is the rest.
/// Throws InvalidArgument for bad input (validate(), a `meta` that is not an object) and IOError naming
/// the file or folder that could not be written.
void write_report(const std::string& dir, const std::vector<ViewResult>& views, const ReportOptions& options = {});

/// The views of compare_folders(), and the predictions that no reference matched (contact sheets, other files).
struct FolderComparison {
  std::vector<ViewResult> views;
  std::vector<std::string> unmatched_predictions;
};

/// Compares the images of any renderer with references (relit eval --predictions DIR --references DIR). The
/// references are a relit dataset folder (its transforms_<split>.json name the images) or any folder of images;
/// a reference's key is its split and file stem: test/r_000 for DIR/test/r_000.exr (the split is the folder
/// relative to DIR with '/' as '_', "images" at the top). The prediction of a key is found under `predictions`
/// the same way, with any image extension (.exr, .pfm, .hdr before .png, .jpg). Alpha channels, where either
/// image has one, give the object mask (metrics::object_mask). `splits`, when not empty, keeps the references and
/// predictions of those splits only (relit eval --split test: a dataset's test views, without its training views).
/// Throws IOError naming the references without a prediction, a split with no reference, a size mismatch, an
/// unreadable image or non-finite pixels.
FolderComparison compare_folders(const Device& device, const std::string& predictions, const std::string& references,
                                 const std::vector<std::string>& splits = {}, const ProgressCallback& progress = {});

/// What a program prints: one line per split, "<split>: PSNR 31.23 dB  SSIM 0.9512  FLIP 0.0812 (50 views)" (FLIP
/// and the object's metrics where the views have them), then
/// exactly "PSNR <mean>" and "SSIM <mean>" over all views, 4 decimals each (scripts parse these two).
/// Each line ends with '\n'. Throws InvalidArgument when `views` is empty.
std::string format_summary_lines(const std::vector<ViewResult>& views);

}  // namespace relit::report
