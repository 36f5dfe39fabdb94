#pragma once
// RBF warps: a displacement field interpolating (or approximating) handle displacements with
// radial basis functions plus a linear polynomial, after Botsch & Kobbelt, "Real-time shape
// editing using radial basis functions" (Eurographics 2005).

#include <memory>
#include <span>
#include <vector>

#include <spacewarp/core/warp.h>
#include <spacewarp/rbf/kernels.h>

namespace spacewarp {

/// x' = x + d(x), d(x) = Σ_j w_j φ(|c_j − x|) + p(x), p linear (p(x) = L x + b). The weights w_j
/// (one Vec3 per center) and p are fitted so that d(c_j) = t_j − c_j at every handle center c_j
/// with target t_j and d(f_k) = 0 at every fixed center f_k (λ = 0), subject to Σ_j w_j = 0 and
/// Σ_j w_j c_jᵀ = 0. One factorisation serves the three coordinates (see rbf/detail/rbf_system.h: a
/// null-space reduction to an SPD system solved by Cholesky). Affine motions of the handles
/// (with no fixed centers) are reproduced exactly everywhere.
///
/// Jacobian: I + L + Σ_j w_j (φ'(r_j) / r_j) (x − c_j)ᵀ, r_j = |x − c_j| (see
/// rbfKernelSlopeOverR for r = 0). applyBatch evaluates four points per SIMD pass over the
/// centers in structure-of-arrays form (an x86-64-v3 clone and a portable one), in parallel
/// (TBB); each point's result is bit-identical to apply() for any thread count. The loop calls
/// no libm (Newton square roots, polynomial exp and log, within a few ulp of std::).
///
/// Cost: the fit is one n × n Cholesky factorisation, ~n³/3 flops (2,000 centers: ~0.2 s);
/// evaluation is O(n) per point (~10⁹ point × center pairs per second on two cores for the
/// triharmonic kernel; see bench/rbf_bench.cpp).
class RbfWarp final : public Warp {
 public:
  /// `centers` (n handles) and `targets` (n), world units. Throws InvalidInput for empty input,
  /// mismatched sizes, non-finite points (naming the index), coinciding centers whose targets
  /// differ (naming both; coinciding centers with agreeing targets are merged, within
  /// options.duplicateTolerance of the centers' bounding-box diagonal), fewer than 4 affinely
  /// independent centers, invalid options or a kernel scale that does not suit the centers
  /// (rbfScaleProblem); SolverError for a singular system.
  RbfWarp(std::span<const Vec3> centers, std::span<const Vec3> targets,
          const RbfOptions& options = {});
  /// As above, with `fixed` centers (world units) whose displacement is zero.
  RbfWarp(std::span<const Vec3> centers, std::span<const Vec3> targets, std::span<const Vec3> fixed,
          const RbfOptions& options = {});

  /// Throws every InvalidInput the constructor would for these arguments, without the fit
  /// (O(n log n) rather than O(n³)): what `spacewarp info` checks. A SolverError of the fit
  /// itself (a numerically singular system) is only found by the constructor.
  static void check(std::span<const Vec3> centers, std::span<const Vec3> targets,
                    std::span<const Vec3> fixed, const RbfOptions& options = {});

  Vec3 apply(const Vec3& x) const override;
  Mat3 jacobian(const Vec3& x) const override;

  const RbfOptions& options() const { return options_; }
  /// The distinct centers of the fit: handles (duplicates merged), then fixed centers.
  std::span<const Vec3> centers() const { return centers_; }
  /// w_j, one per center of centers() (world units per unit of φ).
  std::span<const Vec3> weights() const { return weights_; }
  /// p(x) = linearPart() x + translation().
  const Mat3& linearPart() const { return linear_; }
  const Vec3& translation() const { return translation_; }

  /// Archive (core/archive.h): tag "rbf-warp", the options and the solved state (centers,
  /// weights, linear part, translation). load() checks sizes and finiteness and does not fit.
  void save(ArchiveWriter& out) const override;
  static std::shared_ptr<const RbfWarp> load(ArchiveReader& in);

 protected:
  std::size_t batchGrain() const override;
  UnmappedPoints applyRange(std::span<const Vec3> in, std::span<Vec3> out, std::size_t begin,
                            std::size_t end) const override;

 private:
  RbfOptions options_;
  std::vector<Vec3> centers_;
  std::vector<Vec3> weights_;
  Mat3 linear_{0.0};
  Vec3 translation_{0.0};
  // Structure of arrays for the batch kernel: cx, cy, cz, wx, wy, wz (centers_.size() each).
  std::vector<double> soa_;

  RbfWarp() = default;  // for load()
  void buildSoa();
};

}  // namespace spacewarp
