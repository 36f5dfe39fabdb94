#pragma once
// Bend after Barr, "Global and local deformations of solid primitives" (SIGGRAPH 1984): the
// region along a spine is wrapped onto a circular arc of curvature `rate`.

#include <limits>
#include <memory>
#include <span>

#include <spacewarp/core/detail/axis_frame.h>
#include <spacewarp/core/warp.h>

namespace spacewarp {

/// Parameters of BendWarp.
///
/// Local frame: y = s = dot(x - origin, a) along the unit spine a = normalize(axis), z along the
/// unit direction d (`direction` with its component along a removed), x along b = a × d. With
/// ŷ = clamp(y, lo, hi), θ = k ŷ, S = sin θ, C = cos θ (Barr's bend, center of the bend at y = 0):
///   X = x,   Y = -S z + S / k + C (y - ŷ),   Z = C z + (1 - C) / k + S (y - ŷ).
/// The spine (z = 0) between the limits is wrapped onto the circle of radius 1/k whose center is
/// at origin + d / k; beyond the limits the space moves rigidly with the end of the bent region.
/// The map is locally invertible where 1 - k z > 0 (between the spine's center of curvature and
/// the far side); at 1 - k z = 0 (the center of curvature) it is singular, beyond that it folds.
struct BendOptions {
  Vec3 origin{0.0};  ///< A point on the spine where the bend starts (y = 0), world units.
  /// The spine: the direction along which the object extends and bends. Any finite non-zero
  /// length. Default +z.
  Vec3 axis{0.0, 0.0, 1.0};
  /// Towards the center of curvature for a positive rate. Orthogonalised against `axis`; must not
  /// be parallel to it. Any finite non-zero length. Default +x.
  Vec3 direction{1.0, 0.0, 0.0};
  /// Curvature k: bend angle per unit length along the spine, radians per world unit.
  /// 0 is exactly the identity; negative bends away from `direction`.
  double rate = 0.0;
  double lo = -std::numeric_limits<double>::infinity();  ///< Lower limit on y, world units.
  double hi = std::numeric_limits<double>::infinity();   ///< Upper limit on y, world units.
};

/// The struct's former name, kept for code written against it.
using BendParams [[deprecated("renamed BendOptions")]] = BendOptions;

/// Barr's bend (see BendOptions). Analytic Jacobian: in the local frame, dX/dx = 1,
/// dY/dy = C (1 - k' z), dY/dz = -S, dZ/dy = S (1 - k' z), dZ/dz = C with k' = k between the
/// limits and 0 beyond them (a pure rotation there); det J = 1 - k' z.
///
/// Without limits the bend is periodic along the spine (period 2 pi / |k|) and folds at
/// 1 - k z = 0, so a point has many preimages. exactInverse() (which inverse() uses) names one
/// in closed form: of the one in the bent region with 1 - k z > 0 and bend angle k ŷ in (-π, π]
/// and those in the rigid parts beyond the limits, the one that moves least.
class BendWarp final : public Warp {
 public:
  /// Throws InvalidInput for a zero or non-finite axis or direction, a direction parallel to the
  /// axis, a non-finite origin or rate, a NaN limit or lo > hi (or lo = +inf, hi = -inf).
  explicit BendWarp(const BendOptions& params);

  Vec3 apply(const Vec3& x) const override;
  Mat3 jacobian(const Vec3& x) const override;
  /// In the local frame, with Y, Z the target's coordinates: the bent region maps (y, z) to
  /// (k Y, 1 - k Z) = (1 - k z)(sin k y, cos k y), so k y = atan2(k Y, 1 - k Z) and
  /// 1 - k z = hypot(k Y, 1 - k Z), a candidate when y lies within the limits; the rigid motion
  /// of each part beyond a limit undone is a candidate when the point lands beyond it. The
  /// candidate nearest the target is returned; empty when there is none.
  std::optional<Vec3> exactInverse(const Vec3& y) const override;

  /// The parameters as given (axis and direction not normalised or orthogonalised).
  const BendOptions& params() const { return params_; }
  /// The unit spine a.
  const Vec3& axis() const { return frame_.axis; }

  /// Archive (core/archive.h): tag "bend", the parameters as given.
  void save(ArchiveWriter& out) const override;
  static std::shared_ptr<const BendWarp> load(ArchiveReader& in);
  /// The unit direction d towards the center of curvature, perpendicular to the axis.
  const Vec3& direction() const { return direction_; }

 protected:
  UnmappedPoints applyRange(std::span<const Vec3> in, std::span<Vec3> out, std::size_t begin,
                            std::size_t end) const override;

 private:
  BendOptions params_;
  detail::AxisFrame frame_;
  Vec3 direction_;
};

}  // namespace spacewarp
