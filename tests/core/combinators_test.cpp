#include <spacewarp/core/combinators.h>

#include <cmath>
#include <limits>
#include <memory>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include <spacewarp/core/bend.h>
#include <spacewarp/core/errors.h>
#include <spacewarp/core/taper.h>
#include <spacewarp/core/twist.h>
#include "test_util.h"

namespace spacewarp {
namespace {

using test::randomPoints;
using test::relativeError;

// A general affine map: rotation-shear-scale plus a translation (column-major).
Mat4 generalAffine() {
  Mat4 m(1.0);
  m[0] = {1.2, 0.3, -0.1, 0.0};
  m[1] = {-0.2, 0.9, 0.4, 0.0};
  m[2] = {0.05, -0.3, 1.1, 0.0};
  m[3] = {0.5, -1.0, 2.0, 1.0};
  return m;
}

std::shared_ptr<const Warp> twist() {
  TwistOptions p;
  p.origin = Vec3(0.2, -0.1, 0.0);
  p.axis = Vec3(0.3, 0.1, 1.0);
  p.rate = 0.9;
  return std::make_shared<TwistWarp>(p);
}

std::shared_ptr<const Warp> bend() {
  BendOptions p;
  p.axis = Vec3(1, 0, 0);
  p.direction = Vec3(0, 1, 0.2);
  p.rate = 0.2;
  return std::make_shared<BendWarp>(p);
}

std::shared_ptr<const Warp> taper() {
  TaperOptions p;
  p.origin = Vec3(0.0, 0.0, -0.5);
  p.axis = Vec3(0, 1, 0);
  p.rate = 0.1;
  return std::make_shared<TaperWarp>(p);
}

TEST(IdentityWarp, IsTheIdentity) {
  const IdentityWarp warp;
  std::mt19937 rng(11);
  const std::vector<Vec3> points = randomPoints(rng, 200, -5.0, 5.0);
  EXPECT_TRUE(test::leavesPointsUnchanged(warp, points));
  for (const Vec3& x : points) EXPECT_EQ(warp.jacobian(x), Mat3(1.0));
  test::expectWarpProperties(warp, points, rng);
  EXPECT_TRUE(test::batchIsDeterministic(warp, randomPoints(rng, 100'000, -5.0, 5.0)));
}

TEST(AffineWarp, AppliesTheMatrix) {
  const Mat4 m = generalAffine();
  const AffineWarp warp(m);
  std::mt19937 rng(12);
  const std::vector<Vec3> points = randomPoints(rng, 200, -5.0, 5.0);
  for (const Vec3& x : points) {
    const Vec3 expected = Vec3(m * glm::dvec4(x, 1.0));
    EXPECT_LT(relativeError(warp.apply(x), expected), 1e-15);
  }
  EXPECT_EQ(warp.translation(), Vec3(0.5, -1.0, 2.0));
  EXPECT_EQ(warp.linear(), Mat3(m));
  test::expectWarpProperties(warp, points, rng);
  EXPECT_TRUE(test::batchIsDeterministic(warp, randomPoints(rng, 100'000, -5.0, 5.0)));
}

TEST(AffineWarp, RejectsProjectiveAndNonFiniteMatrices) {
  for (int c = 0; c < 3; ++c) {
    Mat4 m = generalAffine();
    m[c][3] = 0.25;  // a projective last row
    EXPECT_THROW(AffineWarp{m}, InvalidInput) << "column " << c;
  }
  Mat4 w = generalAffine();
  w[3][3] = 2.0;
  EXPECT_THROW(AffineWarp{w}, InvalidInput);
  for (int c = 0; c < 4; ++c) {
    for (int r = 0; r < 3; ++r) {
      Mat4 m = generalAffine();
      m[c][r] = std::numeric_limits<double>::quiet_NaN();
      EXPECT_THROW(AffineWarp{m}, InvalidInput) << "entry " << r << ", " << c;
      m[c][r] = -std::numeric_limits<double>::infinity();
      EXPECT_THROW(AffineWarp{m}, InvalidInput) << "entry " << r << ", " << c;
    }
  }
  const std::string message = test::messageOf<InvalidInput>([] {
    Mat4 m = generalAffine();
    m[1][2] = std::numeric_limits<double>::quiet_NaN();
    AffineWarp{m};
  });
  EXPECT_NE(message.find("(2, 1)"), std::string::npos) << message;
}

TEST(ComposedWarp, RejectsNullWarps) {
  EXPECT_THROW(ComposedWarp(nullptr, twist()), InvalidInput);
  EXPECT_THROW(ComposedWarp(twist(), nullptr), InvalidInput);
}

TEST(ComposedWarp, AppliesBothInOrderWithTheChainRule) {
  const std::vector<std::pair<std::shared_ptr<const Warp>, std::shared_ptr<const Warp>>> pairs = {
      {twist(), bend()},
      {bend(), twist()},
      {taper(), std::make_shared<AffineWarp>(generalAffine())},
      {std::make_shared<AffineWarp>(generalAffine()), taper()},
      {twist(), std::make_shared<ComposedWarp>(bend(), taper())},
  };
  std::mt19937 rng(13);
  for (const auto& [first, second] : pairs) {
    const ComposedWarp warp(first, second);
    const std::vector<Vec3> points = randomPoints(rng, 200, -1.5, 1.5);
    for (const Vec3& x : points) {
      EXPECT_EQ(warp.apply(x), second->apply(first->apply(x)));
      const Mat3 chain = second->jacobian(first->apply(x)) * first->jacobian(x);
      EXPECT_LT(relativeError(warp.jacobian(x), chain), 1e-15);
    }
    test::expectWarpProperties(warp, points, rng);
  }
}

TEST(ComposedWarp, OrderMatters) {
  const ComposedWarp ab(twist(), bend());
  const ComposedWarp ba(bend(), twist());
  const Vec3 x(1.0, 0.5, 1.2);
  EXPECT_GT(glm::length(ab.apply(x) - ba.apply(x)), 1e-3);
}

TEST(ComposedWarp, BatchIsBitIdenticalToApplyForAnyThreadCount) {
  std::mt19937 rng(14);
  const std::vector<Vec3> points = randomPoints(rng, 100'000, -3.0, 3.0);
  EXPECT_TRUE(test::batchIsDeterministic(ComposedWarp(twist(), bend()), points));
  EXPECT_TRUE(test::batchIsDeterministic(
      ComposedWarp(taper(), std::make_shared<ComposedWarp>(twist(), bend())), points));
}

TEST(ComposedWarp, NestedCompositionsAreFlattenedWithTheSameResults) {
  // Built left to right, as Compose(a, b, c) and rig chains do: points, Jacobians and inverses
  // are bit-identical to applying the stages one after the other by hand.
  const std::vector<std::shared_ptr<const Warp>> parts = {twist(), bend(), taper(), twist()};
  std::shared_ptr<const Warp> chain = parts[0];
  for (std::size_t i = 1; i < parts.size(); ++i)
    chain = std::make_shared<ComposedWarp>(chain, parts[i]);
  const auto& composed = static_cast<const ComposedWarp&>(*chain);
  EXPECT_EQ(composed.stages(), parts);
  std::mt19937 rng(5);
  for (const Vec3& x : randomPoints(rng, 100, -2.0, 2.0)) {
    Vec3 y = x;
    Mat3 j = parts[0]->jacobian(x);
    for (std::size_t i = 0; i < parts.size(); ++i) {
      if (i > 0) j = parts[i]->jacobian(y) * j;
      y = parts[i]->apply(y);
    }
    EXPECT_TRUE(test::bitEqual(composed.apply(x), y));
    const Mat3 jacobian = composed.jacobian(x);
    for (int c = 0; c < 3; ++c) EXPECT_TRUE(test::bitEqual(jacobian[c], j[c]));
  }
  // Nested the other way round it is flattened to the same stages.
  const ComposedWarp right(
      parts[0],
      std::make_shared<ComposedWarp>(parts[1], std::make_shared<ComposedWarp>(parts[2], parts[3])));
  EXPECT_EQ(right.stages(), parts);
  EXPECT_THROW(ComposedWarp(std::vector<std::shared_ptr<const Warp>>{twist()}), InvalidInput);
  EXPECT_THROW(ComposedWarp(std::vector<std::shared_ptr<const Warp>>{twist(), nullptr}),
               InvalidInput);
}

TEST(ComposedWarp, AChainOfAHundredThousandStagesCostsNoStack) {
  // Nested, each apply would recurse once per stage: deep enough to overflow a thread's stack.
  TwistOptions p;
  p.rate = 1e-6;
  const auto stage = std::make_shared<TwistWarp>(p);
  const auto chain = std::make_shared<ComposedWarp>(
      std::make_shared<ComposedWarp>(std::vector<std::shared_ptr<const Warp>>(100000, stage)),
      stage);
  EXPECT_EQ(chain->stages().size(), 100001u);
  Vec3 expected(1.0, 0.5, 2.0);
  for (int i = 0; i <= 100000; ++i) expected = stage->apply(expected);
  EXPECT_TRUE(test::bitEqual(chain->apply(Vec3(1.0, 0.5, 2.0)), expected));
}

TEST(ComposedWarp, BatchRejectsMismatchedSizes) {
  test::expectBatchRejectsMismatchedSizes(ComposedWarp(twist(), bend()), 5, 4);
}

}  // namespace
}  // namespace spacewarp
