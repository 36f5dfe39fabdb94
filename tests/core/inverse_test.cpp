#include <spacewarp/core/inverse.h>

#include <cmath>
#include <memory>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include <spacewarp/core/bend.h>
#include <spacewarp/core/combinators.h>
#include <spacewarp/core/taper.h>
#include <spacewarp/core/twist.h>

#include "test_util.h"

namespace spacewarp {
namespace {

using test::randomPoints;
using test::relativeError;

// The identity plus a smooth perturbation of Lipschitz constant 0.3: injective everywhere.
class WobbleWarp final : public Warp {
 public:
  Vec3 apply(const Vec3& x) const override {
    return x + 0.1 * Vec3(std::sin(3.0 * x.y), std::sin(3.0 * x.z), std::sin(3.0 * x.x));
  }
};

// sin along x: not injective, so the seed decides which preimage is found.
class SinWarp final : public Warp {
 public:
  Vec3 apply(const Vec3& x) const override { return Vec3(std::sin(x.x), x.y, x.z); }
};

// Onto the plane z = 0: nothing off the plane has a preimage.
class FlattenWarp final : public Warp {
 public:
  Vec3 apply(const Vec3& x) const override { return Vec3(x.x, x.y, 0.0); }
};

// x + 0.45 |x - 1/2| along x: piecewise linear (slopes 0.55 and 1.45), a kink at x = 1/2.
class KinkWarp final : public Warp {
 public:
  Vec3 apply(const Vec3& x) const override {
    return Vec3(x.x + 0.45 * std::abs(x.x - 0.5), x.y, x.z);
  }
};

std::shared_ptr<const Warp> twist() {
  TwistParams p;
  p.origin = Vec3(0.3, -0.2, 0.1);
  p.axis = Vec3(0.2, 0.1, 1.0);
  p.rate = 1.3;
  p.lo = -1.0;
  p.hi = 1.5;
  return std::make_shared<TwistWarp>(p);
}

std::shared_ptr<const Warp> taper() {
  TaperParams p;
  p.axis = Vec3(1.0, 0.2, 0.0);
  p.rate = 0.4;
  p.lo = -1.0;
  p.hi = 1.0;
  return std::make_shared<TaperWarp>(p);
}

BendParams bendParams() {
  BendParams p;
  p.origin = Vec3(0.1, 0.0, -0.5);
  p.rate = 1.2;
  p.lo = -0.5;
  p.hi = 1.5;
  return p;
}

std::shared_ptr<const Warp> affine() {
  Mat4 m(1.0);
  m[0] = glm::dvec4(1.2, 0.1, -0.3, 0.0);
  m[1] = glm::dvec4(0.2, 0.9, 0.1, 0.0);
  m[2] = glm::dvec4(-0.1, 0.3, 1.1, 0.0);
  m[3] = glm::dvec4(2.0, -1.0, 0.5, 1.0);
  return std::make_shared<AffineWarp>(m);
}

// x -> warp -> inverse returns x to `tolerance` relative to max(1, |x|), by the closed form.
::testing::AssertionResult roundTrips(const Warp& warp, const std::vector<Vec3>& points,
                                      double tolerance = 1e-12) {
  for (const Vec3& x : points) {
    const InverseResult r = inverse(warp, warp.apply(x));
    const double error = glm::length(r.x - x) / std::max(1.0, glm::length(x));
    if (!r.converged || r.iterations != 0 || !(error <= tolerance)) {
      return ::testing::AssertionFailure()
             << "x = " << test::toString(x) << ": converged " << r.converged << ", iterations "
             << r.iterations << ", error " << error;
    }
  }
  return ::testing::AssertionSuccess();
}

TEST(Inverse, ConvergesOnASmoothWarp) {
  const WobbleWarp warp;
  std::mt19937 rng(1);
  for (const Vec3& x : randomPoints(rng, 100, -4.0, 4.0)) {
    const InverseResult r = inverse(warp, warp.apply(x));
    ASSERT_TRUE(r.converged);
    EXPECT_LT(relativeError(r.x, x), 1e-10);
    EXPECT_LE(r.residual, 1e-12 * 5.0);
  }
}

TEST(Inverse, ReportsNonConvergence) {
  const FlattenWarp warp;
  const InverseResult r = inverse(warp, Vec3(1.0, 2.0, 3.0));
  EXPECT_FALSE(r.converged);
  EXPECT_TRUE(isFinite(r.x));
  EXPECT_NEAR(r.residual, glm::length(warp.apply(r.x) - Vec3(1.0, 2.0, 3.0)), 1e-12);
  EXPECT_GT(r.residual, 1.0);
}

TEST(Inverse, HonoursTheSeed) {
  // sin x = 0.5 at x = π/6 + 2πm: the seed picks m.
  const SinWarp warp;
  const Vec3 y(0.5, 1.0, -2.0);
  for (int m = -2; m <= 2; ++m) {
    const double x = std::acos(-1.0) / 6.0 + 2.0 * std::acos(-1.0) * m;
    InverseHint hint;
    hint.seed = Vec3(x + 0.2, 1.0, -2.0);
    const InverseResult r = inverse(warp, y, {}, hint);
    ASSERT_TRUE(r.converged) << m;
    EXPECT_NEAR(r.x.x, x, 1e-9) << m;
  }
}

TEST(Inverse, ChordStepsWithTheExactInverseJacobianConvergeInOneStep) {
  const auto warp = affine();
  const auto& a = static_cast<const AffineWarp&>(*warp);
  InverseOptions options;
  options.closedForm = false;
  InverseHint hint;
  hint.seed = Vec3(0.0);
  hint.chordInverse = glm::inverse(a.linear());
  const Vec3 x(0.4, -1.3, 2.2);
  const InverseResult r = inverse(*warp, warp->apply(x), options, hint);
  ASSERT_TRUE(r.converged);
  EXPECT_LE(r.iterations, 2);
  EXPECT_LT(relativeError(r.x, x), 1e-12);
}

TEST(Inverse, InvertsRigidMotionsExactly) {
  // Rodrigues: R = c I + s [a]x + (1 - c) a aᵀ.
  const Vec3 a = glm::normalize(Vec3(1.0, 2.0, -0.5));
  const double c = std::cos(0.7), s = std::sin(0.7);
  Mat3 rotation = Mat3(c) + (1.0 - c) * glm::outerProduct(a, a);
  for (int i = 0; i < 3; ++i) {
    Vec3 e(0.0);
    e[i] = 1.0;
    rotation[i] += s * glm::cross(a, e);
  }
  Mat4 m(rotation);
  m[3] = glm::dvec4(5.0, -3.0, 2.0, 1.0);
  const AffineWarp warp(m);
  std::mt19937 rng(2);
  for (const Vec3& x : randomPoints(rng, 50, -10.0, 10.0)) {
    for (const bool closedForm : {true, false}) {
      InverseOptions options;
      options.closedForm = closedForm;
      const InverseResult r = inverse(warp, warp.apply(x), options);
      ASSERT_TRUE(r.converged);
      EXPECT_LT(glm::length(r.x - x), 1e-14 * 20.0) << closedForm;
    }
  }
}

TEST(Inverse, FarAwayCoordinates) {
  // The tolerance is relative to the coordinates' scale: far from the origin the inverse
  // still converges, to the same relative accuracy.
  const WobbleWarp warp;
  for (const double far : {1e6, 1e9, -1e12}) {
    const Vec3 x(far, far + 0.3, 0.5 * far);
    const InverseResult r = inverse(warp, warp.apply(x));
    ASSERT_TRUE(r.converged) << far;
    EXPECT_LT(relativeError(r.x, x), 1e-12) << far;
  }
  // Far along the axis (the twist is then well conditioned; off the axis its Jacobian grows
  // with the distance, and so does any inverse's error).
  EXPECT_TRUE(roundTrips(*twist(), {Vec3(0.5, -0.3, 1e8), Vec3(2.0, 1.0, -1e7)}));
}

TEST(Inverse, ContinuationCrossesAKink) {
  const KinkWarp warp;
  const Vec3 x(1.5, 0.0, 0.0);
  const Vec3 y = warp.apply(x);
  // Seeded on the other side of the kink; with no line search worth the name, continuation
  // finishes the job.
  InverseOptions options;
  options.maxIterations = 1;
  InverseHint hint;
  hint.seed = Vec3(-3.0, 0.0, 0.0);
  const InverseResult r = inverse(warp, y, options, hint);
  ASSERT_TRUE(r.converged);
  EXPECT_LT(relativeError(r.x, x), 1e-10);
  options.continuation = false;
  EXPECT_FALSE(inverse(warp, y, options, hint).converged);
}

TEST(ExactInverse, TwistRoundTrips) {
  std::mt19937 rng(3);
  EXPECT_TRUE(roundTrips(*twist(), randomPoints(rng, 300, -3.0, 3.0)));
}

TEST(ExactInverse, TaperRoundTrips) {
  std::mt19937 rng(4);
  EXPECT_TRUE(roundTrips(*taper(), randomPoints(rng, 300, -3.0, 3.0)));
  // Where the cross-section collapses (r = 0) there is no closed form.
  TaperParams p;
  p.rate = -1.0;
  const TaperWarp collapsing(p);
  EXPECT_FALSE(collapsing.exactInverse(Vec3(0.0, 0.0, 1.0)).has_value());
}

TEST(ExactInverse, BendRoundTripsIncludingNearTheEndsOfItsRange) {
  const BendParams p = bendParams();
  const BendWarp warp(p);
  std::mt19937 rng(5);
  // Inside the bent region with 1 - k z > 0 (z < 1/k), near both limits, and a little beyond
  // them (far beyond, the rigid ends of a 2.4 rad bend overlap: no inverse is unique there).
  std::vector<Vec3> points = test::randomPointsWhere(rng, 300, -2.0, 2.0, [&](const Vec3& x) {
    const double s = x.z - p.origin.z;
    return std::abs(p.rate * (x.x - p.origin.x)) < 0.5 && s > p.lo - 0.2 && s < p.hi + 0.2;
  });
  for (const double s : {p.lo, p.lo + 1e-9, p.hi - 1e-9, p.hi, p.hi + 1e-9, p.lo - 1e-9})
    for (const double z : {-0.6, 0.0, 0.5}) points.push_back(p.origin + Vec3(z, 0.3, s));
  EXPECT_TRUE(roundTrips(warp, points));
}

TEST(ExactInverse, BendFindsTheRightPreimageAtLargeAngles) {
  // Bend angles up to nearly π: the closed form returns the preimage on the near side of the
  // centre of curvature.
  BendParams p;
  p.rate = 1.0;
  p.lo = 0.0;
  p.hi = 3.0;
  const BendWarp warp(p);
  std::vector<Vec3> points;
  for (double s = 0.0; s <= 3.0; s += 0.25)
    for (const double z : {-0.5, 0.0, 0.5, 0.9}) points.push_back(Vec3(z, 0.2, s));
  EXPECT_TRUE(roundTrips(warp, points));
}

TEST(ExactInverse, CompositionsRoundTrip) {
  const auto bend = std::make_shared<BendWarp>(bendParams());
  const ComposedWarp twistThenAffine(twist(), affine());
  const ComposedWarp affineThenTaper(affine(), taper());
  const ComposedWarp nested(std::make_shared<ComposedWarp>(taper(), twist()), bend);
  std::mt19937 rng(6);
  const std::vector<Vec3> points = randomPoints(rng, 200, -0.5, 0.5);
  EXPECT_TRUE(roundTrips(twistThenAffine, points));
  EXPECT_TRUE(roundTrips(affineThenTaper, points));
  EXPECT_TRUE(roundTrips(nested, points, 1e-11));
}

TEST(ExactInverse, AWarpWithoutOneFallsBackToNewton) {
  const ComposedWarp mixed(std::make_shared<WobbleWarp>(), twist());
  EXPECT_FALSE(mixed.exactInverse(Vec3(1.0)).has_value());
  const Vec3 x(0.3, 0.2, -0.4);
  const InverseResult r = inverse(mixed, mixed.apply(x));
  ASSERT_TRUE(r.converged);
  EXPECT_GT(r.iterations, 0);
  EXPECT_LT(relativeError(r.x, x), 1e-10);
}

}  // namespace
}  // namespace spacewarp
