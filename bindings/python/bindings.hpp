// The parts of the Python module relit._core; each bind_*.cpp file binds one part of the library.
#pragma once

#include <pybind11/pybind11.h>

namespace relit::python {

void bind_cl(pybind11::module_& m);       // errors, devices, programs, logging, the CLI
void bind_nn(pybind11::module_& m);       // relit.nn: encodings, networks, losses, optimisers
void bind_metrics(pybind11::module_& m);  // relit.metrics: PSNR, SSIM
void bind_report(pybind11::module_& m);   // evaluation reports: write_report, contact_sheet
void bind_scene(pybind11::module_& m);    // scenes, the reference path tracer, dataset generation
void bind_method(pybind11::module_& m);   // training and relighting: Trainer, Model, presets

}  // namespace relit::python
