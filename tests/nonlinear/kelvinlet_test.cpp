#include <spacewarp/nonlinear/kelvinlet.h>

#include <array>
#include <cmath>
#include <limits>
#include <random>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <spacewarp/core/combinators.h>
#include <spacewarp/core/detail/rotation.h>
#include <spacewarp/core/errors.h>
#include "test_util.h"

namespace spacewarp {
namespace {

using ::testing::HasSubstr;

const Vec3 kCenter(0.5, -1.0, 2.0);

// A brush at kCenter; the helpers below add its own parameters.
KelvinletOptions brush(KelvinletBrush kind, double eps, double nu = 0.45) {
  KelvinletOptions o;
  o.brush = kind;
  o.center = kCenter;
  o.radius = eps;
  o.poisson = nu;
  return o;
}

KelvinletOptions grab(const Vec3& d, double eps = 0.7, double nu = 0.45) {
  KelvinletOptions o = brush(KelvinletBrush::Grab, eps, nu);
  o.displacement = d;
  return o;
}

KelvinletOptions twist(const Vec3& axis, double angle, double eps = 0.7) {
  KelvinletOptions o = brush(KelvinletBrush::Twist, eps);
  o.axis = axis;
  o.angle = angle;
  return o;
}

KelvinletOptions scale(double factor, double eps = 0.7) {
  KelvinletOptions o = brush(KelvinletBrush::Scale, eps);
  o.factor = factor;
  return o;
}

Mat3 pinchMatrix() {
  Mat3 p(0.0);
  p[0][0] = 0.3;
  p[1][1] = -0.1;
  p[2][2] = -0.2;
  p[1][0] = p[0][1] = 0.15;
  p[2][1] = p[1][2] = -0.05;
  return p;
}

KelvinletOptions pinch(const Mat3& m, double eps = 0.7, double nu = 0.45) {
  KelvinletOptions o = brush(KelvinletBrush::Pinch, eps, nu);
  o.matrix = m;
  return o;
}

std::vector<KelvinletOptions> allBrushes() {
  std::vector<KelvinletOptions> all = {grab(Vec3(0.3, -0.2, 0.4)),
                                       grab(Vec3(0.3, -0.2, 0.4), 0.4, 0.0),
                                       grab(Vec3(0.3, -0.2, 0.4), 1.1, 0.5),
                                       twist(Vec3(1.0, 2.0, -0.5), 0.8),
                                       scale(1.4),
                                       scale(0.6, 1.3),
                                       pinch(pinchMatrix()),
                                       pinch(pinchMatrix(), 0.5, 0.5)};
  KelvinletOptions stepped = twist(Vec3(0.0, 0.0, 1.0), 2.0);
  stepped.steps = 5;
  all.push_back(stepped);
  KelvinletOptions steppedGrab = grab(Vec3(1.0, 0.5, 0.0));
  steppedGrab.steps = 4;
  all.push_back(steppedGrab);
  return all;
}

TEST(KelvinletWarp, GrabMovesTheCentreByExactlyTheDisplacement) {
  const Vec3 d(0.3, -0.2, 0.4);
  for (double nu : {0.0, 0.3, 0.45, 0.5}) {
    for (double eps : {0.01, 0.7, 50.0}) {
      const KelvinletWarp warp(grab(d, eps, nu));
      EXPECT_LT(glm::length(warp.apply(kCenter) - (kCenter + d)), 1e-15 * glm::length(kCenter + d))
          << nu << " " << eps;
    }
  }
  KelvinletOptions o = grab(Vec3(2.0, 1.0, 0.0));
  o.steps = 7;
  const KelvinletWarp stepped(o);
  EXPECT_LT(glm::length(stepped.apply(kCenter) - (kCenter + o.displacement)), 1e-14);
}

// Evaluated in units of the radius: any finite radius gives the same brush up to scale (the
// world-unit closed forms overflowed beyond ~1e60: radius 1e150 moved the centre by 0.52 of the
// displacement, radii 1e-160 and 1e200 gave non-finite points).
TEST(KelvinletWarp, ExtremeRadiiKeepTheBrushExact) {
  for (const double eps : {1e-300, 1e-150, 1e150, 1e300}) {
    for (const KelvinletFalloff falloff :
         {KelvinletFalloff::Single, KelvinletFalloff::Bi, KelvinletFalloff::Tri}) {
      KelvinletOptions o = grab(Vec3(1.0, 0.0, 0.0), eps);
      o.center = Vec3(0.0);
      o.falloff = falloff;
      const KelvinletWarp warp(o);
      EXPECT_LT(glm::length(warp.apply(Vec3(0.0)) - Vec3(1.0, 0.0, 0.0)), 1e-15) << eps;
      // The same brush at radius 1, scaled: u(ε y; ε f) = ε u₁(y; f) for a grab (a
      // displacement of ε, so that it is resolved next to ε y; at most 1e150).
      KelvinletOptions one = o;
      one.radius = 1.0;
      const Vec3 y(0.3, -0.7, 1.1);
      if (eps <= 1e150) {
        KelvinletOptions scaled = o;
        scaled.displacement = Vec3(eps, 0.0, 0.0);
        const Vec3 u = (KelvinletWarp(scaled).apply(eps * y) - eps * y) / eps;
        EXPECT_LT(glm::length(u - (KelvinletWarp(one).apply(y) - y)), 1e-14) << eps;
      }
      const Mat3 jg = warp.jacobian(eps * y);
      EXPECT_TRUE(isFinite(jg[0]) && isFinite(jg[1]) && isFinite(jg[2])) << eps;

      KelvinletOptions twist;
      twist.brush = KelvinletBrush::Twist;
      twist.radius = eps;
      twist.angle = 0.5;
      twist.falloff = falloff;
      const KelvinletWarp t(twist);
      const Mat3 j = t.jacobian(Vec3(0.0));
      EXPECT_NEAR(j[0][1], 0.5, 1e-14) << eps;  // I + θ [n]× at the centre
      EXPECT_TRUE(isFinite(t.apply(eps * y))) << eps;
      KelvinletOptions twistOne = twist;
      twistOne.radius = 1.0;
      const Vec3 ut = (t.apply(eps * y) - eps * y) / eps;
      EXPECT_LT(glm::length(ut - (KelvinletWarp(twistOne).apply(y) - y)), 1e-14) << eps;
    }
  }
  // Far away in units of a tiny radius (|r|² overflows): no displacement, nothing non-finite.
  const KelvinletWarp tiny(grab(Vec3(1.0, 0.0, 0.0), 1e-300));
  EXPECT_EQ(tiny.apply(kCenter + Vec3(1.0)), kCenter + Vec3(1.0));
}

// Any finite non-zero axis: |axis|² underflowed for [0, 0, 1e-300] (refused as zero).
TEST(KelvinletWarp, TwistAxisOfAnyFiniteLength) {
  KelvinletOptions o;
  o.brush = KelvinletBrush::Twist;
  o.angle = 0.8;
  o.axis = Vec3(0.0, 0.0, 1.0);
  const Vec3 x(0.3, 0.2, -0.1);
  const Vec3 expected = KelvinletWarp(o).apply(x);
  for (const Vec3& axis : {Vec3(0.0, 0.0, 1e-300), Vec3(0.0, 0.0, 1e300),
                           Vec3(0.0, 0.0, std::numeric_limits<double>::denorm_min())}) {
    o.axis = axis;
    EXPECT_EQ(KelvinletWarp(o).apply(x), expected) << axis.z;
  }
}

TEST(KelvinletWarp, GrabClosedFormOnTheAxis) {
  // On the line through the centre along the force, r = t f̂: u = s ((a − b)/ρ + aε²/(2ρ³) +
  // b t²/ρ³) f with a = 1, b = 1/(4(1 − ν)), s = 2ε/(3a − 2b).
  const double eps = 0.7, nu = 0.3, t = 1.9;
  const Vec3 d(0.0, 0.0, 0.25);
  const KelvinletWarp warp(grab(d, eps, nu));
  const double b = 1.0 / (4.0 * (1.0 - nu));
  const double rho = std::sqrt(t * t + eps * eps);
  const double s = 2.0 * eps / (3.0 - 2.0 * b);
  const double factor =
      s * ((1.0 - b) / rho + eps * eps / (2.0 * rho * rho * rho) + b * t * t / std::pow(rho, 3));
  const Vec3 x = kCenter + Vec3(0.0, 0.0, t);
  EXPECT_NEAR(glm::length(warp.apply(x) - (x + factor * d)), 0.0, 1e-15);
}

TEST(KelvinletWarp, FarFieldDecay) {
  // |u| ~ 1/r for grab, 1/r² for the affine brushes, at distances ≫ ε: doubling r divides |u|
  // by 2 or 4 (to 1e-3: x' − x loses digits to the size of x there).
  const Vec3 dir = glm::normalize(Vec3(0.3, 0.8, -0.5));
  const auto ratio = [&](const KelvinletWarp& w) {
    const Vec3 x1 = kCenter + 1000.0 * dir, x2 = kCenter + 2000.0 * dir;
    return glm::length(w.apply(x1) - x1) / glm::length(w.apply(x2) - x2);
  };
  EXPECT_NEAR(ratio(KelvinletWarp(grab(Vec3(0.3, -0.2, 0.4)))), 2.0, 1e-3);
  EXPECT_NEAR(ratio(KelvinletWarp(twist(Vec3(0.2, 1.0, 0.1), 0.5))), 4.0, 1e-3);
  EXPECT_NEAR(ratio(KelvinletWarp(scale(1.5))), 4.0, 1e-3);
  EXPECT_NEAR(ratio(KelvinletWarp(pinch(pinchMatrix()))), 4.0, 1e-3);
}

TEST(KelvinletWarp, MultiScaleFalloffDecaysFasterAndKeepsTheCentre) {
  // Doubling r divides |u| by 2^k and |J − I| by 2^(k + 1): k = 1, 3, 5 for grab and 2, 4, 6
  // for pinch with single, bi and tri falloff; twist and scale have no ε² term in their far
  // field (ε³/ρ³ + 3ε⁵/(2ρ⁵) = ε³/r³ + O(ε⁷/r⁷)), so bi already gives them k = 6 and tri
  // nothing more. Measured on J − I, which the analytic Jacobian gives without the
  // cancellation of x' − x at large x; at r = 100ε, where the next terms are ~(4ε/r)² of the
  // leading one.
  const Vec3 dir = glm::normalize(Vec3(0.3, 0.8, -0.5));
  const auto ratio = [&](KelvinletOptions o, KelvinletFalloff falloff) {
    o.falloff = falloff;
    o.radius = 1.0;
    const KelvinletWarp w(o);
    return test::frobenius(w.jacobian(kCenter + 100.0 * dir) - Mat3(1.0)) /
           test::frobenius(w.jacobian(kCenter + 200.0 * dir) - Mat3(1.0));
  };
  const KelvinletFalloff kinds[] = {KelvinletFalloff::Single, KelvinletFalloff::Bi,
                                    KelvinletFalloff::Tri};
  const auto expectDecay = [&](const KelvinletOptions& o, std::array<int, 3> k) {
    for (int level = 0; level < 3; ++level) {
      const double expected = std::pow(2.0, k[std::size_t(level)] + 1);
      EXPECT_NEAR(ratio(o, kinds[level]), expected, 0.02 * expected)
          << kelvinletBrushName(o.brush) << " falloff " << level;
    }
  };
  expectDecay(grab(Vec3(0.3, -0.2, 0.4)), {1, 3, 5});
  expectDecay(pinch(pinchMatrix()), {2, 4, 6});
  expectDecay(twist(Vec3(0.2, 1.0, 0.1), 0.5), {2, 6, 6});
  expectDecay(scale(1.5), {2, 6, 6});
  // The centre still does exactly what the parameters say.
  for (KelvinletFalloff f : {KelvinletFalloff::Bi, KelvinletFalloff::Tri}) {
    KelvinletOptions g = grab(Vec3(0.3, -0.2, 0.4));
    g.falloff = f;
    EXPECT_LT(glm::length(KelvinletWarp(g).apply(kCenter) - (kCenter + g.displacement)), 1e-14);
    KelvinletOptions t = twist(Vec3(0.0, 0.0, 1.0), 0.7);
    t.falloff = f;
    EXPECT_LT(test::relativeError(KelvinletWarp(t).jacobian(kCenter),
                                  Mat3(1.0) + 0.7 * detail::crossMatrix(Vec3(0.0, 0.0, 1.0))),
              1e-14);
    KelvinletOptions p = pinch(pinchMatrix());
    p.falloff = f;
    EXPECT_LT(test::relativeError(KelvinletWarp(p).jacobian(kCenter), Mat3(1.0) + pinchMatrix()),
              1e-14);
    // And the Jacobian is still analytic everywhere.
    std::mt19937 rng(15);
    std::vector<Vec3> points = test::randomPoints(rng, 30, -3.0, 3.0);
    for (Vec3& x : points) x += kCenter;
    for (const KelvinletOptions& o : {g, t, p}) {
      EXPECT_TRUE(test::jacobianMatchesFiniteDifferences(KelvinletWarp(o), points, 1e-8))
          << kelvinletBrushName(o.brush);
    }
  }
  EXPECT_EQ(kelvinletFalloffFromName("tri"), KelvinletFalloff::Tri);
  EXPECT_THAT(test::messageOf<InvalidInput>([] { kelvinletFalloffFromName("quad"); }),
              HasSubstr("'quad' is not one of: single, bi, tri"));
}

TEST(KelvinletWarp, JacobianAtTheCentre) {
  const Vec3 axis = glm::normalize(Vec3(1.0, 2.0, -0.5));
  const double angle = 0.8;
  EXPECT_LT(test::relativeError(KelvinletWarp(twist(2.0 * axis, angle)).jacobian(kCenter),
                                Mat3(1.0) + angle * detail::crossMatrix(axis)),
            1e-15);
  // With steps the composition (I + θ/n [n]×)ⁿ approaches the rotation.
  KelvinletOptions o = twist(axis, angle);
  o.steps = 64;
  const Mat3 j = KelvinletWarp(o).jacobian(kCenter);
  Mat3 expected(1.0);
  for (int k = 0; k < 64; ++k)
    expected = (Mat3(1.0) + (angle / 64) * detail::crossMatrix(axis)) * expected;
  EXPECT_LT(test::relativeError(j, expected), 1e-14);
  EXPECT_LT(test::relativeError(glm::transpose(j) * j, Mat3(1.0)), 0.02);
  // The centre itself stays put for the affine brushes.
  EXPECT_EQ(KelvinletWarp(twist(axis, angle)).apply(kCenter), kCenter);
  for (int steps : {1, 3}) {
    KelvinletOptions s = scale(1.7);
    s.steps = steps;
    EXPECT_LT(test::relativeError(KelvinletWarp(s).jacobian(kCenter), Mat3(1.7)), 1e-14) << steps;
  }
  for (double nu : {0.0, 0.45, 0.5}) {
    EXPECT_LT(test::relativeError(KelvinletWarp(pinch(pinchMatrix(), 0.7, nu)).jacobian(kCenter),
                                  Mat3(1.0) + pinchMatrix()),
              1e-15)
        << nu;
  }
  // Grab: the gradient at the centre, ∇u(0) = 0 (the displacement is stationary there).
  EXPECT_LT(
      test::relativeError(KelvinletWarp(grab(Vec3(1.0, 2.0, 3.0))).jacobian(kCenter), Mat3(1.0)),
      1e-15);
}

TEST(KelvinletWarp, ScaleAndPinchMoveTheNeighbourhoodLinearly) {
  // A small offset h from the centre moves to about factor · h (scale) or (I + P) h (pinch).
  const Vec3 h(1e-4, -2e-4, 1.5e-4);
  const KelvinletWarp s(scale(1.3));
  EXPECT_LT(glm::length(s.apply(kCenter + h) - (kCenter + 1.3 * h)), 1e-10);
  const KelvinletWarp p(pinch(pinchMatrix()));
  EXPECT_LT(glm::length(p.apply(kCenter + h) - (kCenter + h + pinchMatrix() * h)), 1e-10);
}

TEST(KelvinletWarp, IncompressibleDisplacementIsDivergenceFree) {
  // At ν = 0.5 grab and pinch displacements are divergence-free (twist always): tr(J − I) = 0.
  // At ν < 0.5 grab compresses on one side and expands on the other.
  std::mt19937 rng(11);
  const std::vector<Vec3> points = test::randomPoints(rng, 50, -2.0, 2.0);
  for (const KelvinletOptions& o : {grab(Vec3(0.5, -0.3, 0.2), 0.8, 0.5),
                                    pinch(pinchMatrix(), 0.8, 0.5), twist(Vec3(1, 1, 0), 1.0)}) {
    const KelvinletWarp warp(o);
    for (const Vec3& x : points) {
      const Mat3 fd = test::finiteDifferenceJacobian(warp, kCenter + x);
      EXPECT_NEAR(fd[0][0] + fd[1][1] + fd[2][2] - 3.0, 0.0, 1e-9)
          << kelvinletBrushName(o.brush) << " at " << test::toString(x);
    }
  }
  const KelvinletWarp compressible(grab(Vec3(0.5, -0.3, 0.2), 0.8, 0.2));
  const Mat3 j = compressible.jacobian(kCenter + Vec3(0.5, -0.3, 0.2));
  EXPECT_GT(std::abs(j[0][0] + j[1][1] + j[2][2] - 3.0), 1e-3);
}

TEST(KelvinletWarp, ZeroEditIsTheIdentity) {
  std::mt19937 rng(12);
  const std::vector<Vec3> points = test::randomPoints(rng, 50, -3.0, 3.0);
  EXPECT_TRUE(test::leavesPointsUnchanged(KelvinletWarp(grab(Vec3(0.0))), points));
  EXPECT_TRUE(test::leavesPointsUnchanged(KelvinletWarp(twist(Vec3(0, 1, 0), 0.0)), points));
  EXPECT_TRUE(test::leavesPointsUnchanged(KelvinletWarp(scale(1.0)), points));
  EXPECT_TRUE(test::leavesPointsUnchanged(KelvinletWarp(pinch(Mat3(0.0))), points));
}

TEST(KelvinletWarp, JacobianMatchesFiniteDifferencesEverywhere) {
  std::mt19937 rng(13);
  std::vector<Vec3> points = test::randomPoints(rng, 40, -3.0, 3.0);
  for (Vec3& x : points) x += kCenter;
  points.push_back(kCenter);
  points.push_back(kCenter + Vec3(1e-3, 0.0, 0.0));
  points.push_back(kCenter + Vec3(40.0, -20.0, 10.0));
  for (const KelvinletOptions& o : allBrushes()) {
    const KelvinletWarp warp(o);
    EXPECT_TRUE(test::jacobianMatchesFiniteDifferences(warp, points, 1e-8))
        << kelvinletBrushName(o.brush) << " steps " << o.steps << " nu " << o.poisson;
  }
}

TEST(KelvinletWarp, BatchesAreDeterministicAndNormalsAndInverseWork) {
  std::mt19937 rng(14);
  std::vector<Vec3> points = test::randomPoints(rng, 20000, -2.0, 2.0);
  for (const KelvinletOptions& o : allBrushes()) {
    const KelvinletWarp warp(o);
    EXPECT_TRUE(test::batchIsDeterministic(warp, points)) << kelvinletBrushName(o.brush);
  }
  // Moderate brushes do not fold: inverse and normals.
  const std::vector<Vec3> some(points.begin(), points.begin() + 30);
  for (const KelvinletOptions& o :
       {grab(Vec3(0.2, 0.1, 0.0)), twist(Vec3(0, 0, 1), 0.5), scale(1.2), pinch(pinchMatrix())}) {
    const KelvinletWarp warp(o);
    EXPECT_TRUE(test::inverseRecovers(warp, some)) << kelvinletBrushName(o.brush);
    EXPECT_TRUE(test::normalsStayPerpendicular(warp, some, rng)) << kelvinletBrushName(o.brush);
  }
}

TEST(KelvinletWarp, BrushesComposeWithComposedWarp) {
  auto g = std::make_shared<KelvinletWarp>(grab(Vec3(0.3, 0.0, 0.0)));
  auto t = std::make_shared<KelvinletWarp>(twist(Vec3(0, 0, 1), 0.4));
  const ComposedWarp both(g, t);
  const Vec3 x = kCenter + Vec3(0.4, 0.2, -0.1);
  EXPECT_EQ(both.apply(x), t->apply(g->apply(x)));
  EXPECT_LT(test::relativeError(both.jacobian(x), t->jacobian(g->apply(x)) * g->jacobian(x)),
            1e-14);
}

TEST(KelvinletWarp, RejectsBadParameters) {
  const double nan = std::nan("");
  const double inf = std::numeric_limits<double>::infinity();
  const auto message = [](const KelvinletOptions& o) {
    return test::messageOf<InvalidInput>([&] { KelvinletWarp w(o); });
  };
  for (double eps : {0.0, -1.0, nan, inf})
    EXPECT_THAT(message(grab(Vec3(1.0), eps)), HasSubstr("KelvinletWarp: radius must be"));
  for (double nu : {-0.1, 0.51, nan, 1.0})
    EXPECT_THAT(message(grab(Vec3(1.0), 1.0, nu)), HasSubstr("poisson must be in [0, 0.5]"));
  EXPECT_THAT(message(grab(Vec3(nan, 0.0, 0.0))), HasSubstr("displacement must be finite"));
  KelvinletOptions o = grab(Vec3(1.0));
  o.center = Vec3(inf, 0.0, 0.0);
  EXPECT_THAT(message(o), HasSubstr("center must be finite"));
  o.center = Vec3(0.0, 0.0, 1e200);  // the centre plus a displacement could overflow
  EXPECT_THAT(message(o), HasSubstr("center must be finite and within 1e150"));
  EXPECT_THAT(message(grab(Vec3(0.0, -1e308, 0.0))),
              HasSubstr("displacement must be finite and within 1e150"));
  EXPECT_THAT(message(twist(Vec3(0.0), 1.0)), HasSubstr("axis must be finite and non-zero"));
  EXPECT_THAT(message(twist(Vec3(nan, 1.0, 0.0), 1.0)), HasSubstr("axis must be"));
  EXPECT_THAT(message(twist(Vec3(1.0), nan)), HasSubstr("angle must be finite"));
  for (double f : {0.0, -1.0, nan, inf})
    EXPECT_THAT(message(scale(f)), HasSubstr("factor must be finite and > 0"));
  Mat3 asym = pinchMatrix();
  asym[1][0] += 0.1;
  EXPECT_THAT(message(pinch(asym)), HasSubstr("matrix must be symmetric"));
  EXPECT_THAT(message(pinch(Mat3(1.0))), HasSubstr("matrix must be traceless"));
  Mat3 bad = pinchMatrix();
  bad[2][2] = nan;
  EXPECT_THAT(message(pinch(bad)), HasSubstr("matrix must be finite"));
  for (int steps : {0, -3, 10001}) {
    KelvinletOptions s = scale(1.1);
    s.steps = steps;
    EXPECT_THAT(message(s), HasSubstr("steps must be in 1..10000"));
  }
  EXPECT_EQ(kelvinletBrushFromName("pinch"), KelvinletBrush::Pinch);
  EXPECT_THAT(test::messageOf<InvalidInput>([] { kelvinletBrushFromName("smear"); }),
              HasSubstr("'smear' is not one of: grab, twist, scale, pinch"));
}

}  // namespace
}  // namespace spacewarp
