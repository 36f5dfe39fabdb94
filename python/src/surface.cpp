// Surface editing (surface/): meshes welded from soups, the cotangent Laplacian and mass, handle
// regions, the Laplacian/bi-Laplacian, ARAP and cage-subspace ARAP editors, and edit().

#include <pybind11/stl.h>

#include <algorithm>
#include <cstdio>
#include <mutex>
#include <optional>

#include <spacewarp/core/coordinates.h>
#include <spacewarp/core/errors.h>
#include <spacewarp/core/geometry.h>
#include <spacewarp/rig/handles_file.h>
#include <spacewarp/surface/arap.h>
#include <spacewarp/surface/cage_arap.h>
#include <spacewarp/surface/cotan_laplacian.h>
#include <spacewarp/surface/edit_mesh.h>
#include <spacewarp/surface/handles.h>
#include <spacewarp/surface/laplacian_editing.h>
#include <spacewarp/surface/surface_mesh.h>

#include "common.h"

namespace spacewarp::python {
namespace {

using namespace pybind11::literals;
using GeometryPtr = std::shared_ptr<PolygonSoup>;
using CoordinatesPtr = std::shared_ptr<Coordinates>;

/// An editor and the lock that serialises its calls: the editors are not thread-safe (their
/// factor's workspace) and run with the GIL released. The lock is taken without the GIL, as the
/// deformation graph's is (a solve's progress callable takes the GIL while holding it).
template <class Editor>
struct Locked {
  explicit Locked(Editor e) : editor(std::move(e)) {}
  Editor editor;
  std::mutex mutex;
};

template <class T>
py::array_t<T> indexArray(std::span<const T> values) {
  return py::array_t<T>(static_cast<py::ssize_t>(values.size()), values.data());
}

/// (n, 3) views of the point vectors of results and meshes, kept alive by `owner`.
py::array_t<double> pointsView(const std::vector<Vec3>& points, py::handle owner) {
  return readOnlyView(points.empty() ? nullptr : &points[0].x,
                      {static_cast<py::ssize_t>(points.size()), 3}, owner);
}

template <class T>
py::array_t<T> vectorView(const std::vector<T>& values, py::handle owner) {
  return readOnlyView(values.data(), {static_cast<py::ssize_t>(values.size())}, owner);
}

/// A mesh given as positions (n, 3) and triangles (t, 3) (named so in errors).
struct MeshInput {
  Points positions;
  std::vector<std::array<std::uint32_t, 3>> triangles;
};

MeshInput toMesh(py::handle positions, py::handle triangles) {
  MeshInput mesh{toPoints(positions, "positions", false), {}};
  mesh.triangles = toTriangles(triangles, mesh.positions.size());
  return mesh;
}

// ---------------------------------------------------------------------------------------------
// Meshes

void bindMesh(py::module_& m) {
  py::class_<MeshReport>(m, "MeshReport",
                         R"(What weld_soup() found about a surface (mesh vertex and triangle
indices; polygon indices of the soup). Arrays are read-only views.)")
      .def_readonly("boundary_edges", &MeshReport::boundaryEdges,
                    "Edges with one triangle (holes, open sheets: fine for every method).")
      .def_property_readonly(
          "non_manifold_edges",
          [](py::object self) {
            const auto& edges = self.cast<const MeshReport&>().nonManifoldEdges;
            return readOnlyView(edges.empty() ? nullptr : edges[0].data(),
                                {static_cast<py::ssize_t>(edges.size()), 2}, self);
          },
          "(k, 2) uint32: edges shared by more than two triangles, smaller vertex first.")
      .def_property_readonly(
          "non_manifold_vertices",
          [](py::object self) {
            return vectorView(self.cast<const MeshReport&>().nonManifoldVertices, self);
          },
          "(k,) uint32: vertices whose triangles do not form one fan.")
      .def_property_readonly(
          "dropped_polygons",
          [](py::object self) {
            return vectorView(self.cast<const MeshReport&>().droppedPolygons, self);
          },
          "(k,) uint32: soup polygons that welding collapsed (not in the mesh).")
      .def_property_readonly(
          "degenerate_triangles",
          [](py::object self) {
            return vectorView(self.cast<const MeshReport&>().degenerateTriangles, self);
          },
          "(k,) uint32: mesh triangles without area (collinear corners): in the mesh, but in no "
          "energy.")
      .def_property_readonly(
          "isolated_vertices",
          [](py::object self) {
            return vectorView(self.cast<const MeshReport&>().isolatedVertices, self);
          },
          "(k,) uint32: mesh vertices no triangle uses.")
      .def_readonly("component_count", &MeshReport::componentCount,
                    "Connected components of the triangles (isolated vertices not counted).")
      .def_property_readonly("is_manifold", &MeshReport::isManifold,
                             "Whether every edge has at most two triangles and every vertex one "
                             "fan.")
      .def("__repr__", [](const MeshReport& r) {
        return "<spacewarp.MeshReport: " + std::to_string(r.componentCount) + " components, " +
               std::to_string(r.boundaryEdges) + " boundary edges, " +
               std::to_string(r.nonManifoldEdges.size()) + " non-manifold edges, " +
               std::to_string(r.nonManifoldVertices.size()) + " non-manifold vertices, " +
               std::to_string(r.droppedPolygons.size()) + " dropped polygons, " +
               std::to_string(r.isolatedVertices.size()) + " isolated vertices>";
      });

