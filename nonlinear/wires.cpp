#include <spacewarp/nonlinear/wires.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <string>
#include <utility>

#include <glm/gtc/quaternion.hpp>

#include <spacewarp/core/archive.h>
#include <spacewarp/core/detail/enum_names.h>
#include <spacewarp/core/detail/rotation.h>
#include <spacewarp/core/errors.h>
#include <spacewarp/nonlinear/detail/box_tree.h>
#include <spacewarp/nonlinear/detail/chord_tree.h>

namespace spacewarp {

namespace {

using Quat = glm::dquat;

constexpr int kCatmullRomSamples = 16;  // samples per span (frames and the closest-point chords)
// Chords per wire: a build holds about 0.4 kB per chord (samples, frames, rotations, the chord
// tree), so this bounds one wire's build to about 7 GB.
constexpr double kMaxChords = 0x1p24;
constexpr int kNewtonSteps = 8;

std::string wireName(std::size_t i) { return "WiresWarp: wire " + std::to_string(i); }

// Any unit vector perpendicular to the unit vector t (crossed with the axis least along t).
Vec3 anyPerpendicular(const Vec3& t) {
  const Vec3 a = glm::abs(t);
  const Vec3 axis = a.x <= a.y && a.x <= a.z ? Vec3(1, 0, 0)
                    : a.y <= a.z             ? Vec3(0, 1, 0)
                                             : Vec3(0, 0, 1);
  return glm::normalize(glm::cross(t, axis));
}

// v turned by the smallest rotation taking the unit vector a to the unit vector b (a half turn
// about a perpendicular of a when they are opposite).
Vec3 minimalRotation(const Vec3& a, const Vec3& b, const Vec3& v) {
  const double c = glm::dot(a, b);
  if (c <= -1.0 + 1e-12) {
    const Vec3 p = anyPerpendicular(a);
    return 2.0 * glm::dot(p, v) * p - v;
  }
  const Vec3 k = glm::cross(a, b);  // Rodrigues with |k| = sin, written without the angle
  return c * v + glm::cross(k, v) + (glm::dot(k, v) / (1.0 + c)) * k;
}

// A curve through its points, parameterised by span j ∈ [0, n − 2] and t ∈ [0, 1].
struct Curve {
  WireCurve type = WireCurve::Polyline;
  std::vector<Vec3> p;
  std::vector<std::array<Vec3, 4>> coef;  // Catmull-Rom: C(t) = c0 + c1 t + c2 t² + c3 t³

  std::size_t spans() const { return p.size() - 1; }

