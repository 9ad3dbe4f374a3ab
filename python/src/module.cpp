// The extension module qtmvoronoi._qtmvoronoi: its exception types, then the bindings of each
// concept (bindings.hpp). The package (python/qtmvoronoi/) re-exports what users call.
#include <cpl_vsi.h>
#include <gdal.h>

#include "bindings.hpp"
#include "qtmv_version.hpp"

namespace qtmv::python {

namespace {

Exceptions g_exceptions;

py::handle new_exception(py::module_& m, const char* name, py::handle bases, const char* doc) {
  const std::string qualified = "qtmvoronoi." + std::string(name);
  PyObject* type = PyErr_NewExceptionWithDoc(qualified.c_str(), doc, bases.ptr(), nullptr);
  if (!type) throw py::error_already_set();
  m.add_object(name, py::handle(type));  // the module keeps the reference
  return type;
}

}  // namespace

const Exceptions& exceptions() { return g_exceptions; }

void raise(py::handle type, const std::string& message) {
  PyErr_SetString(type.ptr(), message.c_str());
  throw py::error_already_set();
}

}  // namespace qtmv::python

PYBIND11_MODULE(_qtmvoronoi, m) {
  namespace py = pybind11;
  using namespace qtmv::python;
  m.doc() = "qtmvoronoi's library: the QTM grid over numpy arrays and the Voronoi run (see the package qtmvoronoi).";
  m.attr("__version__") = QTMV_VERSION_STRING;
  m.attr("GDAL_VERSION") = GDALVersionInfo("RELEASE_NAME");
  g_exceptions.error = new_exception(m, "Error", PyExc_RuntimeError, "A failed run; the message is the tool's.");
  const py::tuple option_bases = py::make_tuple(g_exceptions.error, py::handle(PyExc_ValueError));
  g_exceptions.option_error = new_exception(m, "OptionError", option_bases, "A bad option value (also a ValueError).");
  g_exceptions.interrupted = new_exception(m, "Interrupted", g_exceptions.error,
                                           "The run stopped on request (its progress callback returned False); nothing was written.");
  // The package writes its in-memory datasets through osgeo: both must see one /vsimem/.
  m.def("_vsi_file_size", [](const std::string& path) -> long long {
    VSIStatBufL stat;
    return VSIStatL(path.c_str(), &stat) == 0 ? static_cast<long long>(stat.st_size) : -1;
  }, "The size of a GDAL virtual file (bytes), or -1 when there is none: the package's check that osgeo's GDAL is this module's.");
  bind_grid(m);
  bind_options(m);
  bind_run(m);
}
