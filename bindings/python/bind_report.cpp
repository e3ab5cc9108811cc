// Python binding of evaluation reports (relit/report.hpp):
//   views = [{"split": "test", "name": "r_000", "prediction": pred, "reference": ref}, ...]   # (H, W, 3) linear
//   print(relit.write_report("runs/cloud/eval", views, meta={"method": "ours"}), end="")
//   sheet = relit.contact_sheet(views, max_rows=8)                                          # (H, W, 3) float32
// A view is a dict or any object with those attributes; its metrics come from "psnr", "ssim" and "mse" and
// optionally "flip" (or a "metrics" dict/object holding them) when it has them, otherwise write_report computes
// them on the device.
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include "bindings.hpp"
#include "convert.hpp"

#include <relit/cl/device.hpp>
#include <relit/error.hpp>
#include <relit/metrics.hpp>
#include <relit/report.hpp>

#include <algorithm>

namespace py = pybind11;

namespace relit::python {

namespace {

// item[key] of a mapping or item.key of an object; None when absent.
py::object field(const py::handle& item, const char* key) {
  if (py::isinstance<py::dict>(item)) {
    const auto d = py::reinterpret_borrow<py::dict>(item);
    return d.contains(key) ? py::reinterpret_borrow<py::object>(d[key]) : py::none();
  }
  return py::getattr(item, key, py::none());
}

std::vector<float> image_of(const py::object& value, const std::string& where, const char* key, std::uint32_t& w,
                            std::uint32_t& h) {
  if (value.is_none()) throw InvalidArgument(where + " has no '" + key + "' image");
  const FloatArray a = FloatArray::ensure(value);
  if (!a) {
    throw InvalidArgument(where + ": '" + key + "' is not an array of numbers");
  }
  if (a.ndim() != 3 || a.shape(2) != 3)
    throw InvalidArgument(where + ": '" + key + "' must be a (height, width, 3) RGB array, not of shape " +
                          py::str(a.attr("shape")).cast<std::string>());
  const auto ah = static_cast<std::uint32_t>(a.shape(0)), aw = static_cast<std::uint32_t>(a.shape(1));
  if (w == 0 && h == 0) {
    w = aw;
    h = ah;
  } else if (aw != w || ah != h) {
    throw InvalidArgument(where + ": prediction and reference must have the same shape");
  }
  return std::vector<float>(a.data(), a.data() + a.size());
}

// An optional (height, width) alpha of a view.
std::vector<float> alpha_of(const py::object& value, const std::string& where, const char* key, std::uint32_t w,
                            std::uint32_t h) {
  if (value.is_none()) return {};
  const FloatArray a = FloatArray::ensure(value);
  if (!a || a.ndim() != 2 || a.shape(0) != py::ssize_t(h) || a.shape(1) != py::ssize_t(w))
    throw InvalidArgument(where + ": '" + key + "' must be a (height, width) array of the images' size");
  return std::vector<float>(a.data(), a.data() + a.size());
}

// The views as the library's; metrics are computed on `device` for views without them when `need_metrics`
// (with the object's metrics where a view has a 'reference_alpha' or 'prediction_alpha').
std::vector<report::ViewResult> views_from(const py::iterable& items, bool need_metrics, const py::object& device) {
  std::vector<report::ViewResult> views;
  std::vector<std::size_t> missing;  // views whose metrics are to be computed
  std::vector<std::vector<std::uint8_t>> masks;
  std::size_t index = 0;
  for (const py::handle item : items) {
    report::ViewResult v;
    const py::object split = field(item, "split"), name = field(item, "name");
    v.split = split.is_none() ? "test" : py::str(split).cast<std::string>();
    v.name = name.is_none() ? std::to_string(index) : py::str(name).cast<std::string>();
    const std::string where = "views[" + std::to_string(index) + "] ('" + v.split + "/" + v.name + "')";
    v.prediction = image_of(field(item, "prediction"), where, "prediction", v.width, v.height);
    v.reference = image_of(field(item, "reference"), where, "reference", v.width, v.height);
    v.prediction_alpha = alpha_of(field(item, "prediction_alpha"), where, "prediction_alpha", v.width, v.height);
    masks.push_back(
        metrics::object_mask(alpha_of(field(item, "reference_alpha"), where, "reference_alpha", v.width, v.height),
                             v.prediction_alpha, std::size_t(v.width) * v.height));

    py::object source = field(item, "metrics");
    if (source.is_none()) source = py::reinterpret_borrow<py::object>(item);
    const py::object psnr = field(source, "psnr"), ssim = field(source, "ssim"), mse = field(source, "mse");
    const int given = int(!psnr.is_none()) + int(!ssim.is_none()) + int(!mse.is_none());
    if (given == 3) {
      v.metrics.psnr = psnr.cast<double>();
      v.metrics.ssim = ssim.cast<double>();
      v.metrics.mse = mse.cast<double>();
      const py::object flip = field(source, "flip");
      if (!flip.is_none()) v.metrics.flip = flip.cast<double>();  // otherwise NaN: not computed, shown as '–'
    } else if (given != 0) {
      throw InvalidArgument(where + ": give all of psnr, ssim and mse, or none (then they are computed)");
    } else if (need_metrics) {
      missing.push_back(views.size());
    }
    views.push_back(std::move(v));
    ++index;
  }
  if (!missing.empty()) {
    const Device dev = device_arg(device);
    report::validate(views);  // a clear error (NaN, sizes, names) before any kernel runs
    py::gil_scoped_release release;
    for (std::size_t i : missing) {
      auto& v = views[i];
      v.metrics = metrics::compare(dev, v.prediction, v.reference, v.width, v.height, 3, &masks[i]);
    }
  }
  return views;
}

Json meta_json(const py::object& obj) {
  if (obj.is_none()) return Json::object();
  return json_from_python(obj);
}

std::string path_of(const py::object& path) {
  return py::str(py::module_::import("os").attr("fspath")(path)).cast<std::string>();
}

}  // namespace

void bind_report(py::module_& m) {
  m.def(
      "write_report",
      [](const py::object& dir, const py::iterable& views, const py::object& meta, std::size_t max_rows,
         float error_scale, bool write_predictions, bool write_exr, const py::object& device) {
        const std::string path = path_of(dir);
        const auto v = views_from(views, true, device);
        report::ReportOptions o;
        o.meta = meta_json(meta);
        o.sheet.max_rows = max_rows;
        o.sheet.error_scale = error_scale;
        o.write_predictions = write_predictions;
        o.write_exr = write_exr;
        {
          py::gil_scoped_release release;
          report::write_report(path, v, o);
        }
        return report::format_summary_lines(v);
      },
      py::arg("dir"), py::arg("views"), py::arg("meta") = py::none(), py::arg("max_rows") = 8,
      py::arg("error_scale") = 0.25f, py::arg("write_predictions") = false, py::arg("write_exr") = false,
      py::arg("device") = py::none(),
      "Writes an evaluation report into `dir` (created): metrics.json (every view, per-split and overall means,\n"
      "`meta`), metrics.md, contact_sheet_<split>.png, and with write_predictions / write_exr each prediction as\n"
      "<split>/<name>.png / .exr. Every file is written atomically.\n\n"
      "views: dicts or objects with 'prediction' and 'reference' (linear float (H, W, 3) arrays), 'split'\n"
      "(default 'test'), 'name' (default: the index) and optionally 'psnr', 'ssim', 'mse', 'flip' (or 'metrics'\n"
      "holding them); missing metrics are computed with relit.metrics on `device`, over\n"
      "the object too where a view has 'reference_alpha' / 'prediction_alpha' ((H, W)); the .exr of a view with\n"
      "'prediction_alpha' carries it as its alpha channel.\n"
      "Returns the summary lines to print (one per split, then 'PSNR <mean>' and 'SSIM <mean>').");
  m.def(
      "contact_sheet",
      [](const py::iterable& views, std::size_t max_rows, float error_scale, int gutter, bool srgb, bool labels) {
        const auto v = views_from(views, false, py::none());
        std::vector<const report::ViewResult*> ptrs;
        for (const auto& x : v) ptrs.push_back(&x);
        report::ContactSheetOptions o;
        o.max_rows = max_rows;
        o.error_scale = error_scale;
        o.gutter = gutter;
        o.labels = labels;
        Image sheet = report::contact_sheet(ptrs, o);
        if (srgb)
          for (float& x : sheet.pixels) x = linear_to_srgb(x);
        return image_to_numpy(sheet);
      },
      py::arg("views"), py::arg("max_rows") = 8, py::arg("error_scale") = 0.25f, py::arg("gutter") = 4,
      py::arg("srgb") = false, py::arg("labels") = true,
      "The contact sheet of views (as for write_report; metrics are not needed): one row per view (at most\n"
      "max_rows, spread evenly), prediction | reference | error, as float32 (H, W, 3). Linear by default (as\n"
      "relit writes images); srgb=True returns the display values. The error panel maps the mean absolute\n"
      "difference of the sRGB images through 'inferno', error_scale at the top. labels: column titles, each\n"
      "row's name and PSNR, and the colour bar (False: the panels alone).");
}

}  // namespace relit::python
