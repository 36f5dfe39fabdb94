#pragma once
// What every part of the bindings shares: NumPy arrays as spans of points, and running library
// work with the GIL released while progress callbacks and Ctrl-C still reach Python.

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <array>
#include <cstddef>
#include <cstdint>
#include <exception>
#include <functional>
#include <optional>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include <spacewarp/core/math.h>
#include <spacewarp/core/progress.h>

namespace spacewarp {
struct PolygonSoup;
}

namespace spacewarp::python {

namespace py = pybind11;

/// A float64 C-contiguous array (no copy when the input already is one).
using DoubleArray = py::array_t<double, py::array::c_style | py::array::forcecast>;

/// Points given as an (n, 3) array-like (or one point as (3,)), viewed as n Vec3 without a copy
/// when the input is float64 and C-contiguous. Keeps the array alive.
struct Points {
  DoubleArray array;
  std::span<const Vec3> span;
  bool single = false;  ///< Given as one (3,) point: results are returned as (3,) too.

  std::size_t size() const { return span.size(); }
};

/// Converts `object` (named `name` in errors). Throws spacewarp::InvalidInput for another shape
/// ("points must have shape (n, 3), not (4, 2)"); NaN is left for the library to name.
Points toPoints(py::handle object, const char* name = "points", bool allowSingle = true);

/// The index of the first point that is not finite, or points.size().
std::size_t firstNonFinite(std::span<const Vec3> points);

/// Throws InvalidInput naming the first point of `points` (called `name`) that is not finite.
void requireFinite(std::span<const Vec3> points, const char* name = "points");

/// A new (n, 3) float64 array, or `out` checked to be one (float64, C-contiguous, writable,
/// (n, 3)): the array results are written to. `single` gives shape (3,).
DoubleArray outputPoints(std::size_t n, const std::optional<py::array>& out, bool single = false);

/// The writable span of an array made by outputPoints().
std::span<Vec3> pointsOf(DoubleArray& array);

/// An (n, 3) float64 array copied from `points`.
DoubleArray copyPoints(std::span<const Vec3> points);

/// A read-only NumPy view of `data` (shape `shape`) kept alive by `owner`: no copy.
template <class T>
py::array_t<T> readOnlyView(const T* data, std::vector<py::ssize_t> shape, py::handle owner) {
  py::array_t<T> view(std::move(shape), {}, data, owner);
  view.attr("setflags")(py::arg("write") = false);
  return view;
}

/// Vertex indices given as a 1-D array-like of integers (`name` in errors, with the entry at
/// fault: "constrained[3]"). Throws InvalidInput for another shape, a non-integer dtype, or an
/// index that is negative or not below `count`.
std::vector<std::uint32_t> toIndices(py::handle object, const std::string& name,
                                     std::size_t count = std::size_t{1} << 32);

/// Triangles as an (m, 3) integer array (or a sequence of index triples) over `vertexCount`
/// vertices. Throws InvalidInput naming the triangle at fault.
std::vector<std::array<std::uint32_t, 3>> toTriangles(py::handle triangles,
                                                      std::size_t vertexCount);

/// A 3-vector from a sequence of three numbers (`name` in the error).
Vec3 toVec3(py::handle object, const char* name);

/// Polygons as a soup stores them: polygon p is indices[offsets[p] .. offsets[p + 1]).
struct Polygons {
  std::vector<std::uint32_t> offsets{0};
  std::vector<std::uint32_t> indices;
};

/// The polygons `faces` over `vertexCount` vertices: an (m, k) integer array, or a sequence of
/// index sequences (polygons of any size). Throws InvalidInput naming the face for an index
/// that is not an integer or not a vertex.
Polygons toPolygons(py::handle faces, std::size_t vertexCount);

/// `self` as a T, or a TypeError when it was never initialised (made by T.__new__ without
/// __init__: pybind11 then holds no object, and a plain `const T&` argument would be a null
/// reference). Used by the methods defined on the base classes, which every subclass inherits.
template <class T>
const T& initialised(py::handle self) {
  // The instance's own (most derived) bound class: its holder is what __init__ constructs.
  auto* inst = reinterpret_cast<py::detail::instance*>(self.ptr());
  if (!py::isinstance<T>(self) || !inst->get_value_and_holder().holder_constructed())
    throw py::type_error(std::string(py::str(py::type::of(self).attr("__name__"))) +
                         " instance is not initialised (made by __new__ without __init__)");
  return self.cast<const T&>();
}

/// Runs f() with the GIL released and returns what it returns (or rethrows what it throws).
/// Not RAII on purpose: when the interpreter exits while a daemon thread is in here, Python ends
/// that thread as it takes the GIL back (pthread_exit, a forced unwind), and from a destructor
/// such as gil_scoped_release's, which is noexcept, that aborts the process. Taken back here, in
/// plain code, the thread unwinds and ends quietly.
template <class F>
void withoutGil(F&& f) {
  PyThreadState* const state = PyEval_SaveThread();
  std::exception_ptr error;
  try {
    f();
  } catch (...) {
    error = std::current_exception();
  }
  PyEval_RestoreThread(state);
  if (error) std::rethrow_exception(error);
}

/// Runs library work with the GIL released. While it runs, a Ctrl-C (SIGINT) in the main
/// thread sets a flag that the progress callback handed to `work` turns into a cancel, and
/// `progress` (a Python callable(stage, fraction), or None) is called with the GIL held; a
/// callable that raises or returns False cancels too. When the work was cancelled, the Python
/// error that caused it is raised (KeyboardInterrupt, or the callable's exception), or
/// spacewarp.Cancelled when the callable returned False.
void runCancellable(const py::object& progress,
                    const std::function<void(const ProgressCallback&)>& work);

/// f(i) for every i in [0, n), in parallel, in blocks between which a Ctrl-C (and only that:
/// there is no progress callable) cancels; `stage` names the work in a Cancelled.
void forEachPointCancellable(std::size_t n, const char* stage,
                             const std::function<void(std::size_t)>& f);

/// Registers the exception types (spacewarp.InvalidInput, ...) and their translation.
void registerErrors(py::module_& m);

/// Marks a Geometry as read or changed by a call that runs with the GIL released, for the life
/// of the object: the Geometry's setters refuse meanwhile (they would reallocate what the call
/// reads). Create and destroy with the GIL held.
class InUse {
 public:
  explicit InUse(const PolygonSoup& soup);
  ~InUse();
  InUse(const InUse&) = delete;
  InUse& operator=(const InUse&) = delete;

 private:
  const PolygonSoup* soup_;
};

/// Emits a Python warning (category UserWarning) for each message, with the GIL held.
void warnAll(const std::vector<std::string>& messages);

void bindWarps(py::module_& m);
void bindCoordinates(py::module_& m);
void bindGeometry(py::module_& m);
void bindVolume(py::module_& m);
void bindSurface(py::module_& m);
void bindWires(py::module_& m);
void bindSkinning(py::module_& m);
void bindBenchHooks(py::module_& m);
void bindShepard(py::module_& m);
void bindKelvinlet(py::module_& m);
void bindMlsInside(py::module_& m);
void bindArchive(py::module_& m);
void bindStream(py::module_& m);

}  // namespace spacewarp::python
