// Evaluation reports: summaries, contact sheets, metrics.json / metrics.md, written atomically.
#include <relit/error.hpp>
#include <relit/io/file.hpp>
#include <relit/log.hpp>
#include <relit/report.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <mutex>
#include <set>
#include <sstream>
#include <utility>

namespace fs = std::filesystem;

namespace relit::report {

namespace {

using OrderedJson = nlohmann::ordered_json;

// format_summary_lines() names the share of the object's pixels that only the prediction marks above this.
constexpr double kPredictionOnlyWarning = 0.25;

// 'inferno' (van der Walt & Smith, CC0; the matplotlib colour map) at entries 0, 8, 16, ..., 248 and 255 of
// its 256, in sRGB, interpolated linearly between (within a few thousandths of the full table).
constexpr int kInfernoStep = 8;
constexpr float kInferno[33][3] = {
    {0.001462f, 0.000466f, 0.013866f}, {0.013995f, 0.011225f, 0.071862f}, {0.042253f, 0.028139f, 0.141141f},
    {0.081962f, 0.043328f, 0.215289f}, {0.129285f, 0.047293f, 0.290788f}, {0.183429f, 0.040329f, 0.354971f},
    {0.238273f, 0.036621f, 0.396353f}, {0.290763f, 0.045644f, 0.418637f}, {0.341500f, 0.062325f, 0.429425f},
    {0.391453f, 0.080927f, 0.433109f}, {0.441207f, 0.099338f, 0.431594f}, {0.491022f, 0.117179f, 0.425552f},
    {0.540920f, 0.134729f, 0.415123f}, {0.590734f, 0.152563f, 0.400290f}, {0.640135f, 0.171438f, 0.381065f},
    {0.688653f, 0.192239f, 0.357603f}, {0.735683f, 0.215906f, 0.330245f}, {0.780517f, 0.243327f, 0.299523f},
    {0.822386f, 0.275197f, 0.266085f}, {0.860533f, 0.311892f, 0.230606f}, {0.894305f, 0.353399f, 0.193584f},
    {0.923215f, 0.399359f, 0.155193f}, {0.946965f, 0.449191f, 0.115272f}, {0.965397f, 0.502249f, 0.073859f},
    {0.978422f, 0.557937f, 0.034931f}, {0.985952f, 0.615750f, 0.025592f}, {0.987874f, 0.675267f, 0.065257f},
    {0.984075f, 0.736087f, 0.129527f}, {0.974638f, 0.797692f, 0.206332f}, {0.960626f, 0.859069f, 0.298010f},
    {0.947594f, 0.917399f, 0.410665f}, {0.954529f, 0.965896f, 0.540361f}, {0.988362f, 0.998364f, 0.644924f}};

// Labelled sheets: text bands (DejaVu Sans, kFontSize px, light grey), the colour bar and the narrowest cell.
constexpr int kFontSize = 11, kLabelBand = 15, kBarHeight = 8, kMinLabelledCell = 72;
constexpr float kTextLinear = 0.8f;

void warn_missing_font() {
  static std::once_flag once;
  std::call_once(once, [] {
    log_warning(
        "contact sheets: the DejaVu Sans font was not found (Debian: fonts-dejavu-core); the sheets have no "
        "titles or captions");
  });
}

// Linear value of the dark grey between panels (sRGB ≈ 0.1: distinct from the colour map's near-black zero).
constexpr float kGutterLinear = 0.01f;

std::string label(const ViewResult& v, std::size_t index) {
  return "view " + std::to_string(index) + " ('" + v.split + "/" + v.name + "')";
}

bool plain_file_name(const std::string& s) {
  if (s.empty() || s == "." || s == "..") return false;
  return std::none_of(s.begin(), s.end(), [](char c) {
    const auto u = static_cast<unsigned char>(c);
    return c == '/' || c == '\\' || u < 0x20 || u == 0x7f;
  });
}

void check_image(const ViewResult& v, std::size_t index, const std::vector<float>& image, const char* what) {
  const std::size_t expected = std::size_t(v.width) * v.height * 3;
  if (image.size() != expected)
    throw InvalidArgument("report: " + label(v, index) + ": the " + what + " has " + std::to_string(image.size()) +
                          " values, expected width x height x 3 = " + std::to_string(v.width) + " x " +
                          std::to_string(v.height) + " x 3 = " + std::to_string(expected));
  const auto bad = std::find_if(image.begin(), image.end(), [](float x) { return !std::isfinite(x); });
  if (bad != image.end()) {
    const std::size_t k = std::size_t(bad - image.begin()), pixel = k / 3;
    throw InvalidArgument("report: " + label(v, index) + ": the " + what + " has a " +
                          (std::isnan(*bad) ? "NaN" : "infinite value") + " at pixel (x " +
                          std::to_string(pixel % v.width) + ", y " + std::to_string(pixel / v.width) + ") channel " +
                          std::to_string(k % 3));
  }
}

void check_images(const ViewResult& v, std::size_t index) {
  if (v.width == 0 || v.height == 0)
    throw InvalidArgument("report: " + label(v, index) + " has an empty size " + std::to_string(v.width) + " x " +
                          std::to_string(v.height));
  check_image(v, index, v.prediction, "prediction");
  check_image(v, index, v.reference, "reference");
  const std::size_t pixels = std::size_t(v.width) * v.height;
  if (!v.prediction_alpha.empty() && v.prediction_alpha.size() != pixels)
    throw InvalidArgument("report: " + label(v, index) + ": the prediction's alpha has " +
                          std::to_string(v.prediction_alpha.size()) +
                          " values, expected width x height = " + std::to_string(pixels));
  const auto bad =
      std::find_if(v.prediction_alpha.begin(), v.prediction_alpha.end(), [](float a) { return !std::isfinite(a); });
  if (bad != v.prediction_alpha.end())
    throw InvalidArgument("report: " + label(v, index) + ": the prediction's alpha has a non-finite value at pixel " +
                          std::to_string(bad - v.prediction_alpha.begin()));
}

std::string fixed(double v, int digits) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*f", digits, v);
  return buf;
}

std::string scientific(double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.3e", v);
  return buf;
}

// A metric that may be missing (NaN: no object pixels) is shown as "–".
std::string maybe(double v, int digits) { return std::isnan(v) ? "–" : fixed(v, digits); }
std::string maybe_scientific(double v) { return std::isnan(v) ? "–" : scientific(v); }
std::string percent(double v) { return std::isnan(v) ? "–" : fixed(100.0 * v, 1) + " %"; }

// JSON has no infinity (a perfect view's PSNR): null.
OrderedJson number(double v) { return std::isfinite(v) ? OrderedJson(v) : OrderedJson(nullptr); }

OrderedJson means(const SplitSummary& s) {
  return {{"n_views", s.n_views},
          {"psnr", number(s.psnr)},
          {"ssim", number(s.ssim)},
          {"mse", number(s.mse)},
          {"flip", number(s.flip)},
          {"object",
           {{"psnr", number(s.object_psnr)},
            {"ssim", number(s.object_ssim)},
            {"rel_mse", number(s.object_rel_mse)},
            {"flip", number(s.object_flip)},
            {"clipped", number(s.object_clipped)},
            {"fraction", number(s.object_fraction)},
            {"prediction_only", number(s.object_prediction_only)}}}};
}

OrderedJson view_object(const metrics::ImageComparison& m) {
  return {{"pixels", m.object.pixels},
          {"fraction", number(m.object.fraction)},
          {"psnr", number(m.object.psnr)},
          {"ssim", number(m.object.ssim)},
          {"mse", number(m.object.mse)},
          {"rel_mse", number(m.object.rel_mse)},
          {"flip", number(m.object.flip)},
          {"clipped", number(m.object.clipped)},
          {"prediction_only", number(m.object.prediction_only)}};
}

// A Markdown table cell: '|' would end the cell, a line break the table.
std::string cell(const std::string& s) {
  std::string out;
  for (char c : s) {
    if (c == '|')
      out += "\\|";
    else if (c == '\n' || c == '\r')
      out += ' ';
    else
      out += c;
  }
  return out;
}

const Json& checked_meta(const Json& meta) {
  if (!meta.is_object() && !meta.is_null())
    throw InvalidArgument("report: meta must be a JSON object (method, config, steps, ...), not " +
                          std::string(meta.type_name()));
  return meta;
}

// The views of `split`, in order.
std::vector<const ViewResult*> views_of(const std::vector<ViewResult>& views, const std::string& split) {
  std::vector<const ViewResult*> out;
  for (const auto& v : views)
    if (v.split == split) out.push_back(&v);
  return out;
}

std::vector<std::string> sheet_view_names(const std::vector<const ViewResult*>& of, std::size_t max_rows) {
  std::vector<std::string> out;
  for (std::size_t i : select_rows(of.size(), max_rows)) out.push_back(of[i]->name);
  return out;
}

std::string sheet_file(const std::string& split) { return "contact_sheet_" + split + ".png"; }

// The metrics a view may lack (NaN): FLIP (not computed) and the object's (no object pixels), in SplitSummary's
// order of flip, object_psnr ... object_prediction_only.
constexpr std::size_t kOptional = 8;
std::array<double, kOptional> optional_values(const ViewResult& v) {
  const auto& o = v.metrics.object;
  return {v.metrics.flip, o.psnr,           o.ssim, o.rel_mse, o.clipped, o.pixels ? o.fraction : std::nan(""),
          o.flip,         o.prediction_only};
}

std::array<double*, kOptional> optional_fields(SplitSummary& s) {
  return {&s.flip,           &s.object_psnr,     &s.object_ssim, &s.object_rel_mse,
          &s.object_clipped, &s.object_fraction, &s.object_flip, &s.object_prediction_only};
}

// Sums, and how many views have each optional metric (NaN: the view has none).
struct Accumulator {
  SplitSummary sums;
  std::array<std::size_t, kOptional> counts{};
  void add(const ViewResult& v) {
    ++sums.n_views;
    sums.psnr += v.metrics.psnr;
    sums.ssim += v.metrics.ssim;
    sums.mse += v.metrics.mse;
    const auto values = optional_values(v);
    const auto fields = optional_fields(sums);
    for (std::size_t k = 0; k < values.size(); ++k)
      if (!std::isnan(values[k])) {
        *fields[k] += values[k];
        ++counts[k];
      }
  }
  SplitSummary mean() {
    SplitSummary s = sums;
    if (s.n_views == 0) return s;
    s.psnr /= double(s.n_views);
    s.ssim /= double(s.n_views);
    s.mse /= double(s.n_views);
    const auto fields = optional_fields(s);
    for (std::size_t k = 0; k < fields.size(); ++k)
      *fields[k] = counts[k] ? *fields[k] / double(counts[k]) : std::nan("");
    return s;
  }
};

}  // namespace

