#pragma once
// The Warp view of any Coordinates with a posed set of controls, so that everything that
// takes a Warp (soups, point sets, volumes, inversion, normals) works with coordinates.

#include <memory>
#include <span>
#include <vector>

#include <spacewarp/core/coordinates.h>
#include <spacewarp/core/warp.h>

namespace spacewarp {

/// x' = x + Σ_c w_c(x) (C_c(posed) − C_c(rest)). The Jacobian is
/// I + Σ_c (C_c(posed) − C_c(rest)) ∇w_cᵀ when the coordinates offer weight gradients, and
/// central differences (Warp's default) otherwise. Sparse coordinates (at most a quarter of the
/// columns non-zero per point, e.g. a trilinear lattice's 8) are summed over their non-zero
/// weights only, in column order: the same value as the dense sum.
class CoordinateWarp final : public Warp {
 public:
  /// `posed` has controlPointCount() entries. Throws InvalidInput if `coordinates` is null or
  /// `posed` has the wrong size or is not finite.
  CoordinateWarp(std::shared_ptr<const Coordinates> coordinates, std::span<const Vec3> posed);

  Vec3 apply(const Vec3& x) const override;
  Mat3 jacobian(const Vec3& x) const override;

  const Coordinates& coordinates() const { return *coordinates_; }

  /// Archive (core/archive.h): tag "coordinate-warp", the coordinates (nested) and the posed
  /// control points.
  void save(ArchiveWriter& out) const override;
  static std::shared_ptr<const CoordinateWarp> load(ArchiveReader& in);

 protected:
  /// Weights block by block through Coordinates::weightsBatch, so that multi-point kernels
  /// (mean-value, Green) are used; their rows are bit-identical to weights(), so this equals
  /// apply().
  std::size_t batchGrain() const override { return 64; }
  UnmappedPoints applyRange(std::span<const Vec3> in, std::span<Vec3> out, std::size_t begin,
                            std::size_t end) const override;

 private:
  std::shared_ptr<const Coordinates> coordinates_;
  Vec3 displaceSparse(const Vec3& x, std::span<SparseWeight> slots) const;

  std::vector<Vec3> posed_;         // as given, for save()
  std::vector<Vec3> displacement_;  // C(posed) − C(rest), columnCount() entries
  bool sparse_ = false;             // sum over sparseWeights() (as Binding decides)
};

}  // namespace spacewarp
