#include <spacewarp/nonlinear/mls.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <random>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <spacewarp/coords/properties.h>
#include <spacewarp/core/binding.h>
#include <spacewarp/core/errors.h>
#include "placement.h"
#include "test_util.h"

namespace spacewarp {
namespace {

using ::testing::HasSubstr;

constexpr MlsMode kModes[] = {MlsMode::Affine, MlsMode::Similarity, MlsMode::Rigid};

using test::rotation;

using Rig = test::HandleRig;
constexpr auto randomRig = test::randomHandleRig;

// Points in [-1.5, 1.5)^3 at least `gap` from every handle.
std::vector<Vec3> pointsAwayFrom(std::mt19937& rng, const std::vector<Vec3>& handles, std::size_t n,
                                 double gap) {
  return test::randomPointsWhere(rng, n, -1.5, 1.5, [&](const Vec3& x) {
    for (const Vec3& p : handles)
      if (glm::length(x - p) < gap) return false;
    return true;
  });
}

MlsOptions optionsFor(MlsMode mode, double alpha = 1.0) {
  MlsOptions o;
  o.mode = mode;
  o.alpha = alpha;
  return o;
}

TEST(MlsWarp, DefaultsAreRigidWithAlphaOne) {
  const MlsOptions o;
  EXPECT_EQ(o.mode, MlsMode::Rigid);
  EXPECT_EQ(o.alpha, 1.0);
}

TEST(MlsWarp, ModeNamesRoundTrip) {
  for (MlsMode mode : kModes) EXPECT_EQ(mlsModeFromName(mlsModeName(mode)), mode);
  EXPECT_THAT(test::messageOf<InvalidInput>([] { mlsModeFromName("rigidd"); }),
              HasSubstr("'rigidd' is not one of: affine, similarity, rigid"));
}

TEST(MlsWarp, InterpolatesTheHandlesInEveryMode) {
  std::mt19937 rng(1);
  for (MlsMode mode : kModes) {
    for (double alpha : {0.5, 1.0, 2.0}) {
      const Rig rig = randomRig(rng, 10);
      const MlsWarp warp(rig.handles, rig.targets, optionsFor(mode, alpha));
      std::vector<Vec3> batch(rig.handles.size());
      warp.applyBatch(rig.handles, batch);
      for (std::size_t i = 0; i < rig.handles.size(); ++i) {
        EXPECT_LE(test::relativeError(warp.apply(rig.handles[i]), rig.targets[i]), 1e-12)
            << mlsModeName(mode) << " alpha " << alpha << " handle " << i;
        EXPECT_EQ(batch[i], rig.targets[i]);
        // Near the handle the warp tends to the target (no overflow of the weights).
        for (double eps : {1e-3, 1e-9, 1e-200}) {
          const Vec3 near = rig.handles[i] + Vec3(eps, -eps, 0.5 * eps);
          const Vec3 y = warp.apply(near);
          EXPECT_TRUE(isFinite(y));
          EXPECT_LE(glm::length(y - rig.targets[i]), 50.0 * (alpha > 0.5 ? eps : std::sqrt(eps)))
              << mlsModeName(mode) << " alpha " << alpha << " eps " << eps;
        }
      }
    }
  }
}

TEST(MlsWarp, FarPointsStayFinite) {
  std::mt19937 rng(2);
  const Rig rig = randomRig(rng, 8);
  for (MlsMode mode : kModes) {
    const MlsWarp warp(rig.handles, rig.targets, optionsFor(mode));
    for (double far : {1e3, 1e100, 1e150}) EXPECT_TRUE(isFinite(warp.apply(Vec3(far, -far, far))));
  }
}

TEST(MlsWarp, RigidLocalTransformIsARotation) {
  std::mt19937 rng(3);
  Rig rig = randomRig(rng, 12);
  Rig mirrored = rig;  // targets reflected: B has det < 0 in places, R must stay proper
  for (Vec3& q : mirrored.targets) q.z = -q.z;
  for (const Rig* r : {&rig, &mirrored}) {
    const MlsWarp warp(r->handles, r->targets, optionsFor(MlsMode::Rigid));
    for (const Vec3& x : test::randomPoints(rng, 300, -1.5, 1.5)) {
      const Mat3 t = warp.localFit(x).transform;
      EXPECT_LE(test::relativeError(glm::transpose(t) * t, Mat3(1.0)), 1e-12) << test::toString(x);
      EXPECT_NEAR(glm::determinant(t), 1.0, 1e-12);
    }
  }
}

TEST(MlsWarp, SimilarityLocalTransformIsAScaledRotation) {
  std::mt19937 rng(4);
  Rig rig = randomRig(rng, 12);
  for (Vec3& q : rig.targets) q *= 1.7;
  const MlsWarp warp(rig.handles, rig.targets, optionsFor(MlsMode::Similarity));
  for (const Vec3& x : test::randomPoints(rng, 300, -1.5, 1.5)) {
    const Mat3 t = warp.localFit(x).transform;
    const Mat3 tt = glm::transpose(t) * t;
    const double s2 = (tt[0][0] + tt[1][1] + tt[2][2]) / 3.0;
    EXPECT_GT(s2, 0.0);
    EXPECT_LE(test::relativeError(tt / s2, Mat3(1.0)), 1e-12) << test::toString(x);
    EXPECT_GT(glm::determinant(t), 0.0);
  }
}

TEST(MlsWarp, RigidMotionOfTheHandlesIsReproducedInEveryMode) {
  std::mt19937 rng(5);
  const std::vector<Vec3> handles = test::randomPoints(rng, 9, -1.0, 1.0);
  const Mat3 r0 = rotation(Vec3(0.3, -1.0, 0.5), 2.1);
  const Vec3 t0(0.5, -2.0, 1.0);
  std::vector<Vec3> targets;
  for (const Vec3& p : handles) targets.push_back(r0 * p + t0);
  for (MlsMode mode : kModes) {
    const MlsWarp warp(handles, targets, optionsFor(mode));
    for (const Vec3& x : test::randomPoints(rng, 200, -2.0, 2.0)) {
      EXPECT_LE(test::relativeError(warp.apply(x), r0 * x + t0), 1e-10) << mlsModeName(mode);
      EXPECT_LE(test::relativeError(warp.jacobian(x), r0), 1e-10) << mlsModeName(mode);
    }
  }
}

TEST(MlsWarp, SimilarityMotionIsReproducedInSimilarityAndAffineModes) {
  std::mt19937 rng(6);
  const std::vector<Vec3> handles = test::randomPoints(rng, 7, -1.0, 1.0);
  const Mat3 m0 = 0.6 * rotation(Vec3(1.0, 1.0, 0.0), -0.8);
  const Vec3 t0(0.1, 0.2, 0.3);
  std::vector<Vec3> targets;
  for (const Vec3& p : handles) targets.push_back(m0 * p + t0);
  for (MlsMode mode : {MlsMode::Similarity, MlsMode::Affine}) {
    const MlsWarp warp(handles, targets, optionsFor(mode, 1.5));
    for (const Vec3& x : test::randomPoints(rng, 200, -2.0, 2.0)) {
      EXPECT_LE(test::relativeError(warp.apply(x), m0 * x + t0), 1e-10) << mlsModeName(mode);
      EXPECT_LE(test::relativeError(warp.jacobian(x), m0), 1e-10) << mlsModeName(mode);
    }
  }
}

TEST(MlsWarp, AffineMotionIsReproducedInAffineMode) {
  std::mt19937 rng(7);
  const std::vector<Vec3> handles = test::randomPoints(rng, 6, -1.0, 1.0);
  Mat3 a0(Vec3(1.2, 0.3, -0.1), Vec3(0.4, 0.7, 0.2), Vec3(-0.3, 0.1, 1.5));
  const Vec3 t0(-1.0, 0.5, 2.0);
  std::vector<Vec3> targets;
  for (const Vec3& p : handles) targets.push_back(a0 * p + t0);
  const MlsWarp warp(handles, targets, optionsFor(MlsMode::Affine));
  for (const Vec3& x : test::randomPoints(rng, 200, -2.0, 2.0)) {
    EXPECT_LE(test::relativeError(warp.apply(x), a0 * x + t0), 1e-10);
    EXPECT_LE(test::relativeError(warp.jacobian(x), a0), 1e-10);
  }
}

// Analytic Jacobian against fourth-order central differences with step h (world units).
::testing::AssertionResult jacobianMatchesSteps(const Warp& warp, const std::vector<Vec3>& points,
                                                double h) {
  for (std::size_t i = 0; i < points.size(); ++i) {
    const double err = test::relativeError(warp.jacobian(points[i]),
                                           test::finiteDifferenceJacobian(warp, points[i], h));
    if (!(err <= 1e-6)) {
      return ::testing::AssertionFailure()
             << "point " << i << " " << test::toString(points[i]) << ": relative error " << err;
    }
  }
  return ::testing::AssertionSuccess();
}

TEST(MlsWarp, JacobianMatchesFiniteDifferences) {
  std::mt19937 rng(8);
  for (MlsMode mode : kModes) {
    for (double alpha : {0.75, 1.0, 2.0}) {
      Rig rig = randomRig(rng, 8);
      const MlsWarp warp(rig.handles, rig.targets, optionsFor(mode, alpha));
      EXPECT_TRUE(
          test::jacobianMatchesFiniteDifferences(warp, pointsAwayFrom(rng, rig.handles, 100, 0.1)))
          << mlsModeName(mode) << " alpha " << alpha;
      // Reflected targets (rotation correction active) and the handles themselves (alpha = 1).
      for (Vec3& q : rig.targets) q.x = -q.x;
      const MlsWarp mirrored(rig.handles, rig.targets, optionsFor(mode, alpha));
      // The rotation turns fast where B is close to a reflection: a finer difference step.
      EXPECT_TRUE(jacobianMatchesSteps(mirrored, pointsAwayFrom(rng, rig.handles, 100, 0.1), 1e-4))
          << "mirrored " << mlsModeName(mode) << " alpha " << alpha;
      if (alpha == 1.0) {
        EXPECT_TRUE(test::jacobianMatchesFiniteDifferences(warp, rig.handles)) << mlsModeName(mode);
      }
    }
  }
}

TEST(MlsWarp, CoplanarHandlesWorkInRigidAndSimilarityModes) {
  // Rank-2 covariances everywhere: the rotation comes from the eigen-decomposition path.
  std::mt19937 rng(12);
  Rig rig = randomRig(rng, 8);
  for (Vec3& p : rig.handles) p.z = 0.0;
  for (MlsMode mode : {MlsMode::Rigid, MlsMode::Similarity}) {
    const MlsWarp warp(rig.handles, rig.targets, optionsFor(mode));
    for (std::size_t i = 0; i < rig.handles.size(); ++i)
      EXPECT_EQ(warp.apply(rig.handles[i]), rig.targets[i]);
    const std::vector<Vec3> points = pointsAwayFrom(rng, rig.handles, 100, 0.1);
    for (const Vec3& x : points) {
      const Mat3 t = warp.localFit(x).transform;
      const Mat3 tt = glm::transpose(t) * t;
      const double s2 = (tt[0][0] + tt[1][1] + tt[2][2]) / 3.0;
      EXPECT_LE(test::relativeError(tt / s2, Mat3(1.0)), 1e-12) << test::toString(x);
      EXPECT_GT(glm::determinant(t), 0.0);
    }
    EXPECT_TRUE(jacobianMatchesSteps(warp, points, 1e-4)) << mlsModeName(mode);
    EXPECT_TRUE(test::batchIsDeterministic(warp, points)) << mlsModeName(mode);
  }
}

TEST(MlsWarp, BatchIsDeterministicAndEqualsApply) {
  std::mt19937 rng(9);
  for (MlsMode mode : kModes) {
    const Rig rig = randomRig(rng, 16);
    const MlsWarp warp(rig.handles, rig.targets, optionsFor(mode));
    std::vector<Vec3> points = test::randomPoints(rng, 5000, -1.5, 1.5);
    points.insert(points.end(), rig.handles.begin(), rig.handles.end());
    EXPECT_TRUE(test::batchIsDeterministic(warp, points)) << mlsModeName(mode);
    test::expectBatchRejectsMismatchedSizes(warp, 3, 4);
  }
  // More handles than the stack scratch holds.
  const Rig big = randomRig(rng, 100);
  const MlsWarp warp(big.handles, big.targets);
  EXPECT_TRUE(test::batchIsDeterministic(warp, test::randomPoints(rng, 3000, -1.5, 1.5)));
}

TEST(MlsWarp, SmoothWarpProperties) {
  std::mt19937 rng(10);
  Rig rig = randomRig(rng, 8);
  for (Vec3& q : rig.targets)
    q = rig.handles[&q - rig.targets.data()] + 0.3 * (q - rig.handles[&q - rig.targets.data()]);
  for (MlsMode mode : kModes) {
    const MlsWarp warp(rig.handles, rig.targets, optionsFor(mode));
    const std::vector<Vec3> points = pointsAwayFrom(rng, rig.handles, 50, 0.1);
    EXPECT_TRUE(test::inverseRecovers(warp, points)) << mlsModeName(mode);
    EXPECT_TRUE(test::normalsStayPerpendicular(warp, points, rng)) << mlsModeName(mode);
  }
}

std::string errorOf(std::vector<Vec3> handles, std::vector<Vec3> targets, MlsOptions options = {}) {
  return test::messageOf<InvalidInput>(
      [&] { MlsWarp(std::move(handles), std::move(targets), options); });
}

TEST(MlsWarp, RejectsDegenerateInput) {
  const std::vector<Vec3> tet = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  const double nan = std::nan("");
  EXPECT_THAT(errorOf(tet, {tet[0], tet[1], tet[2]}), HasSubstr("4 handles but 3 targets"));
  EXPECT_THAT(errorOf({tet[0], tet[1]}, {tet[0], tet[1]}),
              HasSubstr("rigid mode needs at least 3 handles, got 2"));
  EXPECT_THAT(
      errorOf({tet[0], tet[1], tet[2]}, {tet[0], tet[1], tet[2]}, optionsFor(MlsMode::Affine)),
      HasSubstr("affine mode needs at least 4 handles, got 3"));
  EXPECT_THAT(errorOf({}, {}), HasSubstr("needs at least 3 handles, got 0"));
  std::vector<Vec3> bad = tet;
  bad[2].y = nan;
  EXPECT_THAT(errorOf(bad, tet), HasSubstr("handle 2 is not finite"));
  EXPECT_THAT(errorOf(tet, bad), HasSubstr("target 2 is not finite"));
  bad = tet;
  bad[3] = bad[1];
  EXPECT_THAT(errorOf(bad, tet), HasSubstr("handles 1 and 3 coincide"));
  bad[3] = bad[1] + Vec3(1e-14, 0.0, 0.0);
  EXPECT_THAT(errorOf(bad, tet), HasSubstr("handles 1 and 3 coincide"));
  const std::vector<Vec3> line = {{0, 0, 0}, {1, 1, 1}, {2, 2, 2}, {3, 3, 3.0000000001}};
  EXPECT_THAT(errorOf(line, tet), HasSubstr("the handles are collinear (rigid mode needs 3 "
                                            "non-collinear handles"));
  EXPECT_THAT(errorOf(line, tet, optionsFor(MlsMode::Similarity)),
              HasSubstr("the handles are collinear (similarity mode"));
  EXPECT_THAT(errorOf(tet, line), HasSubstr("the targets are collinear"));
  const std::vector<Vec3> plane = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {1, 1, 0}, {2, 3, 0}};
  EXPECT_THAT(errorOf(plane, plane, optionsFor(MlsMode::Affine)),
              HasSubstr("the handles are coplanar (affine mode needs 4 affinely independent"));
  EXPECT_EQ(errorOf(plane, plane, optionsFor(MlsMode::Rigid)), "");  // planar is fine for rigid
  // Collinear targets are fine in affine mode (the map collapses onto the line).
  EXPECT_EQ(errorOf(tet, {line[0], line[1], line[2], line[3]}, optionsFor(MlsMode::Affine)), "");
  for (double alpha : {0.0, -1.0, nan, std::numeric_limits<double>::infinity()}) {
    EXPECT_THAT(errorOf(tet, tet, optionsFor(MlsMode::Rigid, alpha)),
                HasSubstr("alpha must be finite and > 0"))
        << alpha;
  }
}

TEST(MlsAffineCoordinates, BindingMatchesTheAffineWarp) {
  std::mt19937 rng(11);
  const Rig rig = randomRig(rng, 12);
  auto coords = std::make_shared<MlsAffineCoordinates>(rig.handles, 1.5);
  std::vector<Vec3> points = test::randomPoints(rng, 500, -1.5, 1.5);
  points.insert(points.end(), rig.handles.begin(), rig.handles.end());
  points.push_back(rig.handles[3] + Vec3(1e-12, 0.0, 0.0));  // the limit fit
  const Binding binding(coords, points);
  const MlsWarp warp(rig.handles, rig.targets, optionsFor(MlsMode::Affine, 1.5));
  const std::vector<Vec3> posed = binding.deform(rig.targets);
  for (std::size_t i = 0; i < points.size(); ++i)
    EXPECT_LE(test::relativeError(posed[i], warp.apply(points[i])), 1e-12) << i;
  // Partition of unity and linear precision.
  std::vector<double> row(rig.handles.size());
  for (const Vec3& x : points) {
    coords->weights(x, row);
    double sum = 0.0;
    Vec3 y(0.0);
    for (std::size_t j = 0; j < row.size(); ++j) {
      sum += row[j];
      y += row[j] * rig.handles[j];
    }
    EXPECT_NEAR(sum, 1.0, 1e-12);
    EXPECT_LE(test::relativeError(y, x), 1e-12);
  }
}

TEST(MlsAffineCoordinates, RejectsCoplanarHandles) {
  const std::vector<Vec3> plane = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {1, 1, 0}};
  EXPECT_THAT(test::messageOf<InvalidInput>([&] { MlsAffineCoordinates c(plane); }),
              HasSubstr("MlsAffineCoordinates: the handles are coplanar"));
}

