#pragma once
// Mean-value coordinates for closed triangle meshes (Ju, Schaefer, Warren: "Mean value
// coordinates for closed triangular meshes", SIGGRAPH 2005), evaluated everywhere in space:
// inside and outside the cage, on it, and arbitrarily close to it or to the planes and lines
// of its faces and edges.
//
// For a point x and a cage triangle T, the triangle's mean vector m_T (the integral of the
// unit direction over T projected onto the unit sphere around x) is split along the three
// vertex directions, m_T = Σ_k λ_k u_k, and vertex k of T receives λ_k / |p_k − x|. The
// weights w_i(x) are the normalised sums over all triangles (Σ_i w_i = 1); they reproduce
// linear functions (Σ_i w_i p_i = x) everywhere, are positive inside a convex cage, may be
// negative inside a concave cage and outside any cage, and are linear on the cage faces.
// The numerics are described at the top of mean_value.cpp.

#include <memory>
#include <span>

#include <spacewarp/coords/cage.h>
#include <spacewarp/core/coordinates.h>

namespace spacewarp {

/// Options of MeanValueCoordinates.
struct MeanValueOptions {
  /// Snap distance, relative to Cage::diagonal(). A point at most this far from a cage vertex
  /// gets that vertex's Lagrange weights (exactly δ_ij); failing that, a point at most this far
  /// from the inside of an edge gets the linear interpolation along the edge, and a point at
  /// most this far from the inside of a face the barycentric weights of its projection on
  /// that face. The coordinates are continuous across the cage, so snapping changes weights by
  /// O(snapTolerance); the default is far below any modelling precision. Must be finite and in
  /// [0, 1e-3]; 0 snaps exact hits only.
  double snapTolerance = 1e-14;
};

/// Mean-value coordinates of a closed, outward-oriented triangle cage. One weight per cage
/// vertex (controlPointCount() = columnCount() = cage vertex count); every row is dense and
/// sums to 1. Every method is const and thread-safe; rows are bit-identical whether they come
/// from weights() or weightsBatch(), for any number of threads.
///
/// Accuracy (measured against a quad-precision evaluation of Ju et al.'s formula): weights to
/// about 1e-14 absolute, and Σ_i w_i p_i = x to about 1e-14 cage diagonals, inside the cage,
/// on and arbitrarily near it, near the planes and lines of its faces and edges, and outside up
/// to ~30 diagonals away. Farther out the coordinates are intrinsically ill-conditioned (they
/// grow like the distance while their sum cancels): reproduction degrades like the cube of the
/// distance, to ~1e-12 diagonals at 100 diagonals and ~1e-9 at 1000.
class MeanValueCoordinates final : public Coordinates {
 public:
  /// Shares `cage` (kept alive by this object, which precomputes its topology). Throws
  /// InvalidInput if `cage` is null or an option is out of range.
  explicit MeanValueCoordinates(std::shared_ptr<const Cage> cage,
                                const MeanValueOptions& options = {});
  ~MeanValueCoordinates() override;
  MeanValueCoordinates(const MeanValueCoordinates&) = delete;
  MeanValueCoordinates& operator=(const MeanValueCoordinates&) = delete;

  std::size_t controlPointCount() const override;
  std::span<const Vec3> restControlPoints() const override;

  /// The normalised weights of x (world units) into `row` (cage vertex count entries). Throws
  /// InvalidInput if x is not finite or the row has the wrong size, and SolverError naming x if
  /// the weight sum is zero or not representable there (seen only for points ~1e300 away).
  void weights(const Vec3& x, std::span<double> row) const override;

  const Cage& cage() const;
  const MeanValueOptions& options() const;

  /// Archive (core/archive.h): tag "mean-value", the cage and the options.
  void save(ArchiveWriter& out) const override;
  static std::shared_ptr<const MeanValueCoordinates> load(ArchiveReader& in);

 protected:
  /// Four points at a time (eight on x86-64-v4) through the vectorised kernels; SolverError as
  /// weights().
  std::size_t batchGrain() const override;
  UnmappedPoints weightsRange(std::span<const Vec3> points, std::span<double> rows,
                              std::size_t begin, std::size_t end) const override;

 private:
  struct Impl;
  std::unique_ptr<const Impl> impl_;
};

}  // namespace spacewarp
