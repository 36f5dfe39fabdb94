#pragma once
// Shared internals of the axial warps (twist, bend, taper): parameter validation, the unit axis
// and the clamped axial coordinate of Blender's Simple Deform limits. Not public API.

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include <spacewarp/core/errors.h>
#include <spacewarp/core/math.h>

namespace spacewarp::detail {

/// `v` scaled to unit length without overflow or underflow for huge or tiny components.
/// Precondition: v is finite and not zero.
inline Vec3 safeNormalize(const Vec3& v) {
  const Vec3 scaled = v / maxAbs(v);
  return scaled / glm::length(scaled);
}

/// Throws InvalidInput "<warp>: <what> is not finite" unless `value` is finite.
inline void requireFinite(const char* warp, const char* what, double value) {
  if (!std::isfinite(value))
    throw InvalidInput(std::string(warp) + ": " + what + " is not finite (" +
                       std::to_string(value) + ")");
}

/// Throws InvalidInput unless every component of `v` is finite.
inline void requireFinite(const char* warp, const char* what, const Vec3& v) {
  if (!isFinite(v))
    throw InvalidInput(std::string(warp) + ": " + what + " (" + std::to_string(v.x) + ", " +
                       std::to_string(v.y) + ", " + std::to_string(v.z) + ") is not finite");
}

/// A validated axis: a line through `origin` along the unit vector `axis`, with the limits
/// [lo, hi] on the signed axial coordinate s = dot(x - origin, axis) (world units).
struct AxisFrame {
  Vec3 origin{0.0};
  Vec3 axis{0.0, 0.0, 1.0};
  double lo = -std::numeric_limits<double>::infinity();
  double hi = std::numeric_limits<double>::infinity();

  /// Validates the parameters of warp `warp` (its name, for messages) and normalises the axis.
  /// Throws InvalidInput for a non-finite origin, a zero or non-finite axis, a NaN limit,
  /// lo > hi, lo = +infinity or hi = -infinity (the clamped coordinate would be infinite).
  AxisFrame(const char* warp, const Vec3& originIn, const Vec3& axisIn, double loIn, double hiIn)
      : origin(originIn), lo(loIn), hi(hiIn) {
    requireFinite(warp, "origin", originIn);
    requireFinite(warp, "axis", axisIn);
    if (maxAbs(axisIn) == 0.0) throw InvalidInput(std::string(warp) + ": the axis is zero");
    axis = safeNormalize(axisIn);
    if (std::isnan(lo) || std::isnan(hi))
      throw InvalidInput(std::string(warp) + ": a limit is NaN");
    if (lo > hi) {
      throw InvalidInput(std::string(warp) + ": the lower limit " + std::to_string(lo) +
                         " is above the upper limit " + std::to_string(hi));
    }
    if (lo == std::numeric_limits<double>::infinity() ||
        hi == -std::numeric_limits<double>::infinity()) {
      throw InvalidInput(std::string(warp) +
                         ": the limits leave no finite axial coordinate (lo = +inf or hi = -inf)");
    }
  }

  /// The signed axial coordinate s of x (world units).
  double axial(const Vec3& x) const { return glm::dot(x - origin, axis); }

  /// ŝ = clamp(s, lo, hi); compiles to a min/max pair, no branch.
  double clamp(double s) const { return std::min(std::max(s, lo), hi); }

  /// d ŝ / d s: 1 strictly between the limits or on them (one-sided), 0 beyond them and when
  /// lo == hi (the whole of space then moves rigidly).
  double clampSlope(double s) const { return (lo < hi && s >= lo && s <= hi) ? 1.0 : 0.0; }
};

}  // namespace spacewarp::detail
