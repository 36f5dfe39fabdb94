#pragma once
// Fitting lattices: a lattice around any geometry, and direct manipulation (Hsu, Hughes &
// Kaufman 1992): the control points that carry given points x_k to given targets y_k, in least
// squares with a smoothness regulariser.

#include <array>
#include <span>
#include <vector>

#include <spacewarp/core/math.h>
#include <spacewarp/core/progress.h>
#include <spacewarp/ffd/lattice.h>

namespace spacewarp {

/// Options of fitControlPoints().
struct LatticeFitOptions {
  /// λ ≥ 0, dimensionless: the weight of the smoothness term. The solved energy is
  ///   (1/K) Σ_k |x_k + Σ_c w_c(x_k) d_c − y_k|² + (λ/E) Σ_{(c,c')} |d_c − d_c'|²
  /// over the K constraints and the E pairs of grid neighbours (c, c') (6-neighbourhood), d the
  /// control displacements. Both terms are means of squared world lengths, so λ does not
  /// depend on the scale or on how many constraints and controls there are. The regulariser
  /// also fixes the controls no constraint reaches (they follow their neighbours). Default 1e-4:
  /// small enough that the constraints dominate, large enough that the system is well posed.
  double smoothness = 1e-4;
  /// Told "fit lattice" and the fraction done (assembly, then the solve); may cancel
  /// (Cancelled). Default: none.
  ProgressCallback progress;
};

/// What fitControlPoints() found.
struct ControlPointFit {
  std::vector<Vec3> controlPoints;  ///< The posed control points (controlPointCount(), world).
  double rmsResidual = 0.0;         ///< sqrt(mean_k |warp(x_k) − y_k|²), world units.
  double maxResidual = 0.0;         ///< max_k |warp(x_k) − y_k|, world units.
};

/// Direct manipulation: the posed control points of `lattice` that move each point from[k] to
/// to[k] in least squares, with the smoothness regulariser of `options`. The normal equations
/// (sparse, control count × control count) are solved by Eigen's SimplicialLDLT. Throws
/// InvalidInput if the spans differ in size or are empty, a point is not finite (naming it),
/// no constraint lies where the lattice moves points, or λ is negative or not finite;
/// SolverError if the system is singular (λ = 0 with controls no constraint reaches).
ControlPointFit fitControlPoints(const Lattice& lattice, std::span<const Vec3> from,
                                 std::span<const Vec3> to, const LatticeFitOptions& options = {});

/// An axis-aligned lattice around the bounding box of `points`, grown on every side by
/// `padding` × the box diagonal (padding ≥ 0), with the given resolution and basis (and the
/// other LatticeOptions at their defaults). Throws InvalidInput if `points` is empty or not
/// finite, padding is negative or not finite, or the padded box is flat (e.g. zero padding
/// around planar points), and as Lattice's constructor does.
Lattice fitLattice(std::span<const Vec3> points, double padding, std::array<int, 3> resolution,
                   LatticeBasis basis = LatticeBasis::Trilinear);

}  // namespace spacewarp
