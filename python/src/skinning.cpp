// Skinning: the SkinningWarp (spacewarp.Skinning) and the fast SkinningBinding.

#include <pybind11/stl.h>

#include <algorithm>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <spacewarp/core/coordinates.h>
#include <spacewarp/core/errors.h>
#include <spacewarp/nonlinear/skinning.h>

#include "common.h"

namespace spacewarp::python {
namespace {

using namespace pybind11::literals;

// Bones as a (b, 4, 4) array of row-major homogeneous matrices (or one (4, 4) matrix).
std::vector<Mat4> toBones(py::handle bones) {
  const DoubleArray a = DoubleArray::ensure(bones);
  if (!a || (a.ndim() != 3 && a.ndim() != 2) || a.shape(a.ndim() - 1) != 4 ||
      a.shape(a.ndim() - 2) != 4 || (a.ndim() == 3 && a.shape(0) == 0)) {
    PyErr_Clear();
    throw InvalidInput("bones must have shape (b, 4, 4): one row-major 4 x 4 matrix per bone");
  }
  const py::ssize_t n = a.ndim() == 3 ? a.shape(0) : 1;
  const double* data = a.data();
  std::vector<Mat4> out(static_cast<std::size_t>(n));
  for (py::ssize_t b = 0; b < n; ++b)
    for (int r = 0; r < 4; ++r)
      for (int c = 0; c < 4; ++c) out[std::size_t(b)][c][r] = data[b * 16 + r * 4 + c];
  return out;
}

// Dense weights (n, bones) as sparse skinning weights, keeping `influences` per point.
SkinningWeights toWeights(py::handle weights, std::size_t points, std::size_t bones,
                          std::size_t influences) {
  const DoubleArray a = DoubleArray::ensure(weights);
  if (!a || a.ndim() != 2 || std::size_t(a.shape(0)) != points ||
      std::size_t(a.shape(1)) != bones) {
    PyErr_Clear();
    throw InvalidInput("weights must have shape (" + std::to_string(points) + ", " +
                       std::to_string(bones) + "): one row per point, one column per bone");
  }
  SkinningWeights out;
  withoutGil([&] {
    out = sparseSkinningWeights({a.data(), std::size_t(a.size())}, bones, influences);
  });
  return out;
}

SkinningMode modeOf(const std::string& name) { return skinningModeFromName(name); }

const std::string kModes = R"(mode: "lbs" (linear blend skinning: the bones' matrices averaged; any
affine bones) or "dqs" (dual-quaternion skinning, Kavan et al. 2008: the rigid motions averaged
as unit dual quaternions, each in the hemisphere of the point's largest-weight bone; rigid bones
only).)";

// The docstrings, kept alive for the module's life.
const std::string& skinningDoc() {
  static const std::string doc =
      R"(Skeletal skinning of space. bones: (b, 4, 4) row-major transforms from the
rest pose to the posed one (world units). The weights of a point x come either from `weights`
(n, b) of the vertices of `model` (n, 3) — x takes its nearest vertex's weights, so the warp is
exact on the model — or from `coordinates` (a Coordinates with one control point per bone,
e.g. MlsAffine or Rbf of the bones' handles). Per point the `influences` largest weights are
kept and normalised to sum 1: 0 keeps all; default None: 4 of `weights`, all of `coordinates`
(exact and smooth). Truncating clamps negative weights to 0 (no poles) and, for coordinates,
fades the kept ones by the next largest (continuous in space).
)" + kModes;
  return doc;
}

const std::string& deformDoc() {
  static const std::string doc =
      "The posed points (n, 3) for bones (b, 4, 4), into `out` if given.\n" + kModes;
  return doc;
}

