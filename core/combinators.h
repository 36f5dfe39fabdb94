#pragma once
// Warps built from other warps or from a matrix: identity, affine, composition.

#include <cstddef>
#include <memory>
#include <span>

#include <spacewarp/core/warp.h>

namespace spacewarp {

/// x' = x.
class IdentityWarp final : public Warp {
 public:
  Vec3 apply(const Vec3& x) const override { return x; }
  Mat3 jacobian(const Vec3&) const override { return Mat3(1.0); }
  std::optional<Vec3> exactInverse(const Vec3& y) const override { return y; }
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

 private:
  Mat3 linear_;
  Vec3 translation_;
  Mat3 linearInverse_{1.0};  // valid when !singular_
  bool singular_ = false;
};

/// x' = second(first(x)); the Jacobian follows the chain rule, J = J_second(first(x)) J_first(x).
class ComposedWarp final : public Warp {
 public:
  /// Throws InvalidInput if either warp is null.
  ComposedWarp(std::shared_ptr<const Warp> first, std::shared_ptr<const Warp> second);

  Vec3 apply(const Vec3& x) const override { return second_->apply(first_->apply(x)); }
  Mat3 jacobian(const Vec3& x) const override;
  /// first⁻¹(second⁻¹(y)) when both stages have a closed-form inverse; empty otherwise.
  std::optional<Vec3> exactInverse(const Vec3& y) const override;

 protected:
  /// The smaller of the stages' grains.
  std::size_t batchGrain() const override;
  /// Each stage's own kernel on the range, one after the other.
  UnmappedPoints applyRange(std::span<const Vec3> in, std::span<Vec3> out, std::size_t begin,
                            std::size_t end) const override;

 private:
  std::shared_ptr<const Warp> first_;
  std::shared_ptr<const Warp> second_;
};

}  // namespace spacewarp
