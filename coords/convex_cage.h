#pragma once
// What the coordinates of convex cages (Wachspress, discrete harmonic) share: the policy for
// points outside the cage, and the convexity checks (any faces for Wachspress, triangles for
// discrete harmonic).

#include <spacewarp/coords/cage.h>

namespace spacewarp {

/// What the coordinates of a convex cage give points outside it.
enum class ConvexOutsidePolicy {
  /// Throw InvalidInput, saying how many points of the call are outside and naming the first
  /// (its index in the caller's array, also when a warp or a progress display cuts the call into
  /// blocks), and how to ask for NearestPoint in each front end (CLI, rig, Python, C++).
  Throw,
  /// The coordinates of the nearest point on the cage surface (they reproduce that point, not x).
  NearestPoint,
};

/// The default planarity of convex cages, relative to Cage::diagonal(): how far a corner may be
/// from its face's best-fit plane, or above a neighbouring face's plane, and still count as on it
/// (see coords/detail/convex_polyhedron.h). Coordinates written with 6 decimals or in float32 are
/// off by up to ~5e-7 (absolute) or 6e-8 (relative to the coordinates); 1e-6 of the diagonal admits
/// that for cages of diagonal ≥ 1 near the origin, and still refuses an edge turning inward by
/// 1e-3 radians between faces wider than 1e-3 diagonals.
inline constexpr double kDefaultPlanarity = 1e-6;

/// Throws InvalidInput (naming the cage, its reflex edge by its two vertices, a face that is not
/// planar, or a vertex that is not a corner of the polyhedron) unless `cage` is convex: every face
/// planar, every edge between two faces that are not coplanar turns outward, every vertex lies in
/// at least three face planes, and no vertex is outside a face plane (tolerances relative to the
/// diagonal: `planarity`, in [0, 1e-2], see coords/detail/convex_polyhedron.h). Adjacent coplanar
/// faces count as one face. `method` names the coordinates in the message.
void checkConvexCage(const Cage& cage, const char* method, double planarity = kDefaultPlanarity);

/// What DiscreteHarmonicCoordinates require: checkConvexCage(), and every face of the polytope (a
/// cage face, or adjacent coplanar cage faces counted as one) a triangle. Otherwise throws
/// InvalidInput naming the cage, the face (or the coplanar faces that merge) and its vertices.
void checkSimplicialConvexCage(const Cage& cage, const char* method,
                               double planarity = kDefaultPlanarity);

}  // namespace spacewarp
