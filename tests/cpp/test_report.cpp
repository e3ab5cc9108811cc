// Evaluation reports: hand-computed means, the summary lines, contact-sheet layout and pixels, metrics.json
// and metrics.md parsed back, clear errors for bad input, and files that survive a failed write.
#include "test_support.hpp"

#include <relit/io/file.hpp>
#include <relit/report.hpp>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>

namespace relit {
namespace {

namespace fs = std::filesystem;
using report::ViewResult;

// A w x h view of constant linear colours; metrics set by hand (psnr → mse = 10^(-psnr/10)).
ViewResult view(const std::string& split, const std::string& name, double psnr, double ssim, float pred = 0.5f,
                float ref = 0.5f, std::uint32_t w = 4, std::uint32_t h = 3) {
  ViewResult v;
  v.split = split;
  v.name = name;
  v.width = w;
  v.height = h;
  v.prediction.assign(std::size_t(w) * h * 3, pred);
  v.reference.assign(std::size_t(w) * h * 3, ref);
  v.metrics.psnr = psnr;
  v.metrics.ssim = ssim;
  v.metrics.mse = std::pow(10.0, -psnr / 10.0);
  return v;
}

// The message of the InvalidArgument that `f` throws ("" when it throws none).
template <class F>
std::string invalid_argument_message(F&& f) {
  try {
    f();
  } catch (const InvalidArgument& e) {
    return e.what();
  }
  return "";
}

bool contains(const std::string& s, const std::string& part) { return s.find(part) != std::string::npos; }

// Relative luminance of an sRGB colour.
double luminance(const std::array<float, 3>& c) {
  return 0.2126 * srgb_to_linear(c[0]) + 0.7152 * srgb_to_linear(c[1]) + 0.0722 * srgb_to_linear(c[2]);
}

std::vector<const ViewResult*> pointers(const std::vector<ViewResult>& views) {
  std::vector<const ViewResult*> out;
  for (const auto& v : views) out.push_back(&v);
  return out;
}

TEST(Report, SummariesAreMeansPerSplitInFirstSeenOrder) {
  // Splits interleaved: the order is that of first appearance, not alphabetical.
  const std::vector<ViewResult> views = {view("test_light", "c", 25, 0.8), view("test", "a", 30, 0.9),
                                         view("test_light", "d", 35, 0.6), view("test", "b", 20, 0.7)};
  const auto s = report::summarize(views);
  ASSERT_EQ(s.size(), 2u);
  EXPECT_EQ(s[0].split, "test_light");
  EXPECT_EQ(s[0].n_views, 2u);
  EXPECT_DOUBLE_EQ(s[0].psnr, 30.0);
  EXPECT_DOUBLE_EQ(s[0].ssim, 0.7);
  EXPECT_DOUBLE_EQ(s[0].mse, (std::pow(10.0, -2.5) + std::pow(10.0, -3.5)) / 2);
  EXPECT_EQ(s[1].split, "test");
  EXPECT_DOUBLE_EQ(s[1].psnr, 25.0);
  EXPECT_DOUBLE_EQ(s[1].ssim, 0.8);
  // The PSNR mean is the mean of PSNRs (27.5 dB), not the PSNR of the mean MSE (≈ 24.7 dB).
  const auto all = report::overall(views);
  EXPECT_EQ(all.split, "all");
  EXPECT_EQ(all.n_views, 4u);
  EXPECT_DOUBLE_EQ(all.psnr, 27.5);
  EXPECT_DOUBLE_EQ(all.ssim, 0.75);
  EXPECT_DOUBLE_EQ(all.mse, (std::pow(10.0, -2.5) + std::pow(10.0, -3.0) + std::pow(10.0, -3.5) + 0.01) / 4);
  EXPECT_THROW(report::overall({}), InvalidArgument);
  EXPECT_TRUE(report::summarize({}).empty());
}

TEST(Report, SummaryLinesEndWithTheParsableMeans) {
  const std::vector<ViewResult> views = {view("test", "a", 30, 0.9), view("test", "b", 20.5, 0.7),
                                         view("test_light", "c", 25, 0.81234)};
  EXPECT_EQ(report::format_summary_lines(views),
            "test: PSNR 25.25 dB  SSIM 0.8000 (2 views)\n"
            "test_light: PSNR 25.00 dB  SSIM 0.8123 (1 view)\n"
            "PSNR 25.1667  (mean over all 3 views of 2 splits)\n"
            "SSIM 0.8041  (mean over all 3 views of 2 splits)\n");
  EXPECT_EQ(report::format_summary_lines({views[0], views[1]}),
            "test: PSNR 25.25 dB  SSIM 0.8000 (2 views)\n"
            "PSNR 25.2500  (mean over the 2 test views)\n"
            "SSIM 0.8000  (mean over the 2 test views)\n");
  // With FLIP (metrics::compare computes it): on the split's line, the parsable lines unchanged.
  std::vector<ViewResult> with_flip = {views[0], views[1]};
  with_flip[0].metrics.flip = 0.1;
  with_flip[1].metrics.flip = 0.2;
  EXPECT_EQ(report::format_summary_lines(with_flip),
            "test: PSNR 25.25 dB  SSIM 0.8000  FLIP 0.1500 (2 views)\n"
            "PSNR 25.2500  (mean over the 2 test views)\n"
            "SSIM 0.8000  (mean over the 2 test views)\n");
  // An object whose mask is mostly the prediction's (floaters or haze) is named on the split's line.
  std::vector<ViewResult> hazy = {views[0]};
  auto& o = hazy[0].metrics.object;
  o.pixels = 10;
  o.fraction = 0.5;
  o.psnr = 20;
  o.ssim = 0.5;
  o.rel_mse = 0.1;
  o.clipped = 0;
  o.prediction_only = 0.6;
  EXPECT_EQ(report::format_summary_lines(hazy),
            "test: PSNR 30.00 dB  SSIM 0.9000  | object: PSNR 20.00 dB  SSIM 0.5000  relMSE 1.000e-01  clipped 0.0 %  "
            "prediction only 60.0 % (floaters or haze: the object metrics average over it) (1 view)\n"
            "PSNR 30.0000  (mean over the 1 test view)\n"
            "SSIM 0.9000  (mean over the 1 test view)\n");
  o.prediction_only = 0.1;  // below the warning: not named
  EXPECT_EQ(report::format_summary_lines(hazy).find("prediction only"), std::string::npos);
  with_flip[1].metrics.flip = 1.5;  // outside [0, 1]
  EXPECT_THROW(report::validate(with_flip), InvalidArgument);
  EXPECT_THROW(report::format_summary_lines({}), InvalidArgument);
}

TEST(Report, RowSelectionSpreadsEvenlyFromFirstToLast) {
  EXPECT_EQ(report::select_rows(5, 8), (std::vector<std::size_t>{0, 1, 2, 3, 4}));
  EXPECT_EQ(report::select_rows(10, 4), (std::vector<std::size_t>{0, 3, 6, 9}));
  EXPECT_EQ(report::select_rows(9, 8), (std::vector<std::size_t>{0, 1, 2, 3, 5, 6, 7, 8}));
  EXPECT_EQ(report::select_rows(50, 2), (std::vector<std::size_t>{0, 49}));
  EXPECT_EQ(report::select_rows(7, 1), (std::vector<std::size_t>{0}));
  EXPECT_TRUE(report::select_rows(0, 8).empty());
  EXPECT_THROW(report::select_rows(5, 0), InvalidArgument);
  for (std::size_t n = 1; n <= 40; ++n)
    for (std::size_t m = 1; m <= 10; ++m) {
      const auto rows = report::select_rows(n, m);
      ASSERT_EQ(rows.size(), std::min(n, m)) << n << " " << m;
      EXPECT_EQ(rows.front(), 0u);
      if (rows.size() > 1) {
        EXPECT_EQ(rows.back(), n - 1);
      }
      for (std::size_t k = 1; k < rows.size(); ++k) {
        EXPECT_GT(rows[k], rows[k - 1]) << n << " " << m;
        // Even spacing: gaps differ by at most one view.
        if (k > 1) {
          EXPECT_LE(std::abs(long(rows[k] - rows[k - 1]) - long(rows[1] - rows[0])), 1) << n << " " << m;
        }
      }
    }
}

TEST(Report, ErrorColourMapIsInfernoWithRisingLuminance) {
  // The ends and the middle of matplotlib's 'inferno' (entries 0, 127/128 and 255 of its 256).
  const auto c0 = report::error_colour(0.0f), c1 = report::error_colour(1.0f), mid = report::error_colour(0.5f);
  EXPECT_FLOAT_EQ(c0[0], 0.001462f);
  EXPECT_FLOAT_EQ(c0[1], 0.000466f);
  EXPECT_FLOAT_EQ(c0[2], 0.013866f);
  EXPECT_FLOAT_EQ(c1[0], 0.988362f);
  EXPECT_FLOAT_EQ(c1[1], 0.998364f);
  EXPECT_FLOAT_EQ(c1[2], 0.644924f);
  EXPECT_NEAR(mid[0], 0.7328, 2e-3);  // between 0.729909 and 0.735683
  EXPECT_NEAR(mid[1], 0.2144, 2e-3);  // between 0.212759 and 0.215906
  EXPECT_NEAR(mid[2], 0.3320, 2e-3);  // between 0.333861 and 0.330245
  // Out-of-range values clamp.
  EXPECT_EQ(report::error_colour(-3.0f), c0);
  EXPECT_EQ(report::error_colour(7.0f), c1);
  // A perceptually ordered map: luminance rises all the way (also catches a mistyped control point).
  double last = -1;
  for (int i = 0; i <= 1000; ++i) {
    const double l = luminance(report::error_colour(float(i) / 1000.0f));
    EXPECT_GT(l, last) << "at t = " << i / 1000.0;
    last = l;
  }
}

TEST(Report, ContactSheetPanelsInOrderWithGutters) {
  // Row 0: prediction 0.2, reference 0.6 (distinct, to see the order); row 1: identical images.
  std::vector<ViewResult> views = {view("test", "a", 10, 0.5, 0.2f, 0.6f), view("test", "b", 99, 1, 0.3f, 0.3f)};
  const int w = 4, h = 3, g = 4;
  report::ContactSheetOptions o;
  o.labels = false;  // the panels alone (ContactSheetLabels: the titles, captions and bar)
  const Image sheet = report::contact_sheet(pointers(views), o);
  ASSERT_EQ(sheet.channels, 3);
  EXPECT_EQ(sheet.width, 3 * w + 4 * g);
  EXPECT_EQ(sheet.height, 2 * (h + g) + g);
  for (int c = 0; c < 3; ++c) {
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) {
        EXPECT_FLOAT_EQ(sheet.at(g + x, g + y, c), 0.2f);          // prediction | ...
        EXPECT_FLOAT_EQ(sheet.at(2 * g + w + x, g + y, c), 0.6f);  // ... | reference | ...
        // ... | error: no error → the colour map's zero colour, stored linear.
        const int y1 = 2 * g + h + y;
        EXPECT_FLOAT_EQ(sheet.at(3 * g + 2 * w + x, y1, c), srgb_to_linear(report::error_colour(0)[c]));
      }
    EXPECT_FLOAT_EQ(sheet.at(0, 0, c), 0.01f);      // corner gutter
    EXPECT_FLOAT_EQ(sheet.at(g + w, g, c), 0.01f);  // between prediction and reference
    EXPECT_FLOAT_EQ(sheet.at(g, g + h, c), 0.01f);  // between the rows
    EXPECT_FLOAT_EQ(sheet.at(sheet.width - 1, sheet.height - 1, c), 0.01f);
  }
  // Row 0's error: |sRGB(0.2) - sRGB(0.6)| per channel, / 0.25, through the map.
  const float e = std::fabs(linear_to_srgb(0.2f) - linear_to_srgb(0.6f)) / 0.25f;
  const auto expected = report::error_colour(e);
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(sheet.at(3 * g + 2 * w, g, c), srgb_to_linear(expected[c]), 1e-6);
}

TEST(Report, ContactSheetErrorScaleClampingAndMixedSizes) {
  // Reference at sRGB 0.125, prediction black: error 0.125 = half of the default scale → map(0.5); with
  // error_scale 0.125 → the top of the map. Prediction values beyond [0, 1] are clamped for display.
  ViewResult v = view("test", "a", 20, 0.5, -0.5f, srgb_to_linear(0.125f));
  ViewResult small = view("test", "small", 20, 0.5, 1.7f, 1.0f, 2, 2);
  const std::vector<const ViewResult*> both = {&v, &small};
  report::ContactSheetOptions o;
  o.gutter = 1;
  o.labels = false;
  const Image a = report::contact_sheet(both, o);
  EXPECT_EQ(a.width, 3 * 4 + 4);
  EXPECT_EQ(a.height, 2 * (3 + 1) + 1);
  for (int c = 0; c < 3; ++c) {
    EXPECT_FLOAT_EQ(a.at(1, 1, c), 0.0f);  // -0.5 shown as 0
    EXPECT_NEAR(a.at(1 + 2 * (4 + 1), 1, c), srgb_to_linear(report::error_colour(0.5f)[c]), 1e-5);
    // The 2x2 view in a 4x3 cell: its panel top-left, the rest of the cell gutter.
    EXPECT_FLOAT_EQ(a.at(1, 5, c), 1.0f);  // 1.7 shown as 1
    EXPECT_FLOAT_EQ(a.at(1 + 2, 5, c), 0.01f);
    EXPECT_FLOAT_EQ(a.at(1, 5 + 2, c), 0.01f);
  }
  o.error_scale = 0.125f;
  const Image b = report::contact_sheet(both, o);
  for (int c = 0; c < 3; ++c)
    EXPECT_NEAR(b.at(1 + 2 * (4 + 1), 1, c), srgb_to_linear(report::error_colour(1.0f)[c]), 1e-5);
}

TEST(Report, ContactSheetCapsTheRows) {
  // Ten views of the values 0.0, 0.1, ..., 0.9: four rows show views 0, 3, 6 and 9.
  std::vector<ViewResult> views;
  for (int i = 0; i < 10; ++i) views.push_back(view("test", "v" + std::to_string(i), 20, 0.5, 0.1f * i, 0.5f));
  report::ContactSheetOptions o;
  o.max_rows = 4;
  o.labels = false;
  const Image sheet = report::contact_sheet(pointers(views), o);
  const int h = 3, g = 4;
  ASSERT_EQ(sheet.height, 4 * (h + g) + g);
  const int shown[] = {0, 3, 6, 9};
  for (int r = 0; r < 4; ++r) EXPECT_FLOAT_EQ(sheet.at(g, g + r * (h + g), 0), 0.1f * shown[r]) << "row " << r;
  // The default cap is 8.
  o.max_rows = report::ContactSheetOptions().max_rows;
  EXPECT_EQ(report::contact_sheet(pointers(views), o).height, 8 * (h + g) + g);
}

// Labels: a title band, a caption under each row, and the error map's colour bar under the error column.
TEST(Report, ContactSheetLabels) {
  std::vector<ViewResult> views = {view("test", "a", 10, 0.5, 0.2f, 0.6f), view("test", "b", 20, 1, 0.3f, 0.3f)};
  const int h = 3, g = 4, band = 15, cell = 72, bar = 8;  // 4-pixel views in 72-pixel cells: captions fit
  const Image sheet = report::contact_sheet(pointers(views));
  ASSERT_EQ(sheet.width, 3 * cell + 4 * g);
  ASSERT_EQ(sheet.height, g + band + 2 * (h + band + g) + bar + band + g);
  // The panels sit below the title band, rows a caption band apart.
  for (int c = 0; c < 3; ++c) {
    EXPECT_FLOAT_EQ(sheet.at(g, g + band, c), 0.2f);
    EXPECT_FLOAT_EQ(sheet.at(2 * g + cell, g + band, c), 0.6f);
    EXPECT_FLOAT_EQ(sheet.at(g, g + band + (h + band + g), c), 0.3f);
  }
  // Text is drawn (light pixels) in the title band over each column and in each caption band, nowhere else
  // near it is anything but gutter.
  const auto has_text = [&](int x0, int x1, int y0, int y1) {
    for (int y = y0; y < y1; ++y)
      for (int x = x0; x < x1; ++x)
        if (sheet.at(x, y, 0) > 0.2f) return true;
    return false;
  };
  for (int col = 0; col < 3; ++col) EXPECT_TRUE(has_text(g + col * (cell + g), (col + 1) * (cell + g), g, g + band));
  for (int r = 0; r < 2; ++r) {
    const int y = g + band + r * (h + band + g) + h;
    EXPECT_TRUE(has_text(g, sheet.width, y, y + band)) << "caption " << r;
  }
  // The bar: the colour map from 0 at the left to the top at the right of the error column.
  const int x_err = 3 * g + 2 * cell, y_bar = g + band + 2 * (h + band + g);
  for (int c = 0; c < 3; ++c) {
    EXPECT_NEAR(sheet.at(x_err, y_bar, c), srgb_to_linear(report::error_colour(0)[c]), 1e-6);
    EXPECT_NEAR(sheet.at(x_err + cell - 1, y_bar + bar - 1, c), srgb_to_linear(report::error_colour(1)[c]), 1e-6);
  }
  EXPECT_TRUE(has_text(x_err, x_err + cell, y_bar + bar, y_bar + bar + band));  // "0" and "≥ 0.25"
}

TEST(Report, ContactSheetRejectsBadInput) {
  const ViewResult ok = view("test", "a", 20, 0.5);
  EXPECT_TRUE(contains(invalid_argument_message([] { report::contact_sheet({}); }), "no views"));
  EXPECT_TRUE(contains(invalid_argument_message([&] { report::contact_sheet({&ok, nullptr}); }), "view 1 is null"));
  report::ContactSheetOptions o;
  o.error_scale = 0;
  EXPECT_TRUE(contains(invalid_argument_message([&] { report::contact_sheet({&ok}, o); }), "error_scale"));
  o = {};
  o.max_rows = 0;
  EXPECT_TRUE(contains(invalid_argument_message([&] { report::contact_sheet({&ok}, o); }), "max_rows"));
  ViewResult bad = ok;
  bad.name = "broken";
  bad.reference.pop_back();
  const std::string m = invalid_argument_message([&] { report::contact_sheet({&ok, &bad}); });
  EXPECT_TRUE(contains(m, "test/broken") && contains(m, "reference") && contains(m, "35 values")) << m;
}

TEST(Report, BadViewsAreClearErrorsNamingTheView) {
  const auto message = [](std::vector<ViewResult> views) {
    return invalid_argument_message([&] { report::validate(views); });
  };
  EXPECT_TRUE(contains(message({}), "no views"));

  std::vector<ViewResult> views = {view("test", "a", 20, 0.5), view("test", "b", 20, 0.5)};
  EXPECT_EQ(message(views), "");

  auto v = views;
  v[1].prediction[(2 * 4 + 1) * 3 + 2] = std::numeric_limits<float>::quiet_NaN();  // pixel (1, 2), blue
  std::string m = message(v);
  EXPECT_TRUE(contains(m, "view 1 ('test/b')") && contains(m, "prediction") && contains(m, "NaN") &&
              contains(m, "(x 1, y 2) channel 2"))
      << m;
  v = views;
  v[0].reference[0] = std::numeric_limits<float>::infinity();
  m = message(v);
  EXPECT_TRUE(contains(m, "'test/a'") && contains(m, "reference") && contains(m, "infinite")) << m;

  v = views;
  v[1].prediction.resize(10);
  m = message(v);
  EXPECT_TRUE(contains(m, "'test/b'") && contains(m, "10 values") && contains(m, "4 x 3 x 3 = 36")) << m;

  v = views;
  v[0].width = 0;
  EXPECT_TRUE(contains(message(v), "empty size"));

  v = views;
  v[1].name = "a";
  m = message(v);
  EXPECT_TRUE(contains(m, "view 1") && contains(m, "same name")) << m;
  v[1].split = "test_light";  // the same name in another split is fine
  EXPECT_EQ(message(v), "");

  for (const std::string bad : {"", "..", "x/y", "x\\y", "a\nb"}) {
    v = views;
    v[0].name = bad;
    EXPECT_TRUE(contains(message(v), "name must be a plain file name")) << bad;
    v = views;
    v[0].split = bad;
    EXPECT_TRUE(contains(message(v), "split must be a plain file name")) << bad;
  }

  v = views;
  v[1].metrics.ssim = std::numeric_limits<double>::quiet_NaN();
  m = message(v);
  EXPECT_TRUE(contains(m, "'test/b'") && contains(m, "invalid metrics")) << m;
  v = views;
  v[0].metrics.psnr = std::numeric_limits<double>::infinity();  // a perfect view: fine
  v[0].metrics.mse = 0;
  EXPECT_EQ(message(v), "");
}

TEST(Report, MetricsJsonAndMarkdownParseBack) {
  test::TempDir dir("report");
  std::vector<ViewResult> views = {view("test", "a", 30, 0.9), view("test", "b", 20, 0.7),
                                   view("test_light", "c|d", 25, 0.81234)};
  // View a has object metrics, b has none (an empty mask): the object means are a's.
  auto& obj = views[0].metrics.object;
  obj.pixels = 6;
  obj.fraction = 0.5;
  obj.psnr = 22;
  obj.ssim = 0.6;
  obj.mse = std::pow(10.0, -2.2);
  obj.rel_mse = 0.125;
  obj.clipped = 0.25;
  obj.flip = 0.15;
  obj.prediction_only = 0.375;
  // FLIP: a and b have it, c not (metrics given without it): the means are over a and b.
  views[0].metrics.flip = 0.1;
  views[1].metrics.flip = 0.3;
  report::ReportOptions o;
  o.meta = {{"method", "ours"}, {"steps", 3000}, {"config", {{"lr", 0.01}}}};
  o.sheet.max_rows = 1;
  const fs::path out = dir.path() / "eval" / "nested";  // created
  report::write_report(out.string(), views, o);

  const std::string text = io::read_file((out / "metrics.json").string());
  const Json j = Json::parse(text);
  EXPECT_EQ(j["format"], "relit-eval-report");
  EXPECT_EQ(j["meta"], o.meta);
  EXPECT_EQ(j["mean"]["n_views"], 3);
  EXPECT_DOUBLE_EQ(j["mean"]["psnr"].get<double>(), 25.0);
  EXPECT_DOUBLE_EQ(j["mean"]["ssim"].get<double>(), (0.9 + 0.7 + 0.81234) / 3);
  EXPECT_DOUBLE_EQ(j["splits"]["test"]["psnr"].get<double>(), 25.0);
  EXPECT_DOUBLE_EQ(j["splits"]["test"]["mse"].get<double>(), (1e-3 + 1e-2) / 2);
  EXPECT_EQ(j["splits"]["test"]["n_views"], 2);
  EXPECT_EQ(j["splits"]["test"]["contact_sheet"], "contact_sheet_test.png");
  EXPECT_EQ(j["splits"]["test"]["contact_sheet_views"], Json::array({"a"}));
  EXPECT_DOUBLE_EQ(j["splits"]["test_light"]["ssim"].get<double>(), 0.81234);
  // The splits appear in the file in first-seen order.
  EXPECT_LT(text.find("\"test\": {"), text.find("\"test_light\": {"));
  ASSERT_EQ(j["views"].size(), 3u);
  EXPECT_EQ(j["views"][2]["split"], "test_light");
  EXPECT_EQ(j["views"][2]["name"], "c|d");
  EXPECT_EQ(j["views"][2]["width"], 4);
  EXPECT_EQ(j["views"][2]["height"], 3);
  EXPECT_DOUBLE_EQ(j["views"][1]["psnr"].get<double>(), 20.0);
  EXPECT_DOUBLE_EQ(j["views"][1]["mse"].get<double>(), 0.01);
  EXPECT_DOUBLE_EQ(j["splits"]["test"]["object"]["psnr"].get<double>(), 22.0);
  EXPECT_DOUBLE_EQ(j["mean"]["object"]["rel_mse"].get<double>(), 0.125);
  EXPECT_DOUBLE_EQ(j["mean"]["object"]["clipped"].get<double>(), 0.25);
  EXPECT_DOUBLE_EQ(j["mean"]["object"]["prediction_only"].get<double>(), 0.375);
  EXPECT_DOUBLE_EQ(j["views"][0]["object"]["prediction_only"].get<double>(), 0.375);
  EXPECT_DOUBLE_EQ(j["mean"]["flip"].get<double>(), 0.2);
  EXPECT_DOUBLE_EQ(j["splits"]["test"]["flip"].get<double>(), 0.2);
  EXPECT_TRUE(j["splits"]["test_light"]["flip"].is_null());
  EXPECT_DOUBLE_EQ(j["mean"]["object"]["flip"].get<double>(), 0.15);
  EXPECT_DOUBLE_EQ(j["views"][1]["flip"].get<double>(), 0.3);
  EXPECT_TRUE(j["views"][2]["flip"].is_null());
  EXPECT_DOUBLE_EQ(j["views"][0]["object"]["flip"].get<double>(), 0.15);
  EXPECT_TRUE(j["splits"]["test_light"]["object"]["psnr"].is_null());
  EXPECT_EQ(j["views"][0]["object"]["pixels"], 6);
  EXPECT_DOUBLE_EQ(j["views"][0]["object"]["ssim"].get<double>(), 0.6);
  EXPECT_TRUE(j["views"][1]["object"]["psnr"].is_null());

  const std::string md = io::read_file((out / "metrics.md").string());
  EXPECT_TRUE(contains(md, "- method: ours\n- steps: 3000\n")) << md;
  EXPECT_TRUE(contains(md, "| split | views | PSNR [dB] | SSIM | MSE | FLIP | object PSNR [dB] | object SSIM |")) << md;
  EXPECT_TRUE(contains(
      md,
      "| test | 2 | 25.00 | 0.8000 | 5.500e-03 | 0.2000 | 22.00 | 0.6000 | 1.250e-01 | 0.1500 | 25.0 % | 50.0 % | "
      "37.5 % |"))
      << md;
  EXPECT_TRUE(contains(md, "| test_light | 1 | 25.00 | 0.8123 | 3.162e-03 | – |")) << md;
  EXPECT_TRUE(contains(md, "| **mean** | 3 | 25.00 | 0.8041 |")) << md;
  EXPECT_TRUE(contains(md, "## test\n\n![test contact sheet](contact_sheet_test.png)")) << md;
  EXPECT_TRUE(contains(md, "Shown: a (1 of 2 views)")) << md;
  EXPECT_TRUE(contains(md,
                       "| a | 30.00 | 0.9000 | 1.000e-03 | 0.1000 | 22.00 | 0.6000 | 1.250e-01 | 0.1500 | 25.0 % |\n"
                       "| b | 20.00 | 0.7000 | 1.000e-02 | 0.3000 | – | – | – | – | – |"))
      << md;
  EXPECT_TRUE(contains(md, "| c\\|d | 25.00 | 0.8123 |")) << md;  // '|' escaped in a table cell
  EXPECT_LT(md.find("## test\n"), md.find("## test_light\n"));

  EXPECT_TRUE(fs::exists(out / "contact_sheet_test.png"));
  EXPECT_TRUE(fs::exists(out / "contact_sheet_test_light.png"));
  EXPECT_FALSE(fs::exists(out / "test"));  // predictions only when asked
  // Nothing but the report: no temporary files left behind.
  int files = 0;
  for (const auto& e : fs::directory_iterator(out)) {
    ++files;
    EXPECT_EQ(e.path().filename().string().find(".tmp-"), std::string::npos) << e.path();
  }
  EXPECT_EQ(files, 4);
}

TEST(Report, WrittenContactSheetAndPredictions) {
  test::TempDir dir("report");
  std::vector<ViewResult> views = {view("test", "a", 99, 1, 0.25f, 0.25f), view("test", "b", 10, 0.2, 1.0f, 0.0f)};
  views[1].prediction[0] = 0.75f;
  report::ReportOptions o;
  o.write_predictions = o.write_exr = true;
  o.sheet.labels = false;
  report::write_report(dir.path().string(), views, o);

  const Image sheet = read_image((dir.path() / "contact_sheet_test.png").string());
  const Image expected = report::contact_sheet(pointers(views), o.sheet);
  ASSERT_EQ(sheet.width, expected.width);
  ASSERT_EQ(sheet.height, expected.height);
  // The PNG holds the sRGB values to 8 bits: the error panels show the map's ends.
  const int g = 4, w = 4, h = 3;
  for (int c = 0; c < 3; ++c) {
    EXPECT_NEAR(linear_to_srgb(sheet.at(3 * g + 2 * w, g, c)), report::error_colour(0)[c], 0.6 / 255);
    EXPECT_NEAR(linear_to_srgb(sheet.at(3 * g + 2 * w + 1, 2 * g + h, c)), report::error_colour(1)[c], 0.6 / 255);
    EXPECT_NEAR(linear_to_srgb(sheet.at(g, g, c)), linear_to_srgb(0.25f), 0.6 / 255);
  }
  // Predictions: the EXR is the linear float image, the PNG its sRGB preview.
  const Image exr = read_image((dir.path() / "test" / "b.exr").string());
  ASSERT_EQ(exr.width, 4);
  ASSERT_EQ(exr.height, 3);
  EXPECT_EQ(exr.pixels, views[1].prediction);
  const Image png = read_image((dir.path() / "test" / "b.png").string());
  EXPECT_NEAR(linear_to_srgb(png.at(0, 0, 0)), linear_to_srgb(0.75f), 0.6 / 255);
  EXPECT_TRUE(fs::exists(dir.path() / "test" / "a.png"));
}

TEST(Report, MetricsFromTheDeviceAndAPerfectView) {
  // Real metrics::compare results, including a perfect view (PSNR +inf: null in JSON, "inf" in the lines).
  const Device d = test::test_device();
  std::vector<ViewResult> views;
  for (int k = 0; k < 2; ++k) {
    ViewResult v = view("test", "v" + std::to_string(k), 0, 0, 0.0f, 0.0f, 12, 12);
    for (std::size_t i = 0; i < v.reference.size(); ++i) {
      v.reference[i] = float(i % 7) / 7.0f;
      v.prediction[i] = v.reference[i] + (k == 0 ? 0.0f : 0.05f * float(i % 3));
    }
    v.metrics = metrics::compare(d, v.prediction, v.reference, 12, 12, 3);
    views.push_back(v);
  }
  EXPECT_TRUE(std::isinf(views[0].metrics.psnr));
  ASSERT_TRUE(std::isfinite(views[1].metrics.psnr));
  const Json j = Json::parse(report::metrics_json({views[1]}));
  EXPECT_DOUBLE_EQ(j["views"][0]["psnr"].get<double>(), views[1].metrics.psnr);
  EXPECT_DOUBLE_EQ(j["views"][0]["ssim"].get<double>(), views[1].metrics.ssim);
  EXPECT_DOUBLE_EQ(j["mean"]["mse"].get<double>(), views[1].metrics.mse);
  EXPECT_EQ(views[0].metrics.flip, 0.0);
  EXPECT_GT(views[1].metrics.flip, 0.0);
  EXPECT_DOUBLE_EQ(j["views"][0]["flip"].get<double>(), views[1].metrics.flip);

  const Json both = Json::parse(report::metrics_json(views));
  EXPECT_TRUE(both["views"][0]["psnr"].is_null());
  EXPECT_TRUE(both["mean"]["psnr"].is_null());
  EXPECT_NEAR(both["views"][0]["ssim"].get<double>(), 1.0, 1e-6);
  EXPECT_TRUE(contains(report::format_summary_lines(views), "\nPSNR inf  (mean over"));
}

TEST(Report, PredictionAlphaRoundTripsThroughTheWrittenFolder) {
  // A view with the prediction's alpha: its EXR is RGBA, and comparing the written folder with the references
  // again (relit eval --predictions) finds the same object mask and metrics, floaters (prediction-only pixels)
  // included; --split keeps one split, and a split without references is an error.
  const Device d = test::test_device();
  const std::uint32_t w = 16, h = 12;
  test::TempDir dir("report_alpha");
  std::vector<ViewResult> views;
  for (const char* split : {"test", "train"}) {
    ViewResult v = view(split, "r_000", 0, 0, 0.0f, 0.0f, w, h);
    std::vector<float> ref_alpha(std::size_t(w) * h, 0.0f);
    v.prediction_alpha.assign(std::size_t(w) * h, 0.0f);
    for (std::uint32_t y = 0; y < h; ++y)
      for (std::uint32_t x = 0; x < w; ++x) {
        const std::size_t p = std::size_t(y) * w + x;
        ref_alpha[p] = (x >= 4 && x < 10 && y >= 3 && y < 9) ? 0.9f : 0.0f;
        v.prediction_alpha[p] = (x >= 5 && x < 13 && y >= 3 && y < 9) ? 0.7f : 0.0f;  // a floater right of it
        for (int c = 0; c < 3; ++c) {
          v.reference[3 * p + c] = ref_alpha[p] * (0.3f + 0.1f * float(c));
          v.prediction[3 * p + c] = v.prediction_alpha[p] * (0.35f + 0.05f * float((x + c) % 3));
        }
      }
    const auto mask = metrics::object_mask(ref_alpha, v.prediction_alpha, std::size_t(w) * h);
    v.metrics = metrics::compare(d, v.prediction, v.reference, w, h, 3, &mask);
    views.push_back(v);
    // The references as RGBA EXRs, as a dataset keeps them.
    fs::create_directories(dir.path() / "refs" / split);
    write_image((dir.path() / "refs" / split / "r_000.exr").string(),
                join_rgb_alpha(v.reference, ref_alpha, int(w), int(h)));
  }
  ASSERT_GT(views[0].metrics.object.prediction_only, 0.0);
  report::ReportOptions o;
  o.write_exr = true;
  report::write_report((dir.path() / "eval").string(), views, o);
  const Image exr = read_image((dir.path() / "eval" / "test" / "r_000.exr").string());
  ASSERT_EQ(exr.channels, 4);
  EXPECT_EQ(split_rgb_alpha(exr).second, views[0].prediction_alpha);

  const auto again =
      report::compare_folders(d, (dir.path() / "eval").string(), (dir.path() / "refs").string(), {"test"});
  ASSERT_EQ(again.views.size(), 1u);
  EXPECT_EQ(again.views[0].split, "test");
  const auto &a = again.views[0].metrics.object, &b = views[0].metrics.object;
  EXPECT_EQ(a.pixels, b.pixels);
  EXPECT_DOUBLE_EQ(a.prediction_only, b.prediction_only);
  EXPECT_DOUBLE_EQ(a.psnr, b.psnr);
  EXPECT_DOUBLE_EQ(a.rel_mse, b.rel_mse);
  EXPECT_EQ(report::compare_folders(d, (dir.path() / "eval").string(), (dir.path() / "refs").string()).views.size(),
            2u);
  try {
    report::compare_folders(d, (dir.path() / "eval").string(), (dir.path() / "refs").string(), {"test_light"});
    ADD_FAILURE() << "a split without references was accepted";
  } catch (const IOError& e) {
    EXPECT_TRUE(contains(e.what(), "test_light")) << e.what();
  }
}

TEST(Report, BadInputWritesNothing) {
  test::TempDir dir("report");
  const std::string old_json = "{\"old\": true}\n";
  io::write_file_atomic((dir.path() / "metrics.json").string(), old_json);
  std::vector<ViewResult> views = {view("test", "a", 20, 0.5), view("test", "b", 20, 0.5)};
  views[1].reference[5] = std::numeric_limits<float>::quiet_NaN();
  const std::string m = invalid_argument_message([&] { report::write_report(dir.path().string(), views); });
  EXPECT_TRUE(contains(m, "'test/b'") && contains(m, "NaN")) << m;
  EXPECT_EQ(io::read_file((dir.path() / "metrics.json").string()), old_json);
  EXPECT_FALSE(fs::exists(dir.path() / "metrics.md"));
  EXPECT_FALSE(fs::exists(dir.path() / "contact_sheet_test.png"));

  // Nor does bad meta, and a folder is not created for bad input.
  views[1].reference[5] = 0.5f;
  report::ReportOptions o;
  o.meta = Json::array({1, 2});
  EXPECT_TRUE(contains(invalid_argument_message([&] { report::write_report((dir.path() / "new").string(), views, o); }),
                       "meta must be a JSON object"));
  EXPECT_FALSE(fs::exists(dir.path() / "new"));
  EXPECT_THROW(report::write_report("", views), InvalidArgument);
}

TEST(Report, AFailedWriteLeavesTheOldMetricsIntact) {
  test::TempDir dir("report");
  const std::vector<ViewResult> views = {view("test", "a", 20, 0.5)};
  report::write_report(dir.path().string(), views);
  const std::string old_json = io::read_file((dir.path() / "metrics.json").string());

  // metrics.md cannot be replaced (a non-empty folder is in its way): the write fails naming it, and
  // metrics.json, written last, still describes the old report.
  fs::remove(dir.path() / "metrics.md");
  fs::create_directories(dir.path() / "metrics.md" / "blocker");
  std::vector<ViewResult> changed = {view("test", "a", 35, 0.95)};
  try {
    report::write_report(dir.path().string(), changed);
    FAIL() << "write_report should have failed";
  } catch (const IOError& e) {
    EXPECT_TRUE(contains(e.what(), "metrics.md")) << e.what();
  }
  EXPECT_EQ(io::read_file((dir.path() / "metrics.json").string()), old_json);
  for (const auto& e : fs::directory_iterator(dir.path()))
    EXPECT_EQ(e.path().filename().string().find(".tmp-"), std::string::npos) << e.path();

  // The output folder's name taken by a file: an IOError naming it, the file untouched.
  const fs::path file = dir.path() / "taken";
  std::ofstream(file) << "data";
  try {
    report::write_report(file.string(), views);
    FAIL() << "write_report should have failed";
  } catch (const IOError& e) {
    EXPECT_TRUE(contains(e.what(), "taken")) << e.what();
  }
  EXPECT_EQ(io::read_file(file.string()), "data");
}

// A report write that fails (full disk, failed rename) keeps the old metrics.json and leaves no temporary.
TEST(Report, AFailedAtomicWriteKeepsTheOldReport) {
  test::TempDir dir("report-fail");
  const std::vector<ViewResult> views = {view("test", "a", 30, 0.9), view("test", "b", 20, 0.7)};
  report::write_report(dir.path().string(), views);
  const std::string before = io::read_file((dir.path() / "metrics.json").string());
  const std::vector<ViewResult> other = {view("test", "a", 10, 0.1)};
  for (auto stage : {io::testing::Stage::write, io::testing::Stage::rename}) {
    test::FailWrites fail(stage, "metrics.json");
    EXPECT_THROW(report::write_report(dir.path().string(), other), IOError);
    EXPECT_EQ(io::read_file((dir.path() / "metrics.json").string()), before);
    for (const auto& e : fs::recursive_directory_iterator(dir.path()))
      EXPECT_EQ(io::temporary_owner(e.path().filename().string()), 0) << "left behind: " << e.path();
  }
}

}  // namespace
}  // namespace relit
