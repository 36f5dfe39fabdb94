#pragma once
// Discrete harmonic coordinates of a simplicial convex cage ("discrete-harmonic"): the closed form
// of CGAL 6.2's Discrete_harmonic_coordinates_3 (cotangent weights of the cone over each triangle,
// seen from the point; Ju, Liepa and Warren 2007). Like CGAL's, they take convex polytopes whose
// faces are all triangles: a polygon face, or coplanar triangles that merge into one, is refused,
// because a polygon's 2D coordinates, continued past it to where an interior point projects, have
// poles (weights down to −4956 were measured) and a triangulation of it makes the coordinates
// discontinuous at its corners (discrete_harmonic.cpp has the details). WachspressCoordinates take
// polygon faces.
// The row is Lagrange, linear on edges and barycentric on every face. Weights may be negative
// inside the cage (where the point sees a dihedral angle above 90°). Lowest weight measured at
// 10,000 random interior points: regular octahedron −0.021; icospheres −0.0073, −0.0018, −0.00046
// (1, 2, 3 subdivisions); convex hulls of 20 to 200 random sphere points −0.11 to −0.36 (20
// hulls); tests/coords/discrete_harmonic_test.cpp holds them above −1.
// Both convex-polyhedron coordinates equal the barycentric coordinates on a tetrahedron. The
// cage must be convex: a reflex edge is an error naming it.

#include <memory>
#include <span>

#include <spacewarp/coords/cage.h>
#include <spacewarp/coords/convex_cage.h>
#include <spacewarp/core/coordinates.h>

namespace spacewarp {

/// Options of DiscreteHarmonicCoordinates.
struct DiscreteHarmonicOptions {
  /// Points within snapTolerance × Cage::diagonal() of the cage surface get the coordinates of
  /// the surface there (see discrete_harmonic.cpp). Must be in [0, 1e-3].
  double snapTolerance = 1e-14;
  /// Points outside the cage (farther than snapTolerance): see ConvexOutsidePolicy.
  ConvexOutsidePolicy outside = ConvexOutsidePolicy::Throw;
  /// How far, relative to Cage::diagonal(), a corner may be from its face's best-fit plane (or
  /// above a neighbouring face's plane) and still count as on it; farther is an error naming the
  /// face or reflex edge. A nearly planar face is treated as lying in its best-fit plane, so x is
  /// reproduced to about the corners' distance from it (1.3e-7 diagonals measured on rotated
  /// boxes, prisms and truncated octahedra written in float32 or with 6 decimals), and points
  /// on the cage's own faces, that far off the plane, are not outside. See kDefaultPlanarity for
  /// what the default admits. Must be in [0, 1e-2].
  double planarity = kDefaultPlanarity;
};

/// Discrete harmonic coordinates of a closed, outward-oriented convex cage of triangles, no two
/// adjacent ones coplanar (a simplicial convex polytope). One weight per cage vertex; rows sum to 1
/// and reproduce x inside the cage. Every method is const and thread-safe.
class DiscreteHarmonicCoordinates final : public Coordinates {
 public:
  /// Shares `cage`. Throws InvalidInput if `cage` is null, an option is out of range, the cage
  /// is not convex (naming a reflex edge) or has a vertex that is not a corner, or a face of the
  /// polytope is not a triangle (naming the cage face, or the coplanar faces that merge, and its
  /// vertices).
  explicit DiscreteHarmonicCoordinates(std::shared_ptr<const Cage> cage,
                                       const DiscreteHarmonicOptions& options = {});
  ~DiscreteHarmonicCoordinates() override;
  DiscreteHarmonicCoordinates(const DiscreteHarmonicCoordinates&) = delete;
  DiscreteHarmonicCoordinates& operator=(const DiscreteHarmonicCoordinates&) = delete;

  std::size_t controlPointCount() const override;
  std::span<const Vec3> restControlPoints() const override;

  /// The weights of x (world units) into `row` (cage vertex count entries). Throws
  /// InvalidInput if x is not finite, the row has the wrong size, or x is outside and the
  /// policy is Throw.
  void weights(const Vec3& x, std::span<double> row) const override;

  /// The gradients ∇w_v(x) (per world unit, cage vertex count entries) of the closed form, for x
  /// inside the cage farther than the snap distance from its surface; false elsewhere (callers
  /// then use finite differences). Throws InvalidInput if x is not finite or `out` has the wrong
  /// size.
  bool weightGradients(const Vec3& x, std::span<Vec3> out) const override;

  const Cage& cage() const;
  const DiscreteHarmonicOptions& options() const;

  /// Archive (core/archive.h): tag "discrete-harmonic", the cage and the options.
  void save(ArchiveWriter& out) const override;
  static std::shared_ptr<const DiscreteHarmonicCoordinates> load(ArchiveReader& in);

 protected:
  UnmappedPoints weightsRange(std::span<const Vec3> points, std::span<double> rows,
                              std::size_t begin, std::size_t end) const override;
  [[noreturn]] void throwUnmapped(const UnmappedPoints& unmapped,
                                  std::span<const Vec3> points) const override;

 private:
  struct Impl;
  std::unique_ptr<const Impl> impl_;
};

}  // namespace spacewarp
