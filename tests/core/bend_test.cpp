#include <spacewarp/core/bend.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include <spacewarp/core/errors.h>
#include "test_util.h"

namespace spacewarp {
namespace {

using test::randomPoints;
using test::relativeError;

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kPi = std::numbers::pi;

BendOptions bendParams(Vec3 origin, Vec3 axis, Vec3 direction, double rate, double lo = -kInf,
                       double hi = kInf) {
  BendOptions p = test::AxialOptions<BendOptions>{}(origin, axis, rate, lo, hi);
  p.direction = direction;
  return p;
}

std::vector<BendOptions> configurations() {
  return {
      bendParams(Vec3(0.0), Vec3(0, 0, 1), Vec3(1, 0, 0), 0.5),
      bendParams(Vec3(0.5, -1.0, 2.0), Vec3(1, 2, 3), Vec3(0, 1, 0), -0.4),
      bendParams(Vec3(-1.0, 0.3, 0.0), Vec3(0, -5, 0), Vec3(1, 1, 1), 0.25),
      bendParams(Vec3(0.2, 0.1, -0.3), Vec3(1, 0, 0), Vec3(0.3, 0, -2), 1e-7),
      bendParams(Vec3(1.0, 1.0, 1.0), Vec3(-1, 1, 0.2), Vec3(0, 0, 1), 0.3, -0.5, 0.8),
      bendParams(Vec3(0.0), Vec3(0, 0, 1), Vec3(0, 1, 0), -0.35, 0.0, kInf),
      bendParams(Vec3(0.0, 0.0, 1.0), Vec3(1, 0, 0), Vec3(0, 1, 1), 0.2, -kInf, 0.25),
  };
}

// The local coordinates (y along the spine, z along the direction) of x.
double spineCoordinate(const BendWarp& warp, const Vec3& x) {
  return glm::dot(x - warp.params().origin, warp.axis());
}
double directionCoordinate(const BendWarp& warp, const Vec3& x) {
  return glm::dot(x - warp.params().origin, warp.direction());
}

// Samples random points in [lo, hi)^3 away from the limits (where the bend is not
// differentiable) and, if `invertible`, with 0.25 <= 1 - k z <= 1.75 (locally invertible and well
// conditioned) and a bend angle |k ŷ| <= 1 rad: the range in which inverse()'s Newton iteration,
// seeded by the reflected displacement, reliably lands on this preimage rather than on another
// sheet of the (periodic, folded) unlimited bend.
test::PointSampler<BendWarp> pointsIn(double lo, double hi, bool invertible = false) {
  return [=](const BendWarp& warp, std::mt19937& rng, std::size_t n) {
    const BendOptions& p = warp.params();
    return test::randomPointsWhere(rng, n, lo, hi, [&](const Vec3& x) {
      const double y = spineCoordinate(warp, x);
      const double z = directionCoordinate(warp, x);
      return std::abs(y - p.lo) > 0.02 && std::abs(y - p.hi) > 0.02 &&
             (!invertible || (std::abs(p.rate * z) <= 0.75 &&
                              std::abs(p.rate * std::clamp(y, p.lo, p.hi)) <= 1.0));
    });
  };
}

TEST(BendWarp, RejectsInvalidParameters) {
  const Vec3 z(0, 0, 1), x(1, 0, 0);
  EXPECT_THROW(BendWarp(bendParams(Vec3(0.0), Vec3(0.0), x, 1.0)), InvalidInput);
  EXPECT_THROW(BendWarp(bendParams(Vec3(0.0), Vec3(kNaN, 0, 1), x, 1.0)), InvalidInput);
  EXPECT_THROW(BendWarp(bendParams(Vec3(0.0), z, Vec3(0.0), 1.0)), InvalidInput);
  EXPECT_THROW(BendWarp(bendParams(Vec3(0.0), z, Vec3(kInf, 0, 0), 1.0)), InvalidInput);
  EXPECT_THROW(BendWarp(bendParams(Vec3(0.0), z, Vec3(0, 0, -3), 1.0)), InvalidInput);
  EXPECT_THROW(BendWarp(bendParams(Vec3(0.0), z, Vec3(1e-9, 0, 1), 1.0)), InvalidInput);
  EXPECT_THROW(BendWarp(bendParams(Vec3(0, kNaN, 0), z, x, 1.0)), InvalidInput);
  EXPECT_THROW(BendWarp(bendParams(Vec3(0.0), z, x, kNaN)), InvalidInput);
  EXPECT_THROW(BendWarp(bendParams(Vec3(0.0), z, x, 1.0, 2.0, 1.0)), InvalidInput);
  EXPECT_THROW(BendWarp(bendParams(Vec3(0.0), z, x, 1.0, 0.0, kNaN)), InvalidInput);
  const std::string message = test::messageOf<InvalidInput>(
      [&] { BendWarp(bendParams(Vec3(0.0), z, Vec3(0, 0, 2), 1.0)); });
  EXPECT_NE(message.find("parallel"), std::string::npos) << message;
}

TEST(BendWarp, OrthogonalisesTheDirection) {
  const BendWarp warp(bendParams(Vec3(0.0), Vec3(0, 0, 2), Vec3(3, 0, 5), 1.0));
  EXPECT_EQ(warp.axis(), Vec3(0, 0, 1));
  EXPECT_LT(relativeError(warp.direction(), Vec3(1, 0, 0)), 1e-16);
}

TEST(BendWarp, JacobianMatchesFiniteDifferences) {
  std::mt19937 rng(201);
  test::expectJacobiansMatchFiniteDifferences<BendWarp>(configurations(), rng, pointsIn(-3.0, 3.0));
}

TEST(BendWarp, JacobianDeterminantIsTheRadialStretch) {
  std::mt19937 rng(202);
  const BendWarp warp(configurations()[1]);
  for (const Vec3& x : randomPoints(rng, 200, -3.0, 3.0)) {
    const double expected = 1.0 - warp.params().rate * directionCoordinate(warp, x);
    EXPECT_NEAR(glm::determinant(warp.jacobian(x)), expected, 1e-14);
  }
}

TEST(BendWarp, SpineLandsOnTheCircleOfRadiusOneOverK) {
  const Vec3 origin(1, 2, 3);
  const Vec3 axis = glm::normalize(Vec3(1, 1, 0));
  const Vec3 direction = glm::normalize(Vec3(1, -1, 1));  // ⊥ axis
  const double k = 0.5;
  const BendWarp warp(bendParams(origin, Vec3(1, 1, 0), Vec3(1, -1, 1), k));
  // Arc length pi along the spine is a quarter turn: it lands at origin + (a + d) / k.
  EXPECT_LT(relativeError(warp.apply(origin + kPi * axis), origin + 2.0 * axis + 2.0 * direction),
            1e-15);
  // Arc length 2 pi is half the circle: the point diametrically opposite the origin.
  EXPECT_LT(relativeError(warp.apply(origin + 2.0 * kPi * axis), origin + 4.0 * direction), 1e-15);
  const Vec3 center = origin + direction / k;
  for (double y = -6.0; y <= 6.0; y += 0.25) {
    const Vec3 bent = warp.apply(origin + y * axis);
    EXPECT_NEAR(glm::length(bent - center), 1.0 / k, 1e-14);
    // At angle k y from the origin, seen from the center.
    const Vec3 expected = center + std::sin(k * y) / k * axis - std::cos(k * y) / k * direction;
    EXPECT_LT(relativeError(bent, expected), 1e-14);
    // Fibres along the direction stay straight and radial: z lands on radius 1/k - z.
    const Vec3 off = warp.apply(origin + y * axis + 0.7 * direction);
    EXPECT_NEAR(glm::length(off - center), 1.0 / k - 0.7, 1e-14);
    // The third axis b = a × d is kept.
    const Vec3 b = glm::cross(axis, direction);
    const Vec3 side = warp.apply(origin + y * axis + 0.4 * b);
    EXPECT_NEAR(glm::dot(side - origin, b), 0.4, 1e-14);
    EXPECT_LT(relativeError(side - 0.4 * b, bent), 1e-14);
  }
}

// Barr's formula for the spine point (0, 0, y) in the frame axis = +z, direction = +x,
// evaluated in long double without cancellation: Y = sin(k y) / k, Z = 2 sin²(k y / 2) / k.
TEST(BendWarp, TinyRatesAreAccurate) {
  for (double k : {1e-300, 1e-30, 1e-14, 1e-9, 1e-6, 1e-4, 1e-3, 0.1, 1.0, -1e-12, -0.3}) {
    const BendWarp warp(bendParams(Vec3(0.0), Vec3(0, 0, 1), Vec3(1, 0, 0), k));
    for (double y : {-2.0, -0.3, 0.5, 1.0, 3.0}) {
      const Vec3 bent = warp.apply(Vec3(0, 0, y));
      const long double kl = k, yl = y;
      const long double half = std::sin(0.5L * kl * yl);
      const double expectedZ = static_cast<double>(2.0L * half * half / kl);
      const double expectedY = static_cast<double>(std::sin(kl * yl) / kl);
      // The displacement towards the center, (1 - C) / k ~ k y^2 / 2, is resolved to full
      // relative precision even where it is far below the point's own magnitude.
      EXPECT_NEAR(bent.x, expectedZ, 1e-14 * std::abs(expectedZ)) << "k " << k << " y " << y;
      EXPECT_NEAR(bent.z, expectedY, 1e-15 * std::max(1.0, std::abs(y))) << "k " << k << " y " << y;
      EXPECT_EQ(bent.y, 0.0);
    }
  }
}

TEST(BendWarp, RateZeroIsExactlyTheIdentity) {
  std::mt19937 rng(203);
  const BendWarp plain(bendParams(Vec3(0.3, -0.2, 7.0), Vec3(1, 2, 3), Vec3(0, 0, 1), 0.0));
  const BendWarp limited(
      bendParams(Vec3(0.3, -0.2, 7.0), Vec3(1, 2, 3), Vec3(0, 0, 1), 0.0, -1.0, 0.5));
  const std::vector<Vec3> points = randomPoints(rng, 1000, -100.0, 100.0);
  EXPECT_TRUE(test::leavesPointsUnchanged(plain, points));
  EXPECT_TRUE(test::leavesPointsUnchanged(limited, points));
  EXPECT_LT(relativeError(plain.jacobian(Vec3(1, 2, 3)), Mat3(1.0)), 1e-15);
}

TEST(BendWarp, LimitsAreContinuousAndRigidBeyond) {
  const BendOptions params = configurations()[4];
  const BendWarp warp(params);
  const BendWarp unlimited(bendParams(params.origin, params.axis, params.direction, params.rate));
  const Vec3 a = warp.axis();
  std::mt19937 rng(204);
  const std::vector<Vec3> offsets = test::perpendicularOffsets(rng, 200, a);
  for (double limit : {params.lo, params.hi})
    EXPECT_TRUE(test::continuousAcross(warp, params.origin, a, limit, offsets));
  for (const Vec3& p : offsets) {
    const Vec3 mid = params.origin + 0.1 * a + p;
    EXPECT_LT(relativeError(warp.apply(mid), unlimited.apply(mid)), 1e-14);
  }
  // Beyond each limit the map is one rigid motion: distances kept, Jacobian a rotation, and
  // it continues the end of the bent region along its tangent.
  for (bool upper : {false, true}) {
    const std::vector<Vec3> beyond =
        test::randomPointsWhere(rng, 200, -3.0, 3.0, [&](const Vec3& x) {
          const double y = spineCoordinate(warp, x);
          return upper ? y > params.hi + 0.01 : y < params.lo - 0.01;
        });
    const double limit = upper ? params.hi : params.lo;
    EXPECT_TRUE(test::movesRigidly(warp, beyond));
    for (const Vec3& x : beyond) {
      // x = foot + t a with the foot on the limit plane: x' = foot' + t (J a).
      const double t = spineCoordinate(warp, x) - limit;
      const Vec3 foot = x - t * a;
      EXPECT_LT(relativeError(warp.apply(x), unlimited.apply(foot) + t * (warp.jacobian(x) * a)),
                1e-13);
    }
  }
}

TEST(BendWarp, InverseRecoversPoints) {
  std::mt19937 rng(205);
  test::expectInversesRecover<BendWarp>(configurations(), rng, pointsIn(-2.0, 2.0, true));
}

TEST(BendWarp, NormalsStayPerpendicularToTangents) {
  std::mt19937 rng(206);
  test::expectNormalsStayPerpendicular<BendWarp>(configurations(), rng, pointsIn(-2.0, 2.0, true));
}

TEST(BendWarp, BatchIsBitIdenticalToApplyForAnyThreadCount) {
  std::mt19937 rng(207);
  test::expectBatchesDeterministic<BendWarp>(configurations(),
                                             randomPoints(rng, 100'000, -3.0, 3.0));
}

TEST(BendWarp, BatchRejectsMismatchedSizes) {
  test::expectBatchRejectsMismatchedSizes(BendWarp(configurations()[0]), 3, 4);
}

}  // namespace
}  // namespace spacewarp
