#pragma once
// Green coordinates of tri-quad cages ("qgc"): Thiery and Boubekeur, "Green coordinates for
// triquad cages in 3D", SIGGRAPH Asia 2022. Triangles are as in coords/green.h (one normal
// coordinate each); quads, planar or not, are bilinear patches with four normal coordinates
// each, from the paper's Neumann boundary condition. Interior, surface and exterior points are
// handled as for triangle Green coordinates; outside, a quad continues the coordinates through
// the frame of its patch at the foot of x (exact reproduction, continuous across the quad, not
// analytic there). The quad integrals are adaptive Gauss-Legendre quadrature to ~1e-15, and each
// row of a cage with quads is then projected onto its affine constraints (Σ φ = 1, x reproduced
// at rest), which near a cage vertex absorbs a cancellation round-off of the faces around it: Σ φ
// and reproduction are exact to round-off everywhere, but next to a vertex (1e-14 of the
// diagonal) the entries themselves can be off by ~5e-6. Far outside the error grows as triangle
// Green's (~1e-12 of the diagonal at 1000 diagonals). An all-triangle cage gives
// GreenCoordinates' rows bit for bit. The numerics are described at the top of quad_green.cpp.

#include <memory>
#include <span>
#include <string>

#include <spacewarp/coords/cage.h>
#include <spacewarp/core/coordinates.h>

namespace spacewarp {

/// Options of QuadGreenCoordinates.
struct QuadGreenOptions {
  /// Points closer than surfaceTolerance × cage.diagonal() to the cage surface are surface
  /// points, as GreenOptions::surfaceTolerance. Must be in [0, 1e-3].
  double surfaceTolerance = 1e-14;
};

/// Green coordinates of a cage of triangles and quads. Columns: the V vertex coordinates φ_i
/// first, then the normal coordinates of the faces in face order: one per triangle face, four
/// per quad face (columnName(): "f<j>" for triangle face j, "f<j>.<k>" for corner k of quad
/// face j). Similarities of the cage are reproduced. On an all-triangle cage they are the
/// triangle Green coordinates. Every method is const and thread-safe.
class QuadGreenCoordinates final : public Coordinates {
 public:
  /// Shares `cage`. Throws InvalidInput if `cage` is null, an option is out of range, a face
  /// is neither a triangle nor a quad (naming it), or a quad's bilinear patch folds over (a
  /// planar quad that is not strictly convex, or a non-planar one whose patch normal turns
  /// against its Newell normal somewhere: coords/detail/quad_fold.h; the message names the face
  /// and its vertices; split such a quad into triangles). Quads may be non-planar.
  explicit QuadGreenCoordinates(std::shared_ptr<const Cage> cage,
                                const QuadGreenOptions& options = {});
  ~QuadGreenCoordinates() override;
  QuadGreenCoordinates(const QuadGreenCoordinates&) = delete;
  QuadGreenCoordinates& operator=(const QuadGreenCoordinates&) = delete;

  std::size_t controlPointCount() const override;
  std::span<const Vec3> restControlPoints() const override;
  /// V + (triangle faces) + 4 × (quad faces).
  std::size_t columnCount() const override;
  std::string columnName(std::size_t c) const override;

  /// The coordinates of x: φ for the V vertices, then the normal coordinates (world units).
  /// Throws InvalidInput if x is not finite or row.size() != columnCount().
  void weights(const Vec3& x, std::span<double> row) const override;

  /// The column controls of a posed cage: the posed vertices, then the posed, stretched normal
  /// controls of every face (see quad_green.cpp). Throws InvalidInput as
  /// GreenCoordinates::columnControls.
  void columnControls(std::span<const Vec3> posed, std::span<Vec3> out) const override;

  const Cage& cage() const;
  const QuadGreenOptions& options() const;

  /// Archive (core/archive.h): tag "quad-green", the cage and the options.
  void save(ArchiveWriter& out) const override;
  static std::shared_ptr<const QuadGreenCoordinates> load(ArchiveReader& in);

 protected:
  UnmappedPoints weightsRange(std::span<const Vec3> points, std::span<double> rows,
                              std::size_t begin, std::size_t end) const override;

 private:
  struct Impl;
  std::unique_ptr<const Impl> impl_;
};

}  // namespace spacewarp
