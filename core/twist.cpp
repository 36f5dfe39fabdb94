#include <spacewarp/core/twist.h>

#include <algorithm>
#include <cmath>
#include <string>

#include <spacewarp/core/archive.h>
#include <spacewarp/core/errors.h>

namespace spacewarp {

namespace {

// Everything the per-point map needs, by value, so the batch loop keeps it in registers.
struct TwistKernel {
  Vec3 origin;
  Vec3 axis;  // unit
  double rate;
  double lo;
  double hi;
};

// The one per-point map, used by apply() and applyBatch() alike (bit-identical results).
// Written as x + displacement so that rate = 0 is exactly the identity.
inline Vec3 twistPoint(const TwistKernel& k, const Vec3& x) {
  const Vec3 d = x - k.origin;
  const double s = glm::dot(d, k.axis);
  const double theta = k.rate * std::min(std::max(s, k.lo), k.hi);
  const double c = std::cos(theta);
  const double sn = std::sin(theta);
  const Vec3 p = d - s * k.axis;  // the part of d perpendicular to the axis
  return x + (c - 1.0) * p + sn * glm::cross(k.axis, d);
}

TwistKernel kernelOf(const detail::AxisFrame& f, double rate) {
  return {f.origin, f.axis, rate, f.lo, f.hi};
}

}  // namespace

TwistWarp::TwistWarp(const TwistOptions& params)
    : params_(params), frame_("TwistWarp", params.origin, params.axis, params.lo, params.hi) {
  detail::requireFinite("TwistWarp", "rate", params.rate);
}

Vec3 TwistWarp::apply(const Vec3& x) const { return twistPoint(kernelOf(frame_, params_.rate), x); }

std::optional<Vec3> TwistWarp::exactInverse(const Vec3& y) const {
  return twistPoint(kernelOf(frame_, -params_.rate), y);
}

Mat3 TwistWarp::jacobian(const Vec3& x) const {
  const Vec3& a = frame_.axis;
  const double s = frame_.axial(x);
  const double theta = params_.rate * frame_.clamp(s);
  const double c = std::cos(theta);
  const double sn = std::sin(theta);
  // R = c I + sin [a]x + (1 - c) a aᵀ; column i is R e_i.
  Mat3 r(c);
  r += (1.0 - c) * glm::outerProduct(a, a);
  r[0] += sn * glm::cross(a, Vec3(1.0, 0.0, 0.0));
  r[1] += sn * glm::cross(a, Vec3(0.0, 1.0, 0.0));
  r[2] += sn * glm::cross(a, Vec3(0.0, 0.0, 1.0));
  const double dTheta = params_.rate * frame_.clampSlope(s);
  if (dTheta == 0.0) return r;
  const Vec3 rotated = r * (x - frame_.origin);
  return r + dTheta * glm::outerProduct(glm::cross(a, rotated), a);
}

UnmappedPoints TwistWarp::applyRange(std::span<const Vec3> in, std::span<Vec3> out,
                                     std::size_t begin, std::size_t end) const {
  const TwistKernel k = kernelOf(frame_, params_.rate);
  for (std::size_t i = begin; i != end; ++i) out[i] = twistPoint(k, in[i]);
  return {};
}

void TwistWarp::save(ArchiveWriter& out) const {
  out.tag("twist");
  out.vec3(params_.origin);
  out.vec3(params_.axis);
  out.f64(params_.rate);
  out.f64(params_.lo);
  out.f64(params_.hi);
}

std::shared_ptr<const TwistWarp> TwistWarp::load(ArchiveReader& in) {
  TwistOptions params;
  params.origin = in.vec3();
  params.axis = in.vec3();
  params.rate = in.f64();
  params.lo = in.f64();
  params.hi = in.f64();
  return std::make_shared<const TwistWarp>(params);
}

}  // namespace spacewarp
