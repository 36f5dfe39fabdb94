// Regularized Kelvinlet brushes (nonlinear/kelvinlet.h).

#include <pybind11/stl.h>

#include <memory>
#include <optional>
#include <string>

#include <spacewarp/core/errors.h>
#include <spacewarp/nonlinear/kelvinlet.h>

#include "common.h"

namespace spacewarp::python {

using namespace pybind11::literals;

namespace {

// A 3 × 3 matrix from a (3, 3) array-like (rows first, as NumPy writes it).
Mat3 toMat3(py::handle object, const char* name) {
  const DoubleArray a = DoubleArray::ensure(object);
  if (!a || a.ndim() != 2 || a.shape(0) != 3 || a.shape(1) != 3)
    throw InvalidInput(std::string(name) + " must have shape (3, 3)");
  Mat3 m;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) m[c][r] = a.at(r, c);
  return m;
}

}  // namespace

void bindKelvinlet(py::module_& m) {
  py::class_<KelvinletWarp, Warp, std::shared_ptr<KelvinletWarp>>(
      m, "Kelvinlet",
      R"(A regularized Kelvinlet brush (de Goes and James 2017): the displacement of an infinite
elastic medium under a force spread over `radius` (epsilon > 0, world units) around `center` (3,).
brush "grab" moves the center by `displacement` (3,); "twist" rotates the center's neighbourhood
by `angle` (radians) about `axis` (3,) (the Jacobian there is I + angle [axis]x); "scale" scales it
by `factor` (> 0); "pinch" gives it the displacement gradient `matrix` (3, 3), symmetric and
traceless. poisson: Poisson ratio in [0, 0.5] (default 0.45). falloff: "single" (default),
"bi" or "tri": the brush at radii epsilon, 2 epsilon (and 4 epsilon) combined so that it fades
faster with distance (grab 1/r, 1/r^3, 1/r^5), the center unchanged. steps: the brush applied as that
many sub-brushes (1 = the closed form; more avoid folds for large edits, at steps times the cost).
Keys of another brush raise InvalidInput.)")
      .def(py::init([](const std::string& brush, py::handle center, double radius, double poisson,
                       const std::optional<py::handle>& displacement,
                       const std::optional<py::handle>& axis, std::optional<double> angle,
                       std::optional<double> factor, const std::optional<py::handle>& matrix,
                       const std::string& falloff, int steps) {
             KelvinletOptions o;
             o.brush = kelvinletBrushFromName(brush);
             o.center = toVec3(center, "center");
             o.radius = radius;
             o.poisson = poisson;
             o.steps = steps;
             o.falloff = kelvinletFalloffFromName(falloff);
             const auto given = [](const auto& v) {
               if constexpr (std::is_same_v<std::decay_t<decltype(v)>, std::optional<py::handle>>)
                 return v.has_value() && !v->is_none();
               else
                 return v.has_value();
             };
             const auto require = [&](bool has, const char* key) {
               if (!has) throw InvalidInput("Kelvinlet: brush '" + brush + "' needs " + key);
             };
             const auto refuse = [&](bool has, const char* key) {
               if (has)
                 throw InvalidInput(std::string("Kelvinlet: ") + key +
                                    " has no effect with brush '" + brush + "'");
             };
             const bool d = given(displacement), x = given(axis), a = given(angle),
                        f = given(factor), p = given(matrix);
             refuse(d && o.brush != KelvinletBrush::Grab, "displacement");
             refuse((x || a) && o.brush != KelvinletBrush::Twist, x ? "axis" : "angle");
             refuse(f && o.brush != KelvinletBrush::Scale, "factor");
             refuse(p && o.brush != KelvinletBrush::Pinch, "matrix");
             switch (o.brush) {
               case KelvinletBrush::Grab:
                 require(d, "displacement");
                 o.displacement = toVec3(*displacement, "displacement");
                 break;
               case KelvinletBrush::Twist:
                 require(x, "axis");
                 require(a, "angle");
                 o.axis = toVec3(*axis, "axis");
                 o.angle = *angle;
                 break;
               case KelvinletBrush::Scale:
                 require(f, "factor");
                 o.factor = *factor;
                 break;
               case KelvinletBrush::Pinch:
                 require(p, "matrix");
                 o.matrix = toMat3(*matrix, "matrix");
                 break;
             }
             return std::make_shared<KelvinletWarp>(o);
           }),
           py::kw_only(), "brush"_a, "center"_a, "radius"_a, "poisson"_a = 0.45,
           "displacement"_a = py::none(), "axis"_a = py::none(), "angle"_a = py::none(),
           "factor"_a = py::none(), "matrix"_a = py::none(), "falloff"_a = "single", "steps"_a = 1)
      .def_property_readonly(
          "brush", [](const KelvinletWarp& w) { return kelvinletBrushName(w.options().brush); },
          "\"grab\", \"twist\", \"scale\" or \"pinch\".")
      .def_property_readonly(
          "radius", [](const KelvinletWarp& w) { return w.options().radius; },
          "The regularisation radius epsilon, world units.")
      .def_property_readonly(
          "poisson", [](const KelvinletWarp& w) { return w.options().poisson; },
          "The Poisson ratio.");
}

}  // namespace spacewarp::python
