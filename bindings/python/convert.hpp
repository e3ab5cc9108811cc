// Conversions shared by the bind_*.cpp files: JSON values, device arguments and progress callables.
#pragma once

#include <pybind11/pybind11.h>

#include <relit/cl/device.hpp>
#include <relit/config.hpp>
#include <relit/progress.hpp>

namespace relit::python {

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
