#pragma once
// The coordinates of a lattice: the FFD basis functions B_ijk as the weights of the Coordinates
// interface, so that lattices bind (Binding), export (`spacewarp weights`) and pose like cages.

#include <memory>
#include <span>

#include <spacewarp/core/coordinates.h>
#include <spacewarp/ffd/lattice.h>

namespace spacewarp {

/// Lattice coordinates: one column per control point (i fastest, then j, then k). Inside the
/// box the weights sum to 1 and reproduce the rest grid (Σ w_c P⁰_c = x); outside they follow
/// the lattice's outside policy (all zero for Identity, the nearest surface point's weights for
/// Clamp, those scaled by the falloff for Falloff). Sparse: maxNonZeros() is 8 (trilinear),
/// 64 (B-spline) or every control point (Bernstein). Weight gradients are analytic.
class LatticeCoordinates final : public Coordinates {
 public:
  explicit LatticeCoordinates(Lattice lattice) : lattice_(std::move(lattice)) {}

  const Lattice& lattice() const { return lattice_; }

  std::size_t controlPointCount() const override { return lattice_.controlPointCount(); }
  std::span<const Vec3> restControlPoints() const override { return lattice_.restControlPoints(); }
  std::size_t maxNonZeros() const override { return lattice_.maxNonZeros(); }

  /// Dense row (controlPointCount() entries). Throws InvalidInput if x is not finite or the
  /// row has the wrong size.
  void weights(const Vec3& x, std::span<double> row) const override;
  /// See Lattice::sparseWeights (`out` needs maxNonZeros() entries).
  std::size_t sparseWeights(const Vec3& x, std::span<SparseWeight> out) const override;
  /// Analytic ∇w_c (controlPointCount() entries, per world unit); always returns true.
  bool weightGradients(const Vec3& x, std::span<Vec3> out) const override;

  /// Archive (core/archive.h): tag "lattice", the lattice.
  void save(ArchiveWriter& out) const override;
  static std::shared_ptr<const LatticeCoordinates> load(ArchiveReader& in);

 protected:
  /// A LatticeWarp (the basis evaluated per axis, not a dense row per point).
  std::shared_ptr<const Warp> makeWarpFor(std::shared_ptr<const Coordinates> self,
                                          std::span<const Vec3> posed) const override;

 private:
  Lattice lattice_;
};

}  // namespace spacewarp