// Issue 12: handles far from the origin and of any size. The affine MLS coordinates equal
// those of the handles at the origin and keep partition of unity and linear precision; every
// mode's warp commutes with the placement. Bound: see tests/placement.h.
class MlsPlaced : public ::testing::TestWithParam<test::Placement> {};

TEST_P(MlsPlaced, WeightsAndWarpsDoNotDependOnOffsetOrScale) {
  const test::Placement at = GetParam();
  std::mt19937 rng(52);
  const Rig rig = randomRig(rng, 12);
  const std::vector<Vec3> samples = pointsAwayFrom(rng, rig.handles, 50, 0.05);
  Rig placedRig;
  for (const Vec3& p : rig.handles) placedRig.handles.push_back(test::place(p, at));
  for (const Vec3& q : rig.targets) placedRig.targets.push_back(test::place(q, at));
  std::vector<Vec3> placedSamples;
  for (const Vec3& x : samples) placedSamples.push_back(test::place(x, at));
  const double diagonal = boundingBox(placedRig.handles).diagonal();
  const double tolerance = 1e-11 + 1e2 * test::placementResolution(at, diagonal);

  const MlsAffineCoordinates base(rig.handles), placed(placedRig.handles);
  EXPECT_LE(test::placedWeightError(base, placed, samples, at), tolerance);
  const PropertyReport report = measureProperties(placed, placedSamples, diagonal);
  EXPECT_LE(report.partitionOfUnity, tolerance);
  EXPECT_LE(report.linearReproduction, tolerance);
  EXPECT_LE(report.similarityReproduction, tolerance);

  for (const MlsMode mode : kModes) {
    const MlsWarp baseWarp(rig.handles, rig.targets, optionsFor(mode));
    const MlsWarp placedWarp(placedRig.handles, placedRig.targets, optionsFor(mode));
    double worst = 0.0;
    for (std::size_t i = 0; i < samples.size(); ++i) {
      // The displacements, compared in the base problem's units.
      const Vec3 expected = baseWarp.apply(samples[i]) - samples[i];
      const Vec3 actual = (placedWarp.apply(placedSamples[i]) - placedSamples[i]) / at.scale;
      worst = std::max(worst, glm::length(actual - expected));
    }
    EXPECT_LE(worst / boundingBox(rig.handles).diagonal(), tolerance) << mlsModeName(mode);
  }
}

INSTANTIATE_TEST_SUITE_P(Placements, MlsPlaced, ::testing::ValuesIn(test::placements()),
                         [](const auto& info) { return test::placementName(info.param); });

}  // namespace
}  // namespace spacewarp
