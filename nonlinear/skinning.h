#pragma once
// Skeletal skinning: every point follows a weighted blend of a few bones' transforms, either by
// linear blend skinning (LBS: the matrices are averaged) or by dual-quaternion skinning (DQS:
// the rigid motions are averaged as unit dual quaternions; Kavan, Collins, Žára & O'Sullivan,
// "Geometric skinning with approximate dual quaternion blending", TOG 2008). LBS collapses a
// limb twisted by 180° to a line ("candy wrapper"); DQS keeps its cross-section.
//
// Two layers: SkinningBinding deforms a fixed point set whose weights are stored sparsely (the
// fast path, re-posed every frame), and SkinningWarp maps any point of space (for volumes,
// inversion, normals), with the weights of a point taken from the nearest vertex of a weighted
// model or from any Coordinates whose control points are the bones' handles.

#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include <spacewarp/core/coordinates.h>
#include <spacewarp/core/warp.h>

namespace spacewarp {

class ArchiveReader;
class ArchiveWriter;

/// How the bones' transforms are blended.
enum class SkinningMode {
  Linear,          ///< "lbs": x' = Σ w_i (A_i x + t_i). Any affine bones; negative weights kept.
  DualQuaternion,  ///< "dqs": x' = the rigid motion of the normalised blend Σ ±w_i q̂_i.
};

/// "lbs" or "dqs".
std::string skinningModeName(SkinningMode mode);
/// The mode named "lbs" or "dqs"; throws InvalidInput for any other name.
SkinningMode skinningModeFromName(std::string_view name);

/// Sparse skinning weights: k (bone, weight) pairs per point, struct of arrays, point-major
/// (entry j of point i at i · k + j). In each point the entries are sorted by decreasing |weight|
/// (ties by bone index) — the first is the point's pivot bone for DQS — and the weights sum to 1.
/// Points with fewer than k influences are padded with weight 0 on their first bone.
struct SkinningWeights {
  std::size_t pointCount = 0;
  std::size_t influences = 0;        ///< k, ≥ 1.
  std::vector<std::uint32_t> bones;  ///< pointCount × k bone indices.
  std::vector<double> weights;       ///< pointCount × k weights.
};

/// The sparse weights of dense rows (`rows`: points × boneCount, row-major): per point the
/// `maxInfluences` largest weights (all of them for 0, or when there are fewer bones),
/// renormalised to sum to 1. Keeping all bones keeps negative weights (LBS blends them as they
/// are; DQS blends the signed weights of the hemisphere-aligned quaternions) and needs a
/// positive sum. Keeping fewer clamps negative weights to 0 first and keeps the largest: the kept
/// sum is then at least the largest weight, never near 0 (signed weights cut to their largest
/// magnitudes can sum to ~0: a pole). Throws InvalidInput naming the point (and bone) for a
/// non-finite weight, a sum that overflows, a sum ≤ 0 (at most 1e-12 of the sum of the kept
/// magnitudes; truncating: no positive weight), and if rows.size() is not a multiple of
/// boneCount or boneCount is 0 or above 2³².
SkinningWeights sparseSkinningWeights(std::span<const double> rows, std::size_t boneCount,
                                      std::size_t maxInfluences = 4);

/// The sparse weights of `points` (world units) from `coordinates` whose control points are the
/// bones' handles (one column per bone: controlPointCount() == columnCount()). By default
/// (maxInfluences 0) every bone's weight is kept: exact, and as smooth as the coordinates.
/// Truncated (0 < maxInfluences < bones), as sparseSkinningWeights() and then faded: the
/// (k + 1)-th largest weight is subtracted from the kept ones, so that a bone leaves a point's
/// kept set with weight 0 and the weights stay continuous in space (where the k + 1 largest tie,
/// plain truncation: bounded). Computed in parallel, deterministic. Throws InvalidInput for
/// coordinates with extra columns (Green's face normals), and as weightsBatch() and
/// sparseSkinningWeights() do.
SkinningWeights skinningWeights(const Coordinates& coordinates, std::span<const Vec3> points,
                                std::size_t maxInfluences = 0);

/// Throws InvalidInput naming the bone unless every bone is a finite affine transform (last row
/// 0 0 0 1) and, for DualQuaternion, rigid: a rotation (det R > 0 — a reflection is named as such,
/// |RᵀR − I| ≤ 1e-4 entrywise, so that matrices written with 5 digits pass; DQS uses the unit
/// quaternion of R) plus a translation. DQS of scaled or sheared bones is refused rather than
/// approximated: use LBS.
void checkBones(std::span<const Mat4> bones, SkinningMode mode);

/// A fixed point set with its sparse weights: deform(bones) re-poses it, the fast path.
///
/// Bones are the skinning transforms of the rest pose into the posed one (posed × inverse bind
/// matrix), GLM column-major (world units). Each call prepares the bones once (DQS: their unit
/// dual quaternions) and then blends per point with four-lane SIMD (an x86-64-v3 clone picked at
/// load time) over TBB ranges of fixed size: the result does not depend on the thread count and
/// is bit-identical to SkinningWarp::apply() of a point with the same weights. LBS is bound by
/// memory (~96 bytes per point with 4 bones), DQS by the square root and division of each
/// blend's normalisation (README, bench/nonlinear_bench_skinning.cpp). Weights stay in double:
/// float weights would save 16 of those bytes but make a bone motion common to all a point's
/// bones inexact (Σ w_i ≠ 1 in float).
class SkinningBinding {
 public:
  /// `points` (n, world units) and their weights (weights.pointCount == n). Throws InvalidInput
  /// for a count mismatch, a non-finite point, a bone index ≥ boneCount (naming the point) or
  /// malformed weights (array sizes, k = 0, non-finite weights).
  SkinningBinding(std::vector<Vec3> points, SkinningWeights weights, std::size_t boneCount);

