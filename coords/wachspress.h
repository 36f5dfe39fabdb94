#pragma once
// Wachspress coordinates of a convex polyhedral cage ("wachspress"): the rational closed form of
// Warren, Schaefer, Hirani and Desbrun ("Barycentric coordinates for convex sets", 2007) over the
// polar dual of each vertex, as CGAL 6.2's Wachspress_coordinates_3. Positive inside the cage.
// Both convex-polyhedron coordinates equal the barycentric coordinates on a tetrahedron. The
// cage must be convex: a reflex edge is an error naming it. The numerics are described at the
// top of wachspress.cpp.

#include <memory>
#include <span>

#include <spacewarp/coords/cage.h>
#include <spacewarp/coords/convex_cage.h>
#include <spacewarp/core/coordinates.h>

namespace spacewarp {

/// Options of WachspressCoordinates.
struct WachspressOptions {
  /// Points within snapTolerance × Cage::diagonal() of the cage surface get the coordinates of
  /// the surface there (see wachspress.cpp). Must be in [0, 1e-3].
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

/// Wachspress coordinates of a closed, outward-oriented convex cage (its faces are planar polygons;
/// triangulated faces are merged back where coplanar). One weight per cage vertex; rows sum to
/// 1 and reproduce x inside the cage. Every method is const and thread-safe.
class WachspressCoordinates final : public Coordinates {
 public:
  /// Shares `cage`. Throws InvalidInput if `cage` is null, an option is out of range, or the
  /// cage is not convex (naming a reflex edge) or has a vertex that is not a corner.
  explicit WachspressCoordinates(std::shared_ptr<const Cage> cage,
                                 const WachspressOptions& options = {});
  ~WachspressCoordinates() override;
  WachspressCoordinates(const WachspressCoordinates&) = delete;
  WachspressCoordinates& operator=(const WachspressCoordinates&) = delete;

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
  const WachspressOptions& options() const;

  /// Archive (core/archive.h): tag "wachspress", the cage and the options.
  void save(ArchiveWriter& out) const override;
  static std::shared_ptr<const WachspressCoordinates> load(ArchiveReader& in);

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
