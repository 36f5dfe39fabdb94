#pragma once
// Shepard's inverse-distance weighting (Shepard, "A two-dimensional interpolation function for
// irregularly-spaced data", ACM 1968) as coordinates of point handles, with the local-support
// weights of Franke & Nielson ("Smooth interpolation of large sets of scattered data", 1980).
// Handles p_i move to targets q_i; every point moves by the weighted mean of the handles'
// displacements.

#include <limits>
#include <memory>
#include <span>
#include <vector>

#include <spacewarp/core/coordinates.h>
#include <spacewarp/core/warp.h>

namespace spacewarp {

class ArchiveReader;
class ArchiveWriter;

/// Options of ShepardCoordinates.
struct ShepardOptions {
  /// Weight exponent p: finite, > 0. Default 2 (Shepard's choice). For p > 1 every weight is
  /// flat at every handle (∇w_i(p_j) = 0), so the warp's Jacobian at a handle is the identity
  /// whatever the targets; for p <= 1 the weights have cusps at the handles (not
  /// differentiable there).
  double power = 2.0;
  /// Support radius R, world units: in (0, 1e150], or +infinity (default) for the classic
  /// global weights. With a finite R the weights are Franke & Nielson's ((R − d_i)_+ / (R d_i))^p
  /// and points farther than R from every handle have no weights (reported, never guessed).
  double radius = std::numeric_limits<double>::infinity();
};

/// w_i(x) = u_i(x) / Σ_j u_j(x), u_i = d_i^-p (global) or ((R − d_i)_+ / (R d_i))^p (local
/// support), d_i = |x − p_i|. The weights are non-negative, sum to 1 and interpolate: exactly at
/// a handle they are the Kronecker delta. As a warp (makeWarp) x' = x + Σ_i w_i(x) (q_i − p_i):
/// it maps each handle to its target, reproduces a common translation, but NOT linear functions
/// (Σ_i w_i(x) p_i ≠ x in general: a uniform scale of the handles is not a uniform scale of
/// space; the weighted mean pulls every point towards the handles' displacements, the "flat
/// spots" of Shepard's method around each handle for p > 1).
///
/// Numerics: the u_i are normalised by the nearest handle's (so the largest is 1), so points
/// near a handle or far from all of them neither overflow nor underflow; a point whose squared
/// distance to its nearest handle is 0 in double precision gets that handle's delta.
///
/// Points with no handle within R (finite radius only): weights() and the warp's apply() throw
/// InvalidInput naming the point; weightsBatch() and applyBatch() throw InvalidInput with their
/// number and the first one's index. They are not kept at rest: the weights jump from the last
/// handle's full weight to nothing at the edge of the supports, so any value given there would
/// be a discontinuity the user did not ask for.
///
/// Gradients (weightGradients) are analytic; at a handle they are 0 for p > 1 and not defined for
/// p <= 1 (weightGradients then returns false and callers use finite differences).
///
/// Cost: O(n) per point for n handles (global). With a radius, a point reads the handles listed
/// for its cell of a uniform grid (cells of max(R, extent / 64), each listing the handles of its
/// 3 × 3 × 3 block, about 27 R³ × the handle density; 27 entries per handle in memory) and weighs
/// the k within R; maxNonZeros() is the longest cell list (a bound, found in O(cells)). About 90 ns
/// of CPU per point for 16 global handles, 2 µs for 1024 handles with ~67 in reach
/// (bench/nonlinear_bench_shepard_kelvinlet.cpp).
class ShepardCoordinates final : public Coordinates {
 public:
  /// `handles`: n >= 1 points, world units. Throws InvalidInput naming the problem for no handle,
  /// a non-finite handle or one beyond 1e150 (with its index), coincident handles (closer than
  /// 1e-12 × their bounding-box diagonal, with both indices), a non-finite or non-positive power,
  /// or a radius that is NaN, <= 0 or finite above 1e150.
  explicit ShepardCoordinates(std::vector<Vec3> handles, const ShepardOptions& options = {});
  ~ShepardCoordinates() override;

