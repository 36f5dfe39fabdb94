#include <spacewarp/core/taper.h>

#include <algorithm>
#include <string>

#include <spacewarp/core/archive.h>
#include <spacewarp/core/errors.h>

namespace spacewarp {

namespace {

// Everything the per-point map needs, by value, so the batch loop keeps it in registers.
struct TaperKernel {
  Vec3 origin;
  Vec3 axis;  // unit
  double rate;
  double lo;
  double hi;
};

// The one per-point map, used by apply() and applyBatch() alike (bit-identical results).
// x' = x + (r - 1) p with r - 1 = rate ŝ, so that rate = 0 is exactly the identity.
inline Vec3 taperPoint(const TaperKernel& k, const Vec3& x) {
  const Vec3 d = x - k.origin;
  const double s = glm::dot(d, k.axis);
  const double rMinus1 = k.rate * std::min(std::max(s, k.lo), k.hi);
  return x + rMinus1 * (d - s * k.axis);
}

}  // namespace

TaperWarp::TaperWarp(const TaperOptions& params)
    : params_(params), frame_("TaperWarp", params.origin, params.axis, params.lo, params.hi) {
  detail::requireFinite("TaperWarp", "rate", params.rate);
}

Vec3 TaperWarp::apply(const Vec3& x) const {
  return taperPoint({frame_.origin, frame_.axis, params_.rate, frame_.lo, frame_.hi}, x);
}

std::optional<Vec3> TaperWarp::exactInverse(const Vec3& y) const {
  const Vec3 d = y - frame_.origin;
  const double s = glm::dot(d, frame_.axis);
  const double rMinus1 = params_.rate * frame_.clamp(s);
  const double r = 1.0 + rMinus1;
  if (!(r != 0.0)) return std::nullopt;
  // x = y + (1/r - 1) p with 1/r - 1 = -(r - 1)/r, so that rate = 0 is exactly the identity.
  return y - (rMinus1 / r) * (d - s * frame_.axis);
}

Mat3 TaperWarp::jacobian(const Vec3& x) const {
  const Vec3& a = frame_.axis;
  const Vec3 d = x - frame_.origin;
  const double s = glm::dot(d, a);
  const double r = scaleAt(s);
  const Mat3 aa = glm::outerProduct(a, a);
  const Vec3 p = d - s * a;
  return aa + r * (Mat3(1.0) - aa) +
         glm::outerProduct((params_.rate * frame_.clampSlope(s)) * p, a);
}

UnmappedPoints TaperWarp::applyRange(std::span<const Vec3> in, std::span<Vec3> out,
                                     std::size_t begin, std::size_t end) const {
  const TaperKernel k{frame_.origin, frame_.axis, params_.rate, frame_.lo, frame_.hi};
  for (std::size_t i = begin; i != end; ++i) out[i] = taperPoint(k, in[i]);
  return {};
}

void TaperWarp::save(ArchiveWriter& out) const {
  out.tag("taper");
  out.vec3(params_.origin);
  out.vec3(params_.axis);
  out.f64(params_.rate);
  out.f64(params_.lo);
  out.f64(params_.hi);
}

std::shared_ptr<const TaperWarp> TaperWarp::load(ArchiveReader& in) {
  TaperOptions params;
  params.origin = in.vec3();
  params.axis = in.vec3();
  params.rate = in.f64();
  params.lo = in.f64();
  params.hi = in.f64();
  return std::make_shared<const TaperWarp>(params);
}

}  // namespace spacewarp
