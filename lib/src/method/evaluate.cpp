// relit eval: render the test views, compare, write the report.
#include <relit/io/file.hpp>
#include <relit/method/evaluate.hpp>
#include <relit/method/trainer.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <sstream>

namespace fs = std::filesystem;

namespace relit::method {

namespace {

// A perceptually ordered map from black through purple and orange to pale yellow (control points of the
// 'inferno' family, interpolated linearly), as linear RGB so that write_image's sRGB encoding shows it.
Float3 error_colour(float t) {
  static const std::array<std::array<float, 3>, 6> srgb = {{{0.0f, 0.0f, 0.016f},
                                                            {0.258f, 0.039f, 0.408f},
                                                            {0.576f, 0.149f, 0.404f},
                                                            {0.867f, 0.318f, 0.227f},
                                                            {0.988f, 0.647f, 0.039f},
                                                            {0.988f, 1.0f, 0.643f}}};
  t = std::clamp(t, 0.0f, 1.0f) * float(srgb.size() - 1);
  const std::size_t i = std::min<std::size_t>(static_cast<std::size_t>(t), srgb.size() - 2);
  const float f = t - float(i);
  Float3 c;
  for (int k = 0; k < 3; ++k) c[k] = srgb_to_linear(srgb[i][k] + f * (srgb[i + 1][k] - srgb[i][k]));
  return c;
}

std::string fixed(double v, int digits) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*f", digits, v);
  return buf;
}

Json number(double v) { return std::isfinite(v) ? Json(v) : Json(nullptr); }

}  // namespace

std::vector<SplitSummary> summarize(const std::vector<ViewResult>& views) {
  std::vector<SplitSummary> out;
  SplitSummary all;
  all.split = "all";
  for (const auto& v : views) {
    auto it = std::find_if(out.begin(), out.end(), [&](const SplitSummary& s) { return s.split == v.split; });
    if (it == out.end()) {
      out.push_back({v.split, 0, 0, 0, 0});
      it = out.end() - 1;
    }
    for (SplitSummary* s : {&*it, &all}) {
      ++s->n_views;
      s->psnr += v.metrics.psnr;
      s->ssim += v.metrics.ssim;
      s->mse += v.metrics.mse;
    }
  }
  out.push_back(all);
  for (auto& s : out)
    if (s.n_views) {
      s.psnr /= double(s.n_views);
      s.ssim /= double(s.n_views);
      s.mse /= double(s.n_views);
    }
  return out;
}

Image contact_sheet(const std::vector<const ViewResult*>& views, std::size_t max_rows, float error_scale) {
  if (views.empty()) throw InvalidArgument("contact_sheet: no views");
  if (error_scale <= 0) throw InvalidArgument("contact_sheet: error_scale must be positive");
  std::vector<const ViewResult*> rows;
  const std::size_t n = std::min(views.size(), std::max<std::size_t>(max_rows, 1));
  for (std::size_t k = 0; k < n; ++k) rows.push_back(views[k * views.size() / n]);
  int w = 0, h = 0;
  for (const auto* v : rows) {
    const std::size_t px = std::size_t(v->width) * v->height * 3;
    if (v->prediction.size() != px || v->reference.size() != px)
      throw InvalidArgument("contact_sheet: view " + v->split + "/" + v->name + " has images of the wrong size");
    w = std::max(w, v->width);
    h = std::max(h, v->height);
  }
  const int gutter = 4;
  Image sheet(3 * w + 4 * gutter, int(rows.size()) * (h + gutter) + gutter, 3, 0.01f);
  for (std::size_t r = 0; r < rows.size(); ++r) {
    const ViewResult& v = *rows[r];
    const int y0 = gutter + int(r) * (h + gutter);
    for (int y = 0; y < v.height; ++y)
      for (int x = 0; x < v.width; ++x) {
        const std::size_t i = (std::size_t(y) * v.width + x) * 3;
        float err = 0;
        for (int c = 0; c < 3; ++c) {
          const float p = std::clamp(v.prediction[i + c], 0.0f, 1.0f), g = std::clamp(v.reference[i + c], 0.0f, 1.0f);
          sheet.at(gutter + x, y0 + y, c) = p;
          sheet.at(2 * gutter + w + x, y0 + y, c) = g;
          err += std::fabs(linear_to_srgb(p) - linear_to_srgb(g)) / 3.0f;
        }
        const Float3 col = error_colour(err / error_scale);
        for (int c = 0; c < 3; ++c) sheet.at(3 * gutter + 2 * w + x, y0 + y, c) = col[c];
      }
  }
  return sheet;
}

std::string summary_lines(const std::vector<ViewResult>& views) {
  std::ostringstream out;
  const auto sums = summarize(views);
  for (const auto& s : sums) {
    if (s.split == "all") continue;
    out << s.split << ": PSNR " << fixed(s.psnr, 2) << " dB  SSIM " << fixed(s.ssim, 4) << " (" << s.n_views
        << " views)\n";
  }
  out << "PSNR " << fixed(sums.back().psnr, 4) << "\nSSIM " << fixed(sums.back().ssim, 4) << "\n";
  return out.str();
}

