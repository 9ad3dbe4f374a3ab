// The extension module qtmvoronoi._qtmvoronoi: thin bindings of the library, one file per concept
// (grid_bindings.cpp: the grid's functions over numpy arrays; options_bindings.cpp: VoronoiOptions
// and VoronoiSummary; run_bindings.cpp: run_voronoi with progress, messages and Ctrl-C).
#pragma once

#include <pybind11/pybind11.h>

#include <string>

namespace qtmv::python {

namespace py = pybind11;

/// The package's exception types (module.cpp makes them): qtmvoronoi.Error (a RuntimeError: a
/// failed run, the tool's message), qtmvoronoi.OptionError (an Error and a ValueError: an option's
/// value) and qtmvoronoi.Interrupted (an Error: the progress callback asked the run to stop).
struct Exceptions {
  py::handle error, option_error, interrupted;
};
const Exceptions& exceptions();

/// Raises `type` with `message` (throws py::error_already_set).
[[noreturn]] void raise(py::handle type, const std::string& message);

void bind_grid(py::module_& m);
void bind_options(py::module_& m);
void bind_run(py::module_& m);

}  // namespace qtmv::python