// The kept influences of a binding as (bones (n, k) uint32, weights (n, k) float64).
py::tuple influencesOf(const SkinningBinding& b) {
  const SkinningWeights& w = b.weights();
  DoubleArray weights(
      std::vector<py::ssize_t>{py::ssize_t(w.pointCount), py::ssize_t(w.influences)});
  py::array_t<std::uint32_t> bones(
      std::vector<py::ssize_t>{py::ssize_t(w.pointCount), py::ssize_t(w.influences)});
  std::copy(w.weights.begin(), w.weights.end(), weights.mutable_data());
  std::copy(w.bones.begin(), w.bones.end(), bones.mutable_data());
  return py::make_tuple(bones, weights);
}

// A binding of `points` with the kept influences `bones` and `weights` (n, k each), as
// influencesOf() gives them; the constructor checks them.
std::shared_ptr<SkinningBinding> bindingOf(const Points& points, py::handle bones,
                                           py::handle weights, std::size_t boneCount) {
  using Indices = py::array_t<std::uint32_t, py::array::c_style | py::array::forcecast>;
  const Indices b = Indices::ensure(bones);
  const DoubleArray w = DoubleArray::ensure(weights);
  if (!b || !w || b.ndim() != 2 || w.ndim() != 2 || b.shape(0) != w.shape(0) ||
      b.shape(1) != w.shape(1)) {
    PyErr_Clear();
    throw InvalidInput("SkinningBinding: pickled bones and weights must be (n, k) arrays alike");
  }
  SkinningWeights sparse;
  sparse.pointCount = std::size_t(b.shape(0));
  sparse.influences = std::size_t(b.shape(1));
  sparse.bones.assign(b.data(), b.data() + b.size());
  sparse.weights.assign(w.data(), w.data() + w.size());
  std::vector<Vec3> positions(points.span.begin(), points.span.end());
  std::shared_ptr<SkinningBinding> binding;
  withoutGil([&] {
    binding = std::make_shared<SkinningBinding>(std::move(positions), std::move(sparse), boneCount);
  });
  return binding;
}

}  // namespace

