#pragma once
// Warps built from other warps or from a matrix: identity, affine, composition.

#include <cstddef>
#include <memory>
#include <span>
#include <vector>

#include <spacewarp/core/warp.h>

namespace spacewarp {

/// x' = x.
class IdentityWarp final : public Warp {
 public:
  Vec3 apply(const Vec3& x) const override { return x; }
  Mat3 jacobian(const Vec3&) const override { return Mat3(1.0); }
  std::optional<Vec3> exactInverse(const Vec3& y) const override { return y; }

  /// Archive (core/archive.h): tag "identity", nothing else.
  void save(ArchiveWriter& out) const override;
  static std::shared_ptr<const IdentityWarp> load(ArchiveReader& in);
};

/// x' = M [x, 1] for a 4 x 4 homogeneous matrix whose last row is (0, 0, 0, 1).
class AffineWarp final : public Warp {
 public:
  /// `matrix` is column-major (GLM): matrix[3] is the translation column. Throws InvalidInput
  /// if an entry is not finite or the last row is not (0, 0, 0, 1) (projective maps are not
  /// affine warps).
  explicit AffineWarp(const Mat4& matrix);

  Vec3 apply(const Vec3& x) const override { return linear_ * x + translation_; }
  Mat3 jacobian(const Vec3&) const override { return linear_; }
  /// M⁻¹ (y - t); empty when the linear part is singular (isSingularJacobian).
  std::optional<Vec3> exactInverse(const Vec3& y) const override;

  const Mat3& linear() const { return linear_; }
  const Vec3& translation() const { return translation_; }

  /// Archive: tag "affine", the 4 x 4 matrix (rebuilt through the constructor).
  void save(ArchiveWriter& out) const override;
  static std::shared_ptr<const AffineWarp> load(ArchiveReader& in);

 private:
  Mat3 linear_;
  Vec3 translation_;
  Mat3 linearInverse_{1.0};  // valid when !singular_
  bool singular_ = false;
};

/// x' = second(first(x)); the Jacobian follows the chain rule, J = J_second(first(x)) J_first(x).
/// Compositions of compositions are flattened at construction into one list of stages, applied
/// in a loop: a chain of any length costs no stack depth (to apply, save or destroy), and its
/// points are bit-identical to the nested form's. The Jacobian is accumulated stage by stage,
/// J = J_n (... (J_2 J_1)), which is the nested form's product for a chain built left to right
/// (Compose(Compose(a, b), c)); other groupings agree up to rounding.
class ComposedWarp final : public Warp {
 public:
  /// Throws InvalidInput if either warp is null.
  ComposedWarp(std::shared_ptr<const Warp> first, std::shared_ptr<const Warp> second);
  /// The stages in the order they apply (flattened as above). Throws InvalidInput if there are
  /// fewer than two or one is null.
  explicit ComposedWarp(std::vector<std::shared_ptr<const Warp>> stages);

  Vec3 apply(const Vec3& x) const override;
  Mat3 jacobian(const Vec3& x) const override;
  /// Each stage's closed-form inverse, last stage first; empty if a stage has none.
  std::optional<Vec3> exactInverse(const Vec3& y) const override;

  /// The stages in the order they apply; none is itself a ComposedWarp.
  const std::vector<std::shared_ptr<const Warp>>& stages() const { return stages_; }

  /// Archive: tag "compose", the number of stages (u64), then each stage (a nested warp), so
  /// that the archive's nesting does not grow with the chain's length.
  void save(ArchiveWriter& out) const override;
  static std::shared_ptr<const ComposedWarp> load(ArchiveReader& in);

 protected:
  /// The smallest of the stages' grains.
  std::size_t batchGrain() const override;
  /// Each stage's own kernel on the range, one after the other.
  UnmappedPoints applyRange(std::span<const Vec3> in, std::span<Vec3> out, std::size_t begin,
                            std::size_t end) const override;

 private:
  void append(std::shared_ptr<const Warp> stage);

  std::vector<std::shared_ptr<const Warp>> stages_;
};

}  // namespace spacewarp
