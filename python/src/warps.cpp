// Warp and its implementations, rigs, and the inverse.

#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>

#include <algorithm>
#include <atomic>
#include <limits>
#include <mutex>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <spacewarp/core/bend.h>
#include <spacewarp/core/combinators.h>
#include <spacewarp/core/errors.h>
#include <spacewarp/core/inverse.h>
#include <spacewarp/core/taper.h>
#include <spacewarp/core/twist.h>
#include <spacewarp/core/warp.h>
#include <spacewarp/nonlinear/deformation_graph.h>
#include <spacewarp/nonlinear/mls.h>
#include <spacewarp/rbf/rbf_warp.h>
#include <spacewarp/rig/rig.h>

#include "common.h"
#include "rbf_options.h"

namespace spacewarp::python {
namespace {

using namespace pybind11::literals;
using WarpPtr = std::shared_ptr<Warp>;
constexpr double kInf = std::numeric_limits<double>::infinity();

/// A library warp as Python holds it (pybind11 holders are not const).
WarpPtr held(std::shared_ptr<const Warp> warp) {
  return std::const_pointer_cast<Warp>(std::move(warp));
}

/// Whether two spans share memory without being the same span.
bool overlapsOtherwise(std::span<const Vec3> a, std::span<const Vec3> b) {
  if (a.data() == b.data() || a.empty() || b.empty()) return false;
  const auto lo = [](std::span<const Vec3> s) {
    return reinterpret_cast<std::uintptr_t>(s.data());
  };
  const auto hi = [&](std::span<const Vec3> s) { return lo(s) + s.size_bytes(); };
  return lo(a) < hi(b) && lo(b) < hi(a);
}

DoubleArray applyWarp(const Warp& warp, py::handle points, const std::optional<py::array>& out,
                      const py::object& progress) {
  Points in = toPoints(points);
  DoubleArray result = outputPoints(in.size(), out, in.single);
  const std::span<Vec3> moved = pointsOf(result);
  if (overlapsOtherwise(in.span, moved)) {
    // `out` overlaps `points` but is not `points` itself: blocks would read what earlier blocks
    // wrote, so the input is read from a copy (out=points exactly is done in place).
    in.array = copyPoints(in.span);
    in.span = {reinterpret_cast<const Vec3*>(in.array.data()), in.span.size()};
  }
  // Blocks of 2^16 points, each warped and checked while in cache (a NaN input, or a warp that
  // overflows, is an error as in deform()); the blocks run in parallel, so that a busy core
  // delays no other, and each one reports (a Ctrl-C or a progress callable can stop the work).
  constexpr std::size_t kBlock = std::size_t{1} << 16;
  const std::size_t blocks = (in.size() + kBlock - 1) / kBlock;
  std::atomic<std::size_t> firstBad{in.size()};
  runCancellable(progress, [&](const ProgressCallback& callback) {
    ProgressTracker tracker(callback, "warp", in.size());
    tbb::parallel_for(
        tbb::blocked_range<std::size_t>(0, blocks, 1),
        [&](const tbb::blocked_range<std::size_t>& r) {
          for (std::size_t b = r.begin(); b != r.end(); ++b) {
            const std::size_t begin = b * kBlock, count = std::min(kBlock, in.size() - begin);
            const auto block = moved.subspan(begin, count);
            warp.applyBatch(in.span, moved, begin, begin + count);
            if (const std::size_t bad = firstNonFinite(block); bad < count) {
              std::size_t seen = firstBad.load();
              while (begin + bad < seen && !firstBad.compare_exchange_weak(seen, begin + bad)) {
              }
            }
            tracker.advance(count);
          }
        });
    tracker.finish();
  });
  if (const std::size_t i = firstBad.load(); i < in.size()) {
    const std::string point = "point " + std::to_string(i);
    if (in.span.data() == moved.data())  // in place: the input is gone
      throw InvalidInput(point + ": the warped position is not finite");
    throw InvalidInput(isFinite(in.span[i]) ? "the warp sent " + point + " to a non-finite position"
                                            : point + " is not finite");
  }
  return result;
}

DoubleArray jacobians(const Warp& warp, py::handle points) {
  const Points in = toPoints(points);
  requireFinite(in.span);
  std::vector<py::ssize_t> shape{static_cast<py::ssize_t>(in.size()), 3, 3};
  if (in.single) shape.erase(shape.begin());
  DoubleArray result(shape);
  double* out = result.mutable_data();
  forEachPointCancellable(in.size(), "jacobian", [&](std::size_t i) {
    const Mat3 j = warp.jacobian(in.span[i]);
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) out[9 * i + 3 * r + c] = j[c][r];
  });
  return result;
}

DoubleArray normals(const Warp& warp, py::handle points, py::handle normalsIn) {
  const Points in = toPoints(points);
  const Points n = toPoints(normalsIn, "normals");
  requireFinite(in.span);
  requireFinite(n.span, "normals");
  if (n.size() != in.size() || n.single != in.single) {
    throw InvalidInput("normals must have the shape of points (" + std::to_string(in.size()) +
                       " points, " + std::to_string(n.size()) + " normals)");
  }
  DoubleArray result = outputPoints(in.size(), std::nullopt, in.single);
  const std::span<Vec3> out = pointsOf(result);
  forEachPointCancellable(in.size(), "transform normals", [&](std::size_t i) {
    out[i] = transformNormal(warp, in.span[i], n.span[i]);
  });
  return result;
}

py::tuple inverseOf(const Warp& warp, py::handle points, double tolerance, int maxIterations,
                    double lengthScale, bool continuation, bool closedForm,
                    const py::object& progress) {
  const Points in = toPoints(points);
  if (maxIterations < 0)
    throw InvalidInput("max_iterations must be >= 0, not " + std::to_string(maxIterations));
  if (!(tolerance >= 0.0 && std::isfinite(tolerance)))
    throw InvalidInput("tolerance must be finite and >= 0, not " + std::to_string(tolerance));
  if (!(lengthScale >= 0.0 && std::isfinite(lengthScale)))
    throw InvalidInput("length_scale must be finite and >= 0, not " + std::to_string(lengthScale));
  const InverseOptions options{.maxIterations = maxIterations,
                               .tolerance = tolerance,
                               .lengthScale = lengthScale,
                               .continuation = continuation,
                               .closedForm = closedForm};
  std::vector<InverseResult> results(in.size());
  runCancellable(progress, [&](const ProgressCallback& callback) {
    inverseBatch(warp, in.span, results, options, callback);
  });
  DoubleArray x = outputPoints(in.size(), std::nullopt, in.single);
  py::array_t<bool> converged(static_cast<py::ssize_t>(in.size()));
  py::array_t<double> residual(static_cast<py::ssize_t>(in.size()));
  const std::span<Vec3> xs = pointsOf(x);
  for (std::size_t i = 0; i < results.size(); ++i) {
    xs[i] = results[i].x;
    converged.mutable_at(i) = results[i].converged;
    residual.mutable_at(i) = results[i].residual;
  }
  if (in.single) return py::make_tuple(x, py::bool_(results[0].converged), results[0].residual);
  return py::make_tuple(x, converged, residual);
}

void bindWarpBase(py::module_& m) {
  py::class_<Warp, WarpPtr>(m, "Warp", R"(A map x -> x' of 3D space (world units).

Every warp in spacewarp is one: call it on points, ask for its Jacobian, invert it, carry normals.
Methods release the GIL and are safe to call from several threads at once.)")
      .def(
          "__call__",
          [](py::handle self, py::handle points, const std::optional<py::array>& out,
             const py::object& progress) {
            return applyWarp(initialised<Warp>(self), points, out, progress);
          },
          "points"_a, py::kw_only(), "out"_a = py::none(), "progress"_a = py::none(),
          R"(The warped positions of `points`: (n, 3) float64 (or one (3,) point), world units.

points: (n, 3) array-like, any float dtype and layout (copied only if not float64 C-order).
out: optional (n, 3) float64 C-contiguous array to write into (may be `points` itself).
progress: optional callable(stage: str, fraction: float); return False to cancel.
Returns a new (n, 3) array, or `out`. Raises InvalidInput for non-finite points or points
outside the warp's domain (naming the first); `out`, if given, may then be partly written.)")
      .def(
          "jacobian",
          [](py::handle self, py::handle points) {
            return jacobians(initialised<Warp>(self), points);
          },
          "points"_a,
          R"(The Jacobians d x'/d x at `points`: (n, 3, 3) float64, J[i, r, c] = d x'_r / d x_c
(unitless). Analytic where the warp has one, central differences otherwise.)")
      .def("transform_normals", &normals, "points"_a, "normals"_a,
           R"(The normals `normals` (n, 3) at `points` (n, 3) carried through the warp: J^-T n,
normalised; (n, 3) float64. Where J is singular: the image plane's normal (rank 2) or zero.)")
      .def("inverse", &inverseOf, "points"_a, py::kw_only(), "tolerance"_a = 1e-12,
           "max_iterations"_a = 50, "length_scale"_a = 0.0, "continuation"_a = true,
           "closed_form"_a = true, "progress"_a = py::none(),
           R"(The preimages x of `points` y (n, 3): warp(x) = y.

Returns (x, converged, residual): x (n, 3) float64 world units, converged (n,) bool, residual
(n,) float64 = |warp(x) - y| in world units. Converged when the residual is at most
tolerance * length_scale (world units) if length_scale > 0, else tolerance relative to |y|.
Closed forms where the warp has one (twist, bend, taper, affine and their compositions), else
damped Newton with a continuation fallback (max_iterations each). Never raises for points that
did not converge: check `converged`. Parallel; results do not depend on the thread count.)")
      .def(
          "exact_inverse",
          [](const Warp& w, py::handle y) -> py::object {
            const Vec3 point = toVec3(y, "point");
            requireFinite(std::span<const Vec3>(&point, 1), "point");
            const std::optional<Vec3> x = w.exactInverse(point);
            if (!x) return py::none();
            return copyPoints(std::span<const Vec3>(&*x, 1)).attr("reshape")(3);
          },
          "point"_a,
          "The closed-form preimage of one point (3,), or None when the warp has none there.");
}

void bindAnalyticWarps(py::module_& m) {
  py::class_<IdentityWarp, Warp, std::shared_ptr<IdentityWarp>>(m, "Identity", "x' = x.")
      .def(py::init<>());

  py::class_<TwistWarp, Warp, std::shared_ptr<TwistWarp>>(
      m, "Twist",
      R"(Rotation about an axis by an angle proportional to the position along it: rate radians
per world unit, s (the position along the axis from origin) clamped to [lo, hi].)")
      .def(py::init([](py::handle origin, py::handle axis, double rate, double lo, double hi) {
             return std::make_shared<TwistWarp>(
                 TwistOptions{toVec3(origin, "origin"), toVec3(axis, "axis"), rate, lo, hi});
           }),
           py::kw_only(), "origin"_a = py::make_tuple(0, 0, 0), "axis"_a = py::make_tuple(0, 0, 1),
           "rate"_a = 0.0, "lo"_a = -kInf, "hi"_a = kInf);

  py::class_<BendWarp, Warp, std::shared_ptr<BendWarp>>(
      m, "Bend",
      R"(Bends the axis (through origin) into a circular arc towards `direction`: curvature
`rate` (1 / world units), the bent part limited to lo <= y <= hi along the axis.)")
      .def(py::init([](py::handle origin, py::handle axis, py::handle direction, double rate,
                       double lo, double hi) {
             return std::make_shared<BendWarp>(
                 BendOptions{toVec3(origin, "origin"), toVec3(axis, "axis"),
                             toVec3(direction, "direction"), rate, lo, hi});
           }),
           py::kw_only(), "origin"_a = py::make_tuple(0, 0, 0), "axis"_a = py::make_tuple(0, 0, 1),
           "direction"_a = py::make_tuple(1, 0, 0), "rate"_a = 0.0, "lo"_a = -kInf, "hi"_a = kInf);

  py::class_<TaperWarp, Warp, std::shared_ptr<TaperWarp>>(
      m, "Taper",
      R"(Scales the cross-sections of an axis by 1 + rate * s (s along the axis from origin,
clamped to [lo, hi]; rate in 1 / world units).)")
      .def(py::init([](py::handle origin, py::handle axis, double rate, double lo, double hi) {
             return std::make_shared<TaperWarp>(
                 TaperOptions{toVec3(origin, "origin"), toVec3(axis, "axis"), rate, lo, hi});
           }),
           py::kw_only(), "origin"_a = py::make_tuple(0, 0, 0), "axis"_a = py::make_tuple(0, 0, 1),
           "rate"_a = 0.0, "lo"_a = -kInf, "hi"_a = kInf);

  py::class_<AffineWarp, Warp, std::shared_ptr<AffineWarp>>(
      m, "Affine",
      "x' = A x + t, from a (4, 4) homogeneous matrix (last row 0 0 0 1), a (3, 4) [A | t] or a "
      "(3, 3) A.")
      .def(py::init([](py::handle matrix) {
             const DoubleArray a = DoubleArray::ensure(matrix);
             if (!a || a.ndim() != 2 || a.shape(1) < 3 || a.shape(0) < 3 || a.shape(0) > 4 ||
                 a.shape(1) > 4 || (a.shape(0) == 4 && a.shape(1) != 4)) {
               PyErr_Clear();
               throw InvalidInput("matrix must have shape (4, 4), (3, 4) or (3, 3)");
             }
             Mat4 mat(1.0);
             for (py::ssize_t r = 0; r < a.shape(0); ++r)
               for (py::ssize_t c = 0; c < a.shape(1); ++c) mat[c][r] = a.at(r, c);
             return std::make_shared<AffineWarp>(mat);
           }),
           "matrix"_a)
      .def_property_readonly(
          "matrix",
          [](const AffineWarp& w) {
            DoubleArray a(std::vector<py::ssize_t>{4, 4});
            for (int r = 0; r < 4; ++r)
              for (int c = 0; c < 4; ++c)
                a.mutable_at(r, c) = r == 3 ? (c == 3 ? 1.0 : 0.0)
                                            : (c == 3 ? w.translation()[r] : w.linear()[c][r]);
            return a;
          },
          "The (4, 4) homogeneous matrix.");

  py::class_<ComposedWarp, Warp, std::shared_ptr<ComposedWarp>>(
      m, "Compose", "The warps applied one after the other: Compose(a, b)(x) = b(a(x)).")
      .def(py::init([](const py::args& warps) {
        if (warps.size() < 1) throw InvalidInput("Compose needs at least one warp");
        std::vector<WarpPtr> stages;
        for (std::size_t i = 0; i < warps.size(); ++i) {
          if (!py::isinstance<Warp>(warps[i]))
            throw py::type_error("Compose: argument " + std::to_string(i) + " is a " +
                                 std::string(py::str(py::type::of(warps[i]).attr("__name__"))) +
                                 ", not a spacewarp.Warp");
          stages.push_back(warps[i].cast<WarpPtr>());
        }
        // One stage is composed with the identity (a Compose always has two or more).
        if (stages.size() == 1) stages.push_back(std::make_shared<IdentityWarp>());
        return std::make_shared<ComposedWarp>(
            std::vector<std::shared_ptr<const Warp>>(stages.begin(), stages.end()));
      }));
}

std::vector<Vec3> vectorOf(py::handle points, const char* name) {
  const Points p = toPoints(points, name, false);
  return {p.span.begin(), p.span.end()};
}

/// A deformation graph and the lock that serialises its solves (solve() changes it).
struct Graph {
  DeformationGraph graph;
  std::mutex mutex;
};

void bindNonlinearWarps(py::module_& m) {
  py::class_<MlsWarp, Warp, std::shared_ptr<MlsWarp>>(
      m, "Mls",
      R"(Moving least squares (Schaefer et al. 2006): handles (k, 3) move to targets (k, 3);
each point gets the affine, similarity or rigid map that best fits the handles weighted by
1 / |p - x|^(2 alpha). mode: "affine", "similarity" or "rigid" (default). distances: a
HandleDistances built for the same handles (e.g. InsideDistances, distances measured inside a
model), used instead of |p - x|; None (default): Euclidean.)")
      .def(py::init([](py::handle handles, py::handle targets, const std::string& mode,
                       double alpha, std::shared_ptr<HandleDistances> distances) {
             MlsOptions options;
             options.mode = mlsModeFromName(mode);
             options.alpha = alpha;
             options.distances = std::move(distances);
             return std::make_shared<MlsWarp>(vectorOf(handles, "handles"),
                                              vectorOf(targets, "targets"), options);
           }),
           "handles"_a, "targets"_a, py::kw_only(), "mode"_a = "rigid", "alpha"_a = 1.0,
           "distances"_a = py::none());

  py::class_<DeformationGraphWarp, Warp, std::shared_ptr<DeformationGraphWarp>>(
      m, "DeformationGraphWarp", "A posed deformation graph (DeformationGraph.warp()).");
  py::class_<DeformationGraphReport>(m, "GraphSolveReport", "What DeformationGraph.solve() found.")
      .def_readonly("energies", &DeformationGraphReport::energies,
                    "Energy after each accepted step.")
      .def_readonly("iterations", &DeformationGraphReport::iterations,
                    "Accepted Gauss-Newton steps.")
      .def_readonly("converged", &DeformationGraphReport::converged,
                    "Whether the energy stopped changing within the tolerance.")
      .def_readonly("rotation_energy", &DeformationGraphReport::rotationEnergy,
                    "E_rot at the end (unitless).")
      .def_readonly("regularization_energy", &DeformationGraphReport::regularizationEnergy,
                    "E_reg at the end, in units of the nodes' largest extent squared.")
      .def_readonly("constraint_energy", &DeformationGraphReport::constraintEnergy,
                    "E_con at the end, in units of the nodes' largest extent squared.")
      .def_readonly("component_count", &DeformationGraphReport::componentCount,
                    "Connected parts of the graph.")
      .def_readonly("unconstrained_nodes", &DeformationGraphReport::unconstrainedNodes,
                    "Nodes of parts of the graph that no handle reaches.");

  py::class_<Graph, std::shared_ptr<Graph>>(
      m, "DeformationGraph",
      R"(The embedded deformation graph (Sumner et al. 2007) over `positions` (n, 3): nodes
sampled every `spacing` world units (sampling "voxel" or "poisson"), or given as `nodes` (m, 3);
each point follows its k nearest nodes. solve() poses it; warp() is the posed Warp.)")
      .def(py::init([](py::handle positions, double spacing, int k, const std::string& sampling,
                       const std::optional<py::handle>& nodes) {
             const Points p = toPoints(positions, "positions", false);
             NodeSampling s = NodeSampling::Voxel;
             if (sampling == "poisson")
               s = NodeSampling::PoissonDisk;
             else if (sampling != "voxel")
               throw InvalidInput("sampling must be 'voxel' or 'poisson', not '" + sampling + "'");
             const DeformationGraphOptions options{spacing, k, s};
             std::optional<Points> n;
             if (nodes && !nodes->is_none()) n = toPoints(*nodes, "nodes", false);
             std::shared_ptr<Graph> graph;
             withoutGil([&] {
               graph = std::make_shared<Graph>(n ? DeformationGraph(n->span, p.span, options)
                                                 : DeformationGraph(p.span, options));
             });
             return graph;
           }),
           "positions"_a, py::kw_only(), "spacing"_a = 0.0, "k"_a = 4, "sampling"_a = "voxel",
           "nodes"_a = py::none())
      .def_property_readonly(
          "nodes", [](Graph& g) { return copyPoints(g.graph.nodes()); },
          "The node positions (m, 3), world units.")
      .def_property_readonly(
          "k", [](Graph& g) { return g.graph.k(); }, "Nodes that influence each point.")
      .def_property_readonly(
          "edges",
          [](Graph& g) {
            const auto& edges = g.graph.edges();
            py::array_t<std::uint32_t> a(
                std::vector<py::ssize_t>{static_cast<py::ssize_t>(edges.size()), 2});
            for (std::size_t i = 0; i < edges.size(); ++i) {
              a.mutable_at(i, 0) = edges[i].first;
              a.mutable_at(i, 1) = edges[i].second;
            }
            return a;
          },
          "The graph's edges (e, 2), node indices.")
      .def(
          "solve",
          [](Graph& g, py::handle handles, py::handle targets, double rotationWeight,
             double regularizationWeight, double constraintWeight, int maxIterations,
             double tolerance, const py::object& progress) {
            const Points h = toPoints(handles, "handles", false);
            const Points t = toPoints(targets, "targets", false);
            DeformationGraphReport report;
            runCancellable(progress, [&](const ProgressCallback& callback) {
              const std::lock_guard lock(g.mutex);
              report = g.graph.solve(h.span, t.span,
                                     {rotationWeight, regularizationWeight, constraintWeight,
                                      maxIterations, tolerance, callback});
            });
            return report;
          },
          "handles"_a, "targets"_a, py::kw_only(), "rotation_weight"_a = 1.0,
          "regularization_weight"_a = 10.0, "constraint_weight"_a = 100.0, "max_iterations"_a = 50,
          "tolerance"_a = 1e-6, "progress"_a = py::none(),
          R"(Poses the graph so that the points `handles` (k, 3) reach `targets` (k, 3), world
units (Gauss-Newton on the paper's energy; weights as in the paper). Returns a GraphSolveReport;
check `converged`.)")
      .def(
          "reset",
          [](Graph& g) {
            // A solve holds the lock while its progress callable needs the GIL: lock without it.
            withoutGil([&] {
              const std::lock_guard lock(g.mutex);
              g.graph.reset();
            });
          },
          "Back to the rest pose.")
      .def(
          "warp",
          [](Graph& g) {
            std::shared_ptr<DeformationGraphWarp> warp;
            withoutGil([&] {
              const std::lock_guard lock(g.mutex);
              warp = std::make_shared<DeformationGraphWarp>(g.graph.warp());
            });
            return warp;
          },
          "The graph's current pose as a Warp (a snapshot: later solves do not change it).");
}

void bindRbfWarp(py::module_& m) {
  py::class_<RbfWarp, Warp, std::shared_ptr<RbfWarp>>(
      m, "RbfWarp",
      R"(A radial-basis displacement field (Botsch and Kobbelt 2005) that moves `centers` (k, 3)
to `targets` (k, 3) and keeps `fixed` (f, 3) in place, plus a linear polynomial. kernel:
"triharmonic" (r^3, default), "biharmonic", "thin-plate", "gaussian", "inverse-multiquadric",
"wendland"; scale (world units) for gaussian/inverse multiquadric; radius (world units) for
Wendland; smoothing >= 0 turns interpolation into approximation.)")
      .def(py::init([](py::handle centers, py::handle targets,
                       const std::optional<py::handle>& fixed, const std::string& kernel,
                       double scale, double radius, double smoothing, const py::object& progress) {
             const Points c = toPoints(centers, "centers", false);
             const Points t = toPoints(targets, "targets", false);
             std::optional<Points> f;
             if (fixed && !fixed->is_none()) f = toPoints(*fixed, "fixed", false);
             std::shared_ptr<RbfWarp> warp;
             runCancellable(progress, [&](const ProgressCallback& callback) {
               const RbfOptions options = rbfOptions(kernel, scale, radius, smoothing, callback);
               warp = std::make_shared<RbfWarp>(c.span, t.span,
                                                f ? f->span : std::span<const Vec3>{}, options);
             });
             return warp;
           }),
           "centers"_a, "targets"_a, "fixed"_a = py::none(), py::kw_only(),
           "kernel"_a = "triharmonic", "scale"_a = 1.0, "radius"_a = 1.0, "smoothing"_a = 0.0,
           "progress"_a = py::none());
}

void bindRigs(py::module_& m) {
  m.def(
      "load_rig",
      [](const std::filesystem::path& path, const py::object& progress) {
        Rig rig;
        runCancellable(progress,
                       [&](const ProgressCallback& callback) { rig = loadRig(path, callback); });
        warnAll(rig.warnings);
        return held(rig.warp);
      },
      "path"_a, py::kw_only(), "progress"_a = py::none(),
      R"(The Warp a rig file (JSON, as `spacewarp deform --rig`) describes; the same warp the
CLI builds. Paths inside the rig are relative to its folder. Warnings (a graph solve that did
not converge) are Python warnings. Raises InvalidInput naming the key at fault, IoError.)");
  m.def(
      "rig",
      [](const py::dict& description, const std::optional<std::filesystem::path>& baseDir,
         const py::object& progress) {
        const std::string text =
            py::module_::import("json").attr("dumps")(description).cast<std::string>();
        Rig rig;
        runCancellable(progress, [&](const ProgressCallback& callback) {
          rig = rigFromJson(parseRigJson(text, "rig"), baseDir.value_or("."), "rig", callback);
        });
        warnAll(rig.warnings);
        return held(rig.warp);
      },
      "description"_a, py::kw_only(), "base_dir"_a = py::none(), "progress"_a = py::none(),
      R"(The Warp a rig given as a dict (the JSON of a rig file) describes; relative paths in it
are resolved against base_dir (default: the current folder).)");
  m.def("rig_methods", &rigMethods, "The rig methods (\"twist\", \"mvc\", ...) this build knows.");
}

}  // namespace

void bindWarps(py::module_& m) {
  bindWarpBase(m);
  bindAnalyticWarps(m);
  bindNonlinearWarps(m);
  bindRbfWarp(m);
  bindRigs(m);
}

}  // namespace spacewarp::python