void bindSkinning(py::module_& m) {
  py::class_<SkinningWarp, Warp, std::shared_ptr<SkinningWarp>>(m, "Skinning",
                                                                skinningDoc().c_str())
      .def(py::init([](py::handle bones, const py::object& weights, const py::object& model,
                       const std::shared_ptr<Coordinates>& coordinates, const std::string& mode,
                       std::optional<std::size_t> influences) {
             std::vector<Mat4> b = toBones(bones);
             const SkinningMode skinningMode = modeOf(mode);
             if (coordinates) {
               if (!weights.is_none() || !model.is_none())
                 throw InvalidInput("give either weights and model, or coordinates");
               std::shared_ptr<SkinningWarp> warp;
               withoutGil([&] {
                 warp = std::make_shared<SkinningWarp>(
                     std::move(b), coordinates,
                     SkinningOptions{skinningMode, influences.value_or(0)});
               });
               return warp;
             }
             if (weights.is_none() || model.is_none())
               throw InvalidInput("give weights (n, b) and model (n, 3), or coordinates");
             const Points points = toPoints(model, "model", false);
             SkinningWeights w =
                 toWeights(weights, points.size(), b.size(), influences.value_or(4));
             std::shared_ptr<SkinningWarp> warp;
             withoutGil([&] {
               warp = std::make_shared<SkinningWarp>(
                   std::move(b), std::vector<Vec3>(points.span.begin(), points.span.end()),
                   std::move(w), skinningMode);
             });
             return warp;
           }),
           "bones"_a, py::kw_only(), "weights"_a = py::none(), "model"_a = py::none(),
           "coordinates"_a = nullptr, "mode"_a = "lbs", "influences"_a = py::none())
      .def_property_readonly(
          "mode", [](const SkinningWarp& w) { return skinningModeName(w.mode()); },
          "\"lbs\" or \"dqs\".")
      .def_property_readonly(
          "bone_count", [](const SkinningWarp& w) { return w.bones().size(); }, "b.");

  py::class_<SkinningBinding, std::shared_ptr<SkinningBinding>>(
      m, "SkinningBinding",
      R"(A fixed point set bound to b bones, re-posed by deform(bones): the fast path (SIMD,
parallel, deterministic; bit-identical to Skinning at the same points). points: (n, 3), world
units. weights: (n, b) dense weights, or a Coordinates with one control point per bone, whose
weights at the points are computed once. The `influences` largest weights per point are kept
and normalised to sum 1, as in Skinning: 0 keeps all; default None: 4 of dense weights, all of
coordinates.)")
      .def(py::init(
               [](py::handle points, py::handle weights, std::optional<std::size_t> influences) {
                 const Points p = toPoints(points, "points", false);
                 std::vector<Vec3> positions(p.span.begin(), p.span.end());
                 std::shared_ptr<SkinningBinding> binding;
                 if (py::isinstance<Coordinates>(weights)) {
                   const auto coordinates = weights.cast<std::shared_ptr<Coordinates>>();
                   withoutGil([&] {
                     SkinningWeights w =
                         skinningWeights(*coordinates, positions, influences.value_or(0));
                     binding = std::make_shared<SkinningBinding>(std::move(positions), std::move(w),
                                                                 coordinates->controlPointCount());
                   });
                   return binding;
                 }
                 const DoubleArray a = DoubleArray::ensure(weights);
                 if (!a || a.ndim() != 2) {
                   PyErr_Clear();
                   throw InvalidInput("weights must be an (n, b) array or a Coordinates");
                 }
                 const std::size_t bones = std::size_t(a.shape(1));
                 SkinningWeights w =
                     toWeights(weights, positions.size(), bones, influences.value_or(4));
                 withoutGil([&] {
                   binding =
                       std::make_shared<SkinningBinding>(std::move(positions), std::move(w), bones);
                 });
                 return binding;
               }),
           "points"_a, "weights"_a, py::kw_only(), "influences"_a = py::none())
      .def(
          "deform",
          [](const SkinningBinding& b, py::handle bones, const std::string& mode,
             const std::optional<py::array>& out) {
            const std::vector<Mat4> posed = toBones(bones);
            const SkinningMode skinningMode = modeOf(mode);
            DoubleArray result = outputPoints(b.pointCount(), out);
            const std::span<Vec3> moved = pointsOf(result);
            withoutGil([&] { b.deform(posed, skinningMode, moved); });
            return result;
          },
          "bones"_a, py::kw_only(), "mode"_a = "lbs", "out"_a = py::none(), deformDoc().c_str())
      .def_property_readonly("point_count", &SkinningBinding::pointCount, "n.")
      .def_property_readonly("bone_count", &SkinningBinding::boneCount, "b.")
      .def_property_readonly(
          "rest_points", [](const SkinningBinding& b) { return copyPoints(b.restPoints()); },
          "The bound points (n, 3), a copy.")
      .def_property_readonly(
          "influences", &influencesOf,
          "The kept influences as (bones (n, k) uint32, weights (n, k) float64), largest weight "
          "first, each row summing to 1.")
      // Pickled as its data (points, kept influences, bone count), rebuilt by the constructor,
      // which checks it: a binding can be posed in other processes (one frame per worker).
      .def(py::pickle(
          [](const SkinningBinding& b) {
            return py::make_tuple(copyPoints(b.restPoints()), influencesOf(b), b.boneCount());
          },
          [](const py::tuple& state) {
            if (state.size() != 3)
              throw InvalidInput("SkinningBinding: a pickled state of 3 items");
            const Points points = toPoints(state[0], "points", false);
            const py::tuple influences = state[1].cast<py::tuple>();
            if (influences.size() != 2)
              throw InvalidInput("SkinningBinding: pickled influences are (bones, weights)");
            return bindingOf(points, influences[0], influences[1], state[2].cast<std::size_t>());
          }));
}

}  // namespace spacewarp::python