void validate(const std::vector<ViewResult>& views) {
  if (views.empty()) throw InvalidArgument("report: no views to report");
  std::set<std::pair<std::string, std::string>> seen;
  for (std::size_t i = 0; i < views.size(); ++i) {
    const ViewResult& v = views[i];
    if (!plain_file_name(v.split))
      throw InvalidArgument(
          "report: " + label(v, i) +
          ": the split must be a plain file name (not empty, no '/', '\\', '..' or control characters)");
    if (!plain_file_name(v.name))
      throw InvalidArgument(
          "report: " + label(v, i) +
          ": the name must be a plain file name (not empty, no '/', '\\', '..' or control characters)");
    if (!seen.emplace(v.split, v.name).second)
      throw InvalidArgument("report: " + label(v, i) + ": another view of split '" + v.split + "' has the same name");
    check_images(v, i);
    const auto& m = v.metrics;
    if (std::isnan(m.psnr) || !std::isfinite(m.ssim) || !std::isfinite(m.mse) || m.flip < 0 || m.flip > 1)
      throw InvalidArgument("report: " + label(v, i) + " has invalid metrics (psnr " + std::to_string(m.psnr) +
                            ", ssim " + std::to_string(m.ssim) + ", mse " + std::to_string(m.mse) + ", flip " +
                            std::to_string(m.flip) + "): compute them with metrics::compare");
  }
}

