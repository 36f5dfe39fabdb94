#include <spacewarp/core/taper.h>

#include <cmath>
#include <limits>
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

constexpr test::AxialOptions<TaperOptions> taperParams{};

// In [-2, 2]^3 these keep r > 0 (|rate| * |s| < 1 for |s| <= 2 sqrt(3) + |origin|, or limits).
std::vector<TaperOptions> configurations() {
  return {
      taperParams(Vec3(0.0), Vec3(0, 0, 1), 0.2),
      taperParams(Vec3(0.5, -1.0, 2.0), Vec3(1, 2, 3), -0.12),
      taperParams(Vec3(-1.0, 0.3, 0.0), Vec3(0, -5, 0), 0.25),
      taperParams(Vec3(0.2, 0.1, -0.3), Vec3(1, 0, 0), 1e-9),
      taperParams(Vec3(1.0, 1.0, 1.0), Vec3(-1, 1, 0.2), 0.9, -0.5, 0.8),
      taperParams(Vec3(0.0), Vec3(0, 0, 1), -1.5, -kInf, 0.5),
      taperParams(Vec3(0.0, 0.0, 1.0), Vec3(1, 0, 0), 0.6, -1.0, kInf),
  };
}

double axialCoordinate(const TaperWarp& warp, const Vec3& x) {
  return glm::dot(x - warp.params().origin, warp.axis());
}

// Samples random points in [lo, hi)^3 away from the limits and, if `invertible`, with r >= 0.2.
test::PointSampler<TaperWarp> pointsIn(double lo, double hi, bool invertible = false) {
  return [=](const TaperWarp& warp, std::mt19937& rng, std::size_t n) {
    const TaperOptions& p = warp.params();
    return test::randomPointsWhere(rng, n, lo, hi, [&](const Vec3& x) {
      const double s = axialCoordinate(warp, x);
      return std::abs(s - p.lo) > 0.02 && std::abs(s - p.hi) > 0.02 &&
             (!invertible || warp.scaleAt(s) >= 0.2);
    });
  };
}

TEST(TaperWarp, RejectsInvalidParameters) {
  const Vec3 z(0, 0, 1);
  EXPECT_THROW(TaperWarp(taperParams(Vec3(0.0), Vec3(0.0), 1.0)), InvalidInput);
  EXPECT_THROW(TaperWarp(taperParams(Vec3(0.0), Vec3(0, 0, kNaN), 1.0)), InvalidInput);
  EXPECT_THROW(TaperWarp(taperParams(Vec3(0, 0, -kInf), z, 1.0)), InvalidInput);
  EXPECT_THROW(TaperWarp(taperParams(Vec3(0.0), z, kInf)), InvalidInput);
  EXPECT_THROW(TaperWarp(taperParams(Vec3(0.0), z, 1.0, 0.5, 0.25)), InvalidInput);
  EXPECT_THROW(TaperWarp(taperParams(Vec3(0.0), z, 1.0, kNaN, kNaN)), InvalidInput);
  const std::string message =
      test::messageOf<InvalidInput>([&] { TaperWarp(taperParams(Vec3(0.0), z, 1.0, 3.0, 2.0)); });
  EXPECT_NE(message.find("limit"), std::string::npos) << message;
  // r <= 0 somewhere is allowed (documented to fold space), not rejected.
  EXPECT_NO_THROW(TaperWarp(taperParams(Vec3(0.0), z, -3.0)));
}

TEST(TaperWarp, JacobianMatchesFiniteDifferences) {
  std::mt19937 rng(301);
  test::expectJacobiansMatchFiniteDifferences<TaperWarp>(configurations(), rng,
                                                         pointsIn(-3.0, 3.0));
  // Also where r < 0, which the Jacobian covers too.
  const TaperWarp folding(taperParams(Vec3(0.0), Vec3(0, 1, 0), -1.0));
  EXPECT_TRUE(test::jacobianMatchesFiniteDifferences(folding, randomPoints(rng, 200, -3.0, 3.0)));
}

TEST(TaperWarp, JacobianDeterminantIsRSquared) {
  std::mt19937 rng(302);
  const TaperWarp warp(configurations()[1]);
  for (const Vec3& x : randomPoints(rng, 200, -3.0, 3.0)) {
    const double r = warp.scaleAt(axialCoordinate(warp, x));
    EXPECT_NEAR(glm::determinant(warp.jacobian(x)), r * r, 1e-14);
  }
}