  py::class_<SurfaceMesh, std::shared_ptr<SurfaceMesh>>(
      m, "SurfaceMesh",
      R"(A triangle mesh welded from a Geometry (weld_soup): positions (n, 3) world units,
triangles (t, 3), and the maps back to the soup. Arrays are read-only views (no copy); the
editors take mesh.positions and mesh.triangles.)")
      .def_property_readonly(
          "positions",
          [](py::object self) {
            return pointsView(self.cast<const SurfaceMesh&>().positions, self);
          },
          "(n, 3) float64 mesh vertices, world units.")
      .def_property_readonly(
          "triangles",
          [](py::object self) {
            const auto& t = self.cast<const SurfaceMesh&>().triangles;
            return readOnlyView(t.empty() ? nullptr : t[0].data(),
                                {static_cast<py::ssize_t>(t.size()), 3}, self);
          },
          "(t, 3) uint32 vertex indices, oriented as the soup's polygons.")
      .def_property_readonly(
          "soup_to_mesh",
          [](py::object self) {
            return vectorView(self.cast<const SurfaceMesh&>().soupToMesh, self);
          },
          "(soup n,) uint32: the mesh vertex of each soup vertex.")
      .def_property_readonly(
          "triangle_to_polygon",
          [](py::object self) {
            return vectorView(self.cast<const SurfaceMesh&>().triangleToPolygon, self);
          },
          "(t,) uint32: the soup polygon each triangle was cut from.")
      .def_property_readonly(
          "vertex_component",
          [](py::object self) {
            return vectorView(self.cast<const SurfaceMesh&>().vertexComponent, self);
          },
          "(n,) uint32: the component of each vertex, 0 .. component_count - 1; isolated "
          "vertices get component_count and up, one each.")
      .def_readonly("report", &SurfaceMesh::report, "The MeshReport of the weld.")
      .def_property_readonly("vertex_count", &SurfaceMesh::vertexCount, "Mesh vertices (n).")
      .def(
          "to_soup_positions",
          [](const SurfaceMesh& s, py::handle meshPositions) {
            const Points p = toPoints(meshPositions, "mesh_positions", false);
            std::vector<Vec3> out;
            withoutGil([&] { out = s.toSoupPositions(p.span); });
            return copyPoints(out);
          },
          "mesh_positions"_a,
          R"(The soup's vertices (soup n, 3) moved as the mesh vertices (n, 3) they were welded
into: out[v] = mesh_positions[soup_to_mesh[v]]. Raises InvalidInput for a wrong count.)")
      .def(
          "to_soup",
          [](const SurfaceMesh& s) {
            auto soup = std::make_shared<PolygonSoup>();
            withoutGil([&] { *soup = toSoup(s); });
            return soup;
          },
          "A Geometry of the mesh's triangles (no attributes), e.g. to write it.")
      .def("__repr__", [](const SurfaceMesh& s) {
        return "<spacewarp.SurfaceMesh: " + std::to_string(s.vertexCount()) + " vertices, " +
               std::to_string(s.triangles.size()) + " triangles>";
      });