void write_report(const std::string& out_dir, const std::vector<ViewResult>& views, const Json& meta) {
  if (views.empty()) throw InvalidArgument("write_report: no views");
  fs::create_directories(out_dir);
  const auto sums = summarize(views);
  Json j{{"meta", meta}, {"views", Json::array()}, {"splits", Json::object()}};
  for (const auto& v : views)
    j["views"].push_back({{"split", v.split}, {"name", v.name}, {"psnr", number(v.metrics.psnr)},
                          {"ssim", v.metrics.ssim}, {"mse", v.metrics.mse}});
  for (const auto& s : sums)
    j[s.split == "all" ? "mean" : "splits"].update(
        s.split == "all" ? Json{{"psnr", number(s.psnr)}, {"ssim", s.ssim}, {"mse", s.mse}, {"n_views", s.n_views}}
                         : Json{{s.split, {{"psnr", number(s.psnr)}, {"ssim", s.ssim}, {"mse", s.mse}, {"n_views", s.n_views}}}});
  io::write_file_atomic((fs::path(out_dir) / "metrics.json").string(), j.dump(2) + "\n");

  std::ostringstream md;
  md << "# Evaluation\n\n";
  if (meta.contains("run")) md << "Run: `" << meta["run"].get<std::string>() << "`";
  if (meta.contains("dataset")) md << "  \nDataset: `" << meta["dataset"].get<std::string>() << "`";
  if (meta.contains("step")) md << "  \nTraining steps: " << meta["step"].dump();
  md << "\n\n## Summary\n\n| split | views | PSNR [dB] | SSIM |\n|---|---:|---:|---:|\n";
  for (const auto& s : sums)
    md << "| " << (s.split == "all" ? "**mean**" : s.split) << " | " << s.n_views << " | " << fixed(s.psnr, 2) << " | "
       << fixed(s.ssim, 4) << " |\n";
  std::string split;
  for (const auto& v : views) {
    if (v.split != split) {
      split = v.split;
      md << "\n## " << split << "\n\n![contact sheet](contact_sheet_" << split
         << ".png)\n\nprediction | ground truth | error (mean absolute sRGB difference, black 0 → yellow 0.25)\n\n"
         << "| view | PSNR [dB] | SSIM |\n|---|---:|---:|\n";
    }
    md << "| " << v.name << " | " << fixed(v.metrics.psnr, 2) << " | " << fixed(v.metrics.ssim, 4) << " |\n";
  }
  io::write_file_atomic((fs::path(out_dir) / "metrics.md").string(), md.str());

  for (const auto& s : sums) {
    if (s.split == "all") continue;
    std::vector<const ViewResult*> of;
    for (const auto& v : views)
      if (v.split == s.split) of.push_back(&v);
    write_image((fs::path(out_dir) / ("contact_sheet_" + s.split + ".png")).string(), contact_sheet(of));
  }
}

std::vector<ViewResult> evaluate(const Ours& model, const std::string& dataset_dir, const std::string& out_dir,
                                 const EvalOptions& options, const Json& meta, const ProgressCallback& progress) {
  if (options.splits.empty()) throw InvalidArgument("evaluate: no splits given");
  std::vector<DatasetSplit> splits;
  std::size_t total = 0;
  for (const auto& name : options.splits) {
    splits.push_back(load_split(dataset_dir, name, options.max_views));
    total += splits.back().size();
  }
  std::vector<ViewResult> views;
  ProgressTracker tracker(progress, total, "views");
  RenderSettings rs;
  rs.visibility = options.visibility;
  for (const auto& split : splits)
    for (std::size_t i = 0; i < split.size(); ++i) {
      ViewResult v;
      v.split = split.split;
      v.name = split.names[i];
      v.width = split.width;
      v.height = split.height;
      rs.seed = static_cast<std::uint32_t>(i);
      Image img = render_image(model, split.cameras[i], split.lights[i], rs);
      v.prediction = std::move(img.pixels);
      v.reference = split.image(i);
      v.metrics = metrics::compare(model.device(), v.prediction, v.reference, v.width, v.height, 3);
      if (options.write_images) {
        Image pred(v.width, v.height, 3);
        pred.pixels = v.prediction;
        const fs::path base = fs::path(out_dir) / v.split / v.name;
        fs::create_directories(base.parent_path());
        write_image(base.string() + ".png", pred);
        write_image(base.string() + ".exr", pred);
      }
      views.push_back(std::move(v));
      tracker.update(views.size(), split.split + "/" + split.names[i]);
    }
  write_report(out_dir, views, meta);
  return views;
}

}  // namespace relit::method
