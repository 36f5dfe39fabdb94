#pragma once
// Discrete harmonic coordinates of a convex polyhedral cage ("discrete-harmonic"): the closed
// form of CGAL 6.2's Discrete_harmonic_coordinates_3 (cotangent weights of the cone over each
// face, seen from the point), the same weights on every cage of triangles in general position.
// A polygonal face (or coplanar triangles, merged) takes its 2D discrete harmonic coordinates, so
// the row is Lagrange and linear on edges there too (CGAL takes triangles only). They may be
// negative inside the cage.
// Both convex-polyhedron coordinates equal the barycentric coordinates on a tetrahedron. The
// cage must be convex: a reflex edge is an error naming it. The numerics are described at the
// top of discrete_harmonic.cpp.

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
};

/// DiscreteHarmonic coordinates of a closed, outward-oriented convex cage (its faces are planar
/// polygons; triangulated faces are merged back where coplanar). One weight per cage vertex; rows
/// sum to 1 and reproduce x inside the cage. Every method is const and thread-safe.
class DiscreteHarmonicCoordinates final : public Coordinates {
 public:
  /// Shares `cage`. Throws InvalidInput if `cage` is null, an option is out of range, or the
  /// cage is not convex (naming a reflex edge) or has a vertex that is not a corner.
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