  m.def(
      "weld_soup",
      [](const PolygonSoup& geometry, double relativeTolerance) {
        auto mesh = std::make_shared<SurfaceMesh>();
        const InUse busy(geometry);
        withoutGil([&] { *mesh = weldSoup(geometry, WeldOptions{relativeTolerance}); });
        return mesh;
      },
      "geometry"_a, py::kw_only(), "relative_tolerance"_a = WeldOptions{}.relativeTolerance,
      R"(The SurfaceMesh of a Geometry: vertices closer than relative_tolerance x the bounding-box
diagonal welded into one (the default welds copies of the same point only; 0: exactly equal
positions), polygons fanned into triangles, boundaries, non-manifold parts, dropped polygons and
components reported (mesh.report), never refused. Raises InvalidInput for a geometry without
polygons.)");
}

// ---------------------------------------------------------------------------------------------
// Operators

void bindOperators(py::module_& m) {
  m.def(
      "cotan_laplacian",
      [](py::handle positions, py::handle triangles) {
        const MeshInput mesh = toMesh(positions, triangles);
        Eigen::SparseMatrix<double> l;
        withoutGil([&] { l = cotanLaplacian(mesh.positions.span, mesh.triangles); });
        l.makeCompressed();
        const auto n = static_cast<py::ssize_t>(l.rows());
        const auto nnz = static_cast<py::ssize_t>(l.nonZeros());
        py::array_t<double> data(nnz, l.valuePtr());
        py::array_t<std::int64_t> indices(nnz), indptr(n + 1);
        std::copy_n(l.innerIndexPtr(), nnz, indices.mutable_data());
        std::copy_n(l.outerIndexPtr(), n + 1, indptr.mutable_data());
        return py::module_::import("scipy.sparse")
            .attr("csc_matrix")(py::make_tuple(data, indices, indptr),
                                "shape"_a = py::make_tuple(n, n));
      },
      "positions"_a, "triangles"_a,
      R"(The cotangent stiffness matrix L (n, n) of the mesh positions (n, 3), triangles (t, 3):
a scipy.sparse.csc_matrix, symmetric positive semi-definite, rows summing to 0,
L_ij = -(cot a_ij + cot b_ij) / 2 over the angles opposite edge ij, dimensionless; x^T L x is the
Dirichlet energy of the piecewise-linear function x (needs SciPy). Triangles below 1e-12 of
their longest edge squared in area contribute nothing.)");
  m.def(
      "mass_matrix_diagonal",
      [](py::handle positions, py::handle triangles) {
        const MeshInput mesh = toMesh(positions, triangles);
        Eigen::VectorXd mass;
        withoutGil([&] { mass = massMatrixDiagonal(mesh.positions.span, mesh.triangles); });
        return py::array_t<double>(static_cast<py::ssize_t>(mass.size()), mass.data());
      },
      "positions"_a, "triangles"_a,
      R"(The lumped mass (n,) of the mesh positions (n, 3), triangles (t, 3): the mixed Voronoi
area of each vertex (Meyer et al. 2003), world units squared, summing to the surface area;
vertices without area get the smallest positive mass.)");
}

// ---------------------------------------------------------------------------------------------
// Handle regions

/// Handle regions as dicts {"vertices": [...], "matrix": 4 x 4 rows} or {"vertices": [...],
/// "targets": (k, 3)}, as the CLI's handles file has them; `name` ("regions", "handles") in
/// messages with the entry at fault ("handles[2].vertices[5]").
std::vector<HandleRegion> toRegions(py::handle regions, const std::string& name) {
  if (py::isinstance<py::str>(regions) || py::isinstance<py::dict>(regions) ||
      !py::isinstance<py::sequence>(regions))
    throw py::type_error(name + " must be a list of dicts, not " +
                         std::string(py::str(py::type::of(regions).attr("__name__"))));
  std::vector<HandleRegion> out;
  std::size_t k = 0;
  for (py::handle item : regions) {
    const std::string at = name + "[" + std::to_string(k++) + "]";
    if (!py::isinstance<py::dict>(item))
      throw py::type_error(at + " must be a dict with 'vertices' and 'matrix' or 'targets', not " +
                           std::string(py::str(py::type::of(item).attr("__name__"))));
    const auto region = py::reinterpret_borrow<py::dict>(item);
    for (const auto& entry : region) {
      const py::handle key = entry.first;
      const std::string text = py::str(key);
      if (!py::isinstance<py::str>(key) ||
          (text != "vertices" && text != "matrix" && text != "targets"))
        throw InvalidInput(at + ": unknown key " + std::string(py::repr(key)) +
                           " (the keys: vertices, matrix, targets)");
    }
    if (!region.contains("vertices")) throw InvalidInput(at + ": no 'vertices'");
    const bool hasMatrix = region.contains("matrix"), hasTargets = region.contains("targets");
    if (hasMatrix == hasTargets)
      throw InvalidInput(at + (hasMatrix ? ": give 'matrix' or 'targets', not both"
                                         : ": needs 'matrix' or 'targets'"));
    HandleRegion r;
    r.vertices = toIndices(py::object(region["vertices"]), at + ".vertices");
    if (hasMatrix) {
      const auto a = DoubleArray::ensure(py::object(region["matrix"]));
      if (!a || a.ndim() != 2 || a.shape(0) != 4 || a.shape(1) != 4) {
        PyErr_Clear();
        throw InvalidInput(at + ".matrix must be 4 rows of 4 numbers (an affine map)");
      }
      Mat4 matrix;
      for (int row = 0; row < 4; ++row)
        for (int c = 0; c < 4; ++c) matrix[c][row] = a.at(row, c);
      r.matrix = matrix;
    } else {
      const std::string targets = at + ".targets";
      const Points t = toPoints(py::object(region["targets"]), targets.c_str(), false);
      r.targets.assign(t.span.begin(), t.span.end());
    }
    out.push_back(std::move(r));
  }
  return out;
}

void bindHandles(py::module_& m) {
  m.def(
      "load_handles",
      [](const py::object& path) {
        const std::string file = py::str(py::module_::import("os").attr("fspath")(path));
        std::vector<HandleRegion> regions;
        withoutGil([&] { regions = readHandlesFile(file); });
        py::list out;
        for (const HandleRegion& r : regions) {
          py::dict region;
          region["vertices"] = indexArray<std::uint32_t>(r.vertices);
          if (r.matrix) {
            py::array_t<double> m({4, 4});
            auto view = m.mutable_unchecked<2>();
            for (int row = 0; row < 4; ++row)
              for (int col = 0; col < 4; ++col) view(row, col) = (*r.matrix)[col][row];
            region["matrix"] = m;
          } else {
            region["targets"] = copyPoints(r.targets);
          }
          out.append(region);
        }
        return out;
      },
      "path"_a,
      R"(The handle regions of a handles file, read as `spacewarp edit --handles` reads it (the same
C++ reader: the same checks and messages).

The file is JSON: {"handles": [REGION, ...]}, each region {"vertices": [i, ...], "matrix":
[[4 numbers] x 4 rows]} (the vertices move by that affine map, last row 0 0 0 1; the identity
pins them) or {"vertices": [i, ...], "targets": [[x, y, z], ...]} (one target per vertex, world
units). Indices are the model's vertices in file order.

Returns a list of dicts {"vertices": (k,) uint32, "matrix": (4, 4) float64} or {"vertices": (k,)
uint32, "targets": (k, 3) float64}, as edit() and resolve_handles() take them (which check the
indices against the model). Raises IoError when the file cannot be read or is not JSON (NaN,
duplicate keys), InvalidInput naming the file and the key path at fault
("h.json: handles[2].vertices[5]: ...") for content that is not a handles file.)");
  m.def(
      "resolve_handles",
      [](py::handle regions, py::handle rest) {
        const std::vector<HandleRegion> r = toRegions(regions, "regions");
        const Points p = toPoints(rest, "rest", false);
        VertexConstraints c;
        withoutGil([&] { c = resolveHandles(r, p.span); });
        return py::make_tuple(indexArray<std::uint32_t>(c.vertices), copyPoints(c.targets));
      },
      "regions"_a, "rest"_a,
      R"(The constraints of handle regions on the vertices `rest` (n, 3), world units: returns
(vertices, targets), (k,) uint32 in increasing order and (k, 3) float64. Each region is a dict
as in the CLI's handles file: {"vertices": [i, ...], "matrix": 4 rows of 4} (the vertices move
by that affine map; the identity pins them) or {"vertices": [i, ...], "targets": (k, 3)}. A
vertex in several regions must get the same target from each. Raises InvalidInput naming the
region and entry at fault (TypeError for a region that is not a dict).)");
}

