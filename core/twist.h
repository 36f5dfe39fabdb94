#pragma once
// Twist after Barr, "Global and local deformations of solid primitives" (SIGGRAPH 1984):
// every point turns about an axis by an angle proportional to its position along the axis.

#include <limits>
#include <memory>
#include <span>

#include <spacewarp/core/detail/axis_frame.h>
#include <spacewarp/core/warp.h>

namespace spacewarp {

/// Parameters of TwistWarp. With s = dot(x - origin, normalize(axis)) the signed axial
/// coordinate and ŝ = clamp(s, lo, hi), the point x turns about the line through `origin` along
/// `axis` by the angle rate * ŝ (radians, right-handed about the axis). Beyond the limits the
/// angle stays at its value at the limit, so those points turn rigidly with the end of the
/// twisted region (as Blender's Simple Deform does).
struct TwistOptions {
  Vec3 origin{0.0};          ///< A point on the twist axis, world units. Default: the origin.
  Vec3 axis{0.0, 0.0, 1.0};  ///< Direction of the axis; any finite non-zero length. Default +z.
  double rate = 0.0;         ///< Twist angle per unit length, radians per world unit. 0: identity.
  double lo = -std::numeric_limits<double>::infinity();  ///< Lower limit on s, world units.
  double hi = std::numeric_limits<double>::infinity();   ///< Upper limit on s, world units.
};

/// The struct's former name, kept for code written against it.
using TwistParams [[deprecated("renamed TwistOptions")]] = TwistOptions;

/// x' = origin + R(rate * ŝ) (x - origin), R a rotation about the unit axis a.
/// Jacobian: J = R + θ'(s) (a × R (x - origin)) aᵀ with θ' = rate inside the limits, 0 beyond.
/// det J = 1 everywhere: a twist is a volume-preserving diffeomorphism, invertible everywhere.
class TwistWarp final : public Warp {
 public:
  /// Throws InvalidInput for a zero or non-finite axis, a non-finite origin or rate, a NaN limit
  /// or lo > hi (or lo = +inf, hi = -inf).
  explicit TwistWarp(const TwistOptions& params);

  Vec3 apply(const Vec3& x) const override;
  Mat3 jacobian(const Vec3& x) const override;
  /// The turn back: a rotation keeps s, so x = origin + R(-rate ŝ(y)) (y - origin). Always.
  std::optional<Vec3> exactInverse(const Vec3& y) const override;

  /// The parameters as given (the axis not normalised).
  const TwistOptions& params() const { return params_; }
  /// The unit axis.
  const Vec3& axis() const { return frame_.axis; }

  /// Archive (core/archive.h): tag "twist", the parameters as given.
  void save(ArchiveWriter& out) const override;
  static std::shared_ptr<const TwistWarp> load(ArchiveReader& in);

 protected:
  UnmappedPoints applyRange(std::span<const Vec3> in, std::span<Vec3> out, std::size_t begin,
                            std::size_t end) const override;

 private:
  TwistOptions params_;
  detail::AxisFrame frame_;
};

}  // namespace spacewarp
