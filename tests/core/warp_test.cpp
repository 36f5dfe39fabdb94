#include <spacewarp/core/warp.h>

#include <cmath>
#include <limits>
#include <memory>
#include <random>
#include <span>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <tbb/task_arena.h>
#include <glm/gtc/matrix_transform.hpp>

#include <spacewarp/core/bend.h>
#include <spacewarp/core/combinators.h>
#include <spacewarp/core/errors.h>
#include <spacewarp/core/inverse.h>
#include <spacewarp/core/taper.h>
#include <spacewarp/core/twist.h>
#include "test_util.h"

namespace spacewarp {
namespace {

using test::randomPoints;
using test::relativeError;

// A smooth nonlinear warp that keeps the default (finite-difference) Jacobian and batch.
class SinWarp final : public Warp {
 public:
  Vec3 apply(const Vec3& x) const override {
    return {std::sin(x.y), x.x * x.z, std::exp(0.1 * x.x)};
  }
  static Mat3 exactJacobian(const Vec3& x) {
    Mat3 j(0.0);  // j[c][r] = d out_r / d x_c
    j[1][0] = std::cos(x.y);
    j[0][1] = x.z;
    j[2][1] = x.x;
    j[0][2] = 0.1 * std::exp(0.1 * x.x);
    return j;
  }
};

// x + 0.3 (sin y, sin z, sin x), keeping the default Jacobian.
class WobbleWarp final : public Warp {
 public:
  Vec3 apply(const Vec3& x) const override {
    return x + 0.3 * Vec3(std::sin(x.y), std::sin(x.z), std::sin(x.x));
  }
};

// Maps all of space onto the plane z = 0 (singular everywhere), without overriding anything.
class FlattenWarp final : public Warp {
 public:
  Vec3 apply(const Vec3& x) const override { return {x.x + 0.1 * x.y * x.y, x.y, 0.0}; }
};

TEST(Warp, DefaultJacobianMatchesClosedForm) {
  const SinWarp warp;
  std::mt19937 rng(1);
  for (const Vec3& x : randomPoints(rng, 500, -3.0, 3.0)) {
    const Mat3 j = warp.jacobian(x);
    const Mat3 exact = SinWarp::exactJacobian(x);
    EXPECT_LE(relativeError(j, exact), 1e-8) << test::toString(x);
  }
  // Far from the origin the step grows with |x|, so the relative accuracy holds.
  for (const Vec3& x : randomPoints(rng, 100, 20.0, 40.0)) {
    const Mat3 exact = SinWarp::exactJacobian(x);
    EXPECT_LE(test::frobenius(warp.jacobian(x) - exact) / test::frobenius(exact), 1e-7)
        << test::toString(x);
  }
}

TEST(Warp, TestHelperFiniteDifferencesMatchClosedForm) {
  const SinWarp warp;
  std::mt19937 rng(2);
  for (const Vec3& x : randomPoints(rng, 200, -3.0, 3.0))
    EXPECT_LE(relativeError(test::finiteDifferenceJacobian(warp, x), SinWarp::exactJacobian(x)),
              1e-9);
}

TEST(Warp, TransformVectorIsJacobianTimesVector) {
  const SinWarp warp;
  const Vec3 x(0.3, -0.4, 1.2), v(1.0, 2.0, -0.5);
  EXPECT_EQ(transformVector(warp, x, v), warp.jacobian(x) * v);
}

TEST(Warp, TransformNormalIsInverseTransposeNormalised) {
  Mat4 m(1.0);
  m[0] = {2.0, 0.5, 0.0, 0.0};
  m[1] = {0.0, 1.0, 0.3, 0.0};
  m[2] = {0.1, 0.0, 3.0, 0.0};
  const AffineWarp warp(m);
  const Vec3 n = glm::normalize(Vec3(1.0, -2.0, 0.5));
  const Vec3 expected = glm::normalize(glm::transpose(glm::inverse(warp.linear())) * n);
  EXPECT_LT(relativeError(transformNormal(warp, Vec3(0.0), n), expected), 1e-15);
  // A reflection flips the orientation, but the normal still follows J^-T n, not its opposite.
  const AffineWarp mirror(glm::scale(Mat4(1.0), Vec3(-1.0, 1.0, 1.0)));
  EXPECT_LT(relativeError(transformNormal(mirror, Vec3(0.0), Vec3(1, 0, 0)), Vec3(-1, 0, 0)),
            1e-15);
}

TEST(Warp, TransformNormalOfACollapsedWarpIsZeroNotNaN) {
  const AffineWarp collapse(
      Mat4(0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 2.0, 3.0, 1.0));
  const Vec3 n = transformNormal(collapse, Vec3(1.0), Vec3(0, 0, 1));
  EXPECT_EQ(n, Vec3(0.0));
}

// The verdict depends on how close J's columns are to dependent, not on J's size: a regular J
// scaled to entries of 1e300 (whose determinant and column-length product overflow) or 1e-300
// (which underflow) is regular, a singular one singular, at every scale.
TEST(Warp, SingularJacobianIsScaleInvariant) {
  const Mat3 regular = Mat3(glm::rotate(Mat4(1.0), 0.7, Vec3(1.0, 2.0, 3.0))) *
                       Mat3(Vec3(1, 0, 0), Vec3(0.5, 2, 0), Vec3(0, 0.3, 3));
  const Vec3 u = glm::normalize(Vec3(1.0, 2.0, 3.0));
  const Mat3 projection = Mat3(1.0) - glm::outerProduct(u, u);  // rank 2, det ~ 1e-17
  const Mat3 rankOne = glm::outerProduct(u, Vec3(1.0, -1.0, 2.0));
  for (const double scale : {1e-300, 1e-150, 1e-6, 1.0, 1e6, 1e150, 1e300}) {
    SCOPED_TRACE(scale);
    EXPECT_FALSE(isSingularJacobian(scale * regular));
    EXPECT_FALSE(isSingularJacobian(scale * Mat3(1.0)));
    EXPECT_FALSE(isSingularJacobian(scale * Mat3(Vec3(-1, 0, 0), Vec3(0, 1, 0), Vec3(0, 0, 1))));
    EXPECT_TRUE(isSingularJacobian(scale * projection));
    EXPECT_TRUE(isSingularJacobian(scale * rankOne));
  }
  // Columns of very different lengths: anisotropic, still regular.
  EXPECT_FALSE(isSingularJacobian(Mat3(Vec3(1e300, 0, 0), Vec3(0, 1, 0), Vec3(0, 0, 1e-300))));
  EXPECT_TRUE(isSingularJacobian(Mat3(0.0)));
  EXPECT_TRUE(isSingularJacobian(Mat3(Vec3(1, 0, 0), Vec3(0, 1, 0), Vec3(0.0))));
  const double inf = std::numeric_limits<double>::infinity();
  EXPECT_TRUE(isSingularJacobian(Mat3(Vec3(inf, 0, 0), Vec3(0, 1, 0), Vec3(0, 0, 1))));
  EXPECT_TRUE(isSingularJacobian(
      Mat3(Vec3(std::numeric_limits<double>::quiet_NaN(), 0, 0), Vec3(0, 1, 0), Vec3(0, 0, 1))));
}

// J^-T n normalised does not depend on J's scale: entries of 1e300 or 1e-300 give the same
// normal as the unscaled J (their cofactors would overflow or underflow).
TEST(Warp, TransformNormalOfAHugeOrTinyJacobian) {
  const Mat3 j = Mat3(Vec3(2.0, 0.5, 0.0), Vec3(0.0, 1.0, 0.3), Vec3(0.1, 0.0, -3.0));
  const Vec3 n = glm::normalize(Vec3(1.0, -2.0, 0.5));
  const Vec3 expected = transformNormal(j, n);
  ASSERT_NEAR(glm::length(expected), 1.0, 1e-15);
  for (const double scale : {0x1p-1000, 0x1p-500, 0x1p500, 0x1p1000, 1e-300, 1e300}) {
    SCOPED_TRACE(scale);
    EXPECT_LT(relativeError(transformNormal(scale * j, n), expected), 1e-15);
  }
  // Scaling by powers of two is exact: the same bits.
  EXPECT_EQ(transformNormal(0x1p1000 * j, n), expected);
}

TEST(Warp, InverseOfAHugeAffineWarpConverges) {
  const Mat3 linear = 1e300 * Mat3(Vec3(2.0, 0.5, 0.0), Vec3(0.0, 1.0, 0.3), Vec3(0.1, 0.0, 3.0));
  Mat4 m(1.0);
  for (int c = 0; c < 3; ++c) m[c] = glm::dvec4(linear[c], 0.0);
  const AffineWarp warp(m);
  const Vec3 x(1e-300, -2e-300, 3e-301);
  const InverseResult r = inverse(warp, warp.apply(x));
  EXPECT_TRUE(r.converged);
  EXPECT_LT(relativeError(r.x, x), 1e-12);
}

TEST(Warp, NormalsOfTheDefaultJacobianStayPerpendicular) {
  const SinWarp warp;
  std::mt19937 rng(3);
  // Keep away from the singular set (cos y = 0 or x = 0) so J is well conditioned.
  const std::vector<Vec3> points = test::randomPointsWhere(
      rng, 200, -1.2, 1.2, [](const Vec3& x) { return std::abs(x.x) > 0.2; });
  EXPECT_TRUE(test::normalsStayPerpendicular(warp, points, rng, 1e-12));
}

TEST(Warp, InverseOfASmoothWarpConverges) {
  // The identity plus a perturbation with Lipschitz constant 0.3 < 1: injective everywhere.
  const WobbleWarp warp;
  std::mt19937 rng(4);
  EXPECT_TRUE(test::inverseRecovers(warp, randomPoints(rng, 200, -5.0, 5.0)));
}

TEST(Warp, InverseOfANonInjectiveWarpFindsAPreimage) {
  // sin is not injective: whatever inverse() reports as converged must map onto the target.
  const SinWarp warp;
  std::mt19937 rng(7);
  for (const Vec3& x : test::randomPointsWhere(rng, 200, -1.0, 1.0,
                                               [](const Vec3& p) { return std::abs(p.x) > 0.3; })) {
    const Vec3 y = warp.apply(x);
    const InverseResult r = inverse(warp, y);
    EXPECT_LE(glm::length(warp.apply(r.x) - y), r.residual * (1.0 + 1e-12));
    if (r.converged) {
      const double scale = std::max({maxAbs(y), maxAbs(warp.apply(y) - y), 1e-300});
      EXPECT_LE(r.residual, 1e-12 * scale);
    }
  }
}

TEST(Warp, InverseOfAWarpOntoAPlaneReportsNoConvergence) {
  const FlattenWarp warp;
  InverseResult r;
  ASSERT_NO_THROW(r = inverse(warp, Vec3(1.0, 2.0, 3.0)));
  EXPECT_FALSE(r.converged);
  EXPECT_TRUE(isFinite(r.x));
  EXPECT_GT(r.residual, 1.0);  // z = 3 is out of reach
}

TEST(Warp, InverseRejectsNonFiniteTarget) {
  const SinWarp warp;
  EXPECT_THROW(inverse(warp, Vec3(0.0, std::numeric_limits<double>::quiet_NaN(), 0.0)),
               InvalidInput);
  EXPECT_THROW(inverse(warp, Vec3(std::numeric_limits<double>::infinity(), 0.0, 0.0)),
               InvalidInput);
}

TEST(Warp, InverseHonoursMaxIterations) {
  const TwistWarp warp([] {
    TwistOptions p;
    p.rate = 2.0;
    return p;
  }());
  InverseOptions options;
  options.maxIterations = 1;
  const InverseResult r = inverse(warp, warp.apply(Vec3(1.5, -0.5, 1.0)), options);
  EXPECT_LE(r.iterations, 1);
  if (!r.converged) {
    EXPECT_GT(r.residual, 0.0);
  }
}

TEST(Warp, DefaultBatchIsBitIdenticalToApplyForAnyThreadCount) {
  const SinWarp warp;
  std::mt19937 rng(5);
  EXPECT_TRUE(test::batchIsDeterministic(warp, randomPoints(rng, 100'000, -3.0, 3.0)));
}

TEST(Warp, DefaultBatchRejectsMismatchedSizesAndAcceptsEmpty) {
  const SinWarp warp;
  test::expectBatchRejectsMismatchedSizes(warp, 5, 6);
  std::vector<Vec3> none;
  EXPECT_NO_THROW(warp.applyBatch(none, none));
}

// A warp defined only for x >= 0, with a small batch grain so that a batch spans many ranges:
// its kernel reports the other points, and explains them in its own words.
class HalfSpaceWarp final : public Warp {
 public:
  Vec3 apply(const Vec3& x) const override { return x + Vec3(1.0, 0.0, 0.0); }

 protected:
  std::size_t batchGrain() const override { return 7; }
  UnmappedPoints applyRange(std::span<const Vec3> in, std::span<Vec3> out, std::size_t begin,
                            std::size_t end) const override {
    UnmappedPoints unmapped;
    for (std::size_t i = begin; i != end; ++i) {
      if (in[i].x >= 0.0) {
        out[i] = apply(in[i]);
      } else {
        unmapped.add(i);
      }
    }
    return unmapped;
  }
  void throwUnmapped(const UnmappedPoints& unmapped, std::span<const Vec3>) const override {
    throw InvalidInput("half space: " + std::to_string(unmapped.count) + " points, first " +
                       std::to_string(unmapped.first));
  }
};

std::string batchError(const Warp& warp, std::vector<Vec3> points) {
  try {
    warp.applyBatch(points, points);
  } catch (const InvalidInput& e) {
    return e.what();
  }
  return "no error";
}

TEST(Warp, BatchCountsEveryUnmappedPointAndNamesTheFirstForAnyThreadCount) {
  std::vector<Vec3> points(1000, Vec3(1.0));
  for (std::size_t i : {998u, 35u, 36u, 500u}) points[i].x = -1.0;
  const HalfSpaceWarp warp;
  for (int threads : {1, 2, 4}) {
    tbb::task_arena arena(threads);
    arena.execute([&] { EXPECT_EQ(batchError(warp, points), "half space: 4 points, first 35"); });
  }
}

TEST(Warp, ACompositionLetsTheStageThatCouldNotWarpExplain) {
  std::vector<Vec3> points(100, Vec3(1.0));
  points[40].x = -5.0;  // outside the half space before the shift
  points[60].x = -0.5;  // inside it after the shift by +1
  const auto half = std::make_shared<HalfSpaceWarp>();
  const auto shift = std::make_shared<AffineWarp>(glm::translate(Mat4(1.0), Vec3(1.0, 0.0, 0.0)));
  EXPECT_EQ(batchError(ComposedWarp(half, shift), points), "half space: 2 points, first 40");
  EXPECT_EQ(batchError(ComposedWarp(shift, half), points), "half space: 1 points, first 40");
  // Nested compositions keep the stage that made the report.
  const auto inner = std::make_shared<ComposedWarp>(shift, half);
  EXPECT_EQ(batchError(ComposedWarp(inner, shift), points), "half space: 1 points, first 40");
}

TEST(Warp, TheDefaultExplanationCountsThePoints) {
  class Refusing final : public Warp {
   public:
    Vec3 apply(const Vec3& x) const override { return x; }

   protected:
    UnmappedPoints applyRange(std::span<const Vec3>, std::span<Vec3>, std::size_t begin,
                              std::size_t end) const override {
      UnmappedPoints all;
      for (std::size_t i = begin; i != end; ++i) all.add(i);
      return all;
    }
  };
  EXPECT_EQ(batchError(Refusing(), std::vector<Vec3>(9000, Vec3(0.0))),
            "9000 of 9000 points could not be warped (the first is point 0)");
}

// The analytic warps against the same shared properties through the Warp interface.
TEST(Warp, AnalyticWarpsThroughTheInterface) {
  std::vector<std::unique_ptr<Warp>> warps;
  {
    TwistOptions p;
    p.origin = Vec3(0.1, 0.2, 0.3);
    p.axis = Vec3(1, 1, 1);
    p.rate = 0.8;
    warps.push_back(std::make_unique<TwistWarp>(p));
  }
  {
    BendOptions p;
    p.axis = Vec3(0, 1, 0);
    p.direction = Vec3(0, 0, 1);
    p.rate = 0.3;
    p.lo = -1.0;
    p.hi = 1.0;
    warps.push_back(std::make_unique<BendWarp>(p));
  }
  {
    TaperOptions p;
    p.axis = Vec3(1, 0, 0);
    p.rate = 0.1;
    warps.push_back(std::make_unique<TaperWarp>(p));
  }
  std::mt19937 rng(6);
  for (const auto& warp : warps) {
    // Inside (-0.98, 0.98)^3: away from the bend's limits at +-1.
    test::expectWarpProperties(*warp, randomPoints(rng, 200, -0.98, 0.98), rng);
  }
}

}  // namespace
}  // namespace spacewarp
