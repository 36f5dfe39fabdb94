#include <spacewarp/core/warp.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include <spacewarp/core/detail/batch.h>
#include <spacewarp/core/detail/power_of_two_scale.h>
#include <spacewarp/core/errors.h>

namespace spacewarp {

namespace {

// Columns of J^-T scaled by det(J): the cofactor matrix, well defined even when J is singular.
Mat3 cofactor(const Mat3& j) {
  return Mat3(glm::cross(j[1], j[2]), glm::cross(j[2], j[0]), glm::cross(j[0], j[1]));
}

}  // namespace

bool isSingularJacobian(const Mat3& j) {
  // The determinant of J with each column scaled to unit length: det J / Π |column|, in
  // [-1, 1], and the same for J and s J at any scale s (the product of the column lengths
  // itself would overflow for entries near 1e300, and underflow near 1e-300).
  Mat3 unit;
  for (int c = 0; c < 3; ++c) {
    if (!isFinite(j[c])) return true;
    const double m = maxAbs(j[c]);
    if (m == 0.0) return true;
    const Vec3 column = detail::scaledDown(j[c], m);
    unit[c] = column / glm::length(column);
  }
  return std::abs(glm::determinant(unit)) <= 1e-14;
}

Mat3 Warp::jacobian(const Vec3& x) const {
  const double h = std::cbrt(std::numeric_limits<double>::epsilon()) * std::max(1.0, maxAbs(x));
  Mat3 j;
  for (int axis = 0; axis < 3; ++axis) {
    Vec3 step(0.0);
    step[axis] = h;
    // The realised step (x + h) - (x - h) may differ from 2h in floating point; divide by it.
    const Vec3 plus = x + step;
    const Vec3 minus = x - step;
    j[axis] = (apply(plus) - apply(minus)) / (plus[axis] - minus[axis]);
  }
  return j;
}

std::optional<Vec3> Warp::exactInverse(const Vec3&) const { return std::nullopt; }

void Warp::applyBatch(std::span<const Vec3> in, std::span<Vec3> out) const {
  detail::requireSameSize("Warp::applyBatch", in.size(), out.size());
  applyBatch(in, out, 0, in.size());
}

void Warp::applyBatch(std::span<const Vec3> in, std::span<Vec3> out, std::size_t begin,
                      std::size_t end) const {
  detail::requireSameSize("Warp::applyBatch", in.size(), out.size());
  if (begin > end || end > in.size()) {
    throw InvalidInput("Warp::applyBatch: the block [" + std::to_string(begin) + ", " +
                       std::to_string(end) + ") is not within the " + std::to_string(in.size()) +
                       " points");
  }
  // applyRange() takes indices into the whole batch, so what it reports already names them.
  const UnmappedPoints unmapped = detail::forEachRange(
      end - begin, batchGrain(),
      [&](std::size_t b, std::size_t e) { return applyRange(in, out, begin + b, begin + e); });
  if (unmapped.count > 0) (unmapped.by ? unmapped.by : this)->throwUnmapped(unmapped, in);
}

UnmappedPoints Warp::applyRange(std::span<const Vec3> in, std::span<Vec3> out, std::size_t begin,
                                std::size_t end) const {
  for (std::size_t i = begin; i != end; ++i) out[i] = apply(in[i]);
  return {};
}

void Warp::throwUnmapped(const UnmappedPoints& unmapped, std::span<const Vec3> in) const {
  throw InvalidInput(std::to_string(unmapped.count) + " of " + std::to_string(in.size()) +
                     " points could not be warped (the first is point " +
                     std::to_string(unmapped.first) + ")");
}

Vec3 transformNormal(const Warp& warp, const Vec3& x, const Vec3& n) {
  return transformNormal(warp.jacobian(x), n);
}

Vec3 transformNormal(const Mat3& jacobian, const Vec3& n) {
  const Mat3 j = detail::scaledToUnit(jacobian);
  Vec3 v = cofactor(j) * n;  // = det(J) J^-T n
  if (glm::determinant(j) < 0.0) v = -v;
  const double len = glm::length(v);
  if (!(len > 0.0) || !std::isfinite(len)) return Vec3(0.0);
  return v / len;
}

Vec3 transformVector(const Warp& warp, const Vec3& x, const Vec3& v) {
  return warp.jacobian(x) * v;
}

}  // namespace spacewarp
