#include <spacewarp/nonlinear/shepard.h>

#include <cmath>
#include <limits>
#include <memory>
#include <random>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <spacewarp/coords/properties.h>
#include <spacewarp/core/binding.h>
#include <spacewarp/core/coordinate_warp.h>
#include <spacewarp/core/errors.h>
#include "test_util.h"

namespace spacewarp {
namespace {

using ::testing::HasSubstr;

using Rig = test::HandleRig;
constexpr auto randomRig = test::randomHandleRig;

ShepardOptions withPower(double power, double radius = std::numeric_limits<double>::infinity()) {
  ShepardOptions o;
  o.power = power;
  o.radius = radius;
  return o;
}

std::vector<double> weightsOf(const Coordinates& c, const Vec3& x) {
  std::vector<double> row(c.columnCount());
  c.weights(x, row);
  return row;
}

// Every point of [-2, 2]³ has a handle within the radius 1: a 5 × 5 × 5 grid of spacing 1.
std::vector<Vec3> gridHandles() {
  std::vector<Vec3> h;
  for (int i = -2; i <= 2; ++i)
    for (int j = -2; j <= 2; ++j)
      for (int k = -2; k <= 2; ++k) h.emplace_back(i, j, k);
  return h;
}

TEST(ShepardCoordinates, InterpolatesTheHandles) {
  std::mt19937 rng(1);
  const Rig rig = randomRig(rng, 12);
  for (const ShepardOptions& o : {withPower(2.0), withPower(0.7), withPower(3.5, 1.5)}) {
    auto coords = std::make_shared<ShepardCoordinates>(rig.handles, o);
    const auto warp = makeWarp(coords, rig.targets);
    for (std::size_t i = 0; i < rig.handles.size(); ++i) {
      const std::vector<double> w = weightsOf(*coords, rig.handles[i]);
      for (std::size_t j = 0; j < w.size(); ++j) EXPECT_EQ(w[j], i == j ? 1.0 : 0.0);
      EXPECT_EQ(warp->apply(rig.handles[i]), rig.targets[i]) << "handle " << i;
    }
  }
}

TEST(ShepardCoordinates, PartitionOfUnityAndNonNegative) {
  std::mt19937 rng(2);
  const Rig rig = randomRig(rng, 20);
  const std::vector<Vec3> samples = test::randomPoints(rng, 500, -2.0, 2.0);
  for (const ShepardOptions& o : {withPower(2.0), withPower(1.0), withPower(0.5)}) {
    const ShepardCoordinates coords(rig.handles, o);
    const PropertyReport report = measureProperties(coords, samples, 2.0 * std::sqrt(3.0));
    EXPECT_LE(report.partitionOfUnity, 1e-12) << o.power;
    EXPECT_GE(report.minWeight, 0.0) << o.power;
    // Not linearly precise (Shepard's known flaw): Σ w_i p_i differs from x by a fair fraction
    // of the handles' spread.
    EXPECT_GT(report.linearReproduction, 1e-2) << o.power;
  }
  // Also near and far, where the weights would underflow or overflow if not normalised.
  const ShepardCoordinates coords(rig.handles);
  for (const Vec3& x : {rig.handles[3] + Vec3(1e-200, 0.0, 0.0), Vec3(1e200, -3e199, 2e199),
                        Vec3(1e-300, 0.0, 0.0)}) {
    const std::vector<double> w = weightsOf(coords, x);
    double sum = 0.0;
    for (double v : w) {
      EXPECT_TRUE(std::isfinite(v) && v >= 0.0);
      sum += v;
    }
    EXPECT_NEAR(sum, 1.0, 1e-12) << test::toString(x);
  }
  EXPECT_NEAR(weightsOf(coords, rig.handles[3] + Vec3(1e-200, 0.0, 0.0))[3], 1.0, 1e-15);
  // Far away every handle weighs about the same.
  for (double v : weightsOf(coords, Vec3(1e200, -3e199, 2e199))) EXPECT_NEAR(v, 1.0 / 20, 1e-12);
}

TEST(ShepardCoordinates, ClosedFormForTwoHandles) {
  // Between two handles at distances a and b: w_0 = b^p / (a^p + b^p).
  const ShepardCoordinates coords({Vec3(0.0), Vec3(1.0, 0.0, 0.0)}, withPower(3.0));
  const std::vector<double> w = weightsOf(coords, Vec3(0.25, 0.0, 0.0));
  const double a = std::pow(0.25, 3.0), b = std::pow(0.75, 3.0);
  EXPECT_NEAR(w[0], b / (a + b), 1e-15);
  EXPECT_NEAR(w[1], a / (a + b), 1e-15);
}

TEST(ShepardCoordinates, GradientsMatchFiniteDifferences) {
  std::mt19937 rng(3);
  const Rig rig = randomRig(rng, 10);
  for (const ShepardOptions& o :
       {withPower(2.0), withPower(1.3), withPower(0.8), withPower(2.5, 1.2)}) {
    const ShepardCoordinates coords(rig.handles, o);
    const std::vector<Vec3> points =
        test::randomPointsWhere(rng, 40, -1.2, 1.2, [&](const Vec3& x) {
          for (const Vec3& p : rig.handles)
            if (glm::length(x - p) < 0.05) return false;
          std::vector<double> w(rig.handles.size());
          // Away from every support's edge, where the local weights are not smooth for small p.
          for (const Vec3& p : rig.handles)
            if (std::abs(glm::length(x - p) - o.radius) < 0.05) return false;
          try {
            coords.weights(x, w);
          } catch (const InvalidInput&) {
            return false;
          }
          return true;
        });
    std::vector<Vec3> g(rig.handles.size());
    const double h = 1e-5;
    for (const Vec3& x : points) {
      ASSERT_TRUE(coords.weightGradients(x, g));
      for (int axis = 0; axis < 3; ++axis) {
        Vec3 e(0.0);
        e[axis] = h;
        const std::vector<double> plus = weightsOf(coords, x + e);
        const std::vector<double> minus = weightsOf(coords, x - e);
        for (std::size_t i = 0; i < g.size(); ++i)
          EXPECT_NEAR(g[i][axis], (plus[i] - minus[i]) / (2 * h),
                      1e-6 * std::max(1.0, std::abs(g[i][axis])))
              << "power " << o.power << " handle " << i << " at " << test::toString(x);
      }
    }
    const ShepardWarp warp(rig.handles, rig.targets, o);
    EXPECT_TRUE(test::jacobianMatchesFiniteDifferences(warp, points, 1e-6)) << o.power;
  }
}

TEST(ShepardWarp, JacobianIsTheIdentityAtEveryHandleForPowerAboveOne) {
  // The flat spots: ∇w_i(p_j) = 0 for p > 1, so the warp does not stretch at a handle whatever
  // the targets (here a strong scale of the handles).
  std::mt19937 rng(4);
  const Rig rig = randomRig(rng, 8);
  std::vector<Vec3> scaled;
  for (const Vec3& p : rig.handles) scaled.push_back(3.0 * p);
  for (double power : {1.5, 2.0, 4.0}) {
    const ShepardWarp warp(rig.handles, scaled, withPower(power));
    for (const Vec3& p : rig.handles) {
      EXPECT_EQ(warp.jacobian(p), Mat3(1.0)) << power;
      // And the limit agrees: just off the handle the Jacobian is close to the identity (it
      // differs by O(d^(p − 1))).
      const Mat3 near = warp.jacobian(p + Vec3(1e-12, 0.0, 0.0));
      EXPECT_LT(test::relativeError(near, Mat3(1.0)), 1e-4) << power;
    }
  }
  // For p <= 1 the weights have cusps at the handles: no analytic gradient there.
  const ShepardCoordinates cusp(rig.handles, withPower(1.0));
  std::vector<Vec3> g(rig.handles.size());
  EXPECT_FALSE(cusp.weightGradients(rig.handles[0], g));
}

TEST(ShepardWarp, ReproducesTranslationsButNotScales) {
  std::mt19937 rng(5);
  const Rig rig = randomRig(rng, 15);
  const Vec3 t(0.3, -1.2, 2.0);
  std::vector<Vec3> moved, scaled;
  for (const Vec3& p : rig.handles) {
    moved.push_back(p + t);
    scaled.push_back(2.0 * p);
  }
  const ShepardWarp translation(rig.handles, moved);
  const ShepardWarp scale(rig.handles, scaled);
  double worst = 0.0;
  for (const Vec3& x : test::randomPoints(rng, 200, -1.5, 1.5)) {
    EXPECT_LT(glm::length(translation.apply(x) - (x + t)), 1e-14);
    worst = std::max(worst, glm::length(scale.apply(x) - 2.0 * x));
  }
  EXPECT_GT(worst, 0.1);  // no linear precision
}

TEST(ShepardCoordinates, LocalSupportIsZeroBeyondTheRadius) {
  const std::vector<Vec3> handles = gridHandles();
  const double radius = 1.0;
  const ShepardCoordinates coords(handles, withPower(2.0, radius));
  EXPECT_TRUE(coords.local());
  EXPECT_LT(coords.maxNonZeros(), handles.size());
  std::mt19937 rng(6);
  std::vector<SparseWeight> sparse(coords.maxNonZeros());
  for (const Vec3& x : test::randomPoints(rng, 300, -2.0, 2.0)) {
    const std::vector<double> w = weightsOf(coords, x);
    double sum = 0.0;
    for (std::size_t i = 0; i < handles.size(); ++i) {
      if (glm::length(x - handles[i]) >= radius) {
        EXPECT_EQ(w[i], 0.0);
      }
      EXPECT_GE(w[i], 0.0);
      sum += w[i];
    }
    EXPECT_NEAR(sum, 1.0, 1e-12);
    // The sparse row holds the same non-zero weights.
    const std::size_t count = coords.sparseWeights(x, sparse);
    std::size_t nonZero = 0;
    for (double v : w) nonZero += v != 0.0;
    ASSERT_EQ(count, nonZero);
    for (std::size_t k = 0; k < count; ++k) EXPECT_EQ(sparse[k].weight, w[sparse[k].column]);
  }
  // Closed form with two handles in reach: ((R − d)/(R d))^p.
  const ShepardCoordinates two({Vec3(0.0), Vec3(1.0, 0.0, 0.0)}, withPower(2.0, 0.8));
  const std::vector<double> w = weightsOf(two, Vec3(0.3, 0.0, 0.0));
  const double u0 = std::pow((0.8 - 0.3) / (0.8 * 0.3), 2.0);
  const double u1 = std::pow((0.8 - 0.7) / (0.8 * 0.7), 2.0);
  EXPECT_NEAR(w[0], u0 / (u0 + u1), 1e-15);
}

// maxNonZeros() bounds every point's non-zeros; a radius covering every handle gives n (it was
// found by a radius search around each handle: O(n²) when R covers them all).
TEST(ShepardCoordinates, MaxNonZerosBoundsEveryRowAndIsNWhenTheRadiusCoversAll) {
  std::mt19937 rng(16);
  const std::vector<Vec3> handles = test::randomPoints(rng, 400, 0.0, 1.0);
  for (const double radius : {0.15, 0.4, 10.0}) {
    const ShepardCoordinates coords(handles, withPower(2.0, radius));
    if (radius == 10.0) {
      EXPECT_EQ(coords.maxNonZeros(), handles.size());
    }
    std::size_t most = 0;
    for (std::size_t h = 0; h < handles.size(); h += 3) {
      const std::vector<double> w = weightsOf(coords, handles[h] + Vec3(0.01, -0.02, 0.01));
      std::size_t nonZero = 0;
      for (const double v : w) nonZero += v != 0.0 ? 1 : 0;
      most = std::max(most, nonZero);
    }
    EXPECT_LE(most, coords.maxNonZeros()) << radius;
    EXPECT_GT(most, 0u);
  }
}

TEST(ShepardCoordinates, LocalWeightsMatchABruteForceSum) {
  // The grid that finds the handles within reach, against the formula over every handle: with
  // cells of the radius (dense handles) and of 1/64 of the extent (sparse handles, radius much
  // smaller than their spread).
  std::mt19937 rng(9);
  for (const auto& [spread, radius] : {std::pair{1.0, 0.3}, std::pair{100.0, 0.7}}) {
    const std::vector<Vec3> handles = test::randomPoints(rng, 3000, -spread, spread);
    const double power = 1.5;
    const ShepardCoordinates coords(handles, withPower(power, radius));
    std::size_t checked = 0;
    for (std::size_t t = 0; t < 400; ++t) {
      // Points within reach of handle t.
      const Vec3 x = handles[t] + test::randomPoint(rng, -0.5 * radius, 0.5 * radius);
      std::vector<double> u(handles.size(), 0.0);
      double sum = 0.0;
      for (std::size_t i = 0; i < handles.size(); ++i) {
        const double d = glm::length(x - handles[i]);
        if (d < radius) u[i] = std::pow((radius - d) / (radius * d), power);
        sum += u[i];
      }
      if (sum == 0.0) continue;
      const std::vector<double> w = weightsOf(coords, x);
      for (std::size_t i = 0; i < handles.size(); ++i)
        ASSERT_NEAR(w[i], u[i] / sum, 1e-13) << "spread " << spread << " handle " << i;
      ++checked;
    }
    EXPECT_EQ(checked, 400u);
  }
}

TEST(ShepardCoordinates, PointsOutsideEverySupportAreReportedNotGuessed) {
  const std::vector<Vec3> handles = {Vec3(0.0), Vec3(1.0, 0.0, 0.0)};
  auto coords = std::make_shared<ShepardCoordinates>(handles, withPower(2.0, 0.5));
  const Vec3 outside(0.5, 2.0, 0.0);
  std::vector<double> row(2);
  EXPECT_THAT(test::messageOf<InvalidInput>([&] { coords->weights(outside, row); }),
              HasSubstr("farther than the radius"));
  const auto warp = makeWarp(coords, std::vector<Vec3>{Vec3(0.0, 1.0, 0.0), Vec3(1.0)});
  EXPECT_THAT(test::messageOf<InvalidInput>([&] { warp->apply(outside); }),
              HasSubstr("ShepardWarp: the point (0.5, 2, 0)"));
  const std::vector<Vec3> batch = {Vec3(0.1, 0.0, 0.0), outside, Vec3(5.0), Vec3(0.9, 0.0, 0.0)};
  std::vector<Vec3> out(batch.size());
  EXPECT_THAT(test::messageOf<InvalidInput>([&] { warp->applyBatch(batch, out); }),
              HasSubstr("2 of 4 points are farther than the radius 0.5"));
  EXPECT_THAT(test::messageOf<InvalidInput>([&] { warp->applyBatch(batch, out); }),
              HasSubstr("the first is point 1"));
  std::vector<double> rows(batch.size() * 2);
  EXPECT_THAT(test::messageOf<InvalidInput>([&] { coords->weightsBatch(batch, rows); }),
              HasSubstr("ShepardCoordinates: 2 of 4 points"));
}

TEST(ShepardWarp, MatchesCoordinateWarpAndBindingAndIsDeterministic) {
  std::mt19937 rng(7);
  const Rig rig = randomRig(rng, 16);
  for (const ShepardOptions& o : {withPower(2.0), withPower(1.7, 1.5)}) {
    auto coords = std::make_shared<ShepardCoordinates>(rig.handles, o);
    const auto warp = makeWarp(coords, rig.targets);
    ASSERT_NE(dynamic_cast<const ShepardWarp*>(warp.get()), nullptr);
    const CoordinateWarp generic(coords, rig.targets);
    const std::vector<Vec3> points = test::randomPoints(rng, 5000, -0.6, 0.6);
    for (std::size_t i = 0; i < 200; ++i)
      EXPECT_TRUE(test::bitEqual(warp->apply(points[i]), generic.apply(points[i])));
    EXPECT_TRUE(test::batchIsDeterministic(*warp, points));
    const Binding binding(coords, points);
    std::vector<Vec3> bound(points.size()), direct(points.size());
    binding.deform(rig.targets, bound);
    warp->applyBatch(points, direct);
    for (std::size_t i = 0; i < points.size(); ++i)
      EXPECT_LT(glm::length(bound[i] - direct[i]), 1e-13);
  }
}

TEST(ShepardWarp, InverseAndNormals) {
  std::mt19937 rng(8);
  Rig rig = randomRig(rng, 10);
  for (std::size_t i = 0; i < rig.targets.size(); ++i)
    rig.targets[i] = rig.handles[i] + 0.3 * (rig.targets[i] - rig.handles[i]);
  const ShepardWarp warp(rig.handles, rig.targets);
  const std::vector<Vec3> points = test::randomPoints(rng, 30, -1.0, 1.0);
  EXPECT_TRUE(test::inverseRecovers(warp, points));
  EXPECT_TRUE(test::normalsStayPerpendicular(warp, points, rng));
}

TEST(ShepardCoordinates, RejectsBadParameters) {
  const std::vector<Vec3> h = {Vec3(0.0), Vec3(1.0, 0.0, 0.0), Vec3(0.0, 1.0, 0.0)};
  const auto message = [](auto&& make) { return test::messageOf<InvalidInput>(make); };
  for (double p : {0.0, -1.0, std::nan(""), std::numeric_limits<double>::infinity()}) {
    EXPECT_THAT(message([&] { ShepardCoordinates c(h, withPower(p)); }),
                HasSubstr("ShepardCoordinates: power must be finite and > 0"));
  }
  for (double r : {0.0, -2.0, std::nan(""), 1e200}) {
    EXPECT_THAT(message([&] { ShepardCoordinates c(h, withPower(2.0, r)); }),
                HasSubstr("ShepardCoordinates: radius must be > 0"));
  }
  EXPECT_THAT(message([&] { ShepardCoordinates c({}); }), HasSubstr("needs at least 1 handle"));
  EXPECT_THAT(message([&] {
                ShepardCoordinates c({Vec3(0.0), Vec3(1.0), Vec3(2.0), Vec3(1.0 + 1e-15)});
              }),
              HasSubstr("handles 1 and 3 coincide"));
  EXPECT_THAT(message([&] {
                ShepardCoordinates c({Vec3(2.0), Vec3(2.0)});
              }),
              HasSubstr("handles 0 and 1 coincide"));
  EXPECT_THAT(message([&] {
                ShepardCoordinates c({Vec3(0.0), Vec3(std::nan(""))});
              }),
              HasSubstr("handle 1 is not finite"));
  EXPECT_THAT(message([&] { ShepardWarp w(h, std::vector<Vec3>(2)); }),
              HasSubstr("3 handles but 2 targets"));
  EXPECT_THAT(message([&] {
                ShepardWarp w(h, std::vector<Vec3>{Vec3(0.0), Vec3(std::nan("")), Vec3(0.0)});
              }),
              HasSubstr("target 1 is not finite"));
  // One handle is enough: everything moves with it.
  const ShepardWarp one({Vec3(1.0)}, std::vector<Vec3>{Vec3(2.0)});
  EXPECT_EQ(one.apply(Vec3(5.0, 0.0, 0.0)), Vec3(6.0, 1.0, 1.0));
}

}  // namespace
}  // namespace spacewarp
