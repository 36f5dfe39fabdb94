#pragma once
// The coordinate interface shared by every warp that is linear in its controls: cage
// coordinates (mean-value, Green, harmonic), FFD lattices and RBF handles.
//
// Such a warp moves a point x by a weighted sum of control displacements:
//
//     x' = x + Σ_c w_c(x) (C_c(posed) − C_c(rest))
//
// where C is the column-control matrix built from the posed control points: the control
// points themselves, plus (for Green coordinates) one scaled face normal per cage face. For
// coordinates with linear precision (Σ_c w_c(x) C_c(rest) = x) this is the familiar
// x' = Σ_c w_c(x) C_c(posed); written as a displacement it is exactly the identity at rest
// and also covers warps that do not reproduce x outside their domain (an FFD lattice with an
// identity border).

#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include <spacewarp/core/math.h>
#include <spacewarp/core/warp.h>

namespace spacewarp {

class ArchiveReader;
class ArchiveWriter;

/// One non-zero entry of a sparse weight row.
struct SparseWeight {
  std::uint32_t column = 0;
  double weight = 0.0;
};

/// Coordinates of points with respect to a set of controls. Every method is const and
/// thread-safe.
class Coordinates {
 public:
  virtual ~Coordinates() = default;

  /// How many control points a user poses: cage vertices, lattice points, RBF handles.
  virtual std::size_t controlPointCount() const = 0;

  /// The rest positions of the control points (controlPointCount() entries, world units).
  virtual std::span<const Vec3> restControlPoints() const = 0;

  /// Columns of the weight matrix: controlPointCount(), plus one per face for Green coordinates.
  virtual std::size_t columnCount() const { return controlPointCount(); }

  /// The name of column c, for exports: "v<i>" for control point i, "f<j>" for face j.
  virtual std::string columnName(std::size_t c) const;

  /// The weights of one point: row[c] = w_c(x) for every column. `row` has columnCount()
  /// entries. Throws InvalidInput if x is not finite or the row has the wrong size.
  virtual void weights(const Vec3& x, std::span<double> row) const = 0;

  /// The weights of many points, row-major (points.size() × columnCount()), in parallel (TBB):
  /// [0, n) is cut into ranges of batchGrain() points, each computed by weightsRange(), so the
  /// rows do not depend on the number of threads. Throws InvalidInput if `rows` has the wrong
  /// size or a point is not finite (naming the first), and what throwUnmapped() throws when
  /// some points have no weights.
  void weightsBatch(std::span<const Vec3> points, std::span<double> rows) const;

  /// weightsBatch() of the block [begin, end) of a larger batch `points`, for callers that cut
  /// a batch into blocks (progress, cancellation, a warp's ranges): `rows` holds the block's
  /// rows only ((end − begin) × columnCount()). Errors name indices into `points` and its size,
  /// so that the caller's point is named; the count is of the block's unmapped points.
  void weightsBatch(std::span<const Vec3> points, std::size_t begin, std::size_t end,
                    std::span<double> rows) const;

  /// At most how many weights of one point are non-zero: columnCount() for dense coordinates
  /// (cages, harmonic coordinates included, RBF); 8 for a trilinear lattice.
  virtual std::size_t maxNonZeros() const { return columnCount(); }

  /// The non-zero weights of one point, into `out` (at least maxNonZeros() entries), sorted by
  /// column; returns how many were written. The default filters weights().
  virtual std::size_t sparseWeights(const Vec3& x, std::span<SparseWeight> out) const;

  /// The column controls C (columnCount() entries) for the given control points
  /// (controlPointCount() entries): the points themselves by default; Green coordinates append
  /// the scaled face normals. Throws InvalidInput if `posed` has the wrong size or is not finite.
  virtual void columnControls(std::span<const Vec3> posed, std::span<Vec3> out) const;

  /// The gradients ∇w_c(x) of every weight (columnCount() entries), if the coordinates offer
  /// them analytically; returns false (leaving `out` unspecified) if they do not, and callers
  /// fall back to finite differences.
  virtual bool weightGradients(const Vec3& x, std::span<Vec3> out) const;

  /// Writes these coordinates to an archive (core/archive.h): their tag, then what rebuilds
  /// them (solved state included). The default throws InvalidInput naming the type.
  virtual void save(ArchiveWriter& out) const;

 protected:
  /// Throws InvalidInput unless x is finite and row.size() == columnCount().
  void checkWeightsArguments(const Vec3& x, std::size_t rowSize) const;

  /// The Warp of these coordinates posed by `posed`, for makeWarp(): `self` is this object.
  /// The default is a CoordinateWarp; coordinates with a faster warp of their own override it.
  virtual std::shared_ptr<const Warp> makeWarpFor(std::shared_ptr<const Coordinates> self,
                                                  std::span<const Vec3> posed) const;

  /// Points per range of weightsBatch() (default 64).
  virtual std::size_t batchGrain() const { return 64; }

  /// The batch kernel: the rows of points [begin, end) (indices into the whole batch; row i is
  /// rows[i · columnCount(), (i + 1) · columnCount())), every point finite. Called on disjoint
  /// ranges from several threads at once. Returns the points that have no weights (their rows
  /// unspecified); the default calls weights() per point and reports none.
  virtual UnmappedPoints weightsRange(std::span<const Vec3> points, std::span<double> rows,
                                      std::size_t begin, std::size_t end) const;

  /// Throws for the points of the batch that weightsRange() could not weigh. The default throws
  /// InvalidInput with their number and the first one's index.
  [[noreturn]] virtual void throwUnmapped(const UnmappedPoints& unmapped,
                                          std::span<const Vec3> points) const;

 private:
  friend std::shared_ptr<const Warp> makeWarp(std::shared_ptr<const Coordinates> coordinates,
                                              std::span<const Vec3> posed);
};

/// The fastest Warp of `coordinates` posed by `posed` (controlPointCount() points, world
/// units): x' = x + Σ_c w_c(x) (C_c(posed) − C_c(rest)), computed by the coordinates' own warp
/// where they have one (HarmonicWarp, LatticeWarp, RbfWarp) and by a CoordinateWarp otherwise.
/// The warp keeps `coordinates` alive. Throws InvalidInput if `coordinates` is null or `posed`
/// has the wrong size or is not finite.
std::shared_ptr<const Warp> makeWarp(std::shared_ptr<const Coordinates> coordinates,
                                     std::span<const Vec3> posed);

}  // namespace spacewarp