std::vector<SplitSummary> summarize(const std::vector<ViewResult>& views) {
  std::vector<Accumulator> acc;
  for (const auto& v : views) {
    auto it = std::find_if(acc.begin(), acc.end(), [&](const Accumulator& a) { return a.sums.split == v.split; });
    if (it == acc.end()) {
      acc.push_back({});
      acc.back().sums.split = v.split;
      it = acc.end() - 1;
    }
    it->add(v);
  }
  std::vector<SplitSummary> out;
  for (auto& a : acc) out.push_back(a.mean());
  return out;
}

SplitSummary overall(const std::vector<ViewResult>& views) {
  if (views.empty()) throw InvalidArgument("report: no views to average");
  Accumulator all;
  all.sums.split = "all";
  for (const auto& v : views) all.add(v);
  return all.mean();
}

std::vector<std::size_t> select_rows(std::size_t n_views, std::size_t max_rows) {
  if (max_rows == 0) throw InvalidArgument("report: a contact sheet needs max_rows >= 1");
  std::vector<std::size_t> rows;
  if (n_views <= max_rows) {
    for (std::size_t i = 0; i < n_views; ++i) rows.push_back(i);
  } else if (max_rows == 1) {
    rows.push_back(0);
  } else {
    // round(k (n - 1) / (m - 1)): the first and the last view, evenly spaced between; strictly increasing
    // because n > m.
    const std::size_t span = n_views - 1, steps = max_rows - 1;
    for (std::size_t k = 0; k < max_rows; ++k) rows.push_back((2 * k * span + steps) / (2 * steps));
  }
  return rows;
}

