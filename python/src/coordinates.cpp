// Cages, every Coordinates (cage methods, lattices, RBF and MLS handles), bindings and the
// property measurements of coords/properties.h.

#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>

#include <algorithm>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <spacewarp/coords/cage.h>
#include <spacewarp/coords/discrete_harmonic.h>
#include <spacewarp/coords/green.h>
#include <spacewarp/coords/harmonic.h>
#include <spacewarp/coords/mean_value.h>
#include <spacewarp/coords/properties.h>
#include <spacewarp/coords/quad_green.h>
#include <spacewarp/coords/quad_mean_value.h>
#include <spacewarp/coords/wachspress.h>
#include <spacewarp/core/binding.h>
#include <spacewarp/core/coordinates.h>
#include <spacewarp/core/errors.h>
#include <spacewarp/ffd/lattice_coordinates.h>
#include <spacewarp/ffd/lattice_fit.h>
#include <spacewarp/nonlinear/mls.h>
#include <spacewarp/rbf/rbf_coordinates.h>
#include <spacewarp/rig/cage_rig.h>

#include "common.h"
#include "rbf_options.h"

namespace spacewarp::python {
namespace {

using namespace pybind11::literals;
using CoordinatesPtr = std::shared_ptr<Coordinates>;

std::shared_ptr<Cage> makeCage(py::handle vertices, py::handle faces, const std::string& name) {
  const Points v = toPoints(vertices, "vertices", false);
  PolygonSoup soup;
  soup.positions.assign(v.span.begin(), v.span.end());
  Polygons polygons = toPolygons(faces, soup.size());
  soup.faceOffsets = std::move(polygons.offsets);
  soup.faceIndices = std::move(polygons.indices);
  return std::make_shared<Cage>(soup, name);
}

/// One value per point, computed in parallel with the GIL released.
template <class F>
py::array_t<double> perPoint(py::handle points, const F& f) {
  const Points in = toPoints(points, "points", false);
  requireFinite(in.span);
  py::array_t<double> out(static_cast<py::ssize_t>(in.size()));
  double* o = out.mutable_data();
  withoutGil([&] {
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, in.size(), 256),
                      [&](const tbb::blocked_range<std::size_t>& r) {
                        for (std::size_t i = r.begin(); i != r.end(); ++i) o[i] = f(in.span[i]);
                      });
  });
  return out;
}

