// Python binding of the image metrics: relit.metrics.compare / psnr / ssim / flip / object_mask on numpy images.
#include "bindings.hpp"
#include "convert.hpp"

#include <pybind11/numpy.h>

#include <array>

#include <relit/cl/device.hpp>
#include <relit/error.hpp>
#include <relit/metrics.hpp>

namespace py = pybind11;

namespace relit::python {

namespace {
using Mask = py::array_t<std::uint8_t, py::array::c_style | py::array::forcecast>;

// (height, width, channels) of two images of the same shape, (H, W) or (H, W, C).
std::array<std::uint32_t, 3> shape_of(const FloatArray& prediction, const FloatArray& reference) {
  if (prediction.ndim() < 2 || prediction.ndim() > 3)
    throw InvalidArgument("images must be (height, width) or (height, width, channels) arrays");
  for (py::ssize_t i = 0; i < prediction.ndim(); ++i)
    if (reference.ndim() != prediction.ndim() || reference.shape(i) != prediction.shape(i))
      throw InvalidArgument("prediction and reference must have the same shape");
  return {static_cast<std::uint32_t>(prediction.shape(0)), static_cast<std::uint32_t>(prediction.shape(1)),
          prediction.ndim() == 3 ? static_cast<std::uint32_t>(prediction.shape(2)) : 1u};
}

metrics::ImageComparison compare(const FloatArray& prediction, const FloatArray& reference, const py::object& device,
                                 const py::object& mask = py::none()) {
  const auto [h, w, c] = shape_of(prediction, reference);
  std::vector<std::uint8_t> m;
  if (!mask.is_none()) {
    const auto arr = mask.cast<Mask>();
    if (arr.ndim() != 2 || arr.shape(0) != prediction.shape(0) || arr.shape(1) != prediction.shape(1))
      throw InvalidArgument("the mask must be a (height, width) array of the images' size");
    m.assign(arr.data(), arr.data() + arr.size());
  }
  const Device dev = device_arg(device);
  std::vector<float> a(prediction.data(), prediction.data() + prediction.size());
  std::vector<float> b(reference.data(), reference.data() + reference.size());
  py::gil_scoped_release release;
  return metrics::compare(dev, a, b, w, h, c, mask.is_none() ? nullptr : &m);
}
}  // namespace

void bind_metrics(py::module_& root) {
  py::module_ m = root.def_submodule(
      "metrics", "Image metrics computed in OpenCL: PSNR and SSIM on clamped sRGB, over the image and the object.");
  m.def(
      "compare",
      [](const FloatArray& p, const FloatArray& r, const py::object& device, const py::object& mask) {
        const auto c = compare(p, r, device, mask);
        py::dict d;
        d["mse"] = c.mse;
        d["psnr"] = c.psnr;
        d["ssim"] = c.ssim;
        d["flip"] = c.flip;
        py::dict o;
        o["pixels"] = c.object.pixels;
        o["fraction"] = c.object.fraction;
        o["mse"] = c.object.mse;
        o["psnr"] = c.object.psnr;
        o["ssim"] = c.object.ssim;
        o["rel_mse"] = c.object.rel_mse;
        o["clipped"] = c.object.clipped;
        o["flip"] = c.object.flip;
        o["prediction_only"] = c.object.prediction_only;
        d["object"] = o;
        return d;
      },
      py::arg("prediction"), py::arg("reference"), py::arg("device") = py::none(), py::arg("mask") = py::none(),
      "Linear float images (H, W[, C]) → {'mse', 'psnr', 'ssim', 'flip', 'object': {...}}: PSNR/SSIM of their "
      "clamped sRGB encodings and the mean HDR-FLIP over the image, and over the object's pixels (mask: (H, W), "
      "nonzero on the object; see object_mask) with the linear relative MSE, the share of clipped reference "
      "pixels and 'prediction_only', the share of the object's pixels where the mask is 2 (only the prediction's "
      "alpha: floaters or haze; 0 for a mask of 0 and 1). NaN where there is no object pixel.");
  m.def(
      "flip",
      [](const FloatArray& p, const FloatArray& r, const std::string& range, double ppd, const py::object& start,
         const py::object& stop, std::uint32_t exposures, const py::object& device) {
        const auto [h, w, c] = shape_of(p, r);
        metrics::FlipOptions o;
        if (range != "hdr" && range != "ldr")
          throw InvalidArgument("flip: range must be 'hdr' or 'ldr', not '" + range + "'");
        o.range = range == "hdr" ? metrics::FlipRange::hdr : metrics::FlipRange::ldr;
        o.pixels_per_degree = ppd;
        if (!start.is_none()) o.start_exposure = start.cast<double>();
        if (!stop.is_none()) o.stop_exposure = stop.cast<double>();
        o.exposures = exposures;
        const Device dev = device_arg(device);
        std::vector<float> a(p.data(), p.data() + p.size()), b(r.data(), r.data() + r.size());
        metrics::FlipResult f;
        {
          py::gil_scoped_release release;
          f = metrics::flip(dev, a, b, w, h, c, o);
        }
        py::array_t<float> error({py::ssize_t(h), py::ssize_t(w)});
        std::copy(f.error.begin(), f.error.end(), error.mutable_data());
        py::dict e;
        e["start"] = f.exposures.start;
        e["stop"] = f.exposures.stop;
        e["count"] = f.exposures.count;
        py::dict d;
        d["error"] = error;
        d["mean"] = f.mean;
        d["exposures"] = e;
        return d;
      },
      py::arg("prediction"), py::arg("reference"), py::arg("range") = "hdr",
      py::arg("pixels_per_degree") = metrics::kFlipPixelsPerDegree, py::arg("start_exposure") = py::none(),
      py::arg("stop_exposure") = py::none(), py::arg("exposures") = 0, py::arg("device") = py::none(),
      "FLIP of linear float images (H, W[, C]; R, G, B from the first three channels, one channel is grey) → "
      "{'error': (H, W) per-pixel map in [0, 1], 'mean', 'exposures': {'start', 'stop', 'count'}}. range 'hdr' "
      "(HDR-FLIP: ACES at count exposures from start to stop, by default from the reference) or 'ldr' (the images "
      "clamped to [0, 1]); pixels_per_degree: the observer (67.02: a 0.7 m wide 4K monitor at 0.7 m).");
  m.def(
      "object_mask",
      [](const py::object& reference_alpha, const py::object& prediction_alpha) {
        const auto as_vector = [](const py::object& a) {
          if (a.is_none()) return std::pair<std::vector<float>, std::vector<py::ssize_t>>{};
          const auto arr = a.cast<FloatArray>();
          if (arr.ndim() != 2) throw InvalidArgument("an alpha must be a (height, width) array");
          return std::pair{std::vector<float>(arr.data(), arr.data() + arr.size()),
                           std::vector<py::ssize_t>{arr.shape(0), arr.shape(1)}};
        };
        const auto [ra, rs] = as_vector(reference_alpha);
        const auto [pa, ps] = as_vector(prediction_alpha);
        if (rs.empty() && ps.empty()) throw InvalidArgument("object_mask: give at least one alpha");
        if (!rs.empty() && !ps.empty() && rs != ps) throw InvalidArgument("object_mask: the alphas differ in shape");
        const auto& shape = rs.empty() ? ps : rs;
        const auto mask = metrics::object_mask(ra, pa, std::size_t(shape[0] * shape[1]));
        py::array_t<bool> out({shape[0], shape[1]});
        std::copy(mask.begin(), mask.end(), out.mutable_data());
        return out;
      },
      py::arg("reference_alpha"), py::arg("prediction_alpha") = py::none(),
      "The object's pixels: where the reference's or the prediction's alpha (H, W) exceeds 0.01.");
  m.def(
      "psnr",
      [](const FloatArray& p, const FloatArray& r, const py::object& device) { return compare(p, r, device).psnr; },
      py::arg("prediction"), py::arg("reference"), py::arg("device") = py::none());
  m.def(
      "ssim",
      [](const FloatArray& p, const FloatArray& r, const py::object& device) { return compare(p, r, device).ssim; },
      py::arg("prediction"), py::arg("reference"), py::arg("device") = py::none());
}

}  // namespace relit::python