std::array<float, 3> error_colour(float t) {
  t = std::isnan(t) ? 1.0f : std::clamp(t, 0.0f, 1.0f);
  const float entry = t * 255.0f;  // position in the full 256-entry table
  const int n = int(sizeof kInferno / sizeof kInferno[0]);
  const int i = std::min(int(entry) / kInfernoStep, n - 2);
  const float lo = float(i * kInfernoStep), hi = i + 1 == n - 1 ? 255.0f : float((i + 1) * kInfernoStep);
  const float f = std::clamp((entry - lo) / (hi - lo), 0.0f, 1.0f);
  std::array<float, 3> c{};
  for (int k = 0; k < 3; ++k) c[k] = kInferno[i][k] + f * (kInferno[i + 1][k] - kInferno[i][k]);
  return c;
}

Image contact_sheet(const std::vector<const ViewResult*>& views, const ContactSheetOptions& options) {
  if (views.empty()) throw InvalidArgument("contact_sheet: no views");
  if (!(options.error_scale > 0) || !std::isfinite(options.error_scale))
    throw InvalidArgument("contact_sheet: error_scale must be a positive number, not " +
                          std::to_string(options.error_scale));
  if (options.gutter < 0) throw InvalidArgument("contact_sheet: gutter must be >= 0");
  for (std::size_t i = 0; i < views.size(); ++i) {
    if (!views[i]) throw InvalidArgument("contact_sheet: view " + std::to_string(i) + " is null");
    check_images(*views[i], i);
  }
  std::vector<const ViewResult*> rows;
  for (std::size_t i : select_rows(views.size(), options.max_rows)) rows.push_back(views[i]);

  int w = 0, h = 0;
  for (const auto* v : rows) {
    w = std::max(w, int(v->width));
    h = std::max(h, int(v->height));
  }
  const int g = options.gutter;
  // With labels: a title band above the panels, a caption band under each row and the colour bar at the bottom;
  // cells at least kMinLabelledCell wide so that a caption fits.
  const int band = options.labels ? kLabelBand : 0;
  if (options.labels) w = std::max(w, kMinLabelledCell);
  const int row_pitch = h + band + g, rows_top = g + band;
  const int bar_top = rows_top + int(rows.size()) * row_pitch;
  const int height = options.labels ? bar_top + kBarHeight + band + g : bar_top;
  Image sheet(3 * w + 4 * g, height, 3, kGutterLinear);
  const int x_pred = g, x_ref = 2 * g + w, x_err = 3 * g + 2 * w;
  for (std::size_t r = 0; r < rows.size(); ++r) {
    const ViewResult& v = *rows[r];
    const int y0 = rows_top + int(r) * row_pitch;
    for (int y = 0; y < int(v.height); ++y)
      for (int x = 0; x < int(v.width); ++x) {
        const std::size_t i = (std::size_t(y) * v.width + x) * 3;
        float err = 0;
        for (int c = 0; c < 3; ++c) {
          const float p = std::clamp(v.prediction[i + c], 0.0f, 1.0f);
          const float q = std::clamp(v.reference[i + c], 0.0f, 1.0f);
          sheet.at(x_pred + x, y0 + y, c) = p;
          sheet.at(x_ref + x, y0 + y, c) = q;
          err += std::fabs(linear_to_srgb(p) - linear_to_srgb(q));
        }
        const auto colour = error_colour(err / 3.0f / options.error_scale);
        for (int c = 0; c < 3; ++c) sheet.at(x_err + x, y0 + y, c) = srgb_to_linear(colour[c]);
      }
  }
  if (!options.labels) return sheet;

  bool drawn = true;
  const auto text = [&](int x, int y, const std::string& s, TextAlign align) {
    drawn = draw_text(sheet, x, y, s, kFontSize, kTextLinear, align) && drawn;
  };
  text(x_pred + w / 2, g + 1, "prediction", TextAlign::Center);
  text(x_ref + w / 2, g + 1, "reference", TextAlign::Center);
  text(x_err + w / 2, g + 1, "error", TextAlign::Center);
  for (std::size_t r = 0; r < rows.size(); ++r) {
    const ViewResult& v = *rows[r];
    std::string caption = v.name + ": " + (std::isfinite(v.metrics.psnr) ? fixed(v.metrics.psnr, 2) + " dB" : "exact");
    if (!std::isnan(v.metrics.object.psnr))
      caption +=
          " (object " + (std::isfinite(v.metrics.object.psnr) ? fixed(v.metrics.object.psnr, 2) + " dB)" : "exact)");
    text(x_pred, rows_top + int(r) * row_pitch + h + 1, caption, TextAlign::Left);
  }
  // The colour bar: the error column's width, 0 on the left to error_scale (and above) on the right.
  for (int x = 0; x < w; ++x) {
    const auto colour = error_colour(w > 1 ? float(x) / float(w - 1) : 0.0f);
    for (int y = 0; y < kBarHeight; ++y)
      for (int c = 0; c < 3; ++c) sheet.at(x_err + x, bar_top + y, c) = srgb_to_linear(colour[c]);
  }
  text(x_err, bar_top + kBarHeight + 1, "0", TextAlign::Left);
  text(x_err + w - 1, bar_top + kBarHeight + 1, ">= " + fixed(options.error_scale, 2), TextAlign::Right);
  text(x_err - g - 2, bar_top - 1, "|sRGB error|", TextAlign::Right);
  if (!drawn) warn_missing_font();
  return sheet;
}

