#include <spacewarp/core/combinators.h>

#include <cmath>
#include <string>

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
}

ComposedWarp::ComposedWarp(std::shared_ptr<const Warp> first, std::shared_ptr<const Warp> second)
    : first_(std::move(first)), second_(std::move(second)) {
  if (!first_ || !second_) throw InvalidInput("ComposedWarp: a warp is null");
}

Mat3 ComposedWarp::jacobian(const Vec3& x) const {
  return second_->jacobian(first_->apply(x)) * first_->jacobian(x);
}

void ComposedWarp::applyBatch(std::span<const Vec3> in, std::span<Vec3> out) const {
  // Each stage keeps its own (possibly specialised) batch path.
  first_->applyBatch(in, out);
  second_->applyBatch(out, out);
}

}  // namespace spacewarp
