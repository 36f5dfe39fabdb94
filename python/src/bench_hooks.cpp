// Timings of the plain C++ calls behind two Python calls, on the same arrays in the same process:
// the baseline of bench/python_overhead.py, which measures what calling through Python costs.

#include <chrono>

#include <spacewarp/core/binding.h>
#include <spacewarp/core/coordinates.h>
#include <spacewarp/core/warp.h>

#include "common.h"

namespace spacewarp::python {
namespace {

using namespace pybind11::literals;

template <class F>
double secondsOf(const F& f) {
  const auto start = std::chrono::steady_clock::now();
  f();
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

}  // namespace

void bindBenchHooks(py::module_& m) {
  m.def(
      "_cpp_apply_seconds",
      [](const Warp& warp, py::handle points) {
        const Points in = toPoints(points);
        const py::gil_scoped_release release;
        return secondsOf([&] {
          std::vector<Vec3> out(in.size());
          warp.applyBatch(in.span, out);
        });
      },
      "warp"_a, "points"_a,
      "Seconds of Warp::applyBatch on `points` into a new vector (C++ only).");
  m.def(
      "_cpp_bind_seconds",
      [](std::shared_ptr<Coordinates> coordinates, py::handle points) {
        const Points in = toPoints(points, "points", false);
        const py::gil_scoped_release release;
        return secondsOf([&] { const Binding binding(coordinates, in.span); });
      },
      "coordinates"_a, "points"_a, "Seconds of constructing a Binding of `points` (C++ only).");
}

}  // namespace spacewarp::python