  Vec3 at(std::size_t j, double t) const {
    if (type == WireCurve::Polyline) return p[j] + t * (p[j + 1] - p[j]);
    const auto& c = coef[j];
    return c[0] + t * (c[1] + t * (c[2] + t * c[3]));
  }
  Vec3 d1(std::size_t j, double t) const {
    if (type == WireCurve::Polyline) return p[j + 1] - p[j];
    const auto& c = coef[j];
    return c[1] + t * (2.0 * c[2] + t * 3.0 * c[3]);
  }
  Vec3 d2(std::size_t j, double t) const {
    if (type == WireCurve::Polyline) return Vec3(0.0);
    const auto& c = coef[j];
    return 2.0 * c[2] + (6.0 * t) * c[3];
  }
};

Curve makeCurve(WireCurve type, const std::vector<Vec3>& pts) {
  Curve c;
  c.type = type;
  c.p = pts;
  if (type == WireCurve::CatmullRom) {
    const std::size_t n = pts.size();
    const auto point = [&](std::ptrdiff_t i) -> Vec3 {  // reflected beyond the ends
      if (i < 0) return 2.0 * pts[0] - pts[1];
      if (i >= static_cast<std::ptrdiff_t>(n)) return 2.0 * pts[n - 1] - pts[n - 2];
      return pts[static_cast<std::size_t>(i)];
    };
    for (std::size_t j = 0; j + 1 < n; ++j) {
      const auto s = static_cast<std::ptrdiff_t>(j);
      const Vec3 a = point(s - 1), b = point(s), d = point(s + 1), e = point(s + 2);
      c.coef.push_back({b, 0.5 * (d - a), 0.5 * (2.0 * a - 5.0 * b + 4.0 * d - e),
                        0.5 * (3.0 * b - a - 3.0 * d + e)});
    }
  }
  return c;
}

// The curve's samples: positions and unit tangents (for polylines the points, with the mean of
// the neighbouring segments' directions as tangent; for Catmull-Rom kCatmullRomSamples per span).
struct Samples {
  std::vector<Vec3> x, t;
};

Samples sampleCurve(const Curve& c) {
  Samples s;
  if (c.type == WireCurve::Polyline) {
    const std::size_t n = c.p.size();
    for (std::size_t k = 0; k < n; ++k) {
      const Vec3 in = k > 0 ? glm::normalize(c.p[k] - c.p[k - 1]) : Vec3(0.0);
      const Vec3 out = k + 1 < n ? glm::normalize(c.p[k + 1] - c.p[k]) : Vec3(0.0);
      const Vec3 sum = in + out;
      // A fold back (in = −out) has no mean direction: the outgoing one.
      const Vec3 t = glm::length(sum) > 1e-8 ? glm::normalize(sum) : (k + 1 < n ? out : in);
      s.x.push_back(c.p[k]);
      s.t.push_back(t);
    }
    return s;
  }
  for (std::size_t j = 0; j < c.spans(); ++j) {
    for (int i = 0; i < kCatmullRomSamples; ++i) {
      const double t = static_cast<double>(i) / kCatmullRomSamples;
      s.x.push_back(c.at(j, t));
      s.t.push_back(glm::normalize(c.d1(j, t)));
    }
  }
  s.x.push_back(c.p.back());
  s.t.push_back(glm::normalize(c.d1(c.spans() - 1, 1.0)));
  return s;
}

// Rotation-minimising frames [tangent, normal, binormal] at the samples from the first normal,
// by double reflection (Wang, Jüttler, Zheng & Liu 2008): equivariant under rigid motions.
std::vector<Mat3> transportFrames(const Samples& s, Vec3 normal) {
  std::vector<Mat3> frames;
  frames.reserve(s.x.size());
  for (std::size_t k = 0; k < s.x.size(); ++k) {
    if (k > 0) {
      const Vec3 v1 = s.x[k] - s.x[k - 1];
      const double c1 = glm::dot(v1, v1);
      Vec3 r = normal, t = s.t[k - 1];
      if (c1 > 0.0) {
        r -= (2.0 / c1) * glm::dot(v1, r) * v1;
        t -= (2.0 / c1) * glm::dot(v1, t) * v1;
      }
      const Vec3 v2 = s.t[k] - t;
      const double c2 = glm::dot(v2, v2);
      if (c2 > 0.0) r -= (2.0 / c2) * glm::dot(v2, r) * v2;
      normal = r;
    }
    const Vec3& t = s.t[k];
    normal = glm::normalize(normal - glm::dot(normal, t) * t);
    frames.emplace_back(t, normal, glm::cross(t, normal));
  }
  return frames;
}

// How firmly the rest and deformed points fix the best rigid fit's turn about the rest curve's
// principal line: σ₂ + sign(det H) σ₃ of their cross-covariance H (σ₁ ≥ σ₂ ≥ σ₃ its singular
// values; 0 where the fit is not unique, so the fit's turn flips near there) over R's spread
// off its principal line (what it is for a rigid motion), capped at 1 from half of that on.
// 0 for a straight R.
double fitFirmness(const std::vector<Vec3>& rest, const std::vector<Vec3>& deformed) {
  Vec3 cr(0.0), cd(0.0);
  for (std::size_t k = 0; k < rest.size(); ++k) {
    cr += rest[k];
    cd += deformed[k];
  }
  cr /= static_cast<double>(rest.size());
  cd /= static_cast<double>(rest.size());
  Mat3 h(0.0), c(0.0);
  for (std::size_t k = 0; k < rest.size(); ++k) {
    h += glm::outerProduct(deformed[k] - cd, rest[k] - cr);
    c += glm::outerProduct(rest[k] - cr, rest[k] - cr);
  }
  const auto ascending = [](const Mat3& m) {
    std::array<double, 3> e{};
    Mat3 v;
    detail::symmetricEigen(m, e.data(), v);
    std::sort(e.begin(), e.end());
    return e;
  };
  const std::array<double, 3> spread = ascending(c);
  const double off = spread[0] + spread[1];
  // Off-line spread below rounding of the total: a straight R (its twist is undefined).
  if (!(off > 1e-24 * (off + spread[2]))) return 0.0;
  const std::array<double, 3> s2 = ascending(glm::transpose(h) * h);
  const double s3 = std::sqrt(std::max(0.0, s2[0])), s2nd = std::sqrt(std::max(0.0, s2[1]));
  const double firm = s2nd + (glm::determinant(h) < 0.0 ? -s3 : s3);
  return std::clamp(firm / (0.5 * off), 0.0, 1.0);
}

// The first normals of R and W: W's is R's turned by a rotation G with G R'(0) = W'(0), so that
// M(0) = G. G is the best rigid fit Q of the rest points onto the deformed ones turned by the
// smallest rotation taking Q R'(0) to W'(0), so that a rigid motion Q of the wire gives M = Q;
// where the fit is not firm (fitFirmness < 1: W nearly straight, or bent unlike R) its turn about
// W'(0) is faded towards that of the smallest rotation taking R'(0) to W'(0), so that the twist
// does not flip between nearly equal wires.
std::pair<Vec3, Vec3> firstNormals(const Wire& w, const Samples& r, const Samples& d) {
  const Vec3 tr = r.t[0], td = d.t[0];
  const Vec3 nr = anyPerpendicular(tr);
  if (w.rest == w.deformed) return {nr, nr};  // W = R: the identity exactly
  const Vec3 a = minimalRotation(tr, td, nr);
  const double fade = fitFirmness(w.rest, w.deformed);
  if (!(fade > 0.0)) return {nr, a};
  const Mat3 q = detail::rigidFit(w.rest, w.deformed).r;
  const Vec3 b = minimalRotation(glm::normalize(q * tr), td, q * nr);
  if (fade >= 1.0) return {nr, b};
  const double angle = fade * std::atan2(glm::dot(td, glm::cross(a, b)), glm::dot(a, b));
  return {nr, std::cos(angle) * a + std::sin(angle) * glm::cross(td, a)};
}

bool sameBits(const Mat3& a, const Mat3& b) {
  for (int c = 0; c < 3; ++c)
    for (int r = 0; r < 3; ++r)
      if (a[c][r] != b[c][r]) return false;
  return true;
}

// The rotation q about its axis by f times its angle 2 acos(q.w) ∈ [0, 2π]: q's sign is kept
// (not reduced to the short way), so that F M turns continuously where M passes a half turn.
Quat power(const Quat& q, double f) {
  const Vec3 v(q.x, q.y, q.z);
  const double s = glm::length(v);
  if (!(s > 0.0)) return Quat(1.0, 0.0, 0.0, 0.0);
  const double half = f * std::atan2(s, q.w);
  const Vec3 u = std::sin(half) * (v / s);
  return Quat(std::cos(half), u.x, u.y, u.z);
}

// The rotation vector (axis times angle, angle 2 acos(q.w) ∈ [0, 2π]) of the unit quaternion q:
// exp of it is q itself, sign included.
Vec3 rotationVector(const Quat& q) {
  const Vec3 v(q.x, q.y, q.z);
  const double s = glm::length(v);
  if (!(s > 0.0)) return Vec3(0.0);
  return (2.0 * std::atan2(s, q.w) / s) * v;
}

// SO(3)'s left Jacobian at the rotation vector p applied to y: (I + (1 − cos θ)/θ² [p]× +
// (θ − sin θ)/θ³ [p]×²) y, θ = |p| (series below 1e-4, where the closed forms cancel).
Vec3 leftJacobian(const Vec3& p, const Vec3& y) {
  const double t2 = glm::dot(p, p), t = std::sqrt(t2);
  const double a = t < 1e-4 ? 0.5 - t2 / 24.0 : (1.0 - std::cos(t)) / t2;
  const double b = t < 1e-4 ? 1.0 / 6.0 - t2 / 120.0 : (t - std::sin(t)) / (t2 * t);
  const Vec3 py = glm::cross(p, y);
  return y + a * py + b * glm::cross(p, py);
}

// Its inverse applied to y: (I − [p]×/2 + (1/θ² − (1 + cos θ)/(2 θ sin θ)) [p]×²) y, θ ∈ [0, 2π)
// (singular at 2π, where the partial rotations' axis is undefined).
Vec3 leftJacobianInverse(const Vec3& p, const Vec3& y) {
  const double t2 = glm::dot(p, p), t = std::sqrt(t2);
  const double c =
      t < 1e-4 ? 1.0 / 12.0 + t2 / 720.0 : 1.0 / t2 - (1.0 + std::cos(t)) / (2.0 * t * std::sin(t));
  const Vec3 py = glm::cross(p, y);
  return y - 0.5 * py + c * glm::cross(p, py);
}

double falloff(WireDropoff f, double x) {
  if (f == WireDropoff::Linear) return 1.0 - x;
  const double y = 1.0 - x * x;
  return y * y;
}

void validate(const std::vector<Wire>& wires, const WiresOptions& options) {
  if (wires.empty()) throw InvalidInput("WiresWarp: no wires");
  if (!std::isfinite(options.locality) || !(options.locality >= 0.0))
    throw InvalidInput("WiresWarp: locality must be finite and >= 0, not " +
                       std::to_string(options.locality));
  for (std::size_t i = 0; i < wires.size(); ++i) {
    const Wire& w = wires[i];
    const std::string who = wireName(i);
    if (w.rest.size() < 2)
      throw InvalidInput(who + ": rest needs at least 2 points, got " +
                         std::to_string(w.rest.size()));
    if (w.deformed.size() != w.rest.size())
      throw InvalidInput(who + ": " + std::to_string(w.rest.size()) + " rest points but " +
                         std::to_string(w.deformed.size()) + " deformed points");
    for (const auto& [name, pts] :
         {std::pair{"rest", &w.rest}, std::pair{"deformed", &w.deformed}}) {
      Vec3 lo(std::numeric_limits<double>::infinity()), hi = -lo;
      for (std::size_t k = 0; k < pts->size(); ++k) {
        if (!isFinite((*pts)[k]))
          throw InvalidInput(who + ": " + name + "[" + std::to_string(k) + "] is not finite");
        lo = glm::min(lo, (*pts)[k]);
        hi = glm::max(hi, (*pts)[k]);
      }
      // Squared lengths must stay finite (a span beyond ~1e154 would overflow them).
      if (!std::isfinite(glm::length(hi - lo)))
        throw InvalidInput(who + ": " + name + " spans too far for double precision");
      const double tol = 1e-12 * glm::length(hi - lo);
      for (std::size_t k = 1; k < pts->size(); ++k) {
        if (glm::length((*pts)[k] - (*pts)[k - 1]) <= tol)
          throw InvalidInput(who + ": " + name + "[" + std::to_string(k) + "] repeats " + name +
                             "[" + std::to_string(k - 1) + "]");
      }
      // A Catmull-Rom tangent at point k is (p[k+1] − p[k−1]) / 2: zero at a hairpin, where the
      // frames (and so the map) would be NaN.
      if (w.curve == WireCurve::CatmullRom) {
        for (std::size_t k = 1; k + 1 < pts->size(); ++k) {
          if (glm::length((*pts)[k + 1] - (*pts)[k - 1]) <= tol)
            throw InvalidInput(who + ": " + name + "[" + std::to_string(k + 1) + "] repeats " +
                               name + "[" + std::to_string(k - 1) +
                               "] (a hairpin: the catmull-rom curve has no tangent at " + name +
                               "[" + std::to_string(k) + "])");
        }
      }
    }
    // Refused before anything is allocated (memory grows with the chords).
    const double chords = static_cast<double>(w.rest.size() - 1) *
                          (w.curve == WireCurve::CatmullRom ? kCatmullRomSamples : 1);
    if (chords > kMaxChords)
      throw InvalidInput(who + ": " + std::to_string(w.rest.size()) + " points make " +
                         std::to_string(static_cast<std::size_t>(chords)) +
                         " chords, more than the " +
                         std::to_string(static_cast<std::size_t>(kMaxChords)) +
                         " a wire can have (about 0.4 kB each to build; use fewer points)");
    if (!std::isfinite(w.radius) || !(w.radius > 0.0))
      throw InvalidInput(who + ": radius must be finite and > 0, not " + std::to_string(w.radius));
    if (!(w.innerRadius >= 0.0) || !(w.innerRadius < w.radius))
      throw InvalidInput(who + ": innerRadius must be in [0, radius), not " +
                         std::to_string(w.innerRadius));
    if (!std::isfinite(w.scale) || !(w.scale > 0.0))
      throw InvalidInput(who + ": scale must be finite and > 0, not " + std::to_string(w.scale));
  }
}

}  // namespace

namespace {

constexpr detail::EnumNames<WireCurve, 2> kCurveNames = {
    {{WireCurve::Polyline, "polyline"}, {WireCurve::CatmullRom, "catmull-rom"}}};
constexpr detail::EnumNames<WireDropoff, 2> kDropoffNames = {
    {{WireDropoff::Smooth, "smooth"}, {WireDropoff::Linear, "linear"}}};

}  // namespace

std::string wireCurveName(WireCurve curve) { return detail::enumName(kCurveNames, curve); }

WireCurve wireCurveFromName(std::string_view name) {
  return detail::enumFromName(kCurveNames, name, "wire curve");
}

std::string wireDropoffName(WireDropoff dropoff) {
  return detail::enumName(kDropoffNames, dropoff);
}

WireDropoff wireDropoffFromName(std::string_view name) {
  return detail::enumFromName(kDropoffNames, name, "wire drop-off");
}

// One wire, ready to query: both curves, the rotations at the samples, and a bounding-volume
// hierarchy over the reference curve's sample chords.
struct WiresWarp::Compiled {
  Curve rest, deformed;
  int perSpan = 1;                                             // samples per span
  std::vector<Quat> turn;                                      // M at each sample
  std::unique_ptr<const detail::ChordTree> chords;             // sample chords of R
  double radius = 1.0, inner = 0.0, scale = 1.0, reach = 1.0;  // reach = r + chord deviation
  WireDropoff dropoff = WireDropoff::Smooth;
  Vec3 lo{0.0}, hi{0.0};  // R's samples' box grown by the reach: farther points do not move

