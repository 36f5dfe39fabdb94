#include "core/twist.h"

#include <cmath>
#include <limits>
#include <numbers>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "core/errors.h"
#include "test_util.h"

namespace spacewarp {
namespace {

using test::randomPoints;
using test::relativeError;

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kPi = std::numbers::pi;

TwistParams twistParams(Vec3 origin, Vec3 axis, double rate, double lo = -kInf, double hi = kInf) {
  TwistParams p;
  p.origin = origin;
  p.axis = axis;
  p.rate = rate;
  p.lo = lo;
  p.hi = hi;
  return p;
}

// A spread of configurations: axis-aligned and oblique axes, offset origins, both signs of the
// rate, with and without limits (one-sided and two-sided).
std::vector<TwistParams> configurations() {
  return {
      twistParams(Vec3(0.0), Vec3(0, 0, 1), 1.0),
      twistParams(Vec3(0.5, -1.0, 2.0), Vec3(1, 2, 3), -0.7),
      twistParams(Vec3(-1.0, 0.3, 0.0), Vec3(0, -5, 0), 2.5),
      twistParams(Vec3(0.2, 0.1, -0.3), Vec3(1e-30, 1e-30, 3e-30), 0.3),
      twistParams(Vec3(1.0, 1.0, 1.0), Vec3(-1, 1, 0.2), 1.3, -0.5, 0.8),
      twistParams(Vec3(0.0), Vec3(0, 0, 1), -2.0, 0.0, kInf),
      twistParams(Vec3(0.0, 0.0, 1.0), Vec3(1, 0, 0), 0.9, -kInf, 0.25),
  };
}

// Random points in [-2, 2]^3 at least `margin` away (along the axis) from the limits, where the
// warp is not differentiable.
std::vector<Vec3> pointsAwayFromLimits(const TwistWarp& warp, std::mt19937& rng, std::size_t n,
                                       double margin = 0.02) {
  const TwistParams& p = warp.params();
  return test::randomPointsWhere(rng, n, -2.0, 2.0, [&](const Vec3& x) {
    const double s = glm::dot(x - p.origin, warp.axis());
    return std::abs(s - p.lo) > margin && std::abs(s - p.hi) > margin;
  });
}

TEST(TwistWarp, RejectsInvalidParameters) {
  EXPECT_THROW(TwistWarp(twistParams(Vec3(0.0), Vec3(0.0), 1.0)), InvalidInput);
  EXPECT_THROW(TwistWarp(twistParams(Vec3(0.0), Vec3(0, kNaN, 1), 1.0)), InvalidInput);
  EXPECT_THROW(TwistWarp(twistParams(Vec3(0.0), Vec3(0, kInf, 1), 1.0)), InvalidInput);
  EXPECT_THROW(TwistWarp(twistParams(Vec3(kInf, 0, 0), Vec3(0, 0, 1), 1.0)), InvalidInput);
  EXPECT_THROW(TwistWarp(twistParams(Vec3(0.0), Vec3(0, 0, 1), kNaN)), InvalidInput);
  EXPECT_THROW(TwistWarp(twistParams(Vec3(0.0), Vec3(0, 0, 1), kInf)), InvalidInput);
  EXPECT_THROW(TwistWarp(twistParams(Vec3(0.0), Vec3(0, 0, 1), 1.0, 1.0, -1.0)), InvalidInput);
  EXPECT_THROW(TwistWarp(twistParams(Vec3(0.0), Vec3(0, 0, 1), 1.0, kNaN, 1.0)), InvalidInput);
  EXPECT_THROW(TwistWarp(twistParams(Vec3(0.0), Vec3(0, 0, 1), 1.0, kInf, kInf)), InvalidInput);
  EXPECT_THROW(TwistWarp(twistParams(Vec3(0.0), Vec3(0, 0, 1), 1.0, -kInf, -kInf)), InvalidInput);
  try {
    TwistWarp(twistParams(Vec3(0.0), Vec3(0.0), 1.0));
  } catch (const InvalidInput& e) {
    EXPECT_NE(std::string(e.what()).find("axis"), std::string::npos) << e.what();
  }
  // Equal limits are valid: the whole of space turns rigidly by rate * lo.
  EXPECT_NO_THROW(TwistWarp(twistParams(Vec3(0.0), Vec3(0, 0, 1), 1.0, 0.5, 0.5)));
}

TEST(TwistWarp, NormalisesTheAxis) {
  const TwistWarp warp(twistParams(Vec3(0.0), Vec3(0, 0, 1e-300), 1.0));
  EXPECT_EQ(warp.axis(), Vec3(0, 0, 1));
  const TwistWarp huge(twistParams(Vec3(0.0), Vec3(3e300, 4e300, 0), 1.0));
  EXPECT_NEAR(huge.axis().x, 0.6, 1e-15);
  EXPECT_NEAR(huge.axis().y, 0.8, 1e-15);
}

TEST(TwistWarp, JacobianMatchesFiniteDifferences) {
  std::mt19937 rng(101);
  for (const TwistParams& params : configurations()) {
    const TwistWarp warp(params);
    EXPECT_TRUE(test::jacobianMatchesFiniteDifferences(warp, pointsAwayFromLimits(warp, rng, 200)))
        << "rate " << params.rate << " limits [" << params.lo << ", " << params.hi << "]";
  }
}

TEST(TwistWarp, QuarterTurnAtUnitDistanceMatchesHandComputedRotation) {
  // About +z through the origin: a quarter turn at s = 1 takes +x to +y.
  const TwistWarp aboutZ(twistParams(Vec3(0.0), Vec3(0, 0, 1), kPi / 2));
  EXPECT_LT(relativeError(aboutZ.apply(Vec3(1, 0, 1)), Vec3(0, 1, 1)), 1e-15);
  EXPECT_LT(relativeError(aboutZ.apply(Vec3(2, 3, 1)), Vec3(-3, 2, 1)), 1e-15);
  // At s = -1 the turn is the other way; at s = 2 it is a half turn.
  EXPECT_LT(relativeError(aboutZ.apply(Vec3(2, 3, -1)), Vec3(3, -2, -1)), 1e-15);
  EXPECT_LT(relativeError(aboutZ.apply(Vec3(2, 3, 2)), Vec3(-2, -3, 2)), 1e-15);
  // About -x through (5, 1, 1), given with length 2: the point (4, 2, 1) has s = 1 and offset
  // p = (0, 1, 0) from the axis; a right-handed quarter turn about -x takes +y to -z, so it lands
  // at (5, 1, 1) + (-1, 0, 0) + (0, 0, -1) = (4, 1, 0).
  const TwistWarp aboutMinusX(twistParams(Vec3(5, 1, 1), Vec3(-2, 0, 0), kPi / 2));
  EXPECT_LT(relativeError(aboutMinusX.apply(Vec3(4, 2, 1)), Vec3(4, 1, 0)), 1e-15);
  // Points on the axis do not move.
  EXPECT_LT(relativeError(aboutMinusX.apply(Vec3(3, 1, 1)), Vec3(3, 1, 1)), 1e-15);
}

TEST(TwistWarp, RateZeroIsExactlyTheIdentity) {
  std::mt19937 rng(102);
  const TwistWarp plain(twistParams(Vec3(0.3, -0.2, 7.0), Vec3(1, 2, 3), 0.0));
  const TwistWarp limited(twistParams(Vec3(0.3, -0.2, 7.0), Vec3(1, 2, 3), 0.0, -1.0, 0.5));
  for (const Vec3& x : randomPoints(rng, 1000, -100.0, 100.0)) {
    EXPECT_EQ(plain.apply(x), x);
    EXPECT_EQ(limited.apply(x), x);
  }
  EXPECT_EQ(plain.jacobian(Vec3(1, 2, 3)), Mat3(1.0));
}

TEST(TwistWarp, LimitsAreContinuousAndRigidBeyond) {
  const Vec3 origin(0.5, -0.5, 0.25);
  const Vec3 axis = glm::normalize(Vec3(1, -1, 2));
  const double lo = -0.5, hi = 1.0, rate = 1.7;
  const TwistWarp warp(twistParams(origin, Vec3(1, -1, 2), rate, lo, hi));
  const TwistWarp fullTwist(twistParams(origin, Vec3(1, -1, 2), rate));
  std::mt19937 rng(103);
  for (int i = 0; i < 200; ++i) {
    const Vec3 offset = test::randomPoint(rng, -2.0, 2.0);
    const Vec3 p = offset - glm::dot(offset, axis) * axis;  // perpendicular to the axis
    for (double limit : {lo, hi}) {
      const double delta = 1e-10;
      const Vec3 inside = warp.apply(origin + (limit + (limit == lo ? delta : -delta)) * axis + p);
      const Vec3 outside = warp.apply(origin + (limit + (limit == lo ? -delta : delta)) * axis + p);
      EXPECT_LT(relativeError(inside, outside), 1e-9);
    }
    // Between the limits the limited twist is the plain twist.
    const Vec3 mid = origin + 0.3 * axis + p;
    EXPECT_LT(relativeError(warp.apply(mid), fullTwist.apply(mid)), 1e-14);
  }
  // Beyond hi every point turns by rate * hi: the map there is one rigid motion, that of the
  // plane s = hi, so distances are kept and it agrees with the full twist evaluated at s = hi.
  const std::vector<Vec3> beyond = test::randomPointsWhere(
      rng, 200, -3.0, 3.0, [&](const Vec3& x) { return glm::dot(x - origin, axis) > hi + 0.01; });
  for (std::size_t i = 1; i < beyond.size(); ++i) {
    const double before = glm::length(beyond[i] - beyond[i - 1]);
    const double after = glm::length(warp.apply(beyond[i]) - warp.apply(beyond[i - 1]));
    EXPECT_NEAR(after, before, 1e-12 * before);
    const double s = glm::dot(beyond[i] - origin, axis);
    const Vec3 atHi = beyond[i] - (s - hi) * axis;  // its foot on the plane s = hi
    EXPECT_LT(relativeError(warp.apply(beyond[i]), fullTwist.apply(atHi) + (s - hi) * axis), 1e-13);
    const Mat3 j = warp.jacobian(beyond[i]);
    EXPECT_LT(relativeError(glm::transpose(j) * j, Mat3(1.0)), 1e-14);
    EXPECT_NEAR(glm::determinant(j), 1.0, 1e-14);
  }
}

TEST(TwistWarp, InverseRecoversPoints) {
  std::mt19937 rng(104);
  for (const TwistParams& params : configurations()) {
    const TwistWarp warp(params);
    EXPECT_TRUE(test::inverseRecovers(warp, randomPoints(rng, 200, -2.0, 2.0)))
        << "rate " << params.rate << " limits [" << params.lo << ", " << params.hi << "]";
  }
}

TEST(TwistWarp, InverseWithoutIterationsReportsNoConvergence) {
  const TwistWarp warp(twistParams(Vec3(0.0), Vec3(0, 0, 1), 1.0));
  InverseOptions options;
  options.maxIterations = 0;
  InverseResult r;
  ASSERT_NO_THROW(r = inverse(warp, warp.apply(Vec3(1.0, 0.5, 1.5)), options));
  EXPECT_FALSE(r.converged);
  EXPECT_EQ(r.iterations, 0);
  EXPECT_GT(r.residual, 0.0);
}

TEST(TwistWarp, NormalsStayPerpendicularToTangents) {
  std::mt19937 rng(105);
  for (const TwistParams& params : configurations()) {
    const TwistWarp warp(params);
    EXPECT_TRUE(test::normalsStayPerpendicular(warp, randomPoints(rng, 200, -2.0, 2.0), rng));
  }
}

TEST(TwistWarp, BatchIsBitIdenticalToApplyForAnyThreadCount) {
  std::mt19937 rng(106);
  const std::vector<Vec3> points = randomPoints(rng, 100'000, -3.0, 3.0);
  for (const TwistParams& params : configurations())
    EXPECT_TRUE(test::batchIsDeterministic(TwistWarp(params), points));
}

TEST(TwistWarp, BatchInPlaceMatchesApply) {
  std::mt19937 rng(107);
  const TwistWarp warp(configurations()[1]);
  const std::vector<Vec3> points = randomPoints(rng, 10'000, -3.0, 3.0);
  std::vector<Vec3> inPlace = points;
  warp.applyBatch(inPlace, inPlace);
  for (std::size_t i = 0; i < points.size(); ++i)
    EXPECT_TRUE(test::bitEqual(inPlace[i], warp.apply(points[i])));
}

TEST(TwistWarp, BatchRejectsMismatchedSizes) {
  const TwistWarp warp(configurations()[0]);
  std::vector<Vec3> in(10), out(9);
  EXPECT_THROW(warp.applyBatch(in, out), InvalidInput);
}

}  // namespace
}  // namespace spacewarp
