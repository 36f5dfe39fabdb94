#include <spacewarp/nonlinear/wires.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <glm/gtc/quaternion.hpp>

#include <spacewarp/core/errors.h>
#include "test_util.h"

namespace spacewarp {
namespace {

using ::testing::HasSubstr;

constexpr WireCurve kCurves[] = {WireCurve::Polyline, WireCurve::CatmullRom};

// A bent, non-planar reference curve of about unit size.
std::vector<Vec3> bentCurve() {
  return {
      {-1.0, 0.0, 0.0}, {-0.4, 0.25, 0.05}, {0.2, 0.3, -0.1}, {0.8, 0.1, 0.15}, {1.3, -0.3, 0.2}};
}

// The curve through `p` at span j, t ∈ [0, 1], from the matrix form of the uniform Catmull-Rom
// spline (ends reflected), or the polyline.
Vec3 curveAt(WireCurve curve, const std::vector<Vec3>& p, std::size_t j, double t) {
  if (curve == WireCurve::Polyline) return (1.0 - t) * p[j] + t * p[j + 1];
  const std::size_t n = p.size();
  const Vec3 a = j == 0 ? 2.0 * p[0] - p[1] : p[j - 1];
  const Vec3 d = j + 2 >= n ? 2.0 * p[n - 1] - p[n - 2] : p[j + 2];
  const double t2 = t * t, t3 = t2 * t;
  return 0.5 * ((-t3 + 2 * t2 - t) * a + (3 * t3 - 5 * t2 + 2) * p[j] +
                (-3 * t3 + 4 * t2 + t) * p[j + 1] + (t3 - t2) * d);
}

// Distance from x to the curve by dense sampling (an upper bound, within 1e-4 of the truth here).
double distanceTo(WireCurve curve, const std::vector<Vec3>& p, const Vec3& x) {
  double best = std::numeric_limits<double>::infinity();
  for (std::size_t j = 0; j + 1 < p.size(); ++j)
    for (int i = 0; i <= 400; ++i)
      best = std::min(best, glm::length(x - curveAt(curve, p, j, i / 400.0)));
  return best;
}

Wire wireOf(WireCurve curve, std::vector<Vec3> rest, std::vector<Vec3> deformed, double radius) {
  Wire w;
  w.curve = curve;
  w.rest = std::move(rest);
  w.deformed = std::move(deformed);
  w.radius = radius;
  return w;
}

std::vector<Vec3> moved(const std::vector<Vec3>& p, const Mat3& q, const Vec3& t) {
  std::vector<Vec3> out;
  for (const Vec3& x : p) out.push_back(q * x + t);
  return out;
}

Mat3 rotationAbout(const Vec3& axis, double angle) {
  return glm::mat3_cast(glm::angleAxis(angle, glm::normalize(axis)));
}

// A bend of the reference curve: each point moved by a smooth offset times `amount`.
std::vector<Vec3> bent(const std::vector<Vec3>& p, double amount = 1.0) {
  std::vector<Vec3> out;
  for (const Vec3& x : p) out.push_back(x + amount * Vec3(0.1 * x.y, 0.3 * x.x * x.x, -0.2 * x.x));
  return out;
}

TEST(WiresWarp, NamesRoundTripAndDefaults) {
  for (WireCurve c : kCurves) EXPECT_EQ(wireCurveFromName(wireCurveName(c)), c);
  for (WireDropoff f : {WireDropoff::Smooth, WireDropoff::Linear})
    EXPECT_EQ(wireDropoffFromName(wireDropoffName(f)), f);
  EXPECT_THAT(test::messageOf<InvalidInput>([] { wireCurveFromName("bezier"); }),
              HasSubstr("'bezier' is not one of: polyline, catmull-rom"));
  EXPECT_THAT(test::messageOf<InvalidInput>([] { wireDropoffFromName("cubic"); }),
              HasSubstr("'cubic' is not one of: smooth, linear"));
  const Wire w;
  EXPECT_EQ(w.scale, 1.0);
  EXPECT_EQ(w.innerRadius, 0.0);
  EXPECT_EQ(w.dropoff, WireDropoff::Smooth);
  EXPECT_EQ(w.curve, WireCurve::Polyline);
  EXPECT_EQ(WiresOptions{}.locality, 1.0);
}

TEST(WiresWarp, PointsOnTheRestWireGoOntoTheDeformedWire) {
  const std::vector<Vec3> rest = bentCurve();
  const std::vector<Vec3> deformed = bent(rest);
  for (WireCurve curve : kCurves) {
    const WiresWarp warp({wireOf(curve, rest, deformed, 0.4)});
    for (std::size_t j = 0; j + 1 < rest.size(); ++j) {
      for (double t : {0.0, 0.1, 0.37, 0.5, 0.93, 1.0}) {
        const Vec3 x = curveAt(curve, rest, j, t);
        const Vec3 expected = curveAt(curve, deformed, j, t);
        EXPECT_LE(glm::length(warp.apply(x) - expected), 1e-12)
            << wireCurveName(curve) << " span " << j << " t " << t;
      }
    }
  }
}

TEST(WiresWarp, PointsBeyondTheRadiusDoNotMove) {
  std::mt19937 rng(1);
  const std::vector<Vec3> rest = bentCurve();
  for (WireCurve curve : kCurves) {
    const WiresWarp warp({wireOf(curve, rest, bent(rest), 0.3)});
    std::size_t far = 0, nearby = 0;
    for (const Vec3& x : test::randomPoints(rng, 3000, -1.6, 1.6)) {
      const double d = distanceTo(curve, rest, x);
      const Vec3 y = warp.apply(x);
      if (d > 0.3) {
        ++far;
        EXPECT_TRUE(test::bitEqual(y, x)) << test::toString(x) << " at distance " << d;
      } else if (d < 0.29) {
        ++nearby;
        EXPECT_FALSE(y == x) << test::toString(x) << " at distance " << d;
      }
    }
    EXPECT_GT(far, 1000u);
    EXPECT_GT(nearby, 50u);
  }
}

TEST(WiresWarp, WireAtRestIsTheIdentity) {
  std::mt19937 rng(2);
  const std::vector<Vec3> rest = bentCurve();
  for (WireCurve curve : kCurves) {
    for (WireDropoff f : {WireDropoff::Smooth, WireDropoff::Linear}) {
      Wire w = wireOf(curve, rest, rest, 0.5);
      w.dropoff = f;
      w.innerRadius = 0.1;
      const WiresWarp warp({w, wireOf(curve, rest, rest, 0.8)});
      EXPECT_TRUE(test::leavesPointsUnchanged(warp, test::randomPoints(rng, 2000, -1.5, 1.5)));
    }
  }
}

TEST(WiresWarp, RigidMotionOfTheWireMovesItsInnerTubeRigidly) {
  std::mt19937 rng(3);
  const std::vector<Vec3> rest = bentCurve();
  const Mat3 q = rotationAbout({0.3, -1.0, 0.5}, 0.9);
  const Vec3 shift(0.4, -0.2, 0.7);
  for (WireCurve curve : kCurves) {
    Wire w = wireOf(curve, rest, moved(rest, q, shift), 0.5);
    w.innerRadius = 0.25;
    const WiresWarp warp({w});
    std::size_t inside = 0;
    for (const Vec3& x : test::randomPoints(rng, 4000, -1.5, 1.5)) {
      if (!(distanceTo(curve, rest, x) < 0.24)) continue;
      ++inside;
      EXPECT_LE(glm::length(warp.apply(x) - (q * x + shift)), 1e-12)
          << wireCurveName(curve) << " " << test::toString(x);
    }
    EXPECT_GT(inside, 50u);

    // Paper's drop-off, no inner radius: F = 1 and ∇F = 0 on the wire, so J = Q there.
    const WiresWarp onWire({wireOf(curve, rest, moved(rest, q, shift), 0.5)});
    for (std::size_t j = 0; j + 1 < rest.size(); ++j) {
      const Vec3 x = curveAt(curve, rest, j, 0.4);
      const Mat3 jac = onWire.jacobian(x);
      EXPECT_LE(test::relativeError(jac, q), 1e-12)
          << wireCurveName(curve) << " " << test::toString(jac) << " vs " << test::toString(q);
    }
  }
}

// The rigid-motion property with the rig scaled by 1e-4 and moved 1e3 away (where doubles resolve
// only 1e-9 of the wire's radius) and scaled by 1e3: the grid follows the wire's extent, and the
// analytic Jacobian is the rotation (central differences lose 4 digits at the first).
TEST(WiresWarp, RigidMotionHoldsAtAnyPlacement) {
  std::mt19937 rng(7);
  const Mat3 q = rotationAbout({1.0, 0.2, -0.4}, 0.7);
  for (const auto& [scale, offset] :
       {std::pair{1e-4, Vec3(1e3, -2e3, 5e2)}, std::pair{1e3, Vec3(-4e5, 1e5, 0.0)}}) {
    std::vector<Vec3> rest;
    for (const Vec3& p : bentCurve()) rest.push_back(offset + scale * p);
    Wire w = wireOf(WireCurve::CatmullRom, rest, moved(rest, q, scale * Vec3(0.3, 0.1, -0.2)),
                    0.5 * scale);
    w.innerRadius = 0.25 * scale;
    const WiresWarp warp({w});
    std::size_t inside = 0;
    for (const Vec3& u : test::randomPoints(rng, 4000, -1.5, 1.5)) {
      const Vec3 x = offset + scale * u;
      if (!(distanceTo(WireCurve::CatmullRom, bentCurve(), u) < 0.24)) continue;
      ++inside;
      const Vec3 expected = q * x + (warp.apply(rest[0]) - q * rest[0]);
      EXPECT_LE(glm::length(warp.apply(x) - expected), 1e-12 * glm::length(offset)) << scale;
      // The input itself resolves the wire's frames to ~1e-9 there (chords of 1e-6 at 1e3).
      EXPECT_LE(test::relativeError(warp.jacobian(x), q), 1e-7) << scale;
    }
    EXPECT_GT(inside, 50u);
  }
}

// The largest step between the images of consecutive points.
double largestStep(const Warp& warp, const std::vector<Vec3>& points) {
  double largest = 0.0;
  for (std::size_t i = 0; i + 1 < points.size(); ++i)
    largest = std::max(largest, glm::length(warp.apply(points[i + 1]) - warp.apply(points[i])));
  return largest;
}

// Where the wire's rotation passes a half turn, the partial rotations F M must not switch to the
// other way round (space tore there): a straight wire curled into an arc whose tangent turns
// 0° → 240° (arc length kept), and a rigid half turn of a bent wire.
TEST(WiresWarp, NoTearWhereTheRotationPassesAHalfTurn) {
  const double length = 4.0, turn = 4.0 * std::acos(-1.0) / 3.0, bend = length / turn;
  std::vector<Vec3> rest, curled;
  for (int i = 0; i <= 40; ++i) {
    const double s = length * i / 40.0;
    rest.push_back({s, 0.0, 0.0});
    curled.push_back({bend * std::sin(s / bend), bend * (1.0 - std::cos(s / bend)), 0.0});
  }
  const std::vector<Vec3> bentRest = bentCurve();
  const Mat3 halfTurn = rotationAbout({0.3, -1.0, 0.5}, std::acos(-1.0));
  for (WireCurve curve : kCurves) {
    const WiresWarp curl({wireOf(curve, rest, curled, 0.3)});
    for (const Vec3& offset : {Vec3(0.0, 0.0, 0.15), Vec3(0.0, 0.15, 0.0)}) {
      std::vector<Vec3> line;
      for (int i = 0; i <= 4000; ++i) line.push_back(Vec3(length * i / 4000.0, 0.0, 0.0) + offset);
      // Steps of 1e-3 stretched by at most 1 + 0.15 / bend along the arc (F turns little more).
      EXPECT_LE(largestStep(curl, line), 3e-3) << wireCurveName(curve);
    }
    if (curve == WireCurve::CatmullRom) {
      // The Jacobian with M's angle beyond π (the tangent turned 180° at x = 3).
      std::vector<Vec3> beyond;
      for (int i = 0; i < 20; ++i) beyond.push_back({3.05 + 0.04 * i, 0.05, 0.12});
      EXPECT_TRUE(test::jacobianMatchesFiniteDifferences(curl, beyond, 1e-6));
    }
    // (A polyline's vertices tear slightly at their inner bisectors anyway: see the header.)
    if (curve == WireCurve::Polyline) continue;
    const WiresWarp rigid({wireOf(curve, bentRest, moved(bentRest, halfTurn, {}), 0.5)});
    std::vector<Vec3> beside;
    for (std::size_t j = 0; j + 1 < bentRest.size(); ++j)
      for (int i = 0; i < 1000; ++i)
        beside.push_back(curveAt(curve, bentRest, j, i / 1000.0) + Vec3(0.0, 0.0, 0.3));
    // Input steps below 1e-3; the half turn's partial rotations scale them by a few at most.
    EXPECT_LE(largestStep(rigid, beside), 1e-2) << wireCurveName(curve);
  }
}

// The tube's twist is continuous in W: ±1e-4 bumps of a nearly straight deformed curve, or of an
// S-shaped one whose correlation with an arched R changes sign there, move the points little
// (the best rigid fit turns by a half turn between them, and W's first frame used to follow "the
// first point off the initial tangent line", turning the tube upside down).
TEST(WiresWarp, TinyChangesOfTheWireMoveTheTubeLittle) {
  const auto wire = [](WireCurve curve, std::vector<Vec3> rest, std::vector<Vec3> deformed) {
    Wire w = wireOf(curve, std::move(rest), std::move(deformed), 0.5);
    w.innerRadius = 0.3;
    return w;
  };
  const auto bump = [](double y) {
    return std::vector<Vec3>{{0.0, 0.0, 0.0}, {1.0, y, 0.0}, {2.0, 0.0, 0.0}};
  };
  const std::vector<Vec3> arch = {
      {0.0, 0.0, 0.0}, {1.0, 0.2, 0.0}, {2.0, 0.2, 0.0}, {3.0, 0.0, 0.0}};
  const auto sShape = [](double e) {
    return std::vector<Vec3>{
        {0.0, 0.0, 0.0}, {1.0, 0.2 + e, 0.0}, {2.0, -0.2, 0.0}, {3.0, 0.0, 0.0}};
  };
  for (WireCurve curve : kCurves) {
    const WiresWarp pairs[2][2] = {{WiresWarp({wire(curve, bump(0.2), bump(1e-4))}),
                                    WiresWarp({wire(curve, bump(0.2), bump(-1e-4))})},
                                   {WiresWarp({wire(curve, arch, sShape(1e-4))}),
                                    WiresWarp({wire(curve, arch, sShape(-1e-4))})}};
    for (const auto& [up, down] : pairs) {
      for (const Vec3& x : {Vec3(1.0, 0.2, 0.1), Vec3(0.2, 0.04, 0.1), Vec3(1.8, 0.1, -0.1)}) {
        EXPECT_LE(glm::length(up.apply(x) - down.apply(x)), 1e-3)
            << wireCurveName(curve) << " " << test::toString(x);
        EXPECT_NE(up.apply(x), x);  // inside the tube
      }
    }
  }
}

TEST(WiresWarp, ScaleMovesPointsAwayFromTheCurveByTheDropOff) {
  // A straight wire along x: the closest point is the foot on the axis, d the distance to it.
  const std::vector<Vec3> rest = {{-1.0, 0.0, 0.0}, {0.0, 0.0, 0.0}, {1.0, 0.0, 0.0}};
  const double r = 0.6, r0 = 0.2, s = 1.7;
  for (WireDropoff dropoff : {WireDropoff::Smooth, WireDropoff::Linear}) {
    Wire w = wireOf(WireCurve::Polyline, rest, rest, r);
    w.scale = s;
    w.innerRadius = r0;
    w.dropoff = dropoff;
    const WiresWarp warp({w});
    for (double d : {0.0, 0.1, 0.2, 0.3, 0.45, 0.59, 0.61}) {
      const Vec3 dir = glm::normalize(Vec3(0.0, 0.6, -0.8));
      const Vec3 x = Vec3(0.3, 0.0, 0.0) + d * dir;
      const double u = std::clamp((d - r0) / (r - r0), 0.0, 1.0);
      const double f = d <= r0                          ? 1.0
                       : d >= r                         ? 0.0
                       : dropoff == WireDropoff::Linear ? 1.0 - u
                                                        : (1 - u * u) * (1 - u * u);
      const Vec3 expected = Vec3(0.3, 0.0, 0.0) + (1.0 + (s - 1.0) * f) * d * dir;
      EXPECT_LE(glm::length(warp.apply(x) - expected), 1e-15) << d;
    }
  }
}

TEST(WiresWarp, SeveralWiresCombineAsInThePaper) {
  std::mt19937 rng(4);
  const std::vector<Vec3> a = bentCurve();
  std::vector<Vec3> b;
  for (const Vec3& x : a) b.push_back(Vec3(x.z + 0.2, x.x, -x.y));  // crosses a
  const Wire wa = wireOf(WireCurve::CatmullRom, a, bent(a), 0.6);
  const Wire wb = wireOf(WireCurve::Polyline, b, moved(b, rotationAbout({1, 1, 0}, 0.3), {}), 0.5);
  const WiresWarp alone[] = {WiresWarp({wa}), WiresWarp({wb})};
  for (double m : {0.0, 1.0, 2.5}) {
    const WiresWarp both({wa, wb}, WiresOptions{m});
    std::size_t overlap = 0;
    for (const Vec3& x : test::randomPoints(rng, 2000, -1.2, 1.2)) {
      const Vec3 da = alone[0].apply(x) - x;
      const Vec3 db = alone[1].apply(x) - x;
      const double la = glm::length(da), lb = glm::length(db);
      const double wa_ = la > 0 ? std::pow(la, m) : 0.0;
      const double wb_ = lb > 0 ? std::pow(lb, m) : 0.0;
      const Vec3 expected = wa_ + wb_ > 0 ? x + (wa_ * da + wb_ * db) / (wa_ + wb_) : x;
      overlap += la > 0 && lb > 0;
      EXPECT_LE(glm::length(both.apply(x) - expected), 1e-14) << "m " << m << test::toString(x);
    }
    EXPECT_GT(overlap, 30u);
  }
}

// Many small wires (the rig's index over their reach boxes picks the few near each point): the
// blend of the wires' moves, each wire's move as it is alone, and bit for bit the same in a batch.
TEST(WiresWarp, ManyScatteredWiresBlendTheWiresNearEachPoint) {
  std::mt19937 rng(11);
  std::vector<Wire> wires;
  for (const Vec3& c : test::randomPoints(rng, 300, -5.0, 5.0)) {
    const Vec3 d = test::randomPoint(rng, -0.6, 0.6);
    wires.push_back(wireOf(WireCurve::Polyline, {c - d, c + d},
                           {c - d, c + d + test::randomPoint(rng, -0.2, 0.2)}, 0.5));
  }
  std::vector<std::unique_ptr<WiresWarp>> alone;
  for (const Wire& w : wires) alone.push_back(std::make_unique<WiresWarp>(std::vector<Wire>{w}));
  const WiresWarp all(wires);
  const std::vector<Vec3> points = test::randomPoints(rng, 3000, -5.5, 5.5);
  std::vector<Vec3> batch(points.size());
  all.applyBatch(points, batch);
  std::size_t overlap = 0;
  for (std::size_t p = 0; p < points.size(); ++p) {
    const Vec3& x = points[p];
    Vec3 sum(0.0);
    double weights = 0.0;
    std::size_t moving = 0;
    for (const auto& w : alone) {
      const Vec3 d = w->apply(x) - x;
      sum += glm::length(d) * d;  // locality 1: weights |Δx_i|
      weights += glm::length(d);
      moving += glm::length(d) > 0.0;
    }
    overlap += moving > 1;
    const Vec3 expected = weights > 0.0 ? x + sum / weights : x;
    const Vec3 y = all.apply(x);
    EXPECT_LE(glm::length(y - expected), 1e-13) << test::toString(x);
    if (moving == 0) {
      EXPECT_TRUE(test::bitEqual(y, x)) << test::toString(x);
    }
    EXPECT_TRUE(test::bitEqual(batch[p], y)) << test::toString(x);
  }
  EXPECT_GT(overlap, 20u);
}

TEST(WiresWarp, JacobianMatchesFiniteDifferencesAwayFromTheMedialAxis) {
  std::mt19937 rng(5);
  const std::vector<Vec3> rest = bentCurve();
  std::vector<Vec3> crossing;
  for (const Vec3& x : rest) crossing.push_back(Vec3(x.z + 0.2, x.x, -x.y));
  // Every ingredient: both curves, both drop-offs, inner radius, scale, and the blend of two.
  Wire a = wireOf(WireCurve::CatmullRom, rest, bent(rest), 0.5);
  Wire b = wireOf(WireCurve::Polyline, rest, bent(rest, 0.7), 0.45);
  b.dropoff = WireDropoff::Linear;
  b.innerRadius = 0.05;
  b.scale = 1.4;
  Wire c = wireOf(WireCurve::Polyline, crossing, moved(crossing, rotationAbout({1, 1, 0}, 0.3), {}),
                  0.6);
  c.scale = 0.8;
  std::vector<Vec3> points;
  for (const Vec3& x : test::randomPoints(rng, 400, -1.0, 1.2))
    if (distanceTo(WireCurve::CatmullRom, rest, x) < 0.2) points.push_back(x);
  ASSERT_GT(points.size(), 10u);
  for (const auto& [wires, m] :
       {std::pair{std::vector<Wire>{a}, 1.0}, std::pair{std::vector<Wire>{b}, 1.0},
        std::pair{std::vector<Wire>{a, c}, 2.0}, std::pair{std::vector<Wire>{b, c}, 0.0}}) {
    const WiresWarp warp(wires, WiresOptions{m});
    std::size_t checked = 0;
    for (const Vec3& x : points) {
      // Away from the polyline's vertex bisectors and the drop-off's edges, where it has kinks.
      const Mat3 reference = test::finiteDifferenceJacobian(warp, x, 1e-5);
      const Mat3 coarser = test::finiteDifferenceJacobian(warp, x, 2e-5);
      if (test::relativeError(reference, coarser) > 1e-8) continue;
      ++checked;
      EXPECT_LE(test::relativeError(warp.jacobian(x), reference), 1e-7)
          << wires.size() << " wires, m " << m << " at " << test::toString(x) << "\n"
          << test::toString(warp.jacobian(x)) << "\n"
          << test::toString(reference);
    }
    EXPECT_GT(checked, points.size() / 2);
  }
  // A gentler bend does not fold space: inverse() recovers the points, normals stay normal.
  const WiresWarp gentle({wireOf(WireCurve::CatmullRom, rest, bent(rest, 0.3), 0.5)});
  EXPECT_TRUE(test::jacobianMatchesFiniteDifferences(gentle, points, 1e-6));
  EXPECT_TRUE(test::inverseRecovers(gentle, points));
  EXPECT_TRUE(test::normalsStayPerpendicular(gentle, points, rng, 1e-9));
}

TEST(WiresWarp, BatchIsDeterministicAndEqualsApply) {
  std::mt19937 rng(6);
  const std::vector<Vec3> a = bentCurve();
  std::vector<Vec3> b;
  for (const Vec3& x : a) b.push_back(x + Vec3(0.0, 0.3, 0.1));
  const WiresWarp warp({wireOf(WireCurve::CatmullRom, a, bent(a), 0.4),
                        wireOf(WireCurve::Polyline, b, bent(b), 0.3)},
                       WiresOptions{2.0});
  EXPECT_TRUE(test::batchIsDeterministic(warp, test::randomPoints(rng, 20000, -1.5, 1.5)));
  test::expectBatchRejectsMismatchedSizes(warp, 3, 4);
}

std::string errorOf(std::vector<Wire> wires, WiresOptions options = {}) {
  return test::messageOf<InvalidInput>([&] { WiresWarp(std::move(wires), options); });
}

TEST(WiresWarp, RejectsBadParameters) {
  const std::vector<Vec3> p = bentCurve();
  const Wire good = wireOf(WireCurve::Polyline, p, p, 0.5);
  EXPECT_THAT(errorOf({}), HasSubstr("WiresWarp: no wires"));
  Wire w = good;
  w.deformed.pop_back();
  EXPECT_THAT(errorOf({good, w}), HasSubstr("wire 1: 5 rest points but 4 deformed points"));
  w = wireOf(WireCurve::Polyline, {p[0]}, {p[0]}, 0.5);
  EXPECT_THAT(errorOf({w}), HasSubstr("wire 0: rest needs at least 2 points, got 1"));
  w = good;
  w.rest[2] = w.rest[1];
  EXPECT_THAT(errorOf({w}), HasSubstr("wire 0: rest[2] repeats rest[1]"));
  w = good;
  w.deformed[3] = w.deformed[2] + Vec3(1e-15, 0, 0);
  EXPECT_THAT(errorOf({w}), HasSubstr("wire 0: deformed[3] repeats deformed[2]"));
  w = good;
  w.rest[4].y = std::nan("");
  EXPECT_THAT(errorOf({w}), HasSubstr("wire 0: rest[4] is not finite"));
  for (double r : {0.0, -1.0, std::nan(""), std::numeric_limits<double>::infinity()}) {
    w = good;
    w.radius = r;
    EXPECT_THAT(errorOf({good, w}), HasSubstr("wire 1: radius must be finite and > 0")) << r;
  }
  for (double r0 : {-0.1, 0.5, 0.7, std::nan("")}) {
    w = good;
    w.innerRadius = r0;
    EXPECT_THAT(errorOf({w}), HasSubstr("wire 0: innerRadius must be in [0, radius)")) << r0;
  }
  for (double s : {0.0, -2.0, std::nan("")}) {
    w = good;
    w.scale = s;
    EXPECT_THAT(errorOf({w}), HasSubstr("wire 0: scale must be finite and > 0")) << s;
  }
  for (double m : {-1.0, std::nan(""), std::numeric_limits<double>::infinity()})
    EXPECT_THAT(errorOf({good}, WiresOptions{m}), HasSubstr("locality must be finite and >= 0"));
  EXPECT_EQ(errorOf({good}), "");
  // Coordinates whose squared differences overflow, and a radius that takes the grid past doubles.
  w = wireOf(WireCurve::Polyline, {{-1e308, 0, 0}, {1e308, 0, 0}}, {{0, 0, 0}, {1, 0, 0}}, 1.0);
  EXPECT_THAT(errorOf({w}), HasSubstr("wire 0: rest spans too far for double precision"));
  w = wireOf(WireCurve::Polyline, {{0, 0, 0}, {1, 0, 0}}, {{0, 0, 0}, {1, 0, 0}}, 1.7e308);
  EXPECT_THAT(errorOf({w}), HasSubstr("wire 0: radius reaches beyond the range of doubles"));
}

// 2000 segments each crossing the whole box, radius 1e-7: every segment's box covers the whole
// grid, so r / 8 cells (capped at 2^20) would take 2e9 steps to list; the grid coarsens so that
// the build stays bounded, and the warp still works.
TEST(WiresWarp, ManyLongSegmentsWithATinyRadiusBuildQuickly) {
  std::vector<Vec3> rest, deformed;
  for (int k = 0; k < 2000; ++k) {
    rest.push_back(double(k % 2) * Vec3(1.0, 1.0, 1.0) + Vec3(1e-3 * k, 0.0, 0.0));
    deformed.push_back(rest.back() + Vec3(0.0, 0.0, 1e-8));
  }
  const WiresWarp warp({wireOf(WireCurve::Polyline, rest, deformed, 1e-7)});
  const Vec3 onWire = 0.5 * (rest[10] + rest[11]);
  EXPECT_LE(glm::length(warp.apply(onWire) - (onWire + Vec3(0.0, 0.0, 1e-8))), 1e-15);
  const Vec3 off(0.5, 0.2, 0.9);
  EXPECT_TRUE(test::bitEqual(warp.apply(off), off));
}

// A densely sampled wire (100,000 points, the gentle curve of a finely tessellated model) builds
// and answers: its points go onto the deformed wire, points beyond the radius stay, and a batch
// is apply() bit for bit. (The nearest chord itself is checked against brute force in
// chord_tree_test.cpp.)
TEST(WiresWarp, DenseWireOf100000PointsBuildsAndAnswers) {
  const std::size_t n = 100000;
  std::vector<Vec3> rest(n), deformed(n);
  for (std::size_t k = 0; k < n; ++k) {
    const double s = static_cast<double>(k) / static_cast<double>(n - 1);
    rest[k] = Vec3(s, 0.05 * std::sin(3.0 * s), 0.0);
    deformed[k] = rest[k] + Vec3(0.0, 0.2 * s * s, 0.0);
  }
  const WiresWarp warp({wireOf(WireCurve::Polyline, rest, deformed, 0.3)});
  for (std::size_t k = 0; k + 1 < n; k += 9973) {
    EXPECT_LE(glm::length(warp.apply(rest[k]) - deformed[k]), 1e-12) << k;
    const Vec3 mid = 0.5 * (rest[k] + rest[k + 1]);
    EXPECT_LE(glm::length(warp.apply(mid) - 0.5 * (deformed[k] + deformed[k + 1])), 1e-12) << k;
  }
  std::mt19937 rng(5);
  const std::vector<Vec3> points = test::randomPoints(rng, 400, -0.4, 1.4);
  std::vector<Vec3> batch(points.size());
  warp.applyBatch(points, batch);
  std::size_t moved = 0;
  for (std::size_t i = 0; i < points.size(); ++i) {
    const Vec3 y = warp.apply(points[i]);
    EXPECT_TRUE(test::bitEqual(batch[i], y)) << test::toString(points[i]);
    // The curve lies in the plane z = 0 within y ∈ [0, 0.05]: farther than 0.3 from that strip
    // (in z or beyond its x range) is beyond the radius.
    const Vec3& x = points[i];
    if (std::abs(x.z) >= 0.3 || x.x <= -0.3 || x.x >= 1.3)
      EXPECT_TRUE(test::bitEqual(y, x)) << test::toString(x);
    else if (!(y == x))
      ++moved;
  }
  EXPECT_GT(moved, 20u);
}

// A Catmull-Rom hairpin (p[k+1] == p[k−1]) has a zero tangent at p[k]: it used to give NaN
// positions and Jacobians silently; now refused naming the wire and the points. A polyline takes
// the same points (its tangent there is the outgoing segment's).
TEST(WiresWarp, RefusesCatmullRomHairpins) {
  const std::vector<Vec3> line{{0, 0, 0}, {1, 0, 0}, {2, 0, 0}};
  const std::vector<Vec3> hairpin{{0, 0, 0}, {1, 0, 0}, {0, 0, 0}};
  const std::string inDeformed = test::messageOf<InvalidInput>(
      [&] { WiresWarp({wireOf(WireCurve::CatmullRom, line, hairpin, 0.5)}); });
  EXPECT_THAT(inDeformed, HasSubstr("wire 0: deformed[2] repeats deformed[0]"));
  EXPECT_THAT(inDeformed, HasSubstr("hairpin"));
  EXPECT_THAT(test::messageOf<InvalidInput>(
                  [&] { WiresWarp({wireOf(WireCurve::CatmullRom, hairpin, line, 0.5)}); }),
              HasSubstr("wire 0: rest[2] repeats rest[0]"));
  const WiresWarp polyline({wireOf(WireCurve::Polyline, line, hairpin, 0.5)});
  for (double x = -0.5; x <= 2.5; x += 0.125)
    EXPECT_TRUE(isFinite(polyline.apply(Vec3(x, 0.1, 0.05)))) << x;
}

// A wire of more chords than the grid could list used to build forever (the cell doubled to
// infinity); the chord tree has no such limit, but memory grows with the chords: refused before
// anything is built.
TEST(WiresWarp, RefusesWiresOfTooManyChordsUpFront) {
  const std::size_t n = (std::size_t{1} << 20) + 2;  // 16 chords per Catmull-Rom span: > 2^24
  std::vector<Vec3> rest(n), deformed(n);
  for (std::size_t k = 0; k < n; ++k) {
    rest[k] = Vec3(static_cast<double>(k), static_cast<double>(k % 3), 0.0);
    deformed[k] = rest[k] + Vec3(0.0, 0.0, 1.0);
  }
  EXPECT_THAT(
      test::messageOf<InvalidInput>([&] {
        WiresWarp({wireOf(WireCurve::Polyline, {{0, 0, 0}, {1, 0, 0}}, {{0, 0, 0}, {1, 0, 0}}, 1.0),
                   wireOf(WireCurve::CatmullRom, rest, deformed, 0.5)});
      }),
      HasSubstr("wire 1: 1048578 points make 16777232 chords"));
}

}  // namespace
}  // namespace spacewarp