std::string metrics_json(const std::vector<ViewResult>& views, const ReportOptions& options) {
  validate(views);
  const Json& meta = checked_meta(options.meta);
  OrderedJson j;
  j["format"] = "relit-eval-report";
  j["version"] = 1;
  j["meta"] = meta.is_null() ? OrderedJson::object() : OrderedJson::parse(meta.dump());
  j["mean"] = means(overall(views));
  j["splits"] = OrderedJson::object();
  for (const auto& s : summarize(views)) {
    OrderedJson e = means(s);
    e["contact_sheet"] = sheet_file(s.split);
    e["contact_sheet_views"] = sheet_view_names(views_of(views, s.split), options.sheet.max_rows);
    j["splits"][s.split] = std::move(e);
  }
  j["views"] = OrderedJson::array();
  for (const auto& v : views)
    j["views"].push_back({{"split", v.split},
                          {"name", v.name},
                          {"width", v.width},
                          {"height", v.height},
                          {"psnr", number(v.metrics.psnr)},
                          {"ssim", number(v.metrics.ssim)},
                          {"mse", number(v.metrics.mse)},
                          {"flip", number(v.metrics.flip)},
                          {"object", view_object(v.metrics)}});
  return j.dump(2) + "\n";
}

std::string metrics_markdown(const std::vector<ViewResult>& views, const ReportOptions& options) {
  validate(views);
  const Json& meta = checked_meta(options.meta);
  std::ostringstream md;
  md << "# Evaluation\n\n";
  if (meta.is_object() && !meta.empty()) {
    for (const auto& [key, value] : meta.items()) {
      std::string text = value.is_string() ? value.get<std::string>() : value.dump();
      // A whole run config is too long to read inline; metrics.json has it.
      if ((value.is_object() || value.is_array()) && text.size() > 120)
        text = std::string(value.is_object() ? "{…}" : "[…]") + " (" + std::to_string(value.size()) +
               (value.size() == 1 ? " entry" : " entries") + ", see metrics.json)";
      md << "- " << cell(key) << ": " << cell(text) << "\n";
    }
    md << "\n";
  }
  md << "## Summary\n\n"
     << "Image: the paper's protocol, over the whole image on clamped sRGB. Object: over the pixels where the "
        "reference's "
        "or the prediction's alpha exceeds "
     << fixed(metrics::kObjectAlpha, 2)
     << "; relMSE on the linear images, (p - r)² / (r² + 0.01); FLIP: mean HDR-FLIP of the linear images "
        "(0: no visible difference, 1: the largest); "
        "clipped: the share of the object's pixels whose reference clips in sRGB; object share: the object's pixels "
        "in the image; prediction only: the share of the object's pixels that only the prediction's alpha marks "
        "(floaters or haze: the object metrics average over that much empty space too) (docs/evaluation.md).\n\n"
     << "| split | views | PSNR [dB] | SSIM | MSE | FLIP | object PSNR [dB] | object SSIM | object relMSE | "
        "object FLIP | clipped | object share | prediction only |\n"
        "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n";
  const auto summary_row = [&](const SplitSummary& s, const std::string& name) {
    md << "| " << name << " | " << s.n_views << " | " << fixed(s.psnr, 2) << " | " << fixed(s.ssim, 4) << " | "
       << scientific(s.mse) << " | " << maybe(s.flip, 4) << " | " << maybe(s.object_psnr, 2) << " | "
       << maybe(s.object_ssim, 4) << " | " << maybe_scientific(s.object_rel_mse) << " | " << maybe(s.object_flip, 4)
       << " | " << percent(s.object_clipped) << " | " << percent(s.object_fraction) << " | "
       << percent(s.object_prediction_only) << " |\n";
  };
  const auto summaries = summarize(views);
  for (const auto& s : summaries) summary_row(s, cell(s.split));
  summary_row(overall(views), "**mean**");

  for (const auto& s : summaries) {
    const auto of = views_of(views, s.split);
    const auto shown = sheet_view_names(of, options.sheet.max_rows);
    md << "\n## " << s.split << "\n\n![" << s.split << " contact sheet](" << sheet_file(s.split) << ")\n\n"
       << "Columns: prediction | reference | error (mean absolute difference of the sRGB images, colour map "
       << "'inferno': black = 0, yellow ≥ " << fixed(options.sheet.error_scale, 2)
       << "; the bar under the sheet). Shown: ";
    for (std::size_t i = 0; i < shown.size(); ++i) md << (i ? ", " : "") << shown[i];
    md << " (" << shown.size() << " of " << of.size() << (of.size() == 1 ? " view).\n\n" : " views).\n\n")
       << "| view | PSNR [dB] | SSIM | MSE | FLIP | object PSNR [dB] | object SSIM | object relMSE | object FLIP | "
          "clipped |\n|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n";
    for (const auto* v : of) {
      const auto& m = v->metrics;
      md << "| " << cell(v->name) << " | " << fixed(m.psnr, 2) << " | " << fixed(m.ssim, 4) << " | "
         << scientific(m.mse) << " | " << maybe(m.flip, 4) << " | " << maybe(m.object.psnr, 2) << " | "
         << maybe(m.object.ssim, 4) << " | " << maybe_scientific(m.object.rel_mse) << " | " << maybe(m.object.flip, 4)
         << " | " << percent(m.object.clipped) << " |\n";
    }
  }
  return md.str();
}

