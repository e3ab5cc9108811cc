// Python binding of the image metrics: relit.metrics.compare / psnr / ssim on numpy images.
#include "bindings.hpp"
#include "convert.hpp"

#include <pybind11/numpy.h>

#include <relit/cl/device.hpp>
#include <relit/error.hpp>
#include <relit/metrics.hpp>

namespace py = pybind11;

namespace relit::python {

namespace {
using Image = py::array_t<float, py::array::c_style | py::array::forcecast>;

metrics::ImageComparison compare(const Image& prediction, const Image& reference, const py::object& device) {
  if (prediction.ndim() < 2 || prediction.ndim() > 3)
    throw InvalidArgument("images must be (height, width) or (height, width, channels) arrays");
  for (py::ssize_t i = 0; i < prediction.ndim(); ++i)
    if (reference.ndim() != prediction.ndim() || reference.shape(i) != prediction.shape(i))
      throw InvalidArgument("prediction and reference must have the same shape");
  const auto h = static_cast<std::uint32_t>(prediction.shape(0)), w = static_cast<std::uint32_t>(prediction.shape(1));
  const auto c = prediction.ndim() == 3 ? static_cast<std::uint32_t>(prediction.shape(2)) : 1u;
  const Device dev = device_arg(device);
  std::vector<float> a(prediction.data(), prediction.data() + prediction.size());
  std::vector<float> b(reference.data(), reference.data() + reference.size());
  py::gil_scoped_release release;
  return metrics::compare(dev, a, b, w, h, c);
}
}  // namespace

void bind_metrics(py::module_& root) {
  py::module_ m = root.def_submodule("metrics", "PSNR and SSIM on clamped, sRGB-encoded images (computed in OpenCL).");
  m.def(
      "compare",
      [](const Image& p, const Image& r, const py::object& device) {
        const auto c = compare(p, r, device);
        py::dict d;
        d["mse"] = c.mse;
        d["psnr"] = c.psnr;
        d["ssim"] = c.ssim;
        return d;
      },
      py::arg("prediction"), py::arg("reference"), py::arg("device") = py::none(),
      "Linear float images (H, W[, C]) → {'mse', 'psnr', 'ssim'} of their clamped sRGB encodings.");
  m.def(
      "psnr", [](const Image& p, const Image& r, const py::object& device) { return compare(p, r, device).psnr; },
      py::arg("prediction"), py::arg("reference"), py::arg("device") = py::none());
  m.def(
      "ssim", [](const Image& p, const Image& r, const py::object& device) { return compare(p, r, device).ssim; },
      py::arg("prediction"), py::arg("reference"), py::arg("device") = py::none());
}

}  // namespace relit::python
