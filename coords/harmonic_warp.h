#pragma once
// The Warp view of harmonic coordinates, specialised: the posed cage's displacements are mixed
// once per mesh vertex, so warping a point costs one point location and a 4-term barycentric
// mix, independent of the cage's vertex count (CoordinateWarp, which works for any coordinates,
// forms the whole weight row of every point instead).

#include <memory>
#include <span>
#include <vector>

#include <spacewarp/coords/harmonic.h>
#include <spacewarp/core/warp.h>

namespace spacewarp {

/// x' = x + Σ_c w_c(x) (p'_c − p_c) for harmonic coordinates w and a posed cage p'. Equal to
/// CoordinateWarp on the same coordinates up to round-off (the sums are associated per mesh
/// vertex first); deterministic for any thread count, and applyBatch() is bit-identical to
/// apply(). Points outside the cage follow the coordinates' HarmonicOutsidePolicy: Throw makes
/// apply() and applyBatch() throw InvalidInput with the number of outside points (all of them,
/// for a batch) and the first one's index; NearestPoint moves them with the nearest cage point.
class HarmonicWarp final : public Warp {
 public:
  /// `posed` has one point per cage vertex (world units). Throws InvalidInput if `coordinates`
  /// is null or `posed` has the wrong size or is not finite.
  HarmonicWarp(std::shared_ptr<const HarmonicCoordinates> coordinates, std::span<const Vec3> posed);

  Vec3 apply(const Vec3& x) const override;
  /// Constant per tet: I + Σ_a D_a ∇b_aᵀ over the tet's corners a (D_a the mixed displacement,
  /// b_a the barycentric coordinates); central differences outside the cage (NearestPoint).
  Mat3 jacobian(const Vec3& x) const override;

  const HarmonicCoordinates& coordinates() const { return *coordinates_; }

  /// Archive (core/archive.h): tag "harmonic-warp", the coordinates (their solved field) and
  /// the posed cage; load() mixes the displacements again (no solve).
  void save(ArchiveWriter& out) const override;
  static std::shared_ptr<const HarmonicWarp> load(ArchiveReader& in);

 protected:
  std::size_t batchGrain() const override;
  UnmappedPoints applyRange(std::span<const Vec3> in, std::span<Vec3> out, std::size_t begin,
                            std::size_t end) const override;
  [[noreturn]] void throwUnmapped(const UnmappedPoints& unmapped,
                                  std::span<const Vec3> in) const override;

 private:
  // The displacement of x, or false if x is outside the cage.
  bool displacement(const Vec3& x, Vec3& d) const;

  std::shared_ptr<const HarmonicCoordinates> coordinates_;
  std::vector<Vec3> posed_;               // as given, for save()
  std::vector<Vec3> cageDisplacement_;    // p'_c − p_c
  std::vector<Vec3> vertexDisplacement_;  // per mesh vertex: Σ_c U_vc (p'_c − p_c)
};

}  // namespace spacewarp