void write_report(const std::string& dir, const std::vector<ViewResult>& views, const ReportOptions& options) {
  if (dir.empty()) throw InvalidArgument("write_report: no output folder given");
  // Everything that can fail on bad input happens before the first file is touched.
  const std::string json = metrics_json(views, options);
  const std::string md = metrics_markdown(views, options);
  std::vector<std::pair<std::string, Image>> sheets;
  for (const auto& s : summarize(views))
    sheets.emplace_back(sheet_file(s.split), contact_sheet(views_of(views, s.split), options.sheet));

  const fs::path root(dir);
  const auto make_folder = [](const fs::path& p) {
    io::create_directories(p.string(), "report folder");
    io::remove_stale_temporaries(p.string());  // what a killed evaluation left behind
  };
  make_folder(root);
  if (options.write_predictions || options.write_exr) {
    for (const auto& s : summarize(views)) make_folder(root / s.split);
    for (const auto& v : views) {
      Image image(int(v.width), int(v.height), 3);
      image.pixels = v.prediction;
      const std::string base = (root / v.split / v.name).string();
      if (options.write_predictions) write_image(base + ".png", image);
      // The EXR with the prediction's alpha where the view has it: the object mask for a later eval --predictions.
      if (options.write_exr)
        write_image(base + ".exr", join_rgb_alpha(v.prediction, v.prediction_alpha, int(v.width), int(v.height)));
    }
  }
  for (const auto& [file, image] : sheets) write_image((root / file).string(), image);
  io::write_file_atomic((root / "metrics.md").string(), md);
  io::write_file_atomic((root / "metrics.json").string(), json);  // last: a new metrics.json means a complete report
}

