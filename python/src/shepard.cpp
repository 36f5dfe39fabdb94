// Shepard / inverse-distance-weighting coordinates (nonlinear/shepard.h).

#include <pybind11/stl.h>

#include <limits>
#include <memory>
#include <optional>
#include <vector>

#include <spacewarp/nonlinear/shepard.h>

#include "common.h"

namespace spacewarp::python {

using namespace pybind11::literals;

void bindShepard(py::module_& m) {
  py::class_<ShepardCoordinates, Coordinates, std::shared_ptr<ShepardCoordinates>>(
      m, "Shepard",
      R"(Shepard's inverse-distance weighting over `handles` (k, 3), world units:
w_i(x) = d_i^-power / sum_j d_j^-power (power > 0, default 2), or with a support `radius`
(world units, > 0) Franke and Nielson's ((R - d_i)+ / (R d_i))^power, zero beyond it. The weights
are non-negative, sum to 1 and interpolate the handles; warp(targets) moves every point by the
weighted mean of the handles' displacements (translations are reproduced, linear maps are not).
For power > 1 the warp's Jacobian is the identity at every handle (Shepard's flat spots). With a
radius, points farther than it from every handle have no weights: weights() and the warp raise
InvalidInput for them.)")
      .def(py::init([](py::handle handles, double power, std::optional<double> radius) {
             const Points h = toPoints(handles, "handles", false);
             ShepardOptions options;
             options.power = power;
             if (radius) options.radius = *radius;
             return std::make_shared<ShepardCoordinates>(
                 std::vector<Vec3>(h.span.begin(), h.span.end()), options);
           }),
           "handles"_a, py::kw_only(), "power"_a = 2.0, "radius"_a = py::none())
      .def_property_readonly(
          "power", [](const ShepardCoordinates& c) { return c.options().power; },
          "The weight exponent.")
      .def_property_readonly(
          "radius",
          [](const ShepardCoordinates& c) -> std::optional<double> {
            if (!c.local()) return std::nullopt;
            return c.options().radius;
          },
          "The support radius (world units), or None for global weights.");
}

}  // namespace spacewarp::python
