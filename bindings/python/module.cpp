// relit._core: the Python binding. Names mirror the C++ API.
#include "bindings.hpp"

#include <relit/parallel.hpp>
#include <relit/version.hpp>

namespace py = pybind11;

PYBIND11_MODULE(_core, m) {
  m.doc() = "relit: neural relightable participating media on OpenCL (compiled core)";
  m.attr("__version__") = relit::version();
  m.def("build_features", &relit::build_features,
        "What this build can do beside OpenCL: 'OpenImageIO, OpenVDB, MPI', 'no ...' for what it was built without.");
  relit::python::bind_cl(m);  // first: the exception translators the other parts rely on
  relit::python::bind_nn(m);
  relit::python::bind_metrics(m);
  relit::python::bind_report(m);
  relit::python::bind_scene(m);
  relit::python::bind_method(m);
  // Data parallelism: under mpirun every Python process is a rank (relit/__init__.py ends MPI at exit).
  auto p = m.def_submodule("parallel", "MPI ranks: relit trains, generates and evaluates data-parallel under mpirun");
  p.def("built_with_mpi", &relit::parallel::built_with_mpi, "Whether this relit was built with MPI.");
  p.def("init", &relit::parallel::init, "Starts MPI when an MPI launcher started this process (done on import).");
  p.def("rank", &relit::parallel::rank, "This process's rank (0 without MPI).");
  p.def("size", &relit::parallel::size, "The number of ranks (1 without MPI).");
  p.def("local_rank", &relit::parallel::local_rank, "The rank among the ranks of this machine.");
  p.def("finalize", &relit::parallel::finalize, "Ends MPI after a run in which every rank succeeded.");
  p.def("abort", &relit::parallel::abort_job, py::arg("code") = 1, "Ends the whole MPI job now.");
}
