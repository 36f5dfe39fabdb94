#pragma once
// The Warp of a posed lattice: x' = x + Σ_c w_c(x) (P_c − P⁰_c), evaluated by a fast batch
// kernel specialised per basis.

#include <memory>
#include <span>
#include <vector>

#include <spacewarp/core/warp.h>
#include <spacewarp/ffd/lattice.h>

namespace spacewarp {

/// A lattice and its posed control points as a Warp. apply() and applyBatch() give
/// bit-identical results, for any number of threads; the Jacobian is analytic (one-sided, from
/// inside, on the box surface).
class LatticeWarp final : public Warp {
 public:
  /// `posed` has lattice.controlPointCount() points (world units, i fastest, then j, then k).
  /// Throws InvalidInput if it has the wrong size or a point is not finite (naming its index).
  LatticeWarp(Lattice lattice, std::span<const Vec3> posed);

  Vec3 apply(const Vec3& x) const override;
  Mat3 jacobian(const Vec3& x) const override;
  /// Parallel (TBB) over fixed blocks; no allocation and no virtual call per point.

  const Lattice& lattice() const { return lattice_; }
  /// The posed control points.
  std::span<const Vec3> controlPoints() const { return posed_; }

  /// Archive (core/archive.h): tag "lattice-warp", the lattice and the posed (or fitted)
  /// control points: a fitted lattice is not fitted again.
  void save(ArchiveWriter& out) const override;
  static std::shared_ptr<const LatticeWarp> load(ArchiveReader& in);

 protected:
  UnmappedPoints applyRange(std::span<const Vec3> in, std::span<Vec3> out, std::size_t begin,
                            std::size_t end) const override;

 private:
  Lattice lattice_;
  std::vector<Vec3> posed_;
  std::vector<double> displacement_;  // P − P⁰, 4 doubles per control (x, y, z, 0)
};

}  // namespace spacewarp