void bindCage(py::module_& m) {
  py::class_<Cage, std::shared_ptr<Cage>>(
      m, "Cage",
      R"(A closed, outward-oriented cage: vertices (V, 3) world units and polygons (an (F, k)
integer array, or a list of index lists for mixed sizes). The polygons are kept (faces) for
QuadMeanValue, QuadGreen, Wachspress and DiscreteHarmonic, and triangulated (triangles) for
MeanValue, Green and Harmonic.
Raises InvalidInput naming the element for an open, non-manifold or degenerate cage.)")
      .def(py::init(&makeCage), "vertices"_a, "faces"_a, py::kw_only(), "name"_a = "cage")
      .def_static(
          "from_file",
          [](const std::filesystem::path& path) {
            return std::make_shared<Cage>(Cage::fromFile(path));
          },
          "path"_a, "A cage read from an OBJ, OFF or PLY file.")
      .def_property_readonly(
          "vertices", [](const Cage& c) { return copyPoints(c.vertices()); },
          "(V, 3) float64, world units.")
      .def_property_readonly(
          "triangles",
          [](const Cage& c) {
            py::array_t<std::uint32_t> a(
                std::vector<py::ssize_t>{static_cast<py::ssize_t>(c.triangleCount()), 3});
            std::copy_n(&c.triangles()[0][0], 3 * c.triangleCount(), a.mutable_data());
            return a;
          },
          "(T, 3) uint32 vertex indices, outward oriented.")
      .def_property_readonly(
          "triangle_source",
          [](const Cage& c) {
            return py::array_t<std::uint32_t>(static_cast<py::ssize_t>(c.triangleSource().size()),
                                              c.triangleSource().data());
          },
          "(T,) the input polygon each triangle was cut from.")
      .def_property_readonly("face_count", &Cage::faceCount, "Faces (input polygons), F.")
      .def_property_readonly(
          "faces",
          [](const Cage& c) {
            py::list faces;
            for (std::size_t f = 0; f < c.faceCount(); ++f) {
              const auto face = c.face(f);
              faces.append(
                  py::array_t<std::uint32_t>(static_cast<py::ssize_t>(face.size()), face.data()));
            }
            return faces;
          },
          "The F faces as the polygons they were given as, outward (counter-clockwise seen from "
          "outside, first vertex kept): a list of (k,) uint32 vertex-index arrays.")
      .def_property_readonly(
          "face_offsets",
          [](const Cage& c) {
            return py::array_t<std::uint32_t>(static_cast<py::ssize_t>(c.faceOffsets().size()),
                                              c.faceOffsets().data());
          },
          "(F + 1,) uint32: face f is face_indices[face_offsets[f]:face_offsets[f + 1]].")
      .def_property_readonly(
          "face_indices",
          [](const Cage& c) {
            return py::array_t<std::uint32_t>(static_cast<py::ssize_t>(c.faceIndices().size()),
                                              c.faceIndices().data());
          },
          "uint32 vertex indices of every face in turn (see face_offsets).")
      .def_property_readonly("max_face_size", &Cage::maxFaceSize,
                             "The most vertices of a face: 3 for a triangle cage, 4 with quads.")
      .def_property_readonly("diagonal", &Cage::diagonal, "Bounding-box diagonal, world units.")
      .def_property_readonly("volume", &Cage::volume, "Enclosed volume, world units^3.")
      .def_property_readonly(
          "reoriented_count", &Cage::reorientedCount,
          "Faces (input polygons) reversed for a consistent outward orientation.")
      .def(
          "winding_number",
          [](const Cage& c, py::handle p) {
            return perPoint(p, [&](const Vec3& x) { return c.windingNumber(x); });
          },
          "points"_a, "The generalised winding number (n,) at points (n, 3): 1 inside, 0 outside.")
      .def(
          "contains",
          [](const Cage& c, py::handle p) {
            return perPoint(p, [&](const Vec3& x) { return c.contains(x) ? 1.0 : 0.0; })
                .attr("astype")("bool");
          },
          "points"_a, "(n,) bool: whether each point is strictly inside.")
      .def(
          "posed_vertices",
          [](const Cage& c, const std::filesystem::path& path) {
            return copyPoints(c.posedVerticesFromFile(path));
          },
          "path"_a, "The vertices (V, 3) of a posed cage file, checked against this cage.");
}

DoubleArray weightsOf(const Coordinates& c, py::handle points, const py::object& progress) {
  const Points in = toPoints(points, "points", false);
  const std::size_t columns = c.columnCount();
  py::array_t<double> rows(std::vector<py::ssize_t>{static_cast<py::ssize_t>(in.size()),
                                                    static_cast<py::ssize_t>(columns)});
  const std::span<double> out(rows.mutable_data(), in.size() * columns);
  runCancellable(progress, [&](const ProgressCallback& callback) {
    ProgressTracker tracker(callback, "weights", in.size());
    forEachBlock(in.size(), callback ? std::size_t{1} << 12 : 0, tracker,
                 [&](std::size_t begin, std::size_t count) {
                   c.weightsBatch(in.span, begin, begin + count,
                                  out.subspan(begin * columns, count * columns));
                 });
  });
  return rows;
}

py::object sparseWeightsOf(const Coordinates& c, py::handle points) {
  const py::module_ sparse = py::module_::import("scipy.sparse");
  const Points in = toPoints(points, "points", false);
  const std::size_t k = c.maxNonZeros(), n = in.size();
  std::vector<SparseWeight> entries(n * k);
  std::vector<std::size_t> counts(n);
  requireFinite(in.span);
  forEachPointCancellable(n, "sparse weights", [&](std::size_t i) {
    counts[i] = c.sparseWeights(in.span[i], std::span(entries).subspan(i * k, k));
  });
  py::array_t<std::int64_t> indptr(static_cast<py::ssize_t>(n + 1));
  std::size_t total = 0;
  indptr.mutable_at(0) = 0;
  for (std::size_t i = 0; i < n; ++i)
    indptr.mutable_at(i + 1) = static_cast<std::int64_t>(total += counts[i]);
  py::array_t<std::int64_t> indices(static_cast<py::ssize_t>(total));
  py::array_t<double> data(static_cast<py::ssize_t>(total));
  for (std::size_t i = 0, j = 0; i < n; ++i) {
    for (std::size_t e = 0; e < counts[i]; ++e, ++j) {
      indices.mutable_at(j) = entries[i * k + e].column;
      data.mutable_at(j) = entries[i * k + e].weight;
    }
  }
  return sparse.attr("csr_matrix")(py::make_tuple(data, indices, indptr),
                                   "shape"_a = py::make_tuple(n, c.columnCount()));
}