  std::size_t controlPointCount() const override;
  std::span<const Vec3> restControlPoints() const override;
  void weights(const Vec3& x, std::span<double> row) const override;
  std::size_t maxNonZeros() const override;
  std::size_t sparseWeights(const Vec3& x, std::span<SparseWeight> out) const override;
  bool weightGradients(const Vec3& x, std::span<Vec3> out) const override;

  const ShepardOptions& options() const;
  /// Whether the weights have a finite support radius.
  bool local() const;

  /// Archive tag "shepard": handles, power and radius.
  void save(ArchiveWriter& out) const override;
  /// Rebuilt through the constructor.
  static std::shared_ptr<const ShepardCoordinates> load(ArchiveReader& in);

  struct Impl;  // internals, shared with the warp

 protected:
  std::shared_ptr<const Warp> makeWarpFor(std::shared_ptr<const Coordinates> self,
                                          std::span<const Vec3> posed) const override;
  std::size_t batchGrain() const override { return 256; }
  UnmappedPoints weightsRange(std::span<const Vec3> points, std::span<double> rows,
                              std::size_t begin, std::size_t end) const override;
  [[noreturn]] void throwUnmapped(const UnmappedPoints& unmapped,
                                  std::span<const Vec3> points) const override;

 private:
  friend class ShepardWarp;
  std::unique_ptr<const Impl> impl_;
};

/// The warp of ShepardCoordinates posed by targets q_i: x' = x + Σ_i w_i(x) (q_i − p_i), without a
/// weight row (the displacements are summed as the weights are made). Bit-identical to
/// CoordinateWarp over the same coordinates' weights; applyBatch is parallel and
/// bit-identical to apply() for any thread count. The Jacobian is analytic,
/// I + Σ_i (q_i − p_i) ∇w_iᵀ (the identity at a handle for p > 1; finite differences at a handle
/// for p <= 1). Points without weights throw as ShepardCoordinates does.
class ShepardWarp final : public Warp {
 public:
  /// `targets`: one per handle, world units. Throws InvalidInput for a null `coordinates`, a
  /// wrong count or a non-finite target (with its index).
  ShepardWarp(std::shared_ptr<const ShepardCoordinates> coordinates, std::span<const Vec3> targets);
  /// Builds the coordinates too (throws as ShepardCoordinates does).
  ShepardWarp(std::vector<Vec3> handles, std::span<const Vec3> targets,
              const ShepardOptions& options = {});

  Vec3 apply(const Vec3& x) const override;
  Mat3 jacobian(const Vec3& x) const override;

  const ShepardCoordinates& coordinates() const { return *coordinates_; }

  /// Archive tag "shepard-warp": the coordinates (nested) and the displacements q_i − p_i as
  /// stored, so that the loaded warp adds the very same doubles.
  void save(ArchiveWriter& out) const override;
  /// Checks the nested coordinates' kind, the displacements' count and finiteness.
  static std::shared_ptr<const ShepardWarp> load(ArchiveReader& in);

 protected:
  std::size_t batchGrain() const override { return 1024; }
  UnmappedPoints applyRange(std::span<const Vec3> in, std::span<Vec3> out, std::size_t begin,
                            std::size_t end) const override;
  [[noreturn]] void throwUnmapped(const UnmappedPoints& unmapped,
                                  std::span<const Vec3> in) const override;

 private:
  struct Displacements {};  // selects the constructor from stored displacements
  ShepardWarp(std::shared_ptr<const ShepardCoordinates> coordinates, std::vector<Vec3> displacement,
              Displacements);

  std::shared_ptr<const ShepardCoordinates> coordinates_;
  std::vector<Vec3> displacement_;  // q_i − p_i
};

}  // namespace spacewarp
