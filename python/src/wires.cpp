// spacewarp.Wire and spacewarp.Wires: Singh & Fiume's wires (nonlinear/wires.h).

#include <pybind11/stl.h>

#include <memory>
#include <string>
#include <vector>

#include <spacewarp/nonlinear/wires.h>
#include "common.h"

namespace spacewarp::python {

namespace {

std::vector<Vec3> pointVector(py::handle object, const char* name) {
  const Points p = toPoints(object, name, false);
  return {p.span.begin(), p.span.end()};
}

}  // namespace

void bindWires(py::module_& m) {
  using namespace pybind11::literals;
  py::class_<Wire>(m, "Wire",
                   R"(One wire of spacewarp.Wires: the reference curve `rest` (n, 3) and the
deformed curve `deformed` (n, 3), n >= 2, world units, point k of each at parameter k;
`radius` (> 0, world units) of influence; `inner_radius` in [0, radius): full influence
within it (a rigid motion of the wire moves that tube rigidly); `scale` (> 0) about the curve;
`dropoff` "smooth" ((1 - x^2)^2, default) or "linear"; `curve` "polyline" (default) or
"catmull-rom". Checked when a Wires is built from it.)")
      .def(py::init([](py::handle rest, py::handle deformed, double radius, double innerRadius,
                       double scale, const std::string& dropoff, const std::string& curve) {
             Wire w;
             w.rest = pointVector(rest, "rest");
             w.deformed = pointVector(deformed, "deformed");
             w.radius = radius;
             w.innerRadius = innerRadius;
             w.scale = scale;
             w.dropoff = wireDropoffFromName(dropoff);
             w.curve = wireCurveFromName(curve);
             return w;
           }),
           "rest"_a, "deformed"_a, "radius"_a, py::kw_only(), "inner_radius"_a = 0.0,
           "scale"_a = 1.0, "dropoff"_a = "smooth", "curve"_a = "polyline")
      .def_property_readonly(
          "rest", [](const Wire& w) { return copyPoints(w.rest); }, "The reference curve (n, 3).")
      .def_property_readonly(
          "deformed", [](const Wire& w) { return copyPoints(w.deformed); },
          "The deformed curve (n, 3).")
      .def_readonly("radius", &Wire::radius, "Radius of influence, world units.")
      .def_readonly("inner_radius", &Wire::innerRadius, "Radius of full influence, world units.")
      .def_readonly("scale", &Wire::scale, "Scale about the curve.")
      .def_property_readonly(
          "dropoff", [](const Wire& w) { return wireDropoffName(w.dropoff); },
          "The drop-off: \"smooth\" or \"linear\".")
      .def_property_readonly(
          "curve", [](const Wire& w) { return wireCurveName(w.curve); },
          "The curve: \"polyline\" or \"catmull-rom\".");

  py::class_<WiresWarp, Warp, std::shared_ptr<WiresWarp>>(
      m, "Wires",
      R"(Wires (Singh & Fiume 1998): points within a wire's radius of its rest curve follow the
curve to its deformed one (scaled, turned and moved about their closest rest point, fading
out at the radius); several wires blend as x + sum(d_i |d_i|^m) / sum(|d_i|^m), m =
`locality` (>= 0, default 1). `wires`: a sequence of spacewarp.Wire.)")
      .def(py::init([](std::vector<Wire> wires, double locality) {
             std::shared_ptr<WiresWarp> warp;
             withoutGil([&] {
               warp = std::make_shared<WiresWarp>(std::move(wires), WiresOptions{locality});
             });
             return warp;
           }),
           "wires"_a, py::kw_only(), "locality"_a = 1.0)
      .def_property_readonly(
          "wires",
          [](const WiresWarp& w) { return std::vector<Wire>(w.wires().begin(), w.wires().end()); },
          "The wires (a list of spacewarp.Wire).")
      .def_property_readonly(
          "locality", [](const WiresWarp& w) { return w.options().locality; },
          "The blend's exponent m.");
}

}  // namespace spacewarp::python
