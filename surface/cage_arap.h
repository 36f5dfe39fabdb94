#pragma once
// ARAP in a cage's subspace ("subspace gradient domain deformation", Huang et al. 2006): the
// unknowns are the cage's control points P; the model follows through its binding,
//
//   x(P) = x̄ + W (P − P̄)          (W: n × m, the coordinates of the model's vertices),
//
// and the energy is the model's ARAP energy plus soft handle constraints,
//
//   E(P, R) = Σ_k Σ_{i ∈ cluster k} Σ_{(a,b) ∈ T(i)} w_ab ‖(x_a − x_b) − R_k (x̄_a − x̄_b)‖²
//             + λ Σ_h ‖x_h(P) − t_h‖²
//
// with the edge sets T(i) of ArapEditor's energy (spokes and rims by default).
//
// One rotation per cluster of vertices (clusters grown over the surface from farthest-point
// seeds): with as many clusters as vertices this is exactly the surface ARAP energy of
// ArapEditor. Everything that depends on the model's size is folded into m × m and m × 3
// matrices at construction, so an iteration costs O(K·m + m²) for K clusters and m control
// points, whatever the model's size.
//
// Coordinates whose columns are not the control points themselves (Green's face normals) use
// their vertex block: the normal columns stay at rest, so x is affine in P.

#include <array>
#include <cstdint>
#include <memory>
#include <span>
#include <vector>

#include <spacewarp/core/coordinates.h>
#include <spacewarp/core/math.h>
#include <spacewarp/core/progress.h>
#include <spacewarp/surface/arap.h>

namespace spacewarp {

struct CageArapOptions {
  /// The ARAP energy's edge sets (default SpokesAndRims, as ArapEditor's).
  ArapEnergy energy = ArapEnergy::SpokesAndRims;
  /// Rotation clusters K. 0 (default): 4 per control point, at least 64, at most the vertex
  /// count; the vertex count gives exactly the surface ARAP energy.
  std::size_t rotationClusters = 0;
  /// λ relative to the ARAP stiffness: the handle term's weight is handleWeight × (the sum of
  /// the energy's edge weights, Σ_i Σ_{T(i)} w) / (the number of handle vertices), so its
  /// meaning does not depend on the mesh's size or resolution (default 100, at most 1e6: beyond,
  /// the handle term swamps the ARAP energy in the system's rounding and the iteration stalls
  /// far from the minimum). Larger follows the
  /// handles more closely at the cost of rigidity where the cage cannot do both.
  double handleWeight = 100.0;
  /// At most this many iterations per solve (default 200; an iteration costs O(K·m + m²)).
  int maxIterations = 200;
  /// Stop when an iteration lowers the energy by less than this fraction of it (default 1e-7).
  double relativeTolerance = 1e-7;
  /// Anderson acceleration over this many previous iterations (default 5; 0: none), as
  /// ArapOptions::accelerationWindow.
  int accelerationWindow = 5;
  /// A handle vertex farther than this fraction of the model's bounding-box diagonal from its
  /// target after the solve is reported unreached (default 1e-3).
  double reachTolerance = 1e-3;
};

struct CageArapReport {
  /// Total energy (ARAP + handle term) at the start and after each iteration, non-increasing.
  std::vector<double> energies;
  int iterations = 0;
  bool converged = false;
  bool startedRigid = false;
  /// Distance of each constrained vertex from its target after the solve (constrained order).
  std::vector<double> handleResiduals;
  /// Constrained vertices (mesh indices) left farther than reachTolerance from their targets:
  /// the cage cannot carry them there without giving up rigidity (or at all).
  std::vector<std::uint32_t> unreached;
  double maxResidual = 0.0;
};

struct CageArapResult {
  std::vector<Vec3> controlPoints;  ///< The posed cage (controlPointCount() points).
  std::vector<Vec3> positions;      ///< The model's vertices x(P) (n points).
  CageArapReport report;
};

/// Prefactorised cage-subspace ARAP for one model, one set of coordinates and one set of
/// constrained vertices. Not thread-safe; construct one per thread.
class CageArapEditor {
 public:
  /// `positions`, `triangles`: the model (n vertices, world units); `coordinates`: any
  /// Coordinates (mean-value, harmonic, Green, a lattice, RBF handles) that weigh every model
  /// vertex; `constrained`: the handle vertices. Binds the model (reports stage "bind"), then
  /// builds the subspace matrices (stage "subspace"). Throws InvalidInput as LinearEditor does,
  /// or if a model vertex has no weights, the options are out of range or the matrices would not
  /// fit in memory; SolverError if the subspace system cannot be factorised. Control points that
  /// no model vertex feels (weight 0 everywhere, e.g. far lattice points) are not determined by
  /// the energy: a tiny proximal term keeps them where each solve starts.
  CageArapEditor(std::span<const Vec3> positions,
                 std::span<const std::array<std::uint32_t, 3>> triangles,
                 std::shared_ptr<const Coordinates> coordinates,
                 std::span<const std::uint32_t> constrained, const CageArapOptions& options = {},
                 const ProgressCallback& progress = {});
  ~CageArapEditor();
  CageArapEditor(CageArapEditor&&) noexcept;
  CageArapEditor& operator=(CageArapEditor&&) noexcept;

  /// The cage pose that best moves the constrained vertices to `targets` (one per constrained
  /// vertex, constructor order), starting from the handles' rigid motion or the linear
  /// (rotation-free) solution, whichever has lower energy. Reports stage "cage-arap".
  CageArapResult solve(std::span<const Vec3> targets, const ProgressCallback& progress = {});

  /// Continues from a cage pose (controlPointCount() points).
  CageArapResult solveFrom(std::span<const Vec3> startControlPoints, std::span<const Vec3> targets,
                           const ProgressCallback& progress = {});

  std::size_t clusterCount() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace spacewarp
