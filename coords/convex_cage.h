#pragma once
// What the coordinates of convex cages (Wachspress, discrete harmonic) share: the policy for
// points outside the cage, and the convexity check.

#include <spacewarp/coords/cage.h>

namespace spacewarp {

/// What the coordinates of a convex cage give points outside it.
enum class ConvexOutsidePolicy {
  /// Throw InvalidInput, saying how many points of the call are outside and naming the first.
  Throw,
  /// The coordinates of the nearest point on the cage surface (they reproduce that point, not x).
  NearestPoint,
};

/// Throws InvalidInput (naming the cage, its reflex edge by its two vertices, or a vertex that is
/// not a corner of the polyhedron) unless `cage` is convex: every edge between two faces that are
/// not coplanar (within a tolerance relative to the diagonal) turns outward. `method` names the
/// coordinates in the message.
void checkConvexCage(const Cage& cage, const char* method);

}  // namespace spacewarp