void bindBinding(py::module_& m) {
  py::class_<Binding, std::shared_ptr<Binding>>(
      m, "Binding",
      R"(The weights of a fixed point set, computed once (Coordinates.bind): deform() re-poses
the points by one matrix product. Weights are stored dense or sparse (CSR) as the coordinates
suit; `weights` shows them without a copy.)")
      .def(
          "deform",
          [](const Binding& b, py::handle posed, const std::optional<py::array>& out) {
            const Points p = toPoints(posed, "posed", false);
            DoubleArray result = outputPoints(b.pointCount(), out);
            const std::span<Vec3> o = pointsOf(result);
            withoutGil([&] { b.deform(p.span, o); });
            return result;
          },
          "posed"_a, py::kw_only(), "out"_a = py::none(),
          R"(The bound points deformed by the posed control points `posed` (V, 3): (n, 3)
float64, world units, a new array (or `out`).)")
      .def_property_readonly("point_count", &Binding::pointCount, "Points bound (n).")
      .def_property_readonly("column_count", &Binding::columnCount, "Columns of the weight matrix.")
      .def_property_readonly("is_sparse", &Binding::isSparse,
                             "Whether the weights are stored sparse (CSR): at most a quarter of "
                             "the columns non-zero per point.")
      .def_property_readonly(
          "rest_points", [](const Binding& b) { return copyPoints(b.restPoints()); },
          "The points as bound (n, 3).")
      .def_property_readonly(
          "weights",
          [](py::object self) -> py::object {
            const Binding& b = self.cast<const Binding&>();
            const auto n = static_cast<py::ssize_t>(b.pointCount()),
                       c = static_cast<py::ssize_t>(b.columnCount());
            if (!b.isSparse()) return readOnlyView(b.dense().data(), {n, c}, self);
            const Binding::SparseMatrix& s = b.sparse();
            const auto nnz = static_cast<py::ssize_t>(s.nonZeros());
            const py::array data = readOnlyView(s.valuePtr(), {nnz}, self);
            py::array indices(py::dtype::of<std::int64_t>(), {nnz}, {}, s.innerIndexPtr(), self);
            py::array indptr(py::dtype::of<std::int64_t>(), {n + 1}, {}, s.outerIndexPtr(), self);
            return py::module_::import("scipy.sparse")
                .attr("csr_matrix")(py::make_tuple(data, indices, indptr),
                                    "shape"_a = py::make_tuple(n, c), "copy"_a = false);
          },
          R"(The weight matrix (n, columns): a read-only view of the binding's own dense matrix,
or a scipy.sparse.csr_matrix over its CSR arrays when is_sparse (needs SciPy).)");
}

void bindCoordinatesBase(py::module_& m) {
  py::class_<Coordinates, CoordinatesPtr>(
      m, "Coordinates",
      R"(Coordinates of points with respect to controls (cage vertices, lattice points, RBF
handles): x' = x + sum_c w_c(x) (C_c(posed) - C_c(rest)). Thread-safe; the GIL is released.)")
      .def("weights", &weightsOf, "points"_a, py::kw_only(), "progress"_a = py::none(),
           R"(The weights of `points` (n, 3): an (n, column_count) float64 array, one row per
point. Raises InvalidInput for non-finite points or points outside the domain (naming the first).)")
      .def("sparse_weights", &sparseWeightsOf, "points"_a,
           "The weights as a scipy.sparse.csr_matrix (n, column_count) of the non-zeros (needs "
           "SciPy).")
      .def(
          "bind",
          [](CoordinatesPtr self, py::handle points, const py::object& progress) {
            const Points in = toPoints(points, "points", false);
            std::shared_ptr<Binding> binding;
            runCancellable(progress, [&](const ProgressCallback& callback) {
              binding = std::make_shared<Binding>(self, in.span, callback);
            });
            return binding;
          },
          "points"_a, py::kw_only(), "progress"_a = py::none(),
          "The Binding of `points` (n, 3): their weights computed once, in parallel.")
      .def(
          "warp",
          [](CoordinatesPtr self, py::handle posed) {
            const Points p = toPoints(posed, "posed", false);
            return std::const_pointer_cast<Warp>(makeWarp(self, p.span));
          },
          "posed"_a, "The Warp of these coordinates posed by `posed` (control_point_count, 3).")
      .def(
          "column_controls",
          [](const Coordinates& c, py::handle posed) {
            const Points p = toPoints(posed, "posed", false);
            std::vector<Vec3> out(c.columnCount());
            c.columnControls(p.span, out);
            return copyPoints(out);
          },
          "posed"_a,
          "The column controls C (column_count, 3) of posed control points (V, 3): the points, "
          "plus "
          "Green's scaled face normals.")
      .def_property_readonly(
          "control_point_count", &Coordinates::controlPointCount,
          "Control points a user poses (V): cage vertices, lattice points, handles.")
      .def_property_readonly("column_count", &Coordinates::columnCount,
                             "Columns of a weight row: V, plus one per cage face for Green.")
      .def_property_readonly(
          "rest_control_points",
          [](const Coordinates& c) { return copyPoints(c.restControlPoints()); },
          "(V, 3) world units.")
      .def_property_readonly(
          "column_names",
          [](const Coordinates& c) {
            std::vector<std::string> names(c.columnCount());
            for (std::size_t i = 0; i < names.size(); ++i) names[i] = c.columnName(i);
            return names;
          },
          "One name per column: \"v<i>\" for control point i, \"f<j>\" for face j.");
}