TEST(TaperWarp, ScalesThePerpendicularPart) {
  // Axis +z through (1, 2, 0), rate 0.5: at s = 2 the cross-section doubles, at s = -1 halves.
  const TaperWarp warp(taperParams(Vec3(1, 2, 0), Vec3(0, 0, 3), 0.5));
  EXPECT_EQ(warp.apply(Vec3(2, 2, 2)), Vec3(3, 2, 2));
  EXPECT_EQ(warp.apply(Vec3(1, 5, 2)), Vec3(1, 8, 2));
  EXPECT_EQ(warp.apply(Vec3(3, 4, -1)), Vec3(2, 3, -1));
  EXPECT_EQ(warp.apply(Vec3(1, 2, 7)), Vec3(1, 2, 7));  // on the axis
  // An oblique axis: x' = o + s a + r(s) p, checked by decomposition.
  std::mt19937 rng(303);
  const TaperWarp oblique(configurations()[1]);
  const Vec3 o = oblique.params().origin, a = oblique.axis();
  for (const Vec3& x : randomPoints(rng, 200, -3.0, 3.0)) {
    const double s = glm::dot(x - o, a);
    const Vec3 p = x - o - s * a;
    const Vec3 moved = oblique.apply(x);
    EXPECT_NEAR(glm::dot(moved - o, a), s, 1e-14);
    EXPECT_LT(relativeError(moved, o + s * a + (1.0 + oblique.params().rate * s) * p), 1e-15);
  }
}

TEST(TaperWarp, RateZeroIsExactlyTheIdentity) {
  std::mt19937 rng(304);
  const TaperWarp plain(taperParams(Vec3(0.3, -0.2, 7.0), Vec3(1, 2, 3), 0.0));
  const TaperWarp limited(taperParams(Vec3(0.3, -0.2, 7.0), Vec3(1, 2, 3), 0.0, -1.0, 0.5));
  const std::vector<Vec3> points = randomPoints(rng, 1000, -100.0, 100.0);
  EXPECT_TRUE(test::leavesPointsUnchanged(plain, points));
  EXPECT_TRUE(test::leavesPointsUnchanged(limited, points));
  EXPECT_LT(relativeError(plain.jacobian(Vec3(1, 2, 3)), Mat3(1.0)), 1e-15);
}

TEST(TaperWarp, LimitsAreContinuousAndKeepTheEndScaleBeyond) {
  const TaperOptions params = configurations()[4];
  const TaperWarp warp(params);
  const TaperWarp unlimited(taperParams(params.origin, params.axis, params.rate));
  const Vec3 a = warp.axis();
  std::mt19937 rng(305);
  const std::vector<Vec3> offsets = test::perpendicularOffsets(rng, 200, a);
  for (double limit : {params.lo, params.hi})
    EXPECT_TRUE(test::continuousAcross(warp, params.origin, a, limit, offsets));
  for (const Vec3& p : offsets) {
    const Vec3 mid = params.origin + 0.1 * a + p;
    EXPECT_LT(relativeError(warp.apply(mid), unlimited.apply(mid)), 1e-15);
    // Beyond a limit the cross-section keeps the scale of the limit and slides along the axis.
    for (double limit : {params.lo, params.hi}) {
      const double t = limit == params.lo ? -1.3 : 0.9;
      const Vec3 foot = params.origin + limit * a + p;
      EXPECT_LT(relativeError(warp.apply(foot + t * a), unlimited.apply(foot) + t * a), 1e-14);
      EXPECT_DOUBLE_EQ(warp.scaleAt(limit + t), 1.0 + params.rate * limit);
    }
  }
}

TEST(TaperWarp, InverseRecoversPoints) {
  std::mt19937 rng(306);
  test::expectInversesRecover<TaperWarp>(configurations(), rng, pointsIn(-2.0, 2.0, true));
}

TEST(TaperWarp, InverseOfAPointOffTheCollapsedAxisDoesNotConverge) {
  // r = 1 - s vanishes on the plane s = 1, which collapses onto the axis point (0, 0, 1); the
  // point (1, 0, 1) beside it has no preimage at all.
  const TaperWarp warp(taperParams(Vec3(0.0), Vec3(0, 0, 1), -1.0));
  InverseResult r;
  ASSERT_NO_THROW(r = inverse(warp, Vec3(1, 0, 1)));
  EXPECT_FALSE(r.converged);
  EXPECT_GT(r.residual, 1e-3);
}

TEST(TaperWarp, NormalsStayPerpendicularToTangents) {
  std::mt19937 rng(307);
  test::expectNormalsStayPerpendicular<TaperWarp>(configurations(), rng, pointsIn(-2.0, 2.0, true));
}

TEST(TaperWarp, BatchIsBitIdenticalToApplyForAnyThreadCount) {
  std::mt19937 rng(308);
  test::expectBatchesDeterministic<TaperWarp>(configurations(),
                                              randomPoints(rng, 100'000, -3.0, 3.0));
}

TEST(TaperWarp, BatchRejectsMismatchedSizes) {
  test::expectBatchRejectsMismatchedSizes(TaperWarp(configurations()[0]), 0, 1);
}

}  // namespace
}  // namespace spacewarp