std::string format_summary_lines(const std::vector<ViewResult>& views) {
  const SplitSummary all = overall(views);
  std::ostringstream out;
  for (const auto& s : summarize(views)) {
    out << s.split << ": PSNR " << fixed(s.psnr, 2) << " dB  SSIM " << fixed(s.ssim, 4);
    if (!std::isnan(s.flip)) out << "  FLIP " << fixed(s.flip, 4);
    if (!std::isnan(s.object_psnr)) {
      out << "  | object: PSNR " << fixed(s.object_psnr, 2) << " dB  SSIM " << maybe(s.object_ssim, 4) << "  relMSE "
          << scientific(s.object_rel_mse);
      if (!std::isnan(s.object_flip)) out << "  FLIP " << fixed(s.object_flip, 4);
      out << "  clipped " << percent(s.object_clipped);
      // A prediction whose alpha spreads far beyond the reference's: the object metrics are diluted by it.
      if (s.object_prediction_only > kPredictionOnlyWarning)
        out << "  prediction only " << percent(s.object_prediction_only)
            << " (floaters or haze: the object metrics average over it)";
    }
    out << " (" << s.n_views << (s.n_views == 1 ? " view)\n" : " views)\n");
  }
  // The two parsable lines: "PSNR <value>" first, then which views the mean is of.
  const auto splits = summarize(views);
  std::string of =
      splits.size() == 1
          ? "the " + std::to_string(all.n_views) + " " + splits[0].split + " view" + (all.n_views == 1 ? "" : "s")
          : "all " + std::to_string(all.n_views) + " views of " + std::to_string(splits.size()) + " splits";
  out << "PSNR " << fixed(all.psnr, 4) << "  (mean over " << of << ")\nSSIM " << fixed(all.ssim, 4) << "  (mean over "
      << of << ")\n";
  return out.str();
}

}  // namespace relit::report