// The harmonic `precision` argument: a number, not a bool (pybind11 would take True as 1, where
// the rig's "precision": true is refused).
double precisionArgument(const py::object& precision) {
  if (py::isinstance<py::bool_>(precision))
    throw InvalidInput("precision must be a number in [1, 7] (or 0: none), not a bool");
  try {
    return precision.cast<double>();
  } catch (const py::cast_error&) {
    throw InvalidInput("precision must be a number in [1, 7] (or 0: none), not " +
                       std::string(py::str(py::type::of(precision).attr("__name__"))));
  }
}

// The `outside` argument of the convex-cage coordinates, as the CLI's --outside.
ConvexOutsidePolicy convexOutside(const std::string& outside) {
  if (outside == "raise") return ConvexOutsidePolicy::Throw;
  if (outside == "nearest") return ConvexOutsidePolicy::NearestPoint;
  throw InvalidInput("outside must be \"raise\" or \"nearest\", not \"" + outside + "\"");
}

// `T` made with the GIL released (construction precomputes per face, or checks convexity).
template <class T, class Options>
std::shared_ptr<T> madeWithoutGil(std::shared_ptr<Cage> cage, const Options& options) {
  std::shared_ptr<T> made;
  withoutGil([&] { made = std::make_shared<T>(std::move(cage), options); });
  return made;
}

std::shared_ptr<Coordinates> byName(const std::string& method, std::shared_ptr<Cage> cage,
                                    const CageMethodOptions& options, const py::object& progress) {
  std::shared_ptr<const Coordinates> c;
  runCancellable(progress, [&](const ProgressCallback& callback) {
    c = cageCoordinates(method, std::move(cage), options, callback);
  });
  return std::const_pointer_cast<Coordinates>(c);
}