  std::size_t pointCount() const { return points_.size(); }
  std::size_t boneCount() const { return boneCount_; }
  std::span<const Vec3> restPoints() const { return points_; }
  const SkinningWeights& weights() const { return weights_; }

  /// The posed points for `bones` (boneCount() transforms) into `out` (pointCount() entries).
  /// Throws InvalidInput for wrong sizes and as checkBones() does.
  void deform(std::span<const Mat4> bones, SkinningMode mode, std::span<Vec3> out) const;
  std::vector<Vec3> deform(std::span<const Mat4> bones, SkinningMode mode) const;

 private:
  std::vector<Vec3> points_;
  SkinningWeights weights_;
  std::size_t boneCount_;
};

/// Options of SkinningWarp built from coordinates.
struct SkinningOptions {
  /// LBS or DQS. Default Linear, the common baseline.
  SkinningMode mode = SkinningMode::Linear;
  /// Influences kept per point (skinningWeights(): the largest, faded and renormalised); 0 keeps
  /// all. Default 0: exact and smooth; truncating to 4, what real-time skinning uses, is faster
  /// with many bones but only continuous, and drops negative weights.
  std::size_t maxInfluences = 0;
};

/// Skinning as a warp of space. The weights of a point x are either
///  - those of the nearest vertex of a weighted model (a KD-tree query, deterministic): exact
///    on the model's vertices, piecewise constant in space (a Voronoi partition of the model's
///    vertices), so a volume or another sampling of the model follows it. Of duplicate vertices
///    (same position, different weights) the lowest index wins, at both copies; or
///  - skinningWeights() of coordinates.weights(x), smooth where the coordinates are (continuous
///    when truncated).
/// Then x' is the LBS or DQS blend of the bones at x, bit-identical to a SkinningBinding with the
/// same weights.
///
/// Jacobian: with nearest-vertex weights (constant in each cell) Σ w_i A_i for LBS and R(c₀),
/// the rotation of the blended dual quaternion, for DQS. With coordinates that give
/// weightGradients(): analytic, including the weights' gradient (renormalised over the kept
/// influences) — for LBS Σ w_i A_i + Σ (A_i x + t_i) ∇w_iᵀ, for DQS the chain rule through the
/// blend and its normalisation. Otherwise Warp::jacobian's finite differences.
class SkinningWarp final : public Warp {
 public:
  /// Weights of the vertices of a model (`model`: n points, world units; `weights.pointCount`
  /// == n), extended to space by nearest vertex. Throws InvalidInput as SkinningBinding and
  /// checkBones() do.
  SkinningWarp(std::vector<Mat4> bones, std::vector<Vec3> model, SkinningWeights weights,
               SkinningMode mode);

  /// Weights from `coordinates` whose control points are the bones' handles
  /// (controlPointCount() == bones.size(), no extra columns). Throws InvalidInput for a null
  /// pointer, a count mismatch and as checkBones() does; apply() throws as
  /// sparseSkinningWeights() does for a point whose weights sum to 0.
  SkinningWarp(std::vector<Mat4> bones, std::shared_ptr<const Coordinates> coordinates,
               const SkinningOptions& options = {});
  ~SkinningWarp() override;

  Vec3 apply(const Vec3& x) const override;
  Mat3 jacobian(const Vec3& x) const override;

  std::span<const Mat4> bones() const { return bones_; }
  SkinningMode mode() const { return mode_; }

  /// Archive tag "skinning": the mode, the bones, then either the weighted model's points and
  /// their sparse weights, or the coordinates (nested) and the influences kept.
  void save(ArchiveWriter& out) const override;
  /// Rebuilt through the constructors (the model's KD-tree is rebuilt: the same neighbours).
  static std::shared_ptr<const SkinningWarp> load(ArchiveReader& in);

 protected:
  std::size_t batchGrain() const override;
  UnmappedPoints applyRange(std::span<const Vec3> in, std::span<Vec3> out, std::size_t begin,
                            std::size_t end) const override;

 private:
  struct Impl;
  std::vector<Mat4> bones_;
  SkinningMode mode_;
  std::unique_ptr<const Impl> impl_;
};

}  // namespace spacewarp