  Compiled(const Wire& w, std::size_t index);

  // x's move Δx by this wire, and with `jacobian` its derivative dΔx/dx; false (both untouched)
  // when x is beyond its reach.
  bool move(const Vec3& x, Vec3& delta, Mat3* jacobian = nullptr) const;
};

WiresWarp::Compiled::Compiled(const Wire& w, std::size_t index)
    : rest(makeCurve(w.curve, w.rest)),
      deformed(makeCurve(w.curve, w.deformed)),
      perSpan(w.curve == WireCurve::CatmullRom ? kCatmullRomSamples : 1),
      radius(w.radius),
      inner(w.innerRadius),
      scale(w.scale),
      dropoff(w.dropoff) {
  const Samples sr = sampleCurve(rest);
  const Samples sd = sampleCurve(deformed);
  const auto [nr, nd] = firstNormals(w, sr, sd);
  const std::vector<Mat3> fr = transportFrames(sr, nr);
  const std::vector<Mat3> fd = transportFrames(sd, nd);
  for (std::size_t k = 0; k < fr.size(); ++k) {
    // W = R here gives the identity exactly (so that a wire at rest moves nothing).
    Quat q = sameBits(fr[k], fd[k]) ? Quat(1.0, 0.0, 0.0, 0.0)
                                    : glm::normalize(glm::quat_cast(fd[k] * glm::transpose(fr[k])));
    // The sign nearest the previous sample's (w >= 0 at the start): the quaternion, and so the
    // partial rotations power(M, F), continuous along the curve even where M passes a half turn.
    if (k == 0 ? q.w < 0.0 : glm::dot(q, turn.back()) < 0.0) q = -q;
    turn.push_back(q);
  }

  // How far a Catmull-Rom sub-span strays from its chord: |C''| Δt² / 8, |C''| largest at a span
  // end (it is affine in t).
  double deviation = 0.0;
  if (w.curve == WireCurve::CatmullRom) {
    const double dt = 1.0 / kCatmullRomSamples;
    for (std::size_t j = 0; j < rest.spans(); ++j) {
      const double c2 = std::max(glm::length(rest.d2(j, 0.0)), glm::length(rest.d2(j, 1.0)));
      deviation = std::max(deviation, c2 * dt * dt / 8.0);
    }
  }
  reach = radius + deviation;

  Vec3 bl(std::numeric_limits<double>::infinity()), bh = -bl;
  for (const Vec3& p : sr.x) {
    bl = glm::min(bl, p);
    bh = glm::max(bh, p);
  }
  lo = bl - Vec3(reach);
  hi = bh + Vec3(reach);
  if (!isFinite(lo) || !isFinite(hi) || !isFinite(hi - lo) || !std::isfinite(reach * reach))
    throw InvalidInput(wireName(index) + ": radius reaches beyond the range of doubles");
  chords = std::make_unique<const detail::ChordTree>(sr.x);
}

bool WiresWarp::Compiled::move(const Vec3& x, Vec3& delta, Mat3* jacobian) const {
  if (!(x.x >= lo.x && x.y >= lo.y && x.z >= lo.z && x.x <= hi.x && x.y <= hi.y && x.z <= hi.z))
    return false;  // beyond the reach (or not finite): a few comparisons per far wire
  detail::ChordTree::Hit hit;
  if (!chords->nearest(x, reach * reach, hit)) return false;
  const std::uint32_t bestK = hit.chord;
  const double bestT = hit.t;

  // The closest point of R: span j, t ∈ [0, 1].
  std::size_t j = bestK / static_cast<std::uint32_t>(perSpan);
  double t = bestT;
  if (perSpan > 1) {
    t = (static_cast<double>(bestK % static_cast<std::uint32_t>(perSpan)) + bestT) / perSpan;
    const std::size_t last = rest.spans() - 1;
    for (int step = 0; step < kNewtonSteps; ++step) {
      const Vec3 off = rest.at(j, t) - x;
      const Vec3 v = rest.d1(j, t);
      const double slope = glm::dot(rest.d2(j, t), off) + glm::dot(v, v);
      if (!(slope > 0.0)) break;
      const double dt = glm::dot(v, off) / slope;
      t -= dt;
      if (t < 0.0 && j > 0) {
        --j;
        t += 1.0;
      } else if (t > 1.0 && j < last) {
        ++j;
        t -= 1.0;
      }
      t = std::clamp(t, 0.0, 1.0);
      if (std::abs(dt) <= 1e-14) break;
    }
  }
  const Vec3 foot = rest.at(j, t);
  const Vec3 v = x - foot;
  const double d = glm::length(v);
  if (!(d < radius)) return false;
  const double f = d <= inner ? 1.0 : falloff(dropoff, (d - inner) / (radius - inner));

  // The rotation at (j, t), interpolated between the samples, then its angle times F.
  const double s = t * perSpan;
  const std::size_t k =
      std::min(j * static_cast<std::size_t>(perSpan) + static_cast<std::size_t>(std::floor(s)),
               turn.size() - 2);
  const double a =
      static_cast<double>(j * static_cast<std::size_t>(perSpan)) + s - static_cast<double>(k);
  // Neighbouring samples' rotations are close (one hemisphere): normalised lerp is slerp to
  // within their angle squared, and cheaper.
  const Quat full =
      turn[k] == turn[k + 1] ? turn[k] : glm::normalize((1.0 - a) * turn[k] + a * turn[k + 1]);
  const Quat q = f != 1.0 ? power(full, f) : full;
  const double grow = 1.0 + (scale - 1.0) * f;
  // x' − x, written so that W = R, s = 1 gives exactly 0 (q is then the identity).
  const Vec3 turned = q * v;
  const Vec3 shift = deformed.at(j, t) - foot;
  delta = (grow * turned - v) + f * shift;
  if (!jacobian) return true;

  // dΔ/dx through t(x) (the closest point), F(x) and v = x − R(t):
  //   Δ = S P v − v + F (W(t) − R(t)), S = 1 + (s − 1) F, P = exp(F φ(t)), φ = log M(t),
  //   ∇t = R' / (|R'|² − R''·v) (0 where the closest point is an end of R or a polyline
  //   vertex), ∇F = f'(·) / (r − r₀) v / d, dP/dF v = φ × P v, dP/dt v = (J_l(Fφ) F φ̇) × P v
  //   with φ̇ = J_l(φ)⁻¹ ω, ω the angular velocity of M along t (J_l: SO(3)'s left Jacobian).
  const Vec3 r1 = rest.d1(j, t);
  Vec3 gradT(0.0);
  const bool atVertex = perSpan == 1
                            ? (t == 0.0 || t == 1.0)
                            : ((j == 0 && t == 0.0) || (j + 1 == rest.spans() && t == 1.0));
  if (!atVertex) {
    const double denominator = glm::dot(r1, r1) - glm::dot(rest.d2(j, t), v);
    if (denominator > 0.0) gradT = r1 / denominator;
  }
  Vec3 gradF(0.0);
  if (d > inner) {
    const double u = (d - inner) / (radius - inner);
    const double slope = dropoff == WireDropoff::Linear ? -1.0 : -4.0 * u * (1.0 - u * u);
    gradF = (slope / ((radius - inner) * d)) * v;
  }
  Vec3 omega(0.0);  // angular velocity of M(t), world frame: dM/dt = [ω]× M
  if (!(turn[k] == turn[k + 1])) {
    const Quat blendQ = (1.0 - a) * turn[k] + a * turn[k + 1];
    const double n = glm::length(blendQ);
    const Quat dBlend = static_cast<double>(perSpan) * (turn[k + 1] - turn[k]);
    const Quat dq = (dBlend - glm::dot(full, dBlend) * full) / n;
    const Quat w = dq * glm::conjugate(full);
    omega = 2.0 * Vec3(w.x, w.y, w.z);
  }
  const Vec3 phi = rotationVector(full);
  const Vec3 psi = f * phi;
  const Vec3 dTurnedDt = glm::cross(leftJacobian(psi, f * leftJacobianInverse(phi, omega)), turned);
  const Vec3 dTurnedDf = glm::cross(phi, turned);
  const Mat3 rotation = glm::mat3_cast(q);
  const Mat3 alongT = Mat3(1.0) - glm::outerProduct(r1, gradT);  // dv/dx
  *jacobian = glm::outerProduct(turned, (scale - 1.0) * gradF) +
              grow * (glm::outerProduct(dTurnedDt, gradT) + glm::outerProduct(dTurnedDf, gradF) +
                      rotation * alongT) -
              alongT + glm::outerProduct(shift, gradF) +
              f * glm::outerProduct(deformed.d1(j, t) - r1, gradT);
  return true;
}

WiresWarp::WiresWarp(std::vector<Wire> wires, const WiresOptions& options)
    : wires_(std::move(wires)), options_(options) {
  validate(wires_, options_);
  for (std::size_t i = 0; i < wires_.size(); ++i)
    compiled_.push_back(std::make_unique<const Compiled>(wires_[i], i));
  std::vector<Vec3> lo, hi;
  for (const auto& c : compiled_) {
    lo.push_back(c->lo);
    hi.push_back(c->hi);
  }
  index_ = std::make_unique<const detail::BoxTree>(lo, hi, 0.0);
}

WiresWarp::~WiresWarp() = default;

namespace {

// x' from the moves of the wires (the paper's blend; a single wire's move as it is). Only the
// wires whose reach box holds x (found by `index`) can move it; the others' moves are 0, which
// the blend skips, so visiting those in index order gives the same sums bit for bit.
template <class Wires>
Vec3 blend(const Wires& compiled, const detail::BoxTree& index, double m, const Vec3& x) {
  if (compiled.size() == 1) {
    Vec3 delta;
    return compiled[0]->move(x, delta) ? x + delta : x;
  }
  constexpr std::size_t kLocal = 16;  // wires near one point, without a heap allocation
  constexpr std::size_t kDirect = 8;  // up to this many wires, all are visited
  std::array<std::uint32_t, kLocal> localIds;
  std::vector<std::uint32_t> heapIds;
  std::size_t count = 0;
  if (compiled.size() <= kDirect) {  // each wire's own box test is cheaper than the index
    for (; count < compiled.size(); ++count) localIds[count] = static_cast<std::uint32_t>(count);
  } else {
    index.containing(x, [&](std::uint32_t i) {
      if (count < kLocal) {
        localIds[count] = i;
      } else {
        if (heapIds.empty()) heapIds.assign(localIds.begin(), localIds.end());
        heapIds.push_back(i);
      }
      ++count;
    });
    if (count == 0) return x;
  }
  std::uint32_t* ids = count <= kLocal ? localIds.data() : heapIds.data();
  if (compiled.size() > kDirect) std::sort(ids, ids + count);
  // Weights |Δx_i|^m normalised by the largest |Δx_i| (neither overflow nor underflow).
  std::array<Vec3, kLocal> local;
  std::array<double, kLocal> len{};
  std::vector<Vec3> heapD;
  std::vector<double> heapL;
  Vec3* dx = local.data();
  double* lx = len.data();
  if (count > kLocal) {
    heapD.resize(count);
    heapL.resize(count);
    dx = heapD.data();
    lx = heapL.data();
  }
  double largest = 0.0;
  for (std::size_t c = 0; c < count; ++c) {
    dx[c] = Vec3(0.0);
    compiled[ids[c]]->move(x, dx[c]);
    lx[c] = glm::length(dx[c]);
    largest = std::max(largest, lx[c]);
  }
  if (!(largest > 0.0)) return x;
  Vec3 sum(0.0);
  double weights = 0.0;
  for (std::size_t c = 0; c < count; ++c) {
    if (!(lx[c] > 0.0)) continue;
    const double w = m == 0.0 ? 1.0 : m == 1.0 ? lx[c] / largest : std::pow(lx[c] / largest, m);
    sum += w * dx[c];
    weights += w;
  }
  return x + sum / weights;
}

}  // namespace

Vec3 WiresWarp::apply(const Vec3& x) const {
  return blend(compiled_, *index_, options_.locality, x);
}

Mat3 WiresWarp::jacobian(const Vec3& x) const {
  if (compiled_.size() == 1) {
    Vec3 delta;
    Mat3 j(0.0);
    compiled_[0]->move(x, delta, &j);
    return Mat3(1.0) + j;
  }
  // The blend x + Σ w_i Δ_i / Σ w_i with w_i = |Δ_i|^m: dw_i = m w_i Δ_iᵀ dΔ_i / |Δ_i|², and
  // the weights may be scaled by any common factor (here 1 / the largest |Δ_i|).
  const double m = options_.locality;
  std::vector<Vec3> deltas(compiled_.size(), Vec3(0.0));
  std::vector<Mat3> jacobians(compiled_.size(), Mat3(0.0));
  double largest = 0.0;
  for (std::size_t i = 0; i < compiled_.size(); ++i) {
    compiled_[i]->move(x, deltas[i], &jacobians[i]);
    largest = std::max(largest, glm::length(deltas[i]));
  }
  if (!(largest > 0.0)) return Mat3(1.0);
  Vec3 sum(0.0), sumGradW(0.0);
  Mat3 sumTerms(0.0);
  double weights = 0.0;
  for (std::size_t i = 0; i < compiled_.size(); ++i) {
    const double l = glm::length(deltas[i]);
    if (!(l > 0.0)) continue;
    const double w = std::pow(l / largest, m);
    const Vec3 gradW = (m * w / (l * l)) * (glm::transpose(jacobians[i]) * deltas[i]);
    sum += w * deltas[i];
    weights += w;
    sumGradW += gradW;
    sumTerms += w * jacobians[i] + glm::outerProduct(deltas[i], gradW);
  }
  return Mat3(1.0) + sumTerms / weights - glm::outerProduct(sum, sumGradW) / (weights * weights);
}

UnmappedPoints WiresWarp::applyRange(std::span<const Vec3> in, std::span<Vec3> out,
                                     std::size_t begin, std::size_t end) const {
  for (std::size_t i = begin; i != end; ++i)
    out[i] = blend(compiled_, *index_, options_.locality, in[i]);
  return {};
}

void WiresWarp::save(ArchiveWriter& out) const {
  out.tag("wires");
  out.f64(options_.locality);
  out.u64(wires_.size());
  for (const Wire& w : wires_) {
    out.vec3s(w.rest);
    out.vec3s(w.deformed);
    out.f64(w.radius);
    out.f64(w.innerRadius);
    out.f64(w.scale);
    out.enumeration(w.dropoff);
    out.enumeration(w.curve);
  }
}

std::shared_ptr<const WiresWarp> WiresWarp::load(ArchiveReader& in) {
  WiresOptions options;
  options.locality = in.f64();
  const std::uint64_t count = in.u64();
  std::vector<Wire> wires;  // grown as wires are read: the count is not trusted for memory
  for (std::uint64_t i = 0; i < count; ++i) {
    Wire w;
    w.rest = in.vec3s();
    w.deformed = in.vec3s();
    w.radius = in.f64();
    w.innerRadius = in.f64();
    w.scale = in.f64();
    w.dropoff = in.enumeration<WireDropoff>(kDropoffNames.size());
    w.curve = in.enumeration<WireCurve>(kCurveNames.size());
    wires.push_back(std::move(w));
  }
  return std::make_shared<const WiresWarp>(std::move(wires), options);
}

}  // namespace spacewarp
