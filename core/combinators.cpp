#include <spacewarp/core/combinators.h>

#include <algorithm>
#include <cmath>
#include <string>

#include <spacewarp/core/detail/power_of_two_scale.h>
#include <spacewarp/core/errors.h>

namespace spacewarp {

AffineWarp::AffineWarp(const Mat4& m) : linear_(m), translation_(m[3]) {
  for (int c = 0; c < 4; ++c) {
    for (int r = 0; r < 4; ++r) {
      if (!std::isfinite(m[c][r]))
        throw InvalidInput("affine matrix entry (" + std::to_string(r) + ", " + std::to_string(c) +
                           ") is not finite");
    }
  }
  if (m[0][3] != 0.0 || m[1][3] != 0.0 || m[2][3] != 0.0 || m[3][3] != 1.0)
    throw InvalidInput("affine matrix: the last row must be (0, 0, 0, 1)");
  singular_ = isSingularJacobian(linear_);
  if (!singular_) linearInverse_ = detail::inverseScaled(linear_);  // entries of 1e300 too
}

std::optional<Vec3> AffineWarp::exactInverse(const Vec3& y) const {
  if (singular_) return std::nullopt;
  const Vec3 x = linearInverse_ * (y - translation_);
  // One step of refinement on the residual: the rounding of the inverse matrix is then
  // corrected to the accuracy of apply() itself.
  return x + linearInverse_ * (y - apply(x));
}

ComposedWarp::ComposedWarp(std::shared_ptr<const Warp> first, std::shared_ptr<const Warp> second)
    : first_(std::move(first)), second_(std::move(second)) {
  if (!first_ || !second_) throw InvalidInput("ComposedWarp: a warp is null");
}

Mat3 ComposedWarp::jacobian(const Vec3& x) const {
  return second_->jacobian(first_->apply(x)) * first_->jacobian(x);
}

std::optional<Vec3> ComposedWarp::exactInverse(const Vec3& y) const {
  const std::optional<Vec3> mid = second_->exactInverse(y);
  if (!mid) return std::nullopt;
  return first_->exactInverse(*mid);
}

std::size_t ComposedWarp::batchGrain() const {
  return std::min(first_->batchGrain(), second_->batchGrain());
}

UnmappedPoints ComposedWarp::applyRange(std::span<const Vec3> in, std::span<Vec3> out,
                                        std::size_t begin, std::size_t end) const {
  // Each report names the stage whose kernel made it, so that this stage explains it.
  const auto stage = [](const Warp& warp, UnmappedPoints unmapped) {
    if (unmapped.count > 0 && !unmapped.by) unmapped.by = &warp;
    return unmapped;
  };
  UnmappedPoints unmapped = stage(*first_, first_->applyRange(in, out, begin, end));
  unmapped.merge(stage(*second_, second_->applyRange(out, out, begin, end)));
  return unmapped;
}

}  // namespace spacewarp
