#pragma once
// Taper after Barr, "Global and local deformations of solid primitives" (SIGGRAPH 1984): the
// cross-sections perpendicular to an axis scale by a factor that varies linearly along it.

#include <limits>
#include <memory>
#include <span>

#include <spacewarp/core/detail/axis_frame.h>
#include <spacewarp/core/warp.h>

namespace spacewarp {

/// Parameters of TaperWarp. With a = normalize(axis), s = dot(x - origin, a), ŝ = clamp(s, lo, hi)
/// and p = x - origin - s a (the part perpendicular to the axis), the taper keeps the axial
/// coordinate and scales p by r(ŝ) = 1 + rate ŝ:  x' = origin + s a + r(ŝ) p.
/// Beyond the limits the scale stays at its value at the limit (continuous).
///
/// r ≤ 0 turns the shape inside out: where r = 0 the cross-section collapses onto the axis (the
/// Jacobian is singular and the map not invertible there); where r < 0 the cross-section is
/// mirrored through the axis, so the tapered object passes through itself across the plane
/// r = 0 (det J = r² stays positive: within the plane of the cross-section the mirror is a half
/// turn). Such parameters are not rejected, but inverse() is only supported where r > 0.
struct TaperOptions {
  Vec3 origin{0.0};  ///< A point on the taper axis where r = 1, world units. Default origin.
  Vec3 axis{0.0, 0.0, 1.0};  ///< Direction of the axis; any finite non-zero length. Default +z.
  double rate = 0.0;  ///< dr/ds: change of the scale per unit length, 1 / world units. 0: identity.
  double lo = -std::numeric_limits<double>::infinity();  ///< Lower limit on s, world units.
  double hi = std::numeric_limits<double>::infinity();   ///< Upper limit on s, world units.
};

/// The struct's former name, kept for code written against it.
using TaperParams [[deprecated("renamed TaperOptions")]] = TaperOptions;

/// Barr's taper (see TaperOptions). Analytic Jacobian:
/// J = a aᵀ + r (I - a aᵀ) + r'(s) p aᵀ with r' = rate between the limits, 0 beyond; det J = r².
class TaperWarp final : public Warp {
 public:
  /// Throws InvalidInput for a zero or non-finite axis, a non-finite origin or rate, a NaN limit
  /// or lo > hi (or lo = +inf, hi = -inf).
  explicit TaperWarp(const TaperOptions& params);

  Vec3 apply(const Vec3& x) const override;
  Mat3 jacobian(const Vec3& x) const override;
  /// The taper keeps s, so x = origin + s a + p(y) / r(ŝ); empty where r(ŝ) = 0 (the
  /// cross-section collapsed onto the axis: no unique preimage).
  std::optional<Vec3> exactInverse(const Vec3& y) const override;

  /// The parameters as given (the axis not normalised).
  const TaperOptions& params() const { return params_; }
  /// The unit axis.
  const Vec3& axis() const { return frame_.axis; }

  /// Archive (core/archive.h): tag "taper", the parameters as given.
  void save(ArchiveWriter& out) const override;
  static std::shared_ptr<const TaperWarp> load(ArchiveReader& in);
  /// The scale r(ŝ) = 1 + rate clamp(s, lo, hi) of the cross-section at axial coordinate s.
  double scaleAt(double s) const { return 1.0 + params_.rate * frame_.clamp(s); }

 protected:
  UnmappedPoints applyRange(std::span<const Vec3> in, std::span<Vec3> out, std::size_t begin,
                            std::size_t end) const override;

 private:
  TaperOptions params_;
  detail::AxisFrame frame_;
};

}  // namespace spacewarp
