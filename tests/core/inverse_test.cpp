#include <spacewarp/core/inverse.h>

#include <cmath>
#include <limits>
#include <memory>
#include <optional>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <tbb/task_arena.h>

#include <spacewarp/core/bend.h>
#include <spacewarp/core/combinators.h>
#include <spacewarp/core/errors.h>
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
  TwistOptions p;
  p.origin = Vec3(0.3, -0.2, 0.1);
  p.axis = Vec3(0.2, 0.1, 1.0);
  p.rate = 1.3;
  p.lo = -1.0;
  p.hi = 1.5;
  return std::make_shared<TwistWarp>(p);
}

std::shared_ptr<const Warp> taper() {
  TaperOptions p;
  p.axis = Vec3(1.0, 0.2, 0.0);
  p.rate = 0.4;
  p.lo = -1.0;
  p.hi = 1.0;
  return std::make_shared<TaperWarp>(p);
}

BendOptions bendParams() {
  BendOptions p;
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
    if (!r.converged || !r.closedForm || r.iterations != 0 || !(error <= tolerance)) {
      return ::testing::AssertionFailure()
             << "x = " << test::toString(x) << ": converged " << r.converged << ", closed form "
             << r.closedForm << ", iterations " << r.iterations << ", error " << error;
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
  TaperOptions p;
  p.rate = -1.0;
  const TaperWarp collapsing(p);
  EXPECT_FALSE(collapsing.exactInverse(Vec3(0.0, 0.0, 1.0)).has_value());
}

TEST(ExactInverse, BendRoundTripsIncludingNearTheEndsOfItsRange) {
  const BendOptions p = bendParams();
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
  // center of curvature.
  BendOptions p;
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

// A rotation by 1 rad about z inside the box |x|_inf <= 1, the identity outside: a jump at the
// box's faces, like a lattice whose face controls moved (outside = identity).
class RotationInABox final : public Warp {
 public:
  Vec3 apply(const Vec3& x) const override { return inside(x) ? rotate(x) : x; }
  static bool inside(const Vec3& x) { return maxAbs(x) <= 1.0; }
  static Vec3 rotate(const Vec3& x) {
    return Vec3(std::cos(1.0) * x.x - std::sin(1.0) * x.y,
                std::sin(1.0) * x.x + std::cos(1.0) * x.y, x.z);
  }
};

// Where the reflected seed y - (warp(y) - y) falls outside the box, Newton from it stalls at the
// jump; without a seed from the caller inverse() then starts again from y, and converges.
TEST(Inverse, AfterAFailedDefaultSeedTriesTheTargetItself) {
  const RotationInABox warp;
  std::mt19937 rng(11);
  InverseOptions options;
  options.continuation = false;  // the second seed alone
  std::size_t outsideSeeds = 0;
  for (const Vec3& x : randomPoints(rng, 200, -0.6, 0.6)) {
    const Vec3 y = warp.apply(x);
    if (!RotationInABox::inside(y - (warp.apply(y) - y))) ++outsideSeeds;
    const InverseResult r = inverse(warp, y, options);
    ASSERT_TRUE(r.converged) << test::toString(x);
    EXPECT_LT(glm::length(r.x - x), 1e-12) << test::toString(x);
  }
  EXPECT_GT(outsideSeeds, 20u) << "the case this test is about";
}

// A twist whose closed form is off by 1e-6: inverse() measures the residual, finds it above the
// tolerance, and lets Newton finish from there.
class SloppyTwist final : public Warp {
 public:
  explicit SloppyTwist(std::shared_ptr<const Warp> twist) : twist_(std::move(twist)) {}
  Vec3 apply(const Vec3& x) const override { return twist_->apply(x); }
  Mat3 jacobian(const Vec3& x) const override { return twist_->jacobian(x); }
  std::optional<Vec3> exactInverse(const Vec3& y) const override {
    return *twist_->exactInverse(y) + Vec3(1e-6, 0.0, 0.0);
  }

 private:
  std::shared_ptr<const Warp> twist_;
};

TEST(ExactInverse, AClosedFormAboveTheToleranceSeedsNewton) {
  const SloppyTwist warp(twist());
  std::mt19937 rng(8);
  for (const Vec3& x : randomPoints(rng, 20, -1.0, 1.0)) {
    const InverseResult r = inverse(warp, warp.apply(x));
    EXPECT_TRUE(r.converged);
    EXPECT_FALSE(r.closedForm);
    EXPECT_GT(r.iterations, 0);
    EXPECT_LT(glm::length(r.x - x), 1e-11);
  }
}

// inverseBatch() is inverse() of each point, bit for bit, with one thread or many.
TEST(InverseBatch, IsInverseOfEachPointForAnyThreadCount) {
  const WobbleWarp wobble;
  const std::shared_ptr<const Warp> closedForm = twist();
  std::mt19937 rng(9);
  const std::vector<Vec3> targets = randomPoints(rng, 3000, -3.0, 3.0);
  for (const Warp* warp : {static_cast<const Warp*>(&wobble), closedForm.get()}) {
    std::vector<InverseResult> many(targets.size()), one(targets.size());
    inverseBatch(*warp, targets, many);
    tbb::task_arena(1).execute([&] { inverseBatch(*warp, targets, one); });
    for (std::size_t i = 0; i < targets.size(); ++i) {
      const InverseResult expected = inverse(*warp, targets[i]);
      ASSERT_TRUE(test::bitEqual(many[i].x, expected.x)) << i;
      ASSERT_TRUE(test::bitEqual(one[i].x, expected.x)) << i;
      EXPECT_EQ(many[i].converged, expected.converged) << i;
      EXPECT_EQ(many[i].closedForm, warp == closedForm.get()) << i;
      EXPECT_EQ(many[i].residual, expected.residual) << i;
    }
  }
}

TEST(InverseBatch, RejectsMismatchedSizesAndNonFiniteTargets) {
  const WobbleWarp warp;
  std::vector<Vec3> targets(4, Vec3(0.5));
  std::vector<InverseResult> results(3);
  EXPECT_THROW(inverseBatch(warp, targets, results), InvalidInput);
  results.resize(4);
  targets[2].z = std::numeric_limits<double>::infinity();
  EXPECT_NE(
      test::messageOf<InvalidInput>([&] { inverseBatch(warp, targets, results); }).find("point 2 "),
      std::string::npos);
}

// The inverse's normal rule undoes the warp's: J^T (J^-T n normalised), normalised, is n, at any
// scale of J; where J^T n vanishes the result is zero, never NaN.
TEST(TransformNormalByInverse, UndoesTransformNormal) {
  std::mt19937 rng(10);
  std::uniform_real_distribution<double> u(-2.0, 2.0);
  for (int k = 0; k < 200; ++k) {
    Mat3 j;
    for (int c = 0; c < 3; ++c) j[c] = Vec3(u(rng), u(rng), u(rng));
    if (isSingularJacobian(j) || std::abs(glm::determinant(j)) < 1e-3) continue;
    const Vec3 n = test::randomUnit(rng);
    for (const double scale : {1e-300, 1.0, 1e300}) {
      const Vec3 back = transformNormalByInverse(scale * j, transformNormal(scale * j, n));
      EXPECT_LT(glm::length(back - n), 1e-9) << test::toString(j) << " scale " << scale;
    }
  }
  const Mat3 flatten(Vec3(1, 0, 0), Vec3(0, 1, 0), Vec3(0.0));
  EXPECT_EQ(transformNormalByInverse(flatten, Vec3(0, 0, 1)), Vec3(0.0));
}

}  // namespace
}  // namespace spacewarp
