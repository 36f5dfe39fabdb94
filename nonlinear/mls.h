#pragma once
// Moving-least-squares warps of 3D space: Schaefer, McPhail & Warren, "Image deformation using
// moving least squares" (SIGGRAPH 2006), in 3D after Zhu & Gortler, "3D deformation using moving
// least squares" (Harvard TR-10-07, 2007). Point handles p_i move to targets q_i; every point x
// gets its own best affine, similarity or rigid transform of the handles, weighted towards the
// handles near x.

#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include <spacewarp/core/coordinates.h>
#include <spacewarp/core/handle_distances.h>
#include <spacewarp/core/warp.h>

namespace spacewarp {

class ArchiveReader;
class ArchiveWriter;

/// The class of local transform fitted at each point.
enum class MlsMode {
  Affine,      ///< Any affine map; needs 4 affinely independent handles.
  Similarity,  ///< Uniform scale times rotation; needs 3 non-collinear handles and targets.
  Rigid,       ///< Rotation; needs 3 non-collinear handles and targets. Most shape-preserving.
};

/// "affine", "similarity" or "rigid".
std::string mlsModeName(MlsMode mode);
/// The mode named "affine", "similarity" or "rigid"; throws InvalidInput for any other name.
MlsMode mlsModeFromName(std::string_view name);

/// Options of MlsWarp.
struct MlsOptions {
  /// The local transform class. Default Rigid, the one Schaefer et al. recommend for
  /// shape-preserving edits.
  MlsMode mode = MlsMode::Rigid;
  /// Weight falloff exponent: w_i(x) = 1 / |p_i − x|^(2 alpha); finite, > 0. Default 1 (the
  /// papers' choice). The warp is C¹ at the handles only for alpha > 1/2; near a handle it
  /// approaches the target like |x − p_i|^(2 alpha), so small alpha gives visible jumps there.
  double alpha = 1.0;
  /// The distances d_i(x) the weights use instead of |p_i − x|: w_i(x) = 1 / d_i(x)^(2 alpha),
  /// e.g. distances measured inside a model (volume/inside_distance.h), so that a handle does
  /// not pull parts of the model that are near it only through empty space (Zhu & Gortler
  /// 2007, section 5). Must be built for the same handles, in the same order. Default null:
  /// Euclidean distances.
  std::shared_ptr<const HandleDistances> distances;
};

/// The local fit at one point: x' = transform (x − handleCentroid) + targetCentroid, where the
/// centroids are the weighted centroids p*, q* of handles and targets and `transform` is the
/// weighted best affine map (Affine), s·R (Similarity) or R (Rigid), R a rotation (det +1).
struct MlsFit {
  Mat3 transform{1.0};
  Vec3 handleCentroid{0.0};  ///< p*, world units.
  Vec3 targetCentroid{0.0};  ///< q*, world units.
};

/// x' = T_x (x − p*) + q*, with weights w_i(x) = 1 / |p_i − x|^(2 alpha) (or 1 / d_i(x)^(2 alpha)
/// with MlsOptions::distances), p* = Σ w_i p_i / Σ w_i,
/// q* likewise, p̂_i = p_i − p*, q̂_i = q_i − q*, and
///   - Affine:     T_x = (Σ w_i q̂_i p̂_iᵀ)(Σ w_i p̂_i p̂_iᵀ)⁻¹;
///   - Rigid:      T_x = R, the rotation maximising tr(Rᵀ B) with B = Σ w_i q̂_i p̂_iᵀ: the polar
///                 factor of B from its SVD U Σ Vᵀ, as U diag(1, 1, det(U Vᵀ)) Vᵀ, so that a
///                 reflection is never returned (Zhu & Gortler 2007);
///   - Similarity: T_x = s R, the same R, s = tr(Rᵀ B) / Σ w_i |p̂_i|².
/// The warp interpolates: apply(p_i) = q_i exactly. Affine motions of the handles are reproduced
/// everywhere in every mode that contains them (a rigid motion in all modes, a similarity in
/// Similarity and Affine, any affine map in Affine).
///
/// Numerics: weights are normalised by the nearest handle's, so far and near points neither
/// overflow nor underflow; within about 1e-9 (alpha = 1) of a handle, relative to the other
/// handles' distances, the handle's limit fit is used (p* = p_i, q* = q_i, the other handles
/// weighted), which agrees with the formula to rounding. The rotation is the polar factor of B by
/// Higham's scaled Newton iteration finished by Newton-Schulz steps when det B > 1e-8 |B|_F³ (the
/// common case), else from a cyclic Jacobi eigen-decomposition of BᵀB (rank-2 B from coplanar
/// handles, det B < 0 from folded targets); never a general SVD. Where B has rank < 2 (possible
/// only at isolated points, since collinear handles or targets are rejected)
/// one of the optimal rotations is chosen deterministically.
///
/// With MlsOptions::distances the same holds (interpolation, reproduced motions) and the
/// Jacobian uses their gradients ∇d_i, so it is as smooth as the distances are.
///
/// Jacobian: analytic (derivatives of the weights through the centroids and the covariances;
/// for the rotation, dR = R Ω with (tr S I − S) ω = vee(Rᵀ dB − dBᵀ R), S = Rᵀ B). At a handle
/// it is the limit fit's transform (the derivative for alpha > 1/2). Where the rotation is not
/// unique (tr S I − S singular) it falls back to Warp::jacobian's finite differences.
///
/// Cost: O(n) per point for n handles (two passes over them), plus a 3 × 3 solve or rotation
/// extraction: ~130 ns of CPU per point for 16 handles in Rigid mode, about half of it the
/// rotation (bench/nonlinear_bench.cpp). applyBatch runs in parallel (TBB) without allocating per
/// point; every result is bit-identical to apply() for any thread count. Non-finite x gives
/// non-finite results.
class MlsWarp final : public Warp {
 public:
  /// `handles` p_i and `targets` q_i: n points each, world units, same order. Throws
  /// InvalidInput, naming the problem (and the index), for mismatched counts, non-finite
  /// points, coincident handles (closer than 1e-12 × their bounding-box diagonal), too few
  /// handles for the mode (4 for Affine, 3 otherwise), coplanar handles in Affine mode,
  /// collinear handles or targets in Similarity and Rigid modes (spread in the weakest
  /// direction below 1e-6 of the strongest, which would leave the rotation undetermined), a
  /// non-finite or non-positive alpha, or distances built for other handles.
  MlsWarp(std::vector<Vec3> handles, std::vector<Vec3> targets, const MlsOptions& options = {});

