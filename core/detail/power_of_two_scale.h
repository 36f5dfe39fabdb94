#pragma once
// Exact rescaling by powers of two, so that the products inside a determinant, a cofactor or
// an inverse of 3 × 3 matrices neither overflow nor underflow for entries near 1e±300, while
// every result that was representable before keeps its bits.

#include <algorithm>
#include <cmath>

#include <spacewarp/core/math.h>

namespace spacewarp::detail {

/// v times 2^-e, e the exponent of `magnitude` (> 0, finite): exact (no rounding, as long as
/// no result is subnormal).
inline Vec3 scaledDown(const Vec3& v, double magnitude) {
  const int e = std::ilogb(magnitude);
  return {std::scalbn(v.x, -e), std::scalbn(v.y, -e), std::scalbn(v.z, -e)};
}

/// The largest absolute entry of J.
inline double maxAbsEntry(const Mat3& j) {
  return std::max({spacewarp::maxAbs(j[0]), spacewarp::maxAbs(j[1]), spacewarp::maxAbs(j[2])});
}

/// J scaled by the power of two that brings its largest entry into [1, 2): the same
/// directions, signs and ratios, so J^-T n normalised and the sign of det J are unchanged,
/// while the cofactors of entries near 1e300 or 1e-300 no longer overflow or underflow.
/// J unchanged when it is zero or not finite.
inline Mat3 scaledToUnit(const Mat3& j) {
  const double m = maxAbsEntry(j);
  if (!(m > 0.0) || !std::isfinite(m)) return j;
  return Mat3(scaledDown(j[0], m), scaledDown(j[1], m), scaledDown(j[2], m));
}

/// J^-1 r as (2^-e J)^-1 (2^-e r): bit for bit glm::inverse(J) * r wherever that does not
/// overflow or underflow, and the same step where it would (huge or tiny J). J must be
/// regular (isSingularJacobian false).
inline Vec3 solveScaled(const Mat3& j, const Vec3& r) {
  return glm::inverse(scaledToUnit(j)) * scaledDown(r, maxAbsEntry(j));
}

/// J^-1 as 2^-e (2^-e J)^-1: bit for bit glm::inverse(J) wherever that does not overflow or
/// underflow, and J's inverse where it would (huge or tiny J, whose inverse is representable).
/// J must be regular (isSingularJacobian false).
inline Mat3 inverseScaled(const Mat3& j) {
  const Mat3 inverse = glm::inverse(scaledToUnit(j));
  const double m = maxAbsEntry(j);
  return Mat3(scaledDown(inverse[0], m), scaledDown(inverse[1], m), scaledDown(inverse[2], m));
}

}  // namespace spacewarp::detail
