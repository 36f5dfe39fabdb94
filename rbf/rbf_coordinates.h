#pragma once
// RBF coordinates: the RBF warp with its fit folded in (the "precomputed basis functions" of
// Botsch & Kobbelt 2005), so that re-posing the handles of a bound point set is one matrix
// product (core/binding.h).

#include <memory>
#include <span>
#include <vector>

#include <spacewarp/core/coordinates.h>
#include <spacewarp/rbf/kernels.h>

namespace spacewarp {

/// The weights β_h(x) of the handles such that, for any targets t_h,
///     x' = x + Σ_h β_h(x) (t_h − c_h)  =  RbfWarp(centers, targets, fixed, options).apply(x)
/// (up to rounding). β(x) = Gᵀ φ(x) + Hᵀ q(x), where [G; H] are the handle columns of the
/// inverse of the RBF saddle-point system (computed once, at construction, by applying its one
/// factorisation to the handles' identity right-hand sides), φ(x) the kernel values at the
/// centers and q(x) = [1, x, y, z].
///
/// Fixed centers are part of the fit but are not controls: their displacement is always zero,
/// so their columns would multiply zero and are left out. Without fixed centers the weights
/// have linear precision, Σ_h β_h(x) = 1 and Σ_h β_h(x) c_h = x (thanks to the linear
/// polynomial, for any smoothing), so x' = Σ_h β_h(x) t_h; with fixed centers f_k the missing
/// weights β_k(x) satisfy Σ_h β_h + Σ_k β_k = 1 and Σ_h β_h c_h + Σ_k β_k f_k = x.
///
/// Coinciding handles (within options.duplicateTolerance of the bounding-box diagonal) share
/// their center's weight equally, so posing them apart moves points by their average; a fixed
/// center that coincides with a handle is dropped (the handle controls that spot).
///
/// Cost: construction O(n³) for n centers (one Cholesky factorisation, n right-hand sides) and
/// n × handles doubles of storage; weights() O(n × handles) per point, with no allocation.
class RbfCoordinates final : public Coordinates {
 public:
  /// `centers`: the handles (world units); `fixed`: centers with zero displacement. Throws as
  /// RbfWarp does (InvalidInput, SolverError), except that no targets are checked; also
  /// InvalidInput when memoryEstimate() exceeds the memory available (detail::checkMemory).
  explicit RbfCoordinates(std::span<const Vec3> centers, const RbfOptions& options = {});
  RbfCoordinates(std::span<const Vec3> centers, std::span<const Vec3> fixed,
                 const RbfOptions& options = {});

  /// The peak memory (bytes) of the constructor for `centers` handles and `fixed` centers:
  /// the system's factor and five dense (centers × handles) arrays during the solve, measured
  /// at 34 to 40 (handles + fixed)² bytes for 1,000 to 4,000 handles. An upper bound.
  static double memoryEstimate(std::size_t centers, std::size_t fixed = 0);

  /// The number of handles (not counting fixed centers).
  std::size_t controlPointCount() const override { return handles_.size(); }
  /// The handles as given.
  std::span<const Vec3> restControlPoints() const override { return handles_; }
  void weights(const Vec3& x, std::span<double> row) const override;
  /// ∇β_h(x) = Σ_j G_jh (φ'(r_j) / r_j) (x − c_j) + ∇(H_h · q): always available.
  bool weightGradients(const Vec3& x, std::span<Vec3> out) const override;

  const RbfOptions& options() const { return options_; }
  /// The fixed centers as given.
  std::span<const Vec3> fixedCenters() const { return fixed_; }

  /// Archive (core/archive.h): tag "rbf-coordinates", the options, handles, fixed centers and
  /// the solved basis; load() checks sizes and finiteness and does not fit.
  void save(ArchiveWriter& out) const override;
  static std::shared_ptr<const RbfCoordinates> load(ArchiveReader& in);

 protected:
  /// An RbfWarp with the posed handles as targets (its own fit: O(n³) once, then the
  /// vectorised kernel per point instead of a dense row).
  std::shared_ptr<const Warp> makeWarpFor(std::shared_ptr<const Coordinates> self,
                                          std::span<const Vec3> posed) const override;

 private:
  RbfOptions options_;
  std::vector<Vec3> handles_;
  std::vector<Vec3> fixed_;
  std::vector<Vec3> centers_;  // distinct centers of the fit
  std::vector<double> g_;      // centers_.size() × handles, row-major
  std::vector<double> h_;      // 4 × handles, row-major: the coefficients of 1, x, y, z

  RbfCoordinates() = default;  // for load()
};

}  // namespace spacewarp