void bindCageCoordinates(py::module_& m) {
  py::class_<MeanValueCoordinates, Coordinates, std::shared_ptr<MeanValueCoordinates>>(
      m, "MeanValue",
      "Mean-value coordinates (Ju et al. 2005) of a Cage: (n, V) weights, everywhere in space.")
      .def(py::init([](std::shared_ptr<Cage> cage, double snapTolerance) {
             return std::make_shared<MeanValueCoordinates>(cage, MeanValueOptions{snapTolerance});
           }),
           "cage"_a, py::kw_only(), "snap_tolerance"_a = 1e-14)
      .def_property_readonly(
          "cage", [](const MeanValueCoordinates& c) { return c.cage(); }, "The Cage (a copy).");
  py::class_<GreenCoordinates, Coordinates, std::shared_ptr<GreenCoordinates>>(
      m, "Green",
      "Green coordinates (Lipman et al. 2008) of a Cage: (n, V + F) weights, vertex columns then "
      "face columns.")
      .def(py::init([](std::shared_ptr<Cage> cage, double surfaceTolerance) {
             return std::make_shared<GreenCoordinates>(cage, GreenOptions{surfaceTolerance});
           }),
           "cage"_a, py::kw_only(), "surface_tolerance"_a = 1e-14)
      .def_property_readonly(
          "cage", [](const GreenCoordinates& c) { return c.cage(); }, "The Cage (a copy).");
  py::class_<QuadMeanValueCoordinates, Coordinates, std::shared_ptr<QuadMeanValueCoordinates>>(
      m, "QuadMeanValue",
      R"(Mean-value coordinates of a polygon Cage, quads included (CLI "qmvc"): Langer et al. 2006
for polygons, Thiery et al. 2018 for quads (bilinear patches, planar or not); no face is
triangulated. (n, V) weights that sum to 1 and reproduce the point, everywhere in space; equal
to MeanValue on an all-triangle cage. snap_tolerance: relative to the cage diagonal, in
[0, 1e-3]. polygon_planarity: how far (relative to the cage diagonal, in [0, 1e-2]) a vertex of a
face of more than 4 vertices may be from the face's best-fit plane; the default admits
coordinates written in float32 or with 6 decimals (cages of diagonal >= 1). Raises
InvalidInput naming a face farther from planar (quads may be non-planar).)")
      .def(py::init([](std::shared_ptr<Cage> cage, double snapTolerance, double polygonPlanarity) {
             return madeWithoutGil<QuadMeanValueCoordinates>(
                 std::move(cage), QuadMeanValueOptions{snapTolerance, polygonPlanarity});
           }),
           "cage"_a, py::kw_only(), "snap_tolerance"_a = 1e-14,
           "polygon_planarity"_a = kDefaultPlanarity)
      .def_property_readonly(
          "cage", [](const QuadMeanValueCoordinates& c) { return c.cage(); }, "The Cage (a copy).");
  py::class_<QuadGreenCoordinates, Coordinates, std::shared_ptr<QuadGreenCoordinates>>(
      m, "QuadGreen",
      R"(Green coordinates of a cage of triangles and quads (CLI "qgc"; Thiery and Boubekeur
2022): (n, V + T + 4 Q) weights for T triangle and Q quad faces: the vertex columns, then one
normal column per triangle face and four per quad face, in face order (column_names). Raises
InvalidInput naming a face of more than 4 vertices. surface_tolerance: relative to the cage
diagonal, in [0, 1e-3]. Rows sum to 1 over the vertex columns and reproduce the point at rest
to round-off (they are projected onto those constraints); within ~1e-12 of the diagonal of a cage
vertex single weights may still be off by up to ~5e-6.)")
      .def(py::init([](std::shared_ptr<Cage> cage, double surfaceTolerance) {
             return madeWithoutGil<QuadGreenCoordinates>(std::move(cage),
                                                         QuadGreenOptions{surfaceTolerance});
           }),
           "cage"_a, py::kw_only(), "surface_tolerance"_a = 1e-14)
      .def_property_readonly(
          "cage", [](const QuadGreenCoordinates& c) { return c.cage(); }, "The Cage (a copy).");
  py::class_<WachspressCoordinates, Coordinates, std::shared_ptr<WachspressCoordinates>>(
      m, "Wachspress",
      R"(Wachspress coordinates of a convex Cage (CLI "wachspress"; Warren et al. 2007, as CGAL
6.2): (n, V) weights, positive inside. Raises InvalidInput naming a reflex edge for a cage that
is not convex. outside: "raise" (points outside are an InvalidInput) or "nearest" (the
coordinates of the nearest cage point). snap_tolerance: relative to the cage diagonal.
planarity: relative to the cage diagonal, in [0, 1e-2]: how far a corner may be off its face's
best-fit plane (or above a neighbouring face's plane) and count as on it; the default admits
coordinates written in float32 or with 6 decimals (cages of diagonal >= 1).)")
      .def(py::init([](std::shared_ptr<Cage> cage, double snapTolerance, const std::string& outside,
                       double planarity) {
             return madeWithoutGil<WachspressCoordinates>(
                 std::move(cage),
                 WachspressOptions{snapTolerance, convexOutside(outside), planarity});
           }),
           "cage"_a, py::kw_only(), "snap_tolerance"_a = 1e-14, "outside"_a = "raise",
           "planarity"_a = kDefaultPlanarity)
      .def_property_readonly(
          "cage", [](const WachspressCoordinates& c) { return c.cage(); }, "The Cage (a copy).");
  py::class_<DiscreteHarmonicCoordinates, Coordinates,
             std::shared_ptr<DiscreteHarmonicCoordinates>>(
      m, "DiscreteHarmonic",
      R"(Discrete harmonic coordinates of a convex Cage of triangles (CLI "discrete-harmonic"; as
CGAL 6.2): (n, V) weights, which may be negative inside. Raises InvalidInput naming a reflex edge
for a cage that is not convex, and naming the face for a polygon face (or coplanar triangles that
merge into one), where the closed form has poles: use Wachspress for those. outside: "raise" or
"nearest", as Wachspress. snap_tolerance: relative to the cage diagonal. planarity: as
Wachspress.)")
      .def(py::init([](std::shared_ptr<Cage> cage, double snapTolerance, const std::string& outside,
                       double planarity) {
             return madeWithoutGil<DiscreteHarmonicCoordinates>(
                 std::move(cage),
                 DiscreteHarmonicOptions{snapTolerance, convexOutside(outside), planarity});
           }),
           "cage"_a, py::kw_only(), "snap_tolerance"_a = 1e-14, "outside"_a = "raise",
           "planarity"_a = kDefaultPlanarity)
      .def_property_readonly(
          "cage", [](const DiscreteHarmonicCoordinates& c) { return c.cage(); },
          "The Cage (a copy).");
  py::class_<HarmonicCoordinates, Coordinates, std::shared_ptr<HarmonicCoordinates>>(
      m, "Harmonic",
      R"(Harmonic coordinates (Joshi et al. 2007) of a Cage: a Laplace solve on a TetGen mesh of
about `tets` tetrahedra (0: the library's default, about 200k), or at a `precision` level, a
number in [1, 7] (200000 * 4**(p - 5) tets, so 5.5 lies between 5 and 6; 0: none; not with tets). cache: a file of solved coordinates, loaded when it matches the cage and
tets, else solved and saved there. outside: "raise" or "nearest" for points outside the cage.)")
      .def(py::init([](std::shared_ptr<Cage> cage, std::size_t tets, const py::object& precision,
                       const std::optional<std::filesystem::path>& cache,
                       const std::string& outside, const py::object& progress) {
             const CageMethodOptions options{tets, cache.value_or(""), outside,
                                             precisionArgument(precision)};
             return std::dynamic_pointer_cast<HarmonicCoordinates>(
                 byName("harmonic", cage, options, progress));
           }),
           "cage"_a, py::kw_only(), "tets"_a = 0, "precision"_a = 0.0, "cache"_a = py::none(),
           "outside"_a = "raise", "progress"_a = py::none())
      .def_property_readonly(
          "tet_count", [](const HarmonicCoordinates& c) { return c.mesh().tets.size(); },
          "Tetrahedra of the mesh solved on.")
      .def("save",
           py::overload_cast<const std::filesystem::path&>(&HarmonicCoordinates::save, py::const_),
           "path"_a, "Writes the solve to a file (atomically).");
  m.def(
      "cage_coordinates",
      [](const std::string& method, std::shared_ptr<Cage> cage, std::size_t tets,
         const py::object& precision, const std::optional<std::filesystem::path>& cache,
         const std::string& outside, const py::object& progress) {
        return byName(method, std::move(cage),
                      {tets, cache.value_or(""), outside, precisionArgument(precision)}, progress);
      },
      "method"_a, "cage"_a, py::kw_only(), "tets"_a = 0, "precision"_a = 0.0,
      "cache"_a = py::none(), "outside"_a = "raise", "progress"_a = py::none(),
      "The coordinates of a cage method by its CLI name (see cage_methods()). tets, precision "
      "and cache: harmonic's; outside: harmonic's, wachspress's and discrete-harmonic's.");
  m.def("cage_methods", &cageMethods,
        "The cage methods of this build, sorted: \"discrete-harmonic\", \"green\", \"harmonic\" "
        "(with TetGen), \"mvc\", \"qgc\", \"qmvc\", \"wachspress\".");
}

