#pragma once
// Mean-value coordinates of polygon cages, quads included ("qmvc"): triangles as Ju, Schaefer
// and Warren (coords/mean_value.h), planar polygons by the spherical mean-value construction of
// Langer, Belyaev and Seidel ("Spherical barycentric coordinates", SGP 2006), and quads, planar
// or not, as bilinear patches by Thiery, Memari and Boubekeur ("Mean value coordinates for quad
// cages in 3D", SIGGRAPH Asia 2018). No face is triangulated, so the coordinates do not depend
// on a diagonal or on which vertex a face starts at. The numerics are described at the top of
// quad_mean_value.cpp.

#include <memory>
#include <span>

#include <spacewarp/coords/cage.h>
#include <spacewarp/core/coordinates.h>

namespace spacewarp {

/// Options of QuadMeanValueCoordinates.
struct QuadMeanValueOptions {
  /// Snap distance, relative to Cage::diagonal(), as MeanValueOptions::snapTolerance: a point at
  /// most this far from a cage vertex, edge or face gets the coordinates of the cage surface
  /// there (Lagrange at vertices, linear along edges, the face's own interpolant on faces).
  /// Must be finite and in [0, 1e-3].
  double snapTolerance = 1e-14;
  /// Faces of more than 4 vertices must be planar: every vertex at most this far (relative to
  /// Cage::diagonal()) from the plane through the face's centroid normal to its Newell normal;
  /// such a face is then treated as lying in that best-fit plane. The default (as
  /// kDefaultPlanarity in coords/convex_cage.h) admits coordinates written with 6 decimals or in
  /// float32 for cages of diagonal ≥ 1 near the origin. Must be finite and in [0, 1e-2].
  double polygonPlanarity = 1e-6;
};

/// Mean-value coordinates of a closed, outward-oriented polygon cage. One weight per cage
/// vertex (controlPointCount() = columnCount() = cage vertex count); every row is dense, sums to
/// 1 and reproduces x. On an all-triangle cage they are the triangle mean-value coordinates.
/// Every method is const and thread-safe; rows are bit-identical whether they come from
/// weights() or weightsBatch(), for any number of threads.
///
/// Accuracy: partition of unity and linear precision to ~1e-14 (cage diagonals) inside, on and
/// near the cage and out to 3 diagonals; farther out the weights cancel as MVC's do: measured
/// (2000 points per radius, planar and warped quads) 4e-13 at 10, 1e-13 at 30, 2e-12 at 100 and
/// 1.3e-9 at 1000 diagonals (MVC on the triangulation: 2e-15, 5e-14, 1.4e-12, 1.5e-9), ~1e-11
/// with polygons; points beyond 3000 diagonals are refused, as by MeanValueCoordinates. A quad's
/// share along the one direction its mean vector leaves free is the bilinear integral itself, by
/// error-controlled adaptive Gauss-Legendre quadrature (see quad_mean_value.cpp): rows equal a
/// brute-force long-double integral to ~3e-16 (max |Δw|) inside, outside and 1e-3 … 1e-12 diagonals
/// from faces, edges and vertices. Cost: ~515 ns per (point × quad) on one thread, ~21 times MVC on
/// the quad's two triangles.
class QuadMeanValueCoordinates final : public Coordinates {
 public:
  /// Shares `cage`. Throws InvalidInput if `cage` is null, an option is out of range, or a face
  /// of more than 4 vertices is not planar (see polygonPlanarity; the message names the face),
  /// or a quad's bilinear patch folds over (a planar quad that is not strictly convex, or a
  /// non-planar one whose patch normal turns against its Newell normal somewhere:
  /// coords/detail/quad_fold.h; the message names the face and its vertices; split such a quad
  /// into triangles: near a fold the weights would grow like 1 / distance). Quads may be
  /// non-planar.
  explicit QuadMeanValueCoordinates(std::shared_ptr<const Cage> cage,
                                    const QuadMeanValueOptions& options = {});
  ~QuadMeanValueCoordinates() override;
  QuadMeanValueCoordinates(const QuadMeanValueCoordinates&) = delete;
  QuadMeanValueCoordinates& operator=(const QuadMeanValueCoordinates&) = delete;

  std::size_t controlPointCount() const override;
  std::span<const Vec3> restControlPoints() const override;

  /// The normalised weights of x (world units) into `row` (cage vertex count entries). Throws
  /// InvalidInput if x is not finite or the row has the wrong size.
  void weights(const Vec3& x, std::span<double> row) const override;

  const Cage& cage() const;
  const QuadMeanValueOptions& options() const;

  /// Archive (core/archive.h): tag "quad-mean-value", the cage and the options
  /// (snapTolerance, polygonPlanarity).
  void save(ArchiveWriter& out) const override;
  static std::shared_ptr<const QuadMeanValueCoordinates> load(ArchiveReader& in);

 protected:
  UnmappedPoints weightsRange(std::span<const Vec3> points, std::span<double> rows,
                              std::size_t begin, std::size_t end) const override;

 private:
  struct Impl;
  std::unique_ptr<const Impl> impl_;
};

}  // namespace spacewarp
