// The extension module spacewarp._spacewarp; the package's __init__.py re-exports it.

#include "common.h"

#ifdef SPACEWARP_WITH_VIEW
namespace spacewarp::python {
void bindView(py::module_& m);  // view.cpp, in builds with the command-line tool
}
#endif

PYBIND11_MODULE(_spacewarp, m) {
  namespace py = pybind11;
  m.doc() =
      "spacewarp's C++ engine: warps, cage coordinates, bindings, files, volumes and surface "
      "editing.";
  m.attr("__version__") = SPACEWARP_VERSION;
  spacewarp::python::registerErrors(m);
  spacewarp::python::bindMlsInside(m);  // before Mls, which takes its distances
  spacewarp::python::bindWarps(m);
  spacewarp::python::bindCoordinates(m);
  spacewarp::python::bindGeometry(m);
  spacewarp::python::bindVolume(m);
  spacewarp::python::bindSurface(m);
  spacewarp::python::bindWires(m);
  spacewarp::python::bindSkinning(m);
  spacewarp::python::bindBenchHooks(m);
  spacewarp::python::bindShepard(m);
  spacewarp::python::bindKelvinlet(m);
  spacewarp::python::bindArchive(m);  // after every Warp and Coordinates class
  spacewarp::python::bindStream(m);
#ifdef SPACEWARP_WITH_VIEW
  spacewarp::python::bindView(m);
#endif
}
