// Conversions shared by the bind_*.cpp files: float arrays, JSON values, device arguments and progress callables.
#pragma once

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <relit/cl/device.hpp>
#include <relit/config.hpp>
#include <relit/io/image.hpp>
#include <relit/progress.hpp>

#include <algorithm>

namespace relit::python {

/// A float array argument, C-contiguous (numpy converts other layouts and dtypes).
using FloatArray = pybind11::array_t<float, pybind11::array::c_style | pybind11::array::forcecast>;

/// An image as a (height, width, channels) float32 array (a copy of its pixels).
inline pybind11::array_t<float> image_to_numpy(const Image& img) {
  pybind11::array_t<float> a({img.height, img.width, img.channels});
  std::copy(img.pixels.begin(), img.pixels.end(), a.mutable_data());
  return a;
}

/// A Python value (dict, list, number, ...) as JSON, through Python's json module, which knows every builtin type.
inline Json json_from_python(const pybind11::handle& obj) {
  std::string text;
  try {
    text = pybind11::module_::import("json").attr("dumps")(obj, pybind11::arg("allow_nan") = false).cast<std::string>();
  } catch (const pybind11::error_already_set& e) {
    // Not JSON-representable: NaN or infinity, a set, an object... Say which, as a relit.ConfigError.
    throw ConfigError("", std::string("the value cannot be written as JSON: ") + e.what());
  }
  return parse_json(text, "the value");
}

/// JSON as the Python value json.loads would give.
inline pybind11::object json_to_python(const Json& j) {
  return pybind11::module_::import("json").attr("loads")(j.dump());
}

/// A `device=` argument: None (RELIT_DEVICE or the first device), a selector string, or a relit.Device.
inline Device device_arg(const pybind11::object& device) {
  if (device.is_none()) return Device::select();
  if (pybind11::isinstance<pybind11::str>(device)) return Device::select(device.cast<std::string>());
  return device.cast<Device>();
}

/// A `progress=` callable as a ProgressCallback: it runs with the GIL held; None or True continue.
inline ProgressCallback progress_arg(const pybind11::object& fn) {
  if (fn.is_none()) return {};
  return [fn](const Progress& p) {
    pybind11::gil_scoped_acquire gil;
    pybind11::object r = fn(p);
    return r.is_none() || r.cast<bool>();
  };
}

}  // namespace relit::python
