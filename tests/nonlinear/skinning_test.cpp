#include <spacewarp/nonlinear/skinning.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <numbers>
#include <random>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <spacewarp/core/errors.h>
#include <spacewarp/core/inverse.h>
#include <spacewarp/nonlinear/mls.h>
#include <spacewarp/rbf/rbf_coordinates.h>
#include "test_util.h"

namespace spacewarp {
namespace {

using ::testing::HasSubstr;

constexpr SkinningMode kModes[] = {SkinningMode::Linear, SkinningMode::DualQuaternion};
constexpr double kPi = std::numbers::pi;

// The rigid motion x -> R(axis, angle) (x − center) + center + shift (Rodrigues).
Mat4 rigid(const Vec3& axis, double angle, const Vec3& center = Vec3(0.0),
           const Vec3& shift = Vec3(0.0)) {
  const Mat3 r = test::rotation(axis, angle);
  Mat4 m(r);
  m[3] = glm::dvec4(center - r * center + shift, 1.0);
  return m;
}

Vec3 transform(const Mat4& m, const Vec3& x) { return Vec3(m * glm::dvec4(x, 1.0)); }

Mat4 randomRigid(std::mt19937& rng) {
  std::uniform_real_distribution<double> angle(-2.5, 2.5);
  return rigid(test::randomUnit(rng), angle(rng), test::randomPoint(rng, -1.0, 1.0),
               test::randomPoint(rng, -1.0, 1.0));
}

// Dense random weights, points × bones, positive, not normalised (the library normalises them).
std::vector<double> randomDense(std::mt19937& rng, std::size_t points, std::size_t bones) {
  std::uniform_real_distribution<double> u(0.05, 1.0);
  std::vector<double> rows(points * bones);
  for (double& w : rows) w = u(rng);
  return rows;
}

// A unit cube's worth of random points with random weights on 6 bones, kept to 4.
struct Model {
  std::vector<Vec3> points;
  SkinningWeights weights;
};
Model randomModel(std::mt19937& rng, std::size_t n, std::size_t bones) {
  Model m;
  m.points = test::randomPoints(rng, n, -1.0, 1.0);
  m.weights = sparseSkinningWeights(randomDense(rng, n, bones), bones);
  return m;
}

std::vector<Vec3> handlesOf(std::size_t n) {  // spread, not coplanar
  std::vector<Vec3> h;
  for (std::size_t i = 0; i < n; ++i) {
    const double t = double(i);
    h.emplace_back(std::cos(1.3 * t), std::sin(2.1 * t), 0.4 * t - 1.0);
  }
  return h;
}

TEST(SkinningWeights, KeepsTheLargestInfluencesAndNormalisesThem) {
  const std::vector<double> row = {0.1, -0.5, 0.3, 0.05, 0.4, 0.2};
  // Truncated: the negative weight is dropped (clamped to 0), the largest are kept.
  const SkinningWeights w = sparseSkinningWeights(row, 6, 3);
  ASSERT_EQ(w.influences, 3u);
  EXPECT_THAT(w.bones, ::testing::ElementsAre(4u, 2u, 5u));
  const double sum = 0.4 + 0.3 + 0.2;
  EXPECT_DOUBLE_EQ(w.weights[0], 0.4 / sum);
  EXPECT_DOUBLE_EQ(w.weights[1], 0.3 / sum);
  EXPECT_DOUBLE_EQ(w.weights[2], 0.2 / sum);
  // 0 keeps all of them, signed, by magnitude; more influences than bones keeps all of them too.
  const SkinningWeights all = sparseSkinningWeights(row, 6, 0);
  EXPECT_EQ(all.influences, 6u);
  EXPECT_EQ(all.bones[0], 1u);
  EXPECT_DOUBLE_EQ(all.weights[0], -0.5 / 0.55);
  EXPECT_EQ(sparseSkinningWeights(row, 6, 10).influences, 6u);
  // Many bones, with ties: by decreasing (clamped) weight, ties to the lower bone, whether few
  // influences are kept or many; all of them by decreasing magnitude.
  std::vector<double> many(40);
  for (std::size_t b = 0; b < many.size(); ++b) many[b] = double((b * 7) % 13) - 4.0;
  for (std::size_t k : {std::size_t{5}, std::size_t{20}, std::size_t{35}, std::size_t{40}}) {
    std::vector<std::uint32_t> order(many.size());
    for (std::uint32_t b = 0; b < order.size(); ++b) order[b] = b;
    const auto key = [&](std::uint32_t b) {
      return k < many.size() ? std::max(many[b], 0.0) : std::abs(many[b]);
    };
    std::stable_sort(order.begin(), order.end(),
                     [&](std::uint32_t a, std::uint32_t b) { return key(a) > key(b); });
    const SkinningWeights w = sparseSkinningWeights(many, many.size(), k);
    EXPECT_EQ(w.bones, std::vector<std::uint32_t>(order.begin(), order.begin() + long(k))) << k;
  }
}

// Signed weights cut to their 4 largest magnitudes can sum to ~0 (−1.217 + 1.150 + 0.979 −
// 0.923 = −0.011, the adversarial tester's RBF weights): truncation clamps the negative ones
// first, so the kept weights are a convex combination whose sum is at least the largest.
TEST(SkinningWeights, TruncationDropsNegativeWeightsSoTheKeptSumIsNeverNearZero) {
  const std::vector<double> row = {-1.217, 1.150, 0.979, -0.923, 0.3, -0.2, 0.1, -0.1, 0.01};
  const SkinningWeights w = sparseSkinningWeights(row, row.size(), 4);
  EXPECT_THAT(w.bones, ::testing::ElementsAre(1u, 2u, 4u, 6u));
  double sum = 0.0;
  for (double x : w.weights) {
    EXPECT_GE(x, 0.0);
    EXPECT_LE(x, 1.0);
    sum += x;
  }
  EXPECT_NEAR(sum, 1.0, 1e-15);
  EXPECT_DOUBLE_EQ(w.weights[0], 1.150 / (1.150 + 0.979 + 0.3 + 0.1));
}

TEST(SkinningWeights, BadWeightsAreNamed) {
  const double nan = std::nan("");
  EXPECT_THAT(test::messageOf<InvalidInput>([&] {
                sparseSkinningWeights({{1, 0, 1, nan}}, 2);
              }),
              HasSubstr("point 1 has a non-finite weight for bone 1"));
  EXPECT_THAT(test::messageOf<InvalidInput>([&] {
                sparseSkinningWeights({{1, 0, 0.5, -0.5}}, 2);
              }),
              HasSubstr("weights of point 1 sum to 0"));
  EXPECT_THAT(test::messageOf<InvalidInput>([&] {
                sparseSkinningWeights({{0, 0}}, 2);
              }),
              HasSubstr("weights of point 0 sum to 0"));
  // All negative: −W is not W.
  EXPECT_THAT(test::messageOf<InvalidInput>([&] {
                sparseSkinningWeights({{1, 0, -0.5, -0.5}}, 2);
              }),
              HasSubstr("weights of point 1 sum to -1.0"));
  EXPECT_THAT(test::messageOf<InvalidInput>([&] {
                sparseSkinningWeights({{1, 0, 0, 0, -0.5, -0.5, -0.1, 0}}, 4, 2);
              }),
              HasSubstr("weights of point 1 have no positive weight"));
  // Finite weights whose sum overflows.
  EXPECT_THAT(test::messageOf<InvalidInput>([&] {
                sparseSkinningWeights({{1, 0, 1e308, 1e308}}, 2);
              }),
              HasSubstr("weights of point 1 are too large: their sum is not finite"));
  EXPECT_THAT(test::messageOf<InvalidInput>([&] {
                sparseSkinningWeights({{1, 0, 1}}, 2);
              }),
              HasSubstr("not a whole number of rows"));
}

TEST(SkinningMode, NamesRoundTripAndUnknownNamesAreRefused) {
  for (SkinningMode mode : kModes) EXPECT_EQ(skinningModeFromName(skinningModeName(mode)), mode);
  EXPECT_THAT(test::messageOf<InvalidInput>([] { skinningModeFromName("slerp"); }),
              HasSubstr("skinning mode 'slerp' is not one of: lbs, dqs"));
}

TEST(Skinning, IdentityBonesLeaveEveryPointExactlyInPlace) {
  std::mt19937 rng(1);
  const Model m = randomModel(rng, 500, 6);
  const std::vector<Mat4> bones(6, Mat4(1.0));
  const SkinningBinding binding(m.points, m.weights, 6);
  for (SkinningMode mode : kModes) {
    EXPECT_EQ(binding.deform(bones, mode), m.points) << skinningModeName(mode);
    const SkinningWarp warp(bones, m.points, m.weights, mode);
    EXPECT_TRUE(test::leavesPointsUnchanged(warp, test::randomPoints(rng, 200, -2.0, 2.0)));
  }
}

TEST(Skinning, ACommonRigidMotionOfAllBonesIsReproduced) {
  std::mt19937 rng(2);
  const Model m = randomModel(rng, 500, 6);
  const SkinningBinding binding(m.points, m.weights, 6);
  for (int trial = 0; trial < 5; ++trial) {
    const Mat4 motion = randomRigid(rng);
    const std::vector<Mat4> bones(6, motion);
    for (SkinningMode mode : kModes) {
      const std::vector<Vec3> posed = binding.deform(bones, mode);
      for (std::size_t i = 0; i < posed.size(); ++i)
        ASSERT_LE(test::relativeError(posed[i], transform(motion, m.points[i])), 1e-14)
            << skinningModeName(mode) << " point " << i;
    }
  }
}

TEST(Skinning, APointWeightedOnOneBoneFollowsThatBone) {
  std::mt19937 rng(3);
  std::vector<Mat4> bones;
  for (int b = 0; b < 4; ++b) bones.push_back(randomRigid(rng));
  std::vector<Mat4> affine = bones;
  affine[2][0][1] += 0.3;  // a shear: LBS takes any affine bone
  affine[2][1][1] *= 1.7;
  const std::vector<Vec3> points = test::randomPoints(rng, 40, -1.0, 1.0);
  std::vector<double> rows(points.size() * 4, 0.0);
  for (std::size_t i = 0; i < points.size(); ++i) rows[i * 4 + i % 4] = 2.5;  // normalised to 1
  const SkinningBinding binding(points, sparseSkinningWeights(rows, 4), 4);
  const std::vector<Vec3> lbs = binding.deform(affine, SkinningMode::Linear);
  const std::vector<Vec3> dqs = binding.deform(bones, SkinningMode::DualQuaternion);
  for (std::size_t i = 0; i < points.size(); ++i) {
    EXPECT_LE(test::relativeError(lbs[i], transform(affine[i % 4], points[i])), 1e-15) << i;
    EXPECT_LE(test::relativeError(dqs[i], transform(bones[i % 4], points[i])), 1e-14) << i;
  }
}

// A cylinder of radius r along x over [0, 1], as rings of points; bone 0 holds the x = 0 end,
// bone 1 twists the x = 1 end about the axis. Weights blend smoothly along x.
struct Cylinder {
  static constexpr int kRings = 21, kPerRing = 64;
  static constexpr double kRadius = 0.1;
  std::vector<Vec3> points;
  SkinningWeights weights;
  Cylinder() {
    std::vector<double> rows;
    for (int i = 0; i < kRings; ++i) {
      const double x = double(i) / (kRings - 1);
      const double w1 = x * x * (3.0 - 2.0 * x);
      for (int j = 0; j < kPerRing; ++j) {
        const double a = 2.0 * kPi * j / kPerRing;
        points.emplace_back(x, kRadius * std::cos(a), kRadius * std::sin(a));
        rows.push_back(1.0 - w1);
        rows.push_back(w1);
      }
    }
    weights = sparseSkinningWeights(rows, 2);
  }
  // The area of ring i of `posed` (shoelace in the y-z plane; the rings stay in their planes).
  static double ringArea(const std::vector<Vec3>& posed, int ring) {
    double area = 0.0;
    for (int j = 0; j < kPerRing; ++j) {
      const Vec3& a = posed[std::size_t(ring * kPerRing + j)];
      const Vec3& b = posed[std::size_t(ring * kPerRing + (j + 1) % kPerRing)];
      area += a.y * b.z - a.z * b.y;
    }
    return 0.5 * std::abs(area);
  }
};

TEST(Skinning, CandyWrapperLinearBlendingCollapsesTheTwistedMiddleDualQuaternionsDoNot) {
  const Cylinder c;
  const double twist = 170.0 * kPi / 180.0;
  const std::vector<Mat4> bones = {Mat4(1.0), rigid({1, 0, 0}, twist)};
  const SkinningBinding binding(c.points, c.weights, 2);
  const std::vector<Vec3> lbs = binding.deform(bones, SkinningMode::Linear);
  const std::vector<Vec3> dqs = binding.deform(bones, SkinningMode::DualQuaternion);
  const int middle = Cylinder::kRings / 2;
  const double rest = Cylinder::ringArea(c.points, middle);
  // LBS: the middle ring is ½ (I + R(170°)) of the rest ring, a circle of radius cos(85°) r.
  const double lbsRadius = glm::length(
      Vec3(0.0, lbs[middle * Cylinder::kPerRing].y, lbs[middle * Cylinder::kPerRing].z));
  EXPECT_NEAR(lbsRadius, std::cos(twist / 2) * Cylinder::kRadius, 1e-15);
  EXPECT_LT(Cylinder::ringArea(lbs, middle) / rest, 0.01);
  // DQS: every point keeps its distance from the axis, the middle turns by 85°.
  for (std::size_t i = 0; i < c.points.size(); ++i) {
    EXPECT_NEAR(dqs[i].x, c.points[i].x, 1e-15);
    EXPECT_NEAR(glm::length(Vec3(0.0, dqs[i].y, dqs[i].z)), Cylinder::kRadius, 1e-15) << i;
  }
  const Vec3& turned = dqs[middle * Cylinder::kPerRing];  // the rest point (0.5, r, 0)
  EXPECT_NEAR(std::atan2(turned.z, turned.y), twist / 2, 1e-14);
  // Volume (the rings' mean area, the slices being equally spaced): LBS loses a third or more,
  // DQS keeps it within 1% (the polygonal rings' area is exactly the rest one).
  double restVolume = 0.0, lbsVolume = 0.0, dqsVolume = 0.0;
  for (int i = 0; i < Cylinder::kRings; ++i) {
    restVolume += Cylinder::ringArea(c.points, i);
    lbsVolume += Cylinder::ringArea(lbs, i);
    dqsVolume += Cylinder::ringArea(dqs, i);
  }
  EXPECT_LT(lbsVolume / restVolume, 0.67);
  EXPECT_NEAR(dqsVolume / restVolume, 1.0, 0.01);
}

TEST(Skinning, DualQuaternionsBlendTwoRotationsAboutOneAxisByTheirNormalisedQuaternionArc) {
  // Rotations by a and b about the same axis line (through `center`): the blend with weights
  // (1 − t, t) is the rotation about that line by 2 atan2((1 − t) sin(a/2) + t sin(b/2),
  // (1 − t) cos(a/2) + t cos(b/2)) — the normalised linear blend of the quaternions, which is
  // the mean angle (a + b)/2 at t = ½ and within 2% of linear for |a − b| ≤ 90°.
  const Vec3 axis = glm::normalize(Vec3(1.0, 2.0, -0.5)), center(0.3, -0.2, 0.7);
  const double a = 0.2, b = 1.6;
  const std::vector<Mat4> bones = {rigid(axis, a, center), rigid(axis, b, center)};
  const Vec3 p = center + Vec3(0.4, -0.1, 0.9);
  for (double t : {0.0, 0.25, 0.5, 0.8, 1.0}) {
    const std::vector<double> row = {1.0 - t, t};
    const SkinningWarp warp(bones, {p}, sparseSkinningWeights(row, 2, 0),
                            SkinningMode::DualQuaternion);
    const double expected = 2.0 * std::atan2((1 - t) * std::sin(a / 2) + t * std::sin(b / 2),
                                             (1 - t) * std::cos(a / 2) + t * std::cos(b / 2));
    const Vec3 reference = transform(rigid(axis, expected, center), p);
    EXPECT_LE(test::relativeError(warp.apply(p), reference), 1e-14) << "t = " << t;
    if (t == 0.5) {
      EXPECT_NEAR(expected, (a + b) / 2, 1e-15);
    }
  }
}

TEST(Skinning, DualQuaternionsTakeTheShorterArcFromThePivotBone) {
  // Bone 1's quaternion is given in the far hemisphere (a 350° rotation is −10°): the blend
  // must still interpolate 0° → −10°, not sweep through 180°.
  const std::vector<Mat4> bones = {Mat4(1.0), rigid({0, 0, 1}, 350.0 * kPi / 180.0)};
  const Vec3 p(1.0, 0.0, 0.0);
  const SkinningWarp warp(bones, {p}, sparseSkinningWeights(std::vector<double>{0.5, 0.5}, 2),
                          SkinningMode::DualQuaternion);
  const Vec3 q = warp.apply(p);
  EXPECT_NEAR(std::atan2(q.y, q.x), -5.0 * kPi / 180.0, 1e-14);
}

TEST(Skinning, WeightsFromCoordinatesArePartitionsOfUnityAndMoveTheHandles) {
  std::mt19937 rng(4);
  const std::vector<Vec3> handles = handlesOf(6);
  const auto coordinates = std::make_shared<MlsAffineCoordinates>(handles);
  const std::vector<Vec3> points = test::randomPoints(rng, 300, -1.5, 1.5);
  const SkinningWeights all = skinningWeights(*coordinates, points, 0);
  ASSERT_EQ(all.influences, 6u);
  for (std::size_t i = 0; i < points.size(); ++i) {
    double sum = 0.0;
    for (std::size_t j = 0; j < 6; ++j) sum += all.weights[i * 6 + j];
    EXPECT_NEAR(sum, 1.0, 1e-14) << i;
  }
  // Bone j moves its handle; the other bones hold theirs.
  for (SkinningMode mode : kModes) {
    for (std::size_t j = 0; j < handles.size(); ++j) {
      std::vector<Mat4> bones(handles.size(), Mat4(1.0));
      bones[j] = rigid({0.3, 1, 0.2}, 0.7, Vec3(0.1), Vec3(0.2, -0.4, 0.5));
      const SkinningWarp warp(bones, coordinates, {mode, 4});
      for (std::size_t h = 0; h < handles.size(); ++h) {
        const Vec3 expected = h == j ? transform(bones[j], handles[h]) : handles[h];
        EXPECT_LE(test::relativeError(warp.apply(handles[h]), expected), 1e-12)
            << skinningModeName(mode) << " bone " << j << " handle " << h;
      }
    }
  }
}

TEST(Skinning, TheBindingAndTheWarpGiveTheSameBitsForAnyThreadCount) {
  std::mt19937 rng(5);
  std::vector<Mat4> bones;
  for (int b = 0; b < 6; ++b) bones.push_back(randomRigid(rng));
  // Nearest-vertex weights: the warp at the model's vertices is the binding.
  const Model m = randomModel(rng, 3000, 6);
  const SkinningBinding binding(m.points, m.weights, 6);
  // Weights from coordinates: a binding of skinningWeights() is the warp.
  const auto coordinates = std::make_shared<MlsAffineCoordinates>(handlesOf(6));
  const std::vector<Vec3> points = test::randomPoints(rng, 3000, -1.5, 1.5);
  const SkinningBinding coordinateBinding(points, skinningWeights(*coordinates, points, 4), 6);
  for (SkinningMode mode : kModes) {
    const SkinningWarp warp(bones, m.points, m.weights, mode);
    const std::vector<Vec3> posed = binding.deform(bones, mode);
    std::vector<Vec3> batch(m.points.size());
    warp.applyBatch(m.points, batch);
    for (std::size_t i = 0; i < posed.size(); ++i)
      ASSERT_TRUE(test::bitEqual(posed[i], batch[i]))
          << skinningModeName(mode) << " point " << i << ": " << test::toString(posed[i]) << " "
          << test::toString(batch[i]);
    EXPECT_TRUE(test::batchIsDeterministic(warp, test::randomPoints(rng, 20000, -2.0, 2.0)));

    const SkinningWarp fromCoordinates(bones, coordinates, {mode, 4});
    const std::vector<Vec3> bound = coordinateBinding.deform(bones, mode);
    for (std::size_t i = 0; i < points.size(); ++i)
      ASSERT_TRUE(test::bitEqual(bound[i], fromCoordinates.apply(points[i])));
    EXPECT_TRUE(test::batchIsDeterministic(fromCoordinates, points));
    // The binding itself, on 1 and 2 threads.
    std::vector<Vec3> one(m.points.size()), two(m.points.size());
    tbb::task_arena(1).execute([&] { binding.deform(bones, mode, one); });
    tbb::task_arena(2).execute([&] { binding.deform(bones, mode, two); });
    for (std::size_t i = 0; i < one.size(); ++i) ASSERT_TRUE(test::bitEqual(one[i], two[i]));
  }
}

TEST(Skinning, NearestVertexWeightsAreExactOnTheModelAndConstantAroundIt) {
  std::mt19937 rng(6);
  std::vector<Mat4> bones;
  for (int b = 0; b < 3; ++b) bones.push_back(randomRigid(rng));
  bones[1][0][0] = 1.4;  // LBS: any affine bone
  const std::vector<Vec3> model = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
  const std::vector<double> rows = {1, 0, 0, 0.2, 0.8, 0, 0.1, 0.3, 0.6};
  const SkinningWarp warp(bones, model, sparseSkinningWeights(rows, 3), SkinningMode::Linear);
  // Near vertex 1 the blend is 0.2 A_0 + 0.8 A_1, an affine map: its Jacobian is the blend.
  const Vec3 x(0.9, 0.05, 0.1);
  Mat3 blend = 0.2 * Mat3(bones[0]) + 0.8 * Mat3(bones[1]);
  EXPECT_LE(test::relativeError(warp.jacobian(x), blend), 1e-15);
  EXPECT_LE(test::relativeError(warp.jacobian(x), test::finiteDifferenceJacobian(warp, x, 1e-4)),
            1e-9);
  const Vec3 expected = 0.2 * transform(bones[0], x) + 0.8 * transform(bones[1], x);
  EXPECT_LE(test::relativeError(warp.apply(x), expected), 1e-15);
  // Points out of reach of the KD-tree are reported, not guessed.
  EXPECT_THROW(warp.apply(Vec3(1e200, 0, 0)), InvalidInput);
}

// The adversarial tester's scene: 16 random handles in the unit cube with RBF coordinates
// (signed weights), bones turning up to 60° and moving up to 0.5. Truncated to 4 influences,
// LBS is a convex combination of the bones' images (|x' − x| ≤ the largest bone displacement)
// and, like the default (all weights, exact), continuous: walking a line in fine steps, no step
// is longer than a bounded multiple of the step (a pole or a jump would give steps of the
// bones' displacement, ~10⁴ times longer).
TEST(Skinning, WeightsFromCoordinatesHaveNoPolesOrJumps) {
  std::mt19937 rng(3);
  const std::vector<Vec3> handles = test::randomPoints(rng, 16, 0.0, 1.0);
  std::vector<Mat4> bones;
  std::uniform_real_distribution<double> angle(-kPi / 3, kPi / 3);
  for (std::size_t b = 0; b < handles.size(); ++b)
    bones.push_back(rigid({1, 0, 0}, angle(rng), Vec3(0.0), test::randomPoint(rng, 0.0, 0.5)));
  const auto rbf = std::make_shared<RbfCoordinates>(handles);
  const auto reach = [&](const Vec3& x) {
    double d = 0.0;
    for (const Mat4& m : bones) d = std::max(d, glm::length(transform(m, x) - x));
    return d;
  };
  const SkinningWarp truncated(bones, rbf, {SkinningMode::Linear, 4});
  for (const Vec3& x : test::randomPoints(rng, 2000, 0.0, 1.0))
    EXPECT_LE(glm::length(truncated.apply(x) - x), reach(x) * (1.0 + 1e-12)) << x.x;
  const std::size_t steps = 20000;
  const Vec3 from(-0.2, 0.1, -0.1), to(1.2, 0.9, 1.1);
  std::vector<Vec3> line(steps + 1);
  for (std::size_t i = 0; i <= steps; ++i) line[i] = from + (to - from) * (double(i) / steps);
  const double step = glm::length(to - from) / steps;
  for (SkinningMode mode : kModes) {
    for (std::size_t k : {std::size_t{0}, std::size_t{4}}) {
      const SkinningWarp warp(bones, rbf, {mode, k});
      std::vector<Vec3> moved(line.size());
      warp.applyBatch(line, moved);
      double longest = 0.0;
      for (std::size_t i = 0; i < steps; ++i)
        longest = std::max(longest, glm::length(moved[i + 1] - moved[i]));
      EXPECT_LE(longest, 200.0 * step) << skinningModeName(mode) << " k " << k;
    }
  }
}

TEST(Skinning, JacobiansMatchFiniteDifferences) {
  std::mt19937 rng(7);
  const std::vector<Vec3> handles = handlesOf(5);
  std::vector<Mat4> bones;
  for (std::size_t b = 0; b < handles.size(); ++b)
    bones.push_back(
        rigid(test::randomUnit(rng), 0.8, handles[b], test::randomPoint(rng, -0.3, 0.3)));
  const auto rbf = std::make_shared<RbfCoordinates>(handles);        // analytic weight gradients
  const auto mls = std::make_shared<MlsAffineCoordinates>(handles);  // finite differences
  const std::vector<Vec3> points = test::randomPoints(rng, 50, -1.5, 1.5);
  for (SkinningMode mode : kModes) {
    for (std::size_t k : {std::size_t{0}, std::size_t{3}, std::size_t{5}}) {
      EXPECT_TRUE(
          test::jacobianMatchesFiniteDifferences(SkinningWarp(bones, rbf, {mode, k}), points, 1e-7))
          << skinningModeName(mode);
    }
    EXPECT_TRUE(
        test::jacobianMatchesFiniteDifferences(SkinningWarp(bones, mls, {mode, 0}), points, 1e-6))
        << skinningModeName(mode);
    // The smooth warp also inverts and carries normals.
    std::vector<Mat4> gentle;
    for (std::size_t b = 0; b < handles.size(); ++b)
      gentle.push_back(rigid(test::randomUnit(rng), 0.25, handles[b], Vec3(0.05)));
    const SkinningWarp warp(gentle, rbf, {mode, 0});
    EXPECT_TRUE(test::inverseRecovers(warp, test::randomPoints(rng, 20, -0.8, 0.8)));
    EXPECT_TRUE(test::normalsStayPerpendicular(warp, points, rng, 1e-9));
  }
}

TEST(Skinning, BadInputIsNamed) {
  const std::vector<Vec3> model = {{0, 0, 0}, {1, 0, 0}};
  const SkinningWeights good = sparseSkinningWeights(std::vector<double>{1, 0, 0, 1}, 2);
  const std::vector<Mat4> bones = {Mat4(1.0), rigid({0, 0, 1}, 0.5)};
  // Weights count ≠ points.
  EXPECT_THAT(test::messageOf<InvalidInput>([&] {
                SkinningWarp(bones, {{0, 0, 0}}, good, SkinningMode::Linear);
              }),
              HasSubstr("2 points have weights, but there are 1 points"));
  // Bone index out of range.
  SkinningWeights outOfRange = good;
  outOfRange.bones[3] = 7;
  EXPECT_THAT(test::messageOf<InvalidInput>([&] { SkinningBinding(model, outOfRange, 2); }),
              HasSubstr("point 1 names bone 7, but there are 2 bones"));
  // NaN weights given directly.
  SkinningWeights nan = good;
  nan.weights[0] = std::nan("");
  EXPECT_THAT(test::messageOf<InvalidInput>([&] { SkinningBinding(model, nan, 2); }),
              HasSubstr("point 0 has a non-finite weight"));
  // A non-rigid bone for DQS (LBS takes it); a projective last row for either.
  std::vector<Mat4> scaled = bones;
  scaled[1][0][0] = 2.0;
  EXPECT_NO_THROW(SkinningWarp(scaled, model, good, SkinningMode::Linear));
  EXPECT_THAT(test::messageOf<InvalidInput>(
                  [&] { SkinningWarp(scaled, model, good, SkinningMode::DualQuaternion); }),
              HasSubstr("bone 1: dual-quaternion skinning needs a rigid bone"));
  std::vector<Mat4> mirrored = bones;
  mirrored[0][2][2] = -1.0;
  EXPECT_THAT(test::messageOf<InvalidInput>([&] {
                SkinningBinding(model, good, 2).deform(mirrored, SkinningMode::DualQuaternion);
              }),
              HasSubstr("bone 0: the bone is a reflection (determinant −1): dual-quaternion "
                        "skinning needs rotations; use mode \"lbs\""));
  std::vector<Mat4> projective = bones;
  projective[1][0][3] = 0.1;
  EXPECT_THAT(test::messageOf<InvalidInput>(
                  [&] { SkinningWarp(projective, model, good, SkinningMode::Linear); }),
              HasSubstr("bone 1: the last row of the matrix must be 0 0 0 1"));
  // Bone counts.
  EXPECT_THAT(test::messageOf<InvalidInput>([&] {
                SkinningBinding(model, good, 2).deform({bones.data(), 1}, SkinningMode::Linear);
              }),
              HasSubstr("1 bones given, the binding has 2"));
  const auto coordinates = std::make_shared<MlsAffineCoordinates>(handlesOf(5));
  EXPECT_THAT(test::messageOf<InvalidInput>([&] { SkinningWarp(bones, coordinates); }),
              HasSubstr("2 bones, but the coordinates have 5 weights per point"));
  // Non-finite points.
  EXPECT_THAT(test::messageOf<InvalidInput>([&] {
                SkinningBinding({{0, 0, 0}, {std::nan(""), 0, 0}}, good, 2);
              }),
              HasSubstr("point 1 is not finite"));
}

}  // namespace
}  // namespace spacewarp
