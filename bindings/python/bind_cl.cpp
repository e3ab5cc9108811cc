// Python binding of the error types, the OpenCL layer (devices, programs), logging and the CLI.
// C++ exceptions become Python exceptions with the same message (relit.ConfigError is a ValueError,
// relit.IOError an OSError, relit.DeviceError a RuntimeError; all derive from relit.Error).
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include "bindings.hpp"
#include "cli.hpp"

#include <relit/relit.hpp>

#include <filesystem>
#include <iostream>
#include <new>
#include <stdexcept>

namespace py = pybind11;

namespace relit::python {

namespace {

PyObject* new_exception(py::module_& m, const char* name, PyObject* bases, const char* doc) {
  const std::string qualified = std::string("relit.") + name;
  PyObject* cls = PyErr_NewExceptionWithDoc(qualified.c_str(), doc, bases, nullptr);
  if (!cls) throw py::error_already_set();
  m.add_object(name, py::handle(cls));
  return cls;
}

PyObject* tuple_of(std::initializer_list<PyObject*> classes) {
  PyObject* t = PyTuple_New(static_cast<Py_ssize_t>(classes.size()));
  Py_ssize_t i = 0;
  for (PyObject* c : classes) {
    Py_INCREF(c);
    PyTuple_SET_ITEM(t, i++, c);
  }
  return t;
}

void raise_with_attributes(PyObject* cls, const std::string& message,
                           std::initializer_list<std::pair<const char*, py::object>> attrs) {
  py::object instance = py::reinterpret_steal<py::object>(PyObject_CallFunction(cls, "s", message.c_str()));
  if (!instance) throw py::error_already_set();
  for (const auto& [name, value] : attrs) instance.attr(name) = value;
  PyErr_SetObject(cls, instance.ptr());
}

// The exception classes; the translator below must be a plain function, so they live here.
struct Classes {
  PyObject *error, *invalid, *config, *io, *device, *cl_error, *build, *parallel;
};
Classes classes;

void translate(std::exception_ptr p) {
  const Classes& c = classes;
  try {
    if (p) std::rethrow_exception(p);
  } catch (const relit::BuildError& e) {
    raise_with_attributes(c.build, e.what(),
                          {{"log", py::str(e.log())},
                           {"options", py::str(e.options())},
                           {"device", py::str(e.device())},
                           {"source_path", py::str(e.source_path())},
                           {"program", py::str(e.program())}});
  } catch (const relit::ClError& e) {
    raise_with_attributes(c.cl_error, e.what(), {{"code", py::int_(e.code())}, {"call", py::str(e.call())}});
  } catch (const relit::DeviceError& e) {
    PyErr_SetString(c.device, e.what());
  } catch (const relit::ParallelError& e) {
    PyErr_SetString(c.parallel, e.what());
  } catch (const relit::ConfigError& e) {
    raise_with_attributes(c.config, e.what(), {{"pointer", py::str(e.pointer())}});
  } catch (const relit::InvalidArgument& e) {
    PyErr_SetString(c.invalid, e.what());
  } catch (const relit::IOError& e) {
    PyErr_SetString(c.io, e.what());
  } catch (const relit::Error& e) {
    PyErr_SetString(c.error, e.what());
  } catch (const py::builtin_exception&) {
    throw;  // pybind11's own (TypeError of a conversion, IndexError, ...): its translator sets them
  } catch (const py::error_already_set&) {
    throw;  // a Python exception passing through (KeyboardInterrupt in a progress callback, ...)
  } catch (const std::filesystem::filesystem_error& e) {
    // The error boundary of the binding: nothing else escapes as a bare RuntimeError or an abort.
    PyErr_SetString(c.io, (e.code().message() + ": '" + e.path1().string() + "'").c_str());
  } catch (const nlohmann::json::exception& e) {
    PyErr_SetString(c.config, (std::string("malformed JSON value: ") + e.what()).c_str());
  } catch (const std::bad_alloc&) {
    PyErr_SetString(c.invalid, "out of host memory: the sizes asked for are too large");
  } catch (const std::length_error& e) {
    PyErr_SetString(c.invalid, (std::string("a size is too large: ") + e.what()).c_str());
  } catch (const std::exception& e) {
    PyErr_SetString(c.error, (std::string(e.what()) + " (an unexpected error: please report it)").c_str());
  }
}

void register_exceptions(py::module_& m) {
  PyObject* error = new_exception(m, "Error", PyExc_Exception, "Base class of every error relit raises.");
  PyObject* invalid =
      new_exception(m, "InvalidArgument", tuple_of({error, PyExc_ValueError}), "A bad parameter or value.");
  PyObject* config =
      new_exception(m, "ConfigError", tuple_of({invalid}), "A bad config; .pointer is the JSON pointer.");
  PyObject* io =
      new_exception(m, "IOError", tuple_of({error, PyExc_OSError}), "A missing, unreadable or corrupt file.");
  PyObject* device =
      new_exception(m, "DeviceError", tuple_of({error, PyExc_RuntimeError}), "An OpenCL device problem.");
  PyObject* cl_error = new_exception(m, "ClError", tuple_of({device}), "A failed OpenCL call; .code is its status.");
  PyObject* build = new_exception(m, "BuildError", tuple_of({device}),
                                  "A kernel failed to compile; .log, .options, .device and .source_path say why.");
  PyObject* parallel = new_exception(m, "ParallelError", tuple_of({error, PyExc_RuntimeError}),
                                     "Another MPI rank failed or did not answer in time.");
  classes = {error, invalid, config, io, device, cl_error, build, parallel};
  py::register_exception_translator(&translate);
}

}  // namespace

void bind_cl(py::module_& m) {
  register_exceptions(m);

  py::class_<relit::DeviceInfo>(m, "DeviceInfo", "What an OpenCL device is and can do, as its driver reports it.")
      .def_readonly("index", &relit::DeviceInfo::index, "global index (RELIT_DEVICE=<index>)")
      .def_readonly("platform_index", &relit::DeviceInfo::platform_index)
      .def_readonly("device_index", &relit::DeviceInfo::device_index)
      .def_readonly("platform_name", &relit::DeviceInfo::platform_name)
      .def_readonly("platform_vendor", &relit::DeviceInfo::platform_vendor)
      .def_readonly("platform_version", &relit::DeviceInfo::platform_version)
      .def_readonly("name", &relit::DeviceInfo::name)
      .def_readonly("vendor", &relit::DeviceInfo::vendor)
      .def_readonly("type", &relit::DeviceInfo::type, "'cpu', 'gpu', 'accelerator' or 'other'")
      .def_readonly("version", &relit::DeviceInfo::version)
      .def_readonly("driver_version", &relit::DeviceInfo::driver_version)
      .def_readonly("opencl_c_version", &relit::DeviceInfo::opencl_c_version)
      .def_readonly("compute_units", &relit::DeviceInfo::compute_units)
      .def_readonly("max_clock_mhz", &relit::DeviceInfo::max_clock_mhz)
      .def_readonly("global_memory", &relit::DeviceInfo::global_memory, "bytes")
      .def_readonly("max_allocation", &relit::DeviceInfo::max_allocation, "bytes, largest single buffer")
      .def_readonly("local_memory", &relit::DeviceInfo::local_memory, "bytes per work-group")
      .def_readonly("local_memory_is_global", &relit::DeviceInfo::local_memory_is_global)
      .def_readonly("max_work_group_size", &relit::DeviceInfo::max_work_group_size)
      .def_readonly("preferred_vector_width_float", &relit::DeviceInfo::preferred_vector_width_float)
      .def_readonly("fp64", &relit::DeviceInfo::fp64)
      .def_readonly("extensions", &relit::DeviceInfo::extensions)
      .def("description", &relit::DeviceInfo::description)
      .def("has_extension", &relit::DeviceInfo::has_extension)
      .def("__repr__", [](const relit::DeviceInfo& i) {
        return "<relit.DeviceInfo " + std::to_string(i.index) + ": " + i.description() + ">";
      });

  py::class_<relit::ProgramCheck>(m, "ProgramCheck", "Outcome of building one of relit's kernel programs.")
      .def_readonly("file", &relit::ProgramCheck::file)
      .def_readonly("ok", &relit::ProgramCheck::ok)
      .def_readonly("seconds", &relit::ProgramCheck::seconds)
      .def_readonly("error", &relit::ProgramCheck::error)
      .def("__repr__", [](const relit::ProgramCheck& c) {
        return "<relit.ProgramCheck " + c.file + (c.ok ? " ok" : " FAILED") + ">";
      });

  py::class_<relit::Program>(m, "Program", "A compiled OpenCL program.")
      .def_property_readonly("file", &relit::Program::file)
      .def_property_readonly("options", &relit::Program::options)
      .def("kernel_names", &relit::Program::kernel_names);

  py::class_<relit::Device>(m, "Device",
                            "An OpenCL device with its context, queue and program cache.\n\n"
                            "Device.select(selector) takes an index ('1'), 'platform:device' ('0:1', 'pocl:cpu') or\n"
                            "a case-insensitive part of a platform or device name; '' uses $RELIT_DEVICE, else the\n"
                            "first GPU, else the first device.")
      .def_static("select", &relit::Device::select, py::arg("selector") = "", py::call_guard<py::gil_scoped_release>())
      .def_static("select_all", &relit::Device::select_all, py::arg("selector") = "",
                  py::call_guard<py::gil_scoped_release>())
      .def_property_readonly("info", &relit::Device::info, py::return_value_policy::copy)
      .def_property_readonly("name", [](const relit::Device& d) { return d.info().name; })
      .def("finish", &relit::Device::finish, py::call_guard<py::gil_scoped_release>())
      .def("program", &relit::Device::program, py::arg("file"), py::arg("defines") = relit::Defines{},
           py::arg("options") = "", py::call_guard<py::gil_scoped_release>(),
           "Builds kernels/<file> with -D defines (cached per device, source and options).")
      .def(
          "check_programs", [](const relit::Device& d) { return relit::check_programs(d); },
          py::call_guard<py::gil_scoped_release>(), "Builds every relit kernel program on this device.")
      .def_property_readonly("cached_programs", &relit::Device::cached_programs)
      .def("__eq__", [](const relit::Device& a, const relit::Device& b) { return a == b; })
      .def("__hash__", [](const relit::Device& d) { return std::hash<std::string>()(d.info().name) ^ d.info().index; })
      .def("__repr__", [](const relit::Device& d) { return "<relit.Device " + d.info().description() + ">"; });

  m.def("devices", &relit::list_devices, py::call_guard<py::gil_scoped_release>(),
        "Every device of every OpenCL platform (relit.DeviceInfo), in the order RELIT_DEVICE indices use.");
  m.def(
      "set_log_level", [](const std::string& level) { relit::set_log_level(relit::parse_log_level(level)); },
      py::arg("level"), "'debug', 'info', 'warning', 'error' or 'off'");
  m.def(
      "cli_main",
      [](const std::vector<std::string>& argv) {
        py::gil_scoped_release release;
        const int code = relit::cli::run(argv);
        std::cout.flush();
        return code;
      },
      py::arg("argv"), "Runs the relit command line (argv[0] is the program name); returns the exit code.");
}

}  // namespace relit::python