  Vec3 apply(const Vec3& x) const override;
  Mat3 jacobian(const Vec3& x) const override;

  /// The local fit at x (for a handle, its limit fit, which maps that handle to its target).
  MlsFit localFit(const Vec3& x) const;

  std::span<const Vec3> handles() const { return handles_; }
  std::span<const Vec3> targets() const { return targets_; }
  const MlsOptions& options() const { return options_; }

  /// Archive tag "mls": handles, targets, mode, alpha and the distances (nested, or none).
  void save(ArchiveWriter& out) const override;
  /// Rebuilt through the constructor (so a bad archive is refused as bad parameters are).
  static std::shared_ptr<const MlsWarp> load(ArchiveReader& in);

 protected:
  std::size_t batchGrain() const override;
  UnmappedPoints applyRange(std::span<const Vec3> in, std::span<Vec3> out, std::size_t begin,
                            std::size_t end) const override;

 private:
  std::vector<Vec3> handles_;
  std::vector<Vec3> targets_;
  MlsOptions options_;
};

/// Affine MLS as coordinates: x' = Σ_j A_j(x) q_j with
///   A_j(x) = w_j (1 / Σ w_i + p̂_jᵀ (Σ w_i p̂_i p̂_iᵀ)⁻¹ (x − p*)),
/// linear in the targets, with linear precision (Σ_j A_j(x) p_j = x, Σ_j A_j(x) = 1). So a
/// `Binding` of a fixed point set precomputes A_j once (points × handles, dense) and re-posing the
/// targets is one matrix product; the result equals MlsWarp in Affine mode to rounding.
class MlsAffineCoordinates final : public Coordinates {
 public:
  /// `handles`: n points, world units. Throws InvalidInput as MlsWarp does in Affine mode.
  explicit MlsAffineCoordinates(std::vector<Vec3> handles, double alpha = 1.0);

  std::size_t controlPointCount() const override { return handles_.size(); }
  std::span<const Vec3> restControlPoints() const override { return handles_; }
  void weights(const Vec3& x, std::span<double> row) const override;

  double alpha() const { return alpha_; }

  /// Archive tag "mls-affine": handles and alpha.
  void save(ArchiveWriter& out) const override;
  /// Rebuilt through the constructor.
  static std::shared_ptr<const MlsAffineCoordinates> load(ArchiveReader& in);

 private:
  std::vector<Vec3> handles_;
  double alpha_;
};

}  // namespace spacewarp
