#include <spacewarp/core/twist.h>

#include <cmath>
#include <limits>
#include <numbers>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include <spacewarp/core/errors.h>
#include <spacewarp/core/inverse.h>
#include "test_util.h"

namespace spacewarp {
namespace {

using test::randomPoints;
using test::relativeError;

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kPi = std::numbers::pi;

constexpr test::AxialOptions<TwistOptions> twistParams{};

// A spread of configurations: axis-aligned and oblique axes, offset origins, both signs of the
// rate, with and without limits (one-sided and two-sided).
std::vector<TwistOptions> configurations() {
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

// n random points in [-2, 2]^3 more than 0.02 away (along the axis) from the limits, where the
// warp is not differentiable.
std::vector<Vec3> pointsAwayFromLimits(const TwistWarp& warp, std::mt19937& rng, std::size_t n) {
  const TwistOptions& p = warp.params();
  return test::randomPointsWhere(rng, n, -2.0, 2.0, [&](const Vec3& x) {
    const double s = glm::dot(x - p.origin, warp.axis());
    return std::abs(s - p.lo) > 0.02 && std::abs(s - p.hi) > 0.02;
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
  const std::string message =
      test::messageOf<InvalidInput>([] { TwistWarp(twistParams(Vec3(0.0), Vec3(0.0), 1.0)); });
  EXPECT_NE(message.find("axis"), std::string::npos) << message;
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
  test::expectJacobiansMatchFiniteDifferences<TwistWarp>(configurations(), rng,
                                                         pointsAwayFromLimits);
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
  const std::vector<Vec3> points = randomPoints(rng, 1000, -100.0, 100.0);
  EXPECT_TRUE(test::leavesPointsUnchanged(plain, points));
  EXPECT_TRUE(test::leavesPointsUnchanged(limited, points));
  EXPECT_EQ(plain.jacobian(Vec3(1, 2, 3)), Mat3(1.0));
}

TEST(TwistWarp, LimitsAreContinuousAndRigidBeyond) {
  const Vec3 origin(0.5, -0.5, 0.25);
  const Vec3 axis = glm::normalize(Vec3(1, -1, 2));
  const double lo = -0.5, hi = 1.0, rate = 1.7;
  const TwistWarp warp(twistParams(origin, Vec3(1, -1, 2), rate, lo, hi));
  const TwistWarp fullTwist(twistParams(origin, Vec3(1, -1, 2), rate));
  std::mt19937 rng(103);
  const std::vector<Vec3> offsets = test::perpendicularOffsets(rng, 200, axis);
  for (double limit : {lo, hi})
    EXPECT_TRUE(test::continuousAcross(warp, origin, axis, limit, offsets));
  // Between the limits the limited twist is the plain twist.
  for (const Vec3& p : offsets) {
    const Vec3 mid = origin + 0.3 * axis + p;
    EXPECT_LT(relativeError(warp.apply(mid), fullTwist.apply(mid)), 1e-14);
  }
  // Beyond hi every point turns by rate * hi: the map there is one rigid motion, that of the
  // plane s = hi, so distances are kept and it agrees with the full twist evaluated at s = hi.
  const std::vector<Vec3> beyond = test::randomPointsWhere(
      rng, 200, -3.0, 3.0, [&](const Vec3& x) { return glm::dot(x - origin, axis) > hi + 0.01; });
  EXPECT_TRUE(test::movesRigidly(warp, beyond));
  for (const Vec3& x : beyond) {
    const double s = glm::dot(x - origin, axis);
    const Vec3 atHi = x - (s - hi) * axis;  // its foot on the plane s = hi
    EXPECT_LT(relativeError(warp.apply(x), fullTwist.apply(atHi) + (s - hi) * axis), 1e-13);
  }
}

TEST(TwistWarp, InverseRecoversPoints) {
  std::mt19937 rng(104);
  test::expectInversesRecover<TwistWarp>(configurations(), rng,
                                         test::uniformPoints<TwistWarp>(-2.0, 2.0));
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
  test::expectNormalsStayPerpendicular<TwistWarp>(configurations(), rng,
                                                  test::uniformPoints<TwistWarp>(-2.0, 2.0));
}

TEST(TwistWarp, BatchIsBitIdenticalToApplyForAnyThreadCount) {
  std::mt19937 rng(106);
  test::expectBatchesDeterministic<TwistWarp>(configurations(),
                                              randomPoints(rng, 100'000, -3.0, 3.0));
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
  test::expectBatchRejectsMismatchedSizes(TwistWarp(configurations()[0]), 10, 9);
}

}  // namespace
}  // namespace spacewarp