// ---------------------------------------------------------------------------------------------
// Editors

const char* linearMethodName(LinearEditMethod method) {
  return method == LinearEditMethod::Laplacian ? "laplacian" : "bilaplacian";
}

const char* arapEnergyName(ArapEnergy energy) {
  return energy == ArapEnergy::SpokesAndRims ? "spokes_and_rims" : "spokes";
}

ArapEnergy arapEnergy(const std::string& name) {
  if (name == "spokes_and_rims") return ArapEnergy::SpokesAndRims;
  if (name == "spokes") return ArapEnergy::Spokes;
  throw InvalidInput("energy must be 'spokes_and_rims' or 'spokes', not '" + name + "'");
}

LinearEditMethod linearMethod(const std::string& name) {
  if (name == "laplacian") return LinearEditMethod::Laplacian;
  if (name == "bilaplacian") return LinearEditMethod::BiLaplacian;
  throw InvalidInput("method must be 'laplacian' or 'bilaplacian', not '" + name + "'");
}

void bindLinearEditor(py::module_& m) {
  using Editor = Locked<LinearEditor>;
  py::class_<Editor, std::shared_ptr<Editor>>(
      m, "LinearEditor",
      R"(Prefactorised linear surface editing of the mesh positions (n, 3), triangles (t, 3)
with the vertices `constrained` (k,) as handles: the free vertices' displacement is harmonic
(method "laplacian", Sorkine et al. 2004) or biharmonic ("bilaplacian", Botsch and Kobbelt
2004). Reproduces translations exactly but cannot follow rotations (use ArapEditor). Components
no handle reaches stay at rest (held_vertices).)")
      .def(py::init([](py::handle positions, py::handle triangles, py::handle constrained,
                       const std::string& method) {
             const MeshInput mesh = toMesh(positions, triangles);
             const std::vector<std::uint32_t> c = toIndices(constrained, "constrained");
             const LinearEditOptions options{linearMethod(method)};
             std::shared_ptr<Editor> editor;
             withoutGil([&] {
               editor = std::make_shared<Editor>(
                   LinearEditor(mesh.positions.span, mesh.triangles, c, options));
             });
             return editor;
           }),
           "positions"_a, "triangles"_a, "constrained"_a, py::kw_only(),
           "method"_a = linearMethodName(LinearEditOptions{}.method))
      .def(
          "solve",
          [](Editor& e, py::handle targets) {
            const Points t = toPoints(targets, "targets", false);
            std::vector<Vec3> out;
            withoutGil([&] {
              const std::lock_guard lock(e.mutex);
              out = e.editor.solve(t.span);
            });
            return copyPoints(out);
          },
          "targets"_a,
          R"(All n vertices (n, 3) for the constrained vertices at `targets` (k, 3), one per
constrained vertex in the constructor's order, world units (a back-substitution).)")
      .def_property_readonly(
          "held_vertices",
          [](Editor& e) { return indexArray<std::uint32_t>(e.editor.heldVertices()); },
          "(h,) uint32: vertices kept at rest because no handle reaches their component.");
}

void bindArapEditor(py::module_& m) {
  py::class_<ArapReport>(m, "ArapReport", "What one ArapEditor solve did.")
      .def_property_readonly(
          "energies",
          [](py::object self) { return vectorView(self.cast<const ArapReport&>().energies, self); },
          "(iterations + 1,) float64: the energy at the start and after each iteration, "
          "non-increasing, world units squared.")
      .def_readonly("iterations", &ArapReport::iterations, "Local/global iterations run.")
      .def_readonly("converged", &ArapReport::converged,
                    "Whether the relative decrease fell below relative_tolerance before "
                    "max_iterations.")
      .def_readonly("started_rigid", &ArapReport::startedRigid,
                    "Whether the solve started from the handles' common rigid motion (then a "
                    "rigid motion of all handles is reproduced exactly).");
  py::class_<ArapResult>(m, "ArapResult", "The result of an ArapEditor solve.")
      .def_property_readonly(
          "positions",
          [](py::object self) {
            return pointsView(self.cast<const ArapResult&>().positions, self);
          },
          "(n, 3) float64, all vertices, world units (read-only).")
      .def_readonly("report", &ArapResult::report, "The ArapReport.");

  using Editor = Locked<ArapEditor>;
  const ArapOptions defaults;
  py::class_<Editor, std::shared_ptr<Editor>>(
      m, "ArapEditor",
      R"(Prefactorised as-rigid-as-possible surface editing (Sorkine and Alexa 2007) of the mesh
positions (n, 3), triangles (t, 3) with the vertices `constrained` (k,) as handles: one rotation
per vertex acting on the edges of its triangles (energy "spokes_and_rims", Chao et al. 2010, the
default: bounded below with obtuse triangles) or on its one-ring edges only ("spokes", the
paper's), cotangent weights; at most max_iterations local/global iterations per solve, stopping
when one lowers the energy by less than relative_tolerance of it (0: always max_iterations),
with Anderson acceleration over the last acceleration_window iterations (0: none; an accelerated
step is kept only when it lowers the energy).
Components no handle reaches stay at rest (held_vertices).)")
      .def(py::init([](py::handle positions, py::handle triangles, py::handle constrained,
                       const std::string& energy, int maxIterations, double relativeTolerance,
                       int accelerationWindow) {
             const MeshInput mesh = toMesh(positions, triangles);
             const std::vector<std::uint32_t> c = toIndices(constrained, "constrained");
             const ArapOptions options{arapEnergy(energy), maxIterations, relativeTolerance,
                                       accelerationWindow};
             std::shared_ptr<Editor> editor;
             withoutGil([&] {
               editor = std::make_shared<Editor>(
                   ArapEditor(mesh.positions.span, mesh.triangles, c, options));
             });
             return editor;
           }),
           "positions"_a, "triangles"_a, "constrained"_a, py::kw_only(),
           "energy"_a = arapEnergyName(defaults.energy),
           "max_iterations"_a = defaults.maxIterations,
           "relative_tolerance"_a = defaults.relativeTolerance,
           "acceleration_window"_a = defaults.accelerationWindow)
      .def(
          "solve",
          [](Editor& e, py::handle targets, const py::object& progress) {
            const Points t = toPoints(targets, "targets", false);
            ArapResult result;
            runCancellable(progress, [&](const ProgressCallback& callback) {
              const std::lock_guard lock(e.mutex);
              result = e.editor.solve(t.span, callback);
            });
            return result;
          },
          "targets"_a, py::kw_only(), "progress"_a = py::none(),
          R"(Solves for the constrained vertices at `targets` (k, 3), constructor order, world
units, starting from the Laplacian-editing solution or the handles' rigid motion (the lower
energy). Returns an ArapResult. Reports stage "arap".)")
      .def(
          "solve_from",
          [](Editor& e, py::handle start, py::handle targets, const py::object& progress) {
            const Points s = toPoints(start, "start", false);
            const Points t = toPoints(targets, "targets", false);
            ArapResult result;
            runCancellable(progress, [&](const ProgressCallback& callback) {
              const std::lock_guard lock(e.mutex);
              result = e.editor.solveFrom(s.span, t.span, callback);
            });
            return result;
          },
          "start"_a, "targets"_a, py::kw_only(), "progress"_a = py::none(),
          R"(As solve(), continuing from `start` (n, 3), e.g. the previous frame's positions.)")
      .def(
          "energy",
          [](Editor& e, py::handle positions) {
            const Points p = toPoints(positions, "positions", false);
            double energy = 0.0;
            withoutGil([&] {
              const std::lock_guard lock(e.mutex);
              energy = e.editor.energy(p.span);
            });
            return energy;
          },
          "positions"_a,
          "The ARAP energy of `positions` (n, 3) with its optimal rotations, world units squared.")
      .def_property_readonly(
          "held_vertices",
          [](Editor& e) { return indexArray<std::uint32_t>(e.editor.heldVertices()); },
          "(h,) uint32: vertices kept at rest because no handle reaches their component.");
}

void bindCageArapEditor(py::module_& m) {
  py::class_<CageArapReport>(m, "CageArapReport", "What one CageArapEditor solve did.")
      .def_property_readonly(
          "energies",
          [](py::object self) {
            return vectorView(self.cast<const CageArapReport&>().energies, self);
          },
          "(iterations + 1,) float64: total energy (ARAP + handle term) at the start and after "
          "each iteration, non-increasing.")
      .def_readonly("iterations", &CageArapReport::iterations, "Iterations run.")
      .def_readonly("converged", &CageArapReport::converged,
                    "Whether the relative decrease fell below relative_tolerance before "
                    "max_iterations.")
      .def_readonly("started_rigid", &CageArapReport::startedRigid,
                    "Whether the solve started from the handles' common rigid motion.")
      .def_property_readonly(
          "handle_residuals",
          [](py::object self) {
            return vectorView(self.cast<const CageArapReport&>().handleResiduals, self);
          },
          "(k,) float64: distance of each constrained vertex from its target, world units.")
      .def_property_readonly(
          "unreached",
          [](py::object self) {
            return vectorView(self.cast<const CageArapReport&>().unreached, self);
          },
          "(u,) uint32: constrained vertices (mesh indices) left farther than reach_tolerance "
          "from their targets: the cage cannot carry them there rigidly (or at all).")
      .def_readonly("max_residual", &CageArapReport::maxResidual,
                    "The largest handle residual, world units.");
  py::class_<CageArapResult>(m, "CageArapResult", "The result of a CageArapEditor solve.")
      .def_property_readonly(
          "control_points",
          [](py::object self) {
            return pointsView(self.cast<const CageArapResult&>().controlPoints, self);
          },
          "(m, 3) float64: the posed control points (cage vertices), world units (read-only); "
          "coordinates.warp(control_points) carries any other geometry the same way.")
      .def_property_readonly(
          "positions",
          [](py::object self) {
            return pointsView(self.cast<const CageArapResult&>().positions, self);
          },
          "(n, 3) float64: the model's vertices, world units (read-only).")
      .def_readonly("report", &CageArapResult::report, "The CageArapReport.");

  using Editor = Locked<CageArapEditor>;
  const CageArapOptions defaults;
  py::class_<Editor, std::shared_ptr<Editor>>(
      m, "CageArapEditor",
      R"(ARAP in a cage's subspace (Huang et al. 2006): the unknowns are the control points of
`coordinates` (MeanValue, Green, Harmonic, Lattice, Rbf, ... weighing every vertex of the mesh
positions (n, 3), triangles (t, 3)); the model follows through its binding, and the energy is
its ARAP energy (`energy` as ArapEditor's) with one rotation per cluster of vertices (rotation_clusters; 0: 4 per control
point, at least 64, at most n) plus soft handle constraints on `constrained` (k,) weighted by
handle_weight (relative to the ARAP stiffness). At most max_iterations iterations, stopping
below relative_tolerance (Anderson acceleration over acceleration_window iterations, as
ArapEditor's); handles left farther than reach_tolerance x the model's diagonal are
reported unreached. Building binds the model (stage "bind") and the subspace ("subspace");
raises InvalidInput as LinearEditor does (and for options out of range, or matrices that would
not fit in memory), SolverError when the subspace system cannot be factorised.)")
      .def(py::init([](py::handle positions, py::handle triangles, CoordinatesPtr coordinates,
                       py::handle constrained, const std::string& energy,
                       std::size_t rotationClusters, double handleWeight, int maxIterations,
                       double relativeTolerance, int accelerationWindow, double reachTolerance,
                       const py::object& progress) {
             const MeshInput mesh = toMesh(positions, triangles);
             const std::vector<std::uint32_t> c = toIndices(constrained, "constrained");
             CageArapOptions options;
             options.energy = arapEnergy(energy);
             options.rotationClusters = rotationClusters;
             options.handleWeight = handleWeight;
             options.maxIterations = maxIterations;
             options.relativeTolerance = relativeTolerance;
             options.accelerationWindow = accelerationWindow;
             options.reachTolerance = reachTolerance;
             std::shared_ptr<Editor> editor;
             runCancellable(progress, [&](const ProgressCallback& callback) {
               editor = std::make_shared<Editor>(CageArapEditor(mesh.positions.span, mesh.triangles,
                                                                coordinates, c, options, callback));
             });
             return editor;
           }),
           "positions"_a, "triangles"_a, "coordinates"_a, "constrained"_a, py::kw_only(),
           "energy"_a = arapEnergyName(defaults.energy),
           "rotation_clusters"_a = defaults.rotationClusters,
           "handle_weight"_a = defaults.handleWeight, "max_iterations"_a = defaults.maxIterations,
           "relative_tolerance"_a = defaults.relativeTolerance,
           "acceleration_window"_a = defaults.accelerationWindow,
           "reach_tolerance"_a = defaults.reachTolerance, "progress"_a = py::none())
      .def(
          "solve",
          [](Editor& e, py::handle targets, const py::object& progress) {
            const Points t = toPoints(targets, "targets", false);
            CageArapResult result;
            runCancellable(progress, [&](const ProgressCallback& callback) {
              const std::lock_guard lock(e.mutex);
              result = e.editor.solve(t.span, callback);
            });
            return result;
          },
          "targets"_a, py::kw_only(), "progress"_a = py::none(),
          R"(The cage pose that best moves the constrained vertices to `targets` (k, 3),
constructor order, world units, starting from the handles' rigid motion or the rotation-free
solution (the lower energy). Returns a CageArapResult. Reports stage "cage-arap".)")
      .def(
          "solve_from",
          [](Editor& e, py::handle start, py::handle targets, const py::object& progress) {
            const Points s = toPoints(start, "start_control_points", false);
            const Points t = toPoints(targets, "targets", false);
            CageArapResult result;
            runCancellable(progress, [&](const ProgressCallback& callback) {
              const std::lock_guard lock(e.mutex);
              result = e.editor.solveFrom(s.span, t.span, callback);
            });
            return result;
          },
          "start_control_points"_a, "targets"_a, py::kw_only(), "progress"_a = py::none(),
          "As solve(), continuing from a cage pose `start_control_points` (m, 3).")
      .def_property_readonly(
          "cluster_count", [](Editor& e) { return e.editor.clusterCount(); },
          "Rotation clusters K (n gives exactly the surface ARAP energy).");
}

// ---------------------------------------------------------------------------------------------
// edit(): one call from a Geometry and handle regions to the edited Geometry

/// A number in a warning: four significant digits.
std::string shortNumber(double x) {
  char text[32];
  std::snprintf(text, sizeof text, "%.4g", x);
  return text;
}

SurfaceEditMethod editMethod(const std::string& name) {
  if (name == "laplacian") return SurfaceEditMethod::Laplacian;
  if (name == "bilaplacian") return SurfaceEditMethod::BiLaplacian;
  if (name == "arap") return SurfaceEditMethod::Arap;
  if (name == "cage-arap") return SurfaceEditMethod::CageArap;
  throw InvalidInput("method must be 'laplacian', 'bilaplacian', 'arap' or 'cage-arap', not '" +
                     name + "'");
}

struct EditOptions {
  std::optional<std::string> energy;
  std::optional<int> maxIterations;
  std::optional<int> accelerationWindow;
  std::optional<double> relativeTolerance;
  std::optional<std::size_t> rotationClusters;
  std::optional<double> handleWeight;
  std::optional<double> reachTolerance;
};

/// Refuses options given for a method they do not apply to (as the CLI does).
void checkApplicable(SurfaceEditMethod method, const std::string& name,
                     const CoordinatesPtr& coordinates, const EditOptions& o) {
  const bool iterative = method == SurfaceEditMethod::Arap || method == SurfaceEditMethod::CageArap;
  const bool cage = method == SurfaceEditMethod::CageArap;
  const auto refuse = [&](bool given, bool applies, const char* option) {
    if (given && !applies)
      throw InvalidInput(std::string(option) + " does not apply to method '" + name + "'");
  };
  refuse(o.energy.has_value(), iterative, "energy");
  refuse(o.maxIterations.has_value(), iterative, "max_iterations");
  refuse(o.accelerationWindow.has_value(), iterative, "acceleration_window");
  refuse(o.relativeTolerance.has_value(), iterative, "relative_tolerance");
  refuse(o.rotationClusters.has_value(), cage, "rotation_clusters");
  refuse(o.handleWeight.has_value(), cage, "handle_weight");
  refuse(o.reachTolerance.has_value(), cage, "reach_tolerance");
  refuse(coordinates != nullptr, cage, "coordinates");
  if (cage && !coordinates)
    throw InvalidInput("method 'cage-arap' needs coordinates (e.g. spacewarp.MeanValue(cage))");
}

GeometryPtr editGeometry(const PolygonSoup& geometry, py::handle handles, const std::string& name,
                         const CoordinatesPtr& coordinates, double weldTolerance,
                         const EditOptions& o, const py::object& progress) {
  SurfaceEditOptions options;
  options.method = editMethod(name);
  checkApplicable(options.method, name, coordinates, o);
  if (o.energy) options.arap.energy = options.cageArap.energy = arapEnergy(*o.energy);
  if (o.maxIterations)
    options.arap.maxIterations = options.cageArap.maxIterations = *o.maxIterations;
  if (o.accelerationWindow)
    options.arap.accelerationWindow = options.cageArap.accelerationWindow = *o.accelerationWindow;
  if (o.relativeTolerance)
    options.arap.relativeTolerance = options.cageArap.relativeTolerance = *o.relativeTolerance;
  options.cageArap.rotationClusters =
      o.rotationClusters.value_or(options.cageArap.rotationClusters);
  options.cageArap.handleWeight = o.handleWeight.value_or(options.cageArap.handleWeight);
  options.cageArap.reachTolerance = o.reachTolerance.value_or(options.cageArap.reachTolerance);
  options.coordinates = coordinates;
  const std::vector<HandleRegion> regions = toRegions(handles, "handles");
  const auto out = std::make_shared<PolygonSoup>();
  std::vector<std::string> warnings;
  const InUse busy(geometry);
  runCancellable(progress, [&](const ProgressCallback& callback) {
    *out = geometry;
    const SurfaceMesh mesh = weldSoup(*out, WeldOptions{weldTolerance});
    const double diagonal = boundingBox(out->positions).diagonal();
    const VertexConstraints c =
        mapConstraints(resolveHandles(regions, out->positions), mesh.soupToMesh, 1e-9 * diagonal);
    const SurfaceEdit edit = editMesh(mesh, c, options, callback);
    if (const auto& r = edit.arapReport; r && !r->converged)
      warnings.push_back("ARAP did not converge in " + std::to_string(r->iterations) +
                         " iterations (energy " + shortNumber(r->energies.front()) + " -> " +
                         shortNumber(r->energies.back()) + ")");
    if (const auto& r = edit.cageArapReport; r && !r->converged)
      warnings.push_back("cage-subspace ARAP did not converge in " + std::to_string(r->iterations) +
                         " iterations (energy " + shortNumber(r->energies.front()) + " -> " +
                         shortNumber(r->energies.back()) + ")");
    const MeshReport& report = mesh.report;
    if (!report.nonManifoldEdges.empty() || !report.nonManifoldVertices.empty())
      warnings.push_back(std::to_string(report.nonManifoldEdges.size()) +
                         " non-manifold edges and " +
                         std::to_string(report.nonManifoldVertices.size()) +
                         " non-manifold vertices: the methods still run, but the result there "
                         "may crease");
    if (!report.droppedPolygons.empty() || !report.degenerateTriangles.empty())
      warnings.push_back(std::to_string(report.droppedPolygons.size()) +
                         " polygons collapsed by welding and " +
                         std::to_string(report.degenerateTriangles.size()) +
                         " triangles without area take no part in the edit");
    if (const auto& r = edit.cageArapReport; r && !r->unreached.empty())
      warnings.push_back(std::to_string(r->unreached.size()) +
                         " handle vertices are left farther than reach_tolerance from their "
                         "targets (max residual " +
                         shortNumber(r->maxResidual) +
                         "): the cage cannot carry them there rigidly");
    // Green's face-normal columns (triangle or quad Green) are not cage vertices.
    if (options.method == SurfaceEditMethod::CageArap && coordinates &&
        coordinates->columnCount() > coordinates->controlPointCount())
      warnings.push_back(
          "cage-arap with Green coordinates moves their vertex terms only (the face normals' "
          "terms stay at rest), so it does not reproduce rotations exactly; MeanValue and "
          "Harmonic do");
    if (!edit.heldVertices.empty())
      warnings.push_back(std::to_string(edit.heldVertices.size()) +
                         " mesh vertices are in parts no handle reaches: they stay at rest");
    applyEdit(*out, mesh, edit.positions);
  });
  warnAll(warnings);
  return out;
}

void bindEdit(py::module_& m) {
  m.def(
      "edit",
      [](const PolygonSoup& geometry, py::handle handles, const std::string& method,
         const CoordinatesPtr& coordinates, double weldTolerance, std::optional<std::string> energy,
         std::optional<int> maxIterations, std::optional<int> accelerationWindow,
         std::optional<double> relativeTolerance, std::optional<std::size_t> rotationClusters,
         std::optional<double> handleWeight, std::optional<double> reachTolerance,
         const py::object& progress) {
        return editGeometry(geometry, handles, method, coordinates, weldTolerance,
                            {energy, maxIterations, accelerationWindow, relativeTolerance,
                             rotationClusters, handleWeight, reachTolerance},
                            progress);
      },
      "geometry"_a, "handles"_a, py::kw_only(), "method"_a = "arap", "coordinates"_a = nullptr,
      "weld_tolerance"_a = WeldOptions{}.relativeTolerance, "energy"_a = py::none(),
      "max_iterations"_a = py::none(), "acceleration_window"_a = py::none(),
      "relative_tolerance"_a = py::none(), "rotation_clusters"_a = py::none(),
      "handle_weight"_a = py::none(), "reach_tolerance"_a = py::none(), "progress"_a = py::none(),
      R"(The Geometry edited by its surface, as `spacewarp edit` does: welded (weld_soup with
weld_tolerance), the handle regions resolved (resolve_handles; vertex indices are the geometry's,
as in the CLI's handles file) and carried to the mesh, solved by method "laplacian",
"bilaplacian", "arap" or "cage-arap" (which needs `coordinates`, e.g. MeanValue(cage)), and
returned as a new Geometry with the polygons, attributes and groups of the input. Per-vertex
normals are recomputed from the edited polygons (area-weighted, on the side the input's pointed
to); per-corner normals turn with their polygon. Options left None take the editor's defaults
(ArapEditor, CageArapEditor); an option the method does not use raises InvalidInput. A solve
that did not converge, handles left unreached and parts no handle reaches are UserWarnings.)");
}

}  // namespace

void bindSurface(py::module_& m) {
  bindMesh(m);
  bindOperators(m);
  bindHandles(m);
  bindLinearEditor(m);
  bindArapEditor(m);
  bindCageArapEditor(m);
  bindEdit(m);
}

}  // namespace spacewarp::python
