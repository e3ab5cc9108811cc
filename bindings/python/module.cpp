// relit._core: the Python binding. Names mirror the C++ API.
#include "bindings.hpp"

#include <relit/version.hpp>

PYBIND11_MODULE(_core, m) {
  m.doc() = "relit: neural relightable participating media on OpenCL (compiled core)";
  m.attr("__version__") = relit::version();
  relit::python::bind_cl(m);  // first: the exception translators the other parts rely on
  relit::python::bind_nn(m);
  relit::python::bind_metrics(m);
  relit::python::bind_report(m);
  relit::python::bind_scene(m);
  relit::python::bind_method(m);
}