LatticeBasis basisFromName(const std::string& name) {
  if (name == "trilinear") return LatticeBasis::Trilinear;
  if (name == "bernstein") return LatticeBasis::Bernstein;
  if (name == "bspline") return LatticeBasis::BSpline;
  throw InvalidInput("basis must be 'trilinear', 'bernstein' or 'bspline', not '" + name + "'");
}

// The `ends` argument, given explicitly: refused with a basis that has no phantom controls (as
// the rig's "ends" key is).
LatticeEnds endsFromName(const std::string& ends, LatticeBasis basis) {
  if (basis != LatticeBasis::BSpline)
    throw InvalidInput(
        "ends applies to the bspline basis only (the other bases have no phantom "
        "controls)");
  if (ends == "repeat") return LatticeEnds::Repeat;
  if (ends == "extrapolate") return LatticeEnds::Extrapolate;
  throw InvalidInput("ends must be 'extrapolate' or 'repeat', not '" + ends + "'");
}

void bindLattice(py::module_& m) {
  py::class_<LatticeCoordinates, Coordinates, std::shared_ptr<LatticeCoordinates>>(
      m, "Lattice",
      R"(A free-form deformation lattice (Sederberg and Parry 1986): a box at `origin` along
`axes` (3 unit vectors) with `extents` (world units), resolution (l, m, n) control points,
basis "trilinear", "bernstein" or "bspline"; ends of the bspline basis: "extrapolate" (linear
phantom controls, the default) or "repeat" (the end control repeated, Blender's lattice); given
with another basis it is an error, as the rig's key; points
outside: "identity", "clamp" or "falloff" (over falloff x the box diagonal). Control point
(i, j, k) is index i + l (j + m k).)")
      .def(py::init([](py::handle origin, py::handle axes, py::handle extents,
                       std::array<int, 3> resolution, const std::string& basis,
                       const std::string& outside, double falloff,
                       const std::optional<std::string>& ends) {
             LatticeOptions o;
             o.origin = toVec3(origin, "origin");
             const Points a = toPoints(axes, "axes", false);
             if (a.size() != 3) throw InvalidInput("axes must have shape (3, 3)");
             std::copy(a.span.begin(), a.span.end(), o.axes.begin());
             o.extents = toVec3(extents, "extents");
             o.resolution = resolution;
             o.basis = basisFromName(basis);
             if (ends) o.ends = endsFromName(*ends, o.basis);
             if (outside == "identity")
               o.outside = LatticeOutside::Identity;
             else if (outside == "clamp")
               o.outside = LatticeOutside::Clamp;
             else if (outside == "falloff")
               o.outside = LatticeOutside::Falloff;
             else
               throw InvalidInput("outside must be 'identity', 'clamp' or 'falloff', not '" +
                                  outside + "'");
             o.falloff = falloff;
             return std::make_shared<LatticeCoordinates>(Lattice(o));
           }),
           py::kw_only(), "origin"_a = py::make_tuple(0, 0, 0),
           "axes"_a = py::make_tuple(py::make_tuple(1, 0, 0), py::make_tuple(0, 1, 0),
                                     py::make_tuple(0, 0, 1)),
           "extents"_a = py::make_tuple(1, 1, 1), "resolution"_a = std::array<int, 3>{2, 2, 2},
           "basis"_a = "trilinear", "outside"_a = "identity", "falloff"_a = 0.1,
           "ends"_a = py::none())
      .def_static(
          "around",
          [](py::handle points, double padding, std::array<int, 3> resolution,
             const std::string& basis, const std::optional<std::string>& ends) {
            const Points p = toPoints(points, "points", false);
            const Lattice fitted = fitLattice(p.span, padding, resolution, basisFromName(basis));
            if (!ends) return std::make_shared<LatticeCoordinates>(fitted);
            LatticeOptions o = fitted.params();
            o.ends = endsFromName(*ends, o.basis);
            return std::make_shared<LatticeCoordinates>(Lattice(o));
          },
          "points"_a, py::kw_only(), "padding"_a = 0.05,
          "resolution"_a = std::array<int, 3>{4, 4, 4}, "basis"_a = "trilinear",
          "ends"_a = py::none(),
          "An axis-aligned lattice around `points` (n, 3), padded by `padding` x the box "
          "diagonal; `ends` as for the constructor.")
      .def(
          "fit",
          [](const LatticeCoordinates& c, py::handle from, py::handle to, double smoothness,
             const py::object& progress) {
            const Points f = toPoints(from, "from", false);
            const Points t = toPoints(to, "to", false);
            ControlPointFit fit;
            runCancellable(progress, [&](const ProgressCallback& callback) {
              fit = fitControlPoints(c.lattice(), f.span, t.span, {smoothness, callback});
            });
            return py::make_tuple(copyPoints(fit.controlPoints), fit.rmsResidual, fit.maxResidual);
          },
          "from_points"_a, "to_points"_a, py::kw_only(), "smoothness"_a = 1e-4,
          "progress"_a = py::none(),
          R"(Direct manipulation (Hsu et al. 1992): the posed control points (V, 3) that carry
`from_points` (k, 3) to `to_points` (k, 3) in least squares with a smoothness regulariser.
Returns (posed, rms_residual, max_residual), world units.)")
      .def_property_readonly(
          "resolution", [](const LatticeCoordinates& c) { return c.lattice().resolution(); },
          "Control points per axis (l, m, n).");
}

void bindHandleCoordinates(py::module_& m) {
  py::class_<RbfCoordinates, Coordinates, std::shared_ptr<RbfCoordinates>>(
      m, "Rbf",
      R"(RBF handle coordinates (Botsch and Kobbelt 2005, the fit folded in): handles `centers`
(k, 3), `fixed` (f, 3) held in place; kernel and options as RbfWarp. warp(posed) is the RbfWarp
that moves the centers to `posed`.)")
      .def(py::init([](py::handle centers, const std::optional<py::handle>& fixed,
                       const std::string& kernel, double scale, double radius, double smoothing,
                       const py::object& progress) {
             const Points c = toPoints(centers, "centers", false);
             std::optional<Points> f;
             if (fixed && !fixed->is_none()) f = toPoints(*fixed, "fixed", false);
             std::shared_ptr<RbfCoordinates> result;
             runCancellable(progress, [&](const ProgressCallback& callback) {
               const RbfOptions options = rbfOptions(kernel, scale, radius, smoothing, callback);
               result = std::make_shared<RbfCoordinates>(
                   c.span, f ? f->span : std::span<const Vec3>{}, options);
             });
             return result;
           }),
           "centers"_a, "fixed"_a = py::none(), py::kw_only(), "kernel"_a = "triharmonic",
           "scale"_a = 1.0, "radius"_a = 1.0, "smoothing"_a = 0.0, "progress"_a = py::none());
  py::class_<MlsAffineCoordinates, Coordinates, std::shared_ptr<MlsAffineCoordinates>>(
      m, "MlsAffine", "The coordinates of affine moving least squares over `handles` (k, 3).")
      .def(py::init([](py::handle handles, double alpha) {
             const Points h = toPoints(handles, "handles", false);
             return std::make_shared<MlsAffineCoordinates>(
                 std::vector<Vec3>(h.span.begin(), h.span.end()), alpha);
           }),
           "handles"_a, py::kw_only(), "alpha"_a = 1.0);
}

py::dict reportDict(const PropertyReport& r) {
  return py::dict("sample_count"_a = r.sampleCount, "partition_of_unity"_a = r.partitionOfUnity,
                  "linear_reproduction"_a = r.linearReproduction, "min_weight"_a = r.minWeight,
                  "negative_fraction"_a = r.negativeFraction,
                  "samples_with_negative"_a = r.samplesWithNegative, "lagrange"_a = r.lagrange,
                  "face_interpolation"_a = r.faceInterpolation,
                  "similarity_reproduction"_a = r.similarityReproduction);
}

void bindProperties(py::module_& m) {
  m.def(
      "coordinate_properties",
      [](const Coordinates& c, py::handle samples, std::shared_ptr<Cage> cage,
         std::optional<double> diagonal) {
        const Points s = toPoints(samples, "samples", false);
        if (!cage && !diagonal)
          throw InvalidInput(
              "coordinate_properties needs the cage, or the diagonal that lengths are relative to");
        PropertyReport report;
        withoutGil([&] {
          report =
              cage ? measureProperties(c, *cage, s.span) : measureProperties(c, s.span, *diagonal);
        });
        return reportDict(report);
      },
      "coordinates"_a, "samples"_a, py::kw_only(), "cage"_a = nullptr, "diagonal"_a = py::none(),
      R"(The C++ property kit (the figures of `spacewarp compare`) for spacewarp Coordinates at
`samples` (n, 3): a dict of partition_of_unity, linear_reproduction (relative to the cage
diagonal), min_weight, negative_fraction, samples_with_negative, lagrange, face_interpolation,
similarity_reproduction (NaN where a check needs the cage). For any weight matrix, see
spacewarp.testing.)");
  m.def(
      "interior_samples",
      [](const Cage& cage, std::size_t count, std::uint64_t seed) {
        std::vector<Vec3> samples;
        withoutGil([&] { samples = interiorSamples(cage, count, seed); });
        return copyPoints(samples);
      },
      "cage"_a, "count"_a, py::kw_only(), "seed"_a = 1,
      "`count` points (count, 3) uniformly inside the cage, deterministic for a seed.");
}

}  // namespace

void bindCoordinates(py::module_& m) {
  bindCage(m);
  bindBinding(m);
  bindCoordinatesBase(m);
  bindCageCoordinates(m);
  bindLattice(m);
  bindHandleCoordinates(m);
  bindProperties(m);
}

}  // namespace spacewarp::python
