#include <spacewarp/core/bend.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include <spacewarp/core/archive.h>
#include <spacewarp/core/errors.h>

namespace spacewarp {

namespace {

// Everything the per-point map needs, by value, so the batch loop keeps it in registers.
struct BendKernel {
  Vec3 origin;
  Vec3 axis;       // unit spine a (local y)
  Vec3 direction;  // unit d ⊥ a (local z)
  double rate;     // curvature k
  double lo;
  double hi;
};

// The trigonometry of the bend at the clamped spine coordinate yh, from the half angle
// t = k yh / 2 so that S / k and (1 - C) / k are accurate for any k, including 0:
//   S = 2 sin t cos t,  1 - C = 2 sin² t,
//   S / k = yh sinc(t) cos t,  (1 - C) / k = yh sinc(t) sin t.
struct BendTrig {
  double s;               // S = sin(k yh)
  double oneMinusC;       // 1 - C
  double sOverK;          // S / k
  double oneMinusCOverK;  // (1 - C) / k
};

inline BendTrig bendTrig(double k, double yh) {
  const double t = 0.5 * k * yh;
  const double sh = std::sin(t);
  const double ch = std::cos(t);
  // sin(t) / t, by its Taylor series where the quotient would be 0 / 0 or lose accuracy;
  // the truncation error there is below t^4 / 120 < 1e-18.
  const double sinc = std::abs(t) < 1e-4 ? 1.0 - t * t * (1.0 / 6.0) : sh / t;
  return {2.0 * sh * ch, 2.0 * sh * sh, yh * sinc * ch, yh * sinc * sh};
}

// The one per-point map, used by apply() and applyBatch() alike (bit-identical results).
// Computed as x + (ΔY a + ΔZ d) so that rate = 0 is exactly the identity:
//   ΔY = Y - y = (S/k - ŷ) - (1 - C)(y - ŷ) - S z,   ΔZ = Z - z = (1-C)/k - (1 - C) z + S (y - ŷ).
inline Vec3 bendPoint(const BendKernel& k, const Vec3& x) {
  const Vec3 rel = x - k.origin;
  const double y = glm::dot(rel, k.axis);
  const double z = glm::dot(rel, k.direction);
  const double yh = std::min(std::max(y, k.lo), k.hi);
  const double dy = y - yh;
  const BendTrig g = bendTrig(k.rate, yh);
  const double dY = (g.sOverK - yh) - g.oneMinusC * dy - g.s * z;
  const double dZ = g.oneMinusCOverK - g.oneMinusC * z + g.s * dy;
  return x + dY * k.axis + dZ * k.direction;
}

Vec3 orthogonalDirection(const Vec3& direction, const Vec3& axis) {
  detail::requireFinite("BendWarp", "direction", direction);
  if (maxAbs(direction) == 0.0) throw InvalidInput("BendWarp: the direction is zero");
  const Vec3 d = detail::safeNormalize(direction);
  const Vec3 perp = d - glm::dot(d, axis) * axis;
  // |perp| is the sine of the angle between direction and axis.
  if (!(glm::length(perp) > 1e-6)) {
    throw InvalidInput(
        "BendWarp: the direction is parallel to the axis (within 1e-6 rad); it must have a "
        "component perpendicular to the spine");
  }
  return glm::normalize(perp);
}

}  // namespace

BendWarp::BendWarp(const BendOptions& params)
    : params_(params),
      frame_("BendWarp", params.origin, params.axis, params.lo, params.hi),
      direction_(orthogonalDirection(params.direction, frame_.axis)) {
  detail::requireFinite("BendWarp", "rate", params.rate);
}

Vec3 BendWarp::apply(const Vec3& x) const {
  return bendPoint({frame_.origin, frame_.axis, direction_, params_.rate, frame_.lo, frame_.hi}, x);
}

std::optional<Vec3> BendWarp::exactInverse(const Vec3& target) const {
  const double k = params_.rate;
  if (k == 0.0) return target;
  const Vec3& a = frame_.axis;
  const Vec3& d = direction_;
  const Vec3 rel = target - frame_.origin;
  const double Y = glm::dot(rel, a);
  const double Z = glm::dot(rel, d);
  // Candidates: the rigid parts beyond each limit, and the bent region (angle and distance
  // from the center of curvature, scaled by k). Beyond the bent region the parts can overlap
  // (the bend folds far from the spine): the candidate that moves least is taken.
  std::optional<Vec3> best;
  double bestMove = std::numeric_limits<double>::infinity();
  auto consider = [&](double y, double z) {
    const double move = std::hypot(y - Y, z - Z);
    if (move < bestMove) {
      bestMove = move;
      best = target + (y - Y) * a + (z - Z) * d;
    }
  };
  // Beyond a limit the space moved rigidly with the end of the bent region: rotate back.
  for (const double limit : {frame_.hi, frame_.lo}) {
    if (!std::isfinite(limit)) continue;
    const BendTrig g = bendTrig(k, limit);
    const double c = 1.0 - g.oneMinusC;
    const double du = Y - g.sOverK, dw = Z - g.oneMinusCOverK;
    const double dy = c * du + g.s * dw;
    if (limit == frame_.hi ? dy > 0.0 : dy < 0.0) consider(limit + dy, -g.s * du + c * dw);
  }
  const double u = k * Y, w = 1.0 - k * Z;
  const double h = std::hypot(u, w);
  const double angleY = std::atan2(u, w) / k;
  const double y = frame_.clamp(angleY);
  // The angle is rounded: a point on a limit may come out a hair beyond it (and then not
  // beyond it in the rigid part's terms), where the two maps agree to first order: clamped.
  const bool inside =
      y == angleY || (!best && std::abs(y - angleY) <= 1e-9 * std::max(1.0, std::abs(y)));
  // z = (1 - h) / k without cancellation: 1 - h² = k (2 Z - k (Y² + Z²)).
  if (h > 0.0 && inside) consider(y, (2.0 * Z - k * (Y * Y + Z * Z)) / (1.0 + h));
  return best;
}

Mat3 BendWarp::jacobian(const Vec3& x) const {
  const Vec3& a = frame_.axis;
  const Vec3& d = direction_;
  const Vec3 b = glm::cross(a, d);
  const Vec3 rel = x - frame_.origin;
  const double y = glm::dot(rel, a);
  const double z = glm::dot(rel, d);
  const BendTrig g = bendTrig(params_.rate, frame_.clamp(y));
  const double c = 1.0 - g.oneMinusC;
  // Local Jacobian in the (b, a, d) frame; k' = k between the limits, 0 beyond.
  const double stretch = 1.0 - params_.rate * frame_.clampSlope(y) * z;
  const double yy = c * stretch, yz = -g.s, zy = g.s * stretch, zz = c;
  // J = F L Fᵀ with F = [b a d].
  return glm::outerProduct(b, b) + glm::outerProduct(a, yy * a + yz * d) +
         glm::outerProduct(d, zy * a + zz * d);
}

UnmappedPoints BendWarp::applyRange(std::span<const Vec3> in, std::span<Vec3> out,
                                    std::size_t begin, std::size_t end) const {
  const BendKernel k{frame_.origin, frame_.axis, direction_, params_.rate, frame_.lo, frame_.hi};
  for (std::size_t i = begin; i != end; ++i) out[i] = bendPoint(k, in[i]);
  return {};
}

void BendWarp::save(ArchiveWriter& out) const {
  out.tag("bend");
  out.vec3(params_.origin);
  out.vec3(params_.axis);
  out.vec3(params_.direction);
  out.f64(params_.rate);
  out.f64(params_.lo);
  out.f64(params_.hi);
}

std::shared_ptr<const BendWarp> BendWarp::load(ArchiveReader& in) {
  BendOptions params;
  params.origin = in.vec3();
  params.axis = in.vec3();
  params.direction = in.vec3();
  params.rate = in.f64();
  params.lo = in.f64();
  params.hi = in.f64();
  return std::make_shared<const BendWarp>(params);
}

}  // namespace spacewarp
