// Tests of nonlinear/deformation_graph.h: node sampling, weights, the Gauss-Newton solve
// (identity, rigid motions, bending, disconnected graphs), the Warp view, invalid input.

#include "nonlinear/deformation_graph.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "core/deform.h"
#include "core/errors.h"
#include "core/geometry.h"
#include "test_util.h"

using namespace spacewarp;
using ::testing::HasSubstr;

namespace {

// Points filling the box [lo, hi].
std::vector<Vec3> boxPoints(const Vec3& lo, const Vec3& hi, std::size_t n, unsigned seed) {
  std::mt19937 rng(seed);
  std::vector<Vec3> points(n);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (Vec3& p : points) {
    const double a = u(rng), b = u(rng), c = u(rng);
    p = lo + (hi - lo) * Vec3(a, b, c);
  }
  return points;
}

// A rotation by `angle` radians about the unit axis.
Mat3 rotation(const Vec3& axis, double angle) {
  const Vec3 a = glm::normalize(axis);
  const double c = std::cos(angle), s = std::sin(angle);
  Mat3 r(c);
  r += (1.0 - c) * glm::outerProduct(a, a);
  r[0] += s * glm::cross(a, Vec3(1.0, 0.0, 0.0));
  r[1] += s * glm::cross(a, Vec3(0.0, 1.0, 0.0));
  r[2] += s * glm::cross(a, Vec3(0.0, 0.0, 1.0));
  return r;
}

bool nonIncreasing(const std::vector<double>& e) {
  for (std::size_t i = 1; i < e.size(); ++i)
    if (!(e[i] <= e[i - 1])) return false;
  return true;
}

DeformationGraphOptions spacingOf(double s, int k = 4) {
  DeformationGraphOptions o;
  o.spacing = s;
  o.k = k;
  return o;
}

}  // namespace

TEST(DeformationGraph, SamplesOneNodePerOccupiedCellDeterministically) {
  const std::vector<Vec3> points = boxPoints(Vec3(0.0), Vec3(2.0), 4000, 1);
  const DeformationGraph a(points, spacingOf(0.5));
  const DeformationGraph b(points, spacingOf(0.5));
  EXPECT_EQ(a.nodeCount(), 64u);  // 4 x 4 x 4 cells, all occupied
  ASSERT_EQ(a.nodeCount(), b.nodeCount());
  for (std::size_t i = 0; i < a.nodeCount(); ++i) {
    EXPECT_EQ(a.nodes()[i], b.nodes()[i]);
    // Each node is an input point.
    EXPECT_NE(std::find(points.begin(), points.end(), a.nodes()[i]), points.end());
  }
  EXPECT_EQ(a.edges(), b.edges());
  for (const auto& [i, j] : a.edges()) EXPECT_LT(i, j);
}

TEST(DeformationGraph, WeightsAreAPartitionOfUnityOverTheKNearestNodes) {
  const std::vector<Vec3> points = boxPoints(Vec3(-1.0), Vec3(1.0), 3000, 2);
  const DeformationGraph graph(points, spacingOf(0.4, 5));
  std::mt19937 rng(3);
  for (const Vec3& x : test::randomPoints(rng, 100, -1.2, 1.2)) {
    const NodeWeights w = graph.weights(x);
    ASSERT_EQ(w.nodes.size(), 5u);
    ASSERT_EQ(w.weights.size(), 5u);
    // Brute-force k + 1 nearest.
    std::vector<std::pair<double, std::uint32_t>> byDistance;
    for (std::uint32_t j = 0; j < graph.nodeCount(); ++j)
      byDistance.emplace_back(glm::length(x - graph.nodes()[j]), j);
    std::sort(byDistance.begin(), byDistance.end());
    const double dMax = byDistance[5].first;
    double sumRaw = 0.0;
    for (int i = 0; i < 5; ++i) sumRaw += std::pow(1.0 - byDistance[i].first / dMax, 2);
    double sum = 0.0;
    for (int i = 0; i < 5; ++i) {
      EXPECT_EQ(w.nodes[i], byDistance[i].second);
      const double expected = std::pow(1.0 - byDistance[i].first / dMax, 2) / sumRaw;
      EXPECT_NEAR(w.weights[i], expected, 1e-14);
      EXPECT_GE(w.weights[i], 0.0);
      sum += w.weights[i];
    }
    EXPECT_NEAR(sum, 1.0, 1e-14);
  }
}

TEST(DeformationGraph, UnmovedHandlesGiveTheIdentity) {
  const std::vector<Vec3> points = boxPoints(Vec3(0.0), Vec3(1.0), 2000, 4);
  DeformationGraph graph(points, spacingOf(0.25));
  const std::vector<Vec3> handles(points.begin(), points.begin() + 10);
  const DeformationGraphReport report = graph.solve(handles, handles);
  EXPECT_TRUE(report.converged);
  EXPECT_EQ(report.energies.front(), 0.0);
  for (const Mat3& a : graph.affineMaps()) EXPECT_EQ(a, Mat3(1.0));
  for (const Vec3& t : graph.translations()) EXPECT_EQ(t, Vec3(0.0));
  const DeformationGraphWarp warp = graph.warp();
  std::mt19937 rng(5);
  for (const Vec3& x : test::randomPoints(rng, 200, -0.5, 1.5))
    EXPECT_LE(glm::length(warp.apply(x) - x), 1e-12);
}

TEST(DeformationGraph, OneRigidMotionOfAllHandlesIsReproduced) {
  const std::vector<Vec3> points = boxPoints(Vec3(0.0), Vec3(2.0, 1.0, 1.0), 4000, 6);
  DeformationGraph graph(points, spacingOf(0.3));
  const Mat3 r = rotation(Vec3(1.0, 2.0, 0.5), 0.6);
  const Vec3 shift(0.3, -0.2, 0.5);
  std::vector<Vec3> handles, targets;
  for (std::size_t i = 0; i < points.size(); i += 100) {
    handles.push_back(points[i]);
    targets.push_back(r * points[i] + shift);
  }
  DeformationGraphSolveOptions options;
  options.tolerance = 1e-12;
  const DeformationGraphReport report = graph.solve(handles, targets, options);
  EXPECT_TRUE(report.converged);
  EXPECT_TRUE(nonIncreasing(report.energies));
  EXPECT_LT(report.energies.back(), 1e-16);
  EXPECT_EQ(report.unconstrainedComponents, 0);
  const DeformationGraphWarp warp = graph.warp();
  for (const Vec3& x : points)
    EXPECT_LE(test::relativeError(warp.apply(x), r * x + shift), 1e-6) << test::toString(x);
}

TEST(DeformationGraph, BendingKeepsNodesNearlyRigidAndNeverRaisesTheEnergy) {
  // A bar along x; the left end is held, the right end turned by 45 degrees about z.
  const std::vector<Vec3> points = boxPoints(Vec3(0.0), Vec3(6.0, 1.0, 1.0), 8000, 7);
  DeformationGraph graph(points, spacingOf(0.34));
  const Mat3 r = rotation(Vec3(0.0, 0.0, 1.0), glm::radians(30.0));
  const Vec3 pivot(5.5, 0.5, 0.5);
  std::vector<Vec3> handles, targets;
  for (const Vec3& p : points) {
    if (p.x < 0.3) {
      handles.push_back(p);
      targets.push_back(p);
    } else if (p.x > 5.7) {
      handles.push_back(p);
      targets.push_back(pivot + r * (p - pivot) + Vec3(0.0, 1.0, 0.0));
    }
  }
  const DeformationGraphReport report = graph.solve(handles, targets);
  EXPECT_TRUE(report.converged);
  EXPECT_GT(report.iterations, 1);
  EXPECT_TRUE(nonIncreasing(report.energies));
  EXPECT_LT(report.energies.back(), 1e-2 * report.energies.front());
  // Each node's map is close to a rotation: mean Rot(A_j) below 5e-3 (column lengths and
  // angles within about 2 %), far below what the same edit gives without E_rot.
  EXPECT_LT(report.rotationEnergy / double(graph.nodeCount()), 5e-3);
  DeformationGraph unrotated(points, spacingOf(0.34));
  DeformationGraphSolveOptions noRotation;
  noRotation.rotationWeight = 0.0;
  const DeformationGraphReport loose = unrotated.solve(handles, targets, noRotation);
  EXPECT_LT(report.rotationEnergy, 0.5 * loose.rotationEnergy);
  const Mat3 aEnd = graph.affineMaps()[graph.weights(Vec3(5.9, 0.5, 0.5)).nodes[0]];
  EXPECT_LT(test::relativeError(aEnd, r), 0.15);
}

TEST(DeformationGraph, DampingKeepsTheEnergyFromRisingOnAHardEdit) {
  const std::vector<Vec3> points = boxPoints(Vec3(0.0), Vec3(1.0), 2000, 8);
  DeformationGraph graph(points, spacingOf(0.2));
  // Fold one corner through the body: a large, non-rigid edit.
  std::vector<Vec3> handles{Vec3(0.0), Vec3(1.0, 0.0, 0.0), Vec3(1.0)},
      targets{Vec3(0.0), Vec3(1.0, 0.0, 0.0), Vec3(-1.5, -1.0, 0.2)};
  DeformationGraphSolveOptions options;
  options.constraintWeight = 1e4;
  const DeformationGraphReport report = graph.solve(handles, targets, options);
  EXPECT_TRUE(nonIncreasing(report.energies));
  EXPECT_EQ(report.energies.size(), std::size_t(report.iterations) + 1);
  EXPECT_LT(report.energies.back(), report.energies.front());
}

TEST(DeformationGraph, RepeatedSolvesAreBitIdentical) {
  // Later iterations reuse an earlier factor as a preconditioner: the result must still be a
  // pure function of the input.
  const std::vector<Vec3> points = boxPoints(Vec3(0.0), Vec3(3.0, 1.0, 1.0), 4000, 12);
  std::vector<Vec3> handles, targets;
  for (const Vec3& p : points) {
    if (p.x < 0.3 || p.x > 2.7) {
      handles.push_back(p);
      targets.push_back(p.x < 0.3 ? p : p + Vec3(0.0, 0.6, 0.2));
    }
  }
  DeformationGraph first(points, spacingOf(0.3));
  DeformationGraph second(points, spacingOf(0.3));
  const DeformationGraphReport a = first.solve(handles, targets);
  const DeformationGraphReport b = second.solve(handles, targets);
  EXPECT_GT(a.iterations, 1);
  EXPECT_TRUE(nonIncreasing(a.energies));
  EXPECT_EQ(a.energies, b.energies);
  for (std::size_t j = 0; j < first.nodeCount(); ++j) {
    EXPECT_EQ(first.affineMaps()[j], second.affineMaps()[j]) << j;
    EXPECT_EQ(first.translations()[j], second.translations()[j]) << j;
  }
}

TEST(DeformationGraph, ReusedAnalysisGivesTheSameSolveAsAFreshGraph) {
  // The second solve on `reused` takes the cached symbolic analysis; the result must equal a
  // fresh graph's bit for bit (the numeric factorisation is never carried over).
  const std::vector<Vec3> points = boxPoints(Vec3(0.0), Vec3(3.0, 1.0, 1.0), 3000, 14);
  std::vector<Vec3> handles, targets, otherTargets;
  for (const Vec3& p : points) {
    if (p.x < 0.3 || p.x > 2.7) {
      handles.push_back(p);
      targets.push_back(p.x < 0.3 ? p : p + Vec3(0.0, 0.6, 0.2));
      otherTargets.push_back(p.x < 0.3 ? p : p + Vec3(0.0, -0.4, 0.5));
    }
  }
  DeformationGraph reused(points, spacingOf(0.3));
  DeformationGraph fresh(points, spacingOf(0.3));
  reused.solve(handles, targets);
  reused.reset();
  const DeformationGraphReport a = reused.solve(handles, otherTargets);
  const DeformationGraphReport b = fresh.solve(handles, otherTargets);
  EXPECT_EQ(a.energies, b.energies);
  for (std::size_t j = 0; j < fresh.nodeCount(); ++j) {
    EXPECT_EQ(reused.affineMaps()[j], fresh.affineMaps()[j]) << j;
    EXPECT_EQ(reused.translations()[j], fresh.translations()[j]) << j;
  }
}

TEST(DeformationGraph, ComponentsWithoutConstraintsStayInPlace) {
  std::vector<Vec3> points = boxPoints(Vec3(0.0), Vec3(1.0), 1500, 9);
  const std::vector<Vec3> far = boxPoints(Vec3(50.0), Vec3(51.0), 1500, 10);
  points.insert(points.end(), far.begin(), far.end());
  DeformationGraph graph(points, spacingOf(0.25));
  const std::vector<Vec3> handles{Vec3(0.0), Vec3(1.0)};
  const std::vector<Vec3> targets{Vec3(0.0), Vec3(1.3, 1.2, 1.0)};
  const DeformationGraphReport report = graph.solve(handles, targets);
  EXPECT_EQ(report.componentCount, 2);
  EXPECT_EQ(report.unconstrainedComponents, 1);
  ASSERT_FALSE(report.unconstrainedNodes.empty());
  for (std::uint32_t j : report.unconstrainedNodes) {
    EXPECT_GE(graph.nodes()[j].x, 50.0);
    EXPECT_EQ(graph.affineMaps()[j], Mat3(1.0));
    EXPECT_EQ(graph.translations()[j], Vec3(0.0));
  }
  std::size_t farNodes = 0;
  for (const Vec3& g : graph.nodes()) farNodes += g.x >= 50.0 ? 1 : 0;
  EXPECT_EQ(report.unconstrainedNodes.size(), farNodes);
  const DeformationGraphWarp warp = graph.warp();
  for (const Vec3& x : far) EXPECT_EQ(warp.apply(x), x);
  EXPECT_GT(glm::length(warp.apply(Vec3(1.0)) - Vec3(1.0)), 0.1);
}

TEST(DeformationGraph, ExplicitNodesAndNoHandles) {
  std::vector<Vec3> nodes;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      for (int k = 0; k < 3; ++k) nodes.emplace_back(i, j, k);
  DeformationGraph graph(nodes, {}, spacingOf(0.0));
  EXPECT_EQ(graph.nodeCount(), 27u);
  const DeformationGraphReport report = graph.solve({}, {});
  EXPECT_TRUE(report.converged);
  EXPECT_EQ(report.unconstrainedComponents, report.componentCount);
  EXPECT_EQ(report.unconstrainedNodes.size(), 27u);
}

TEST(DeformationGraphWarp, JacobianMatchesFiniteDifferencesAndBatchIsDeterministic) {
  const std::vector<Vec3> points = boxPoints(Vec3(0.0), Vec3(2.0, 1.0, 1.0), 3000, 11);
  DeformationGraph graph(points, spacingOf(0.3));
  std::vector<Vec3> handles{Vec3(0.0), Vec3(0.0, 1.0, 1.0), Vec3(2.0, 0.0, 0.0),
                            Vec3(2.0, 1.0, 1.0)};
  std::vector<Vec3> targets{Vec3(0.0), Vec3(0.0, 1.0, 1.0), Vec3(2.2, 0.5, 0.1),
                            Vec3(1.9, 1.4, 1.2)};
  graph.solve(handles, targets);
  const DeformationGraphWarp warp = graph.warp();
  std::mt19937 rng(12);
  const std::vector<Vec3> probes = test::randomPoints(rng, 60, 0.0, 1.0);
  for (const Vec3& x : probes) {
    const Mat3 fd = test::finiteDifferenceJacobian(warp, x, 1e-5);
    EXPECT_LE(test::relativeError(warp.jacobian(x), fd), 1e-6) << test::toString(x);
  }
  const std::vector<Vec3> many = test::randomPoints(rng, 20000, -0.5, 2.5);
  EXPECT_TRUE(test::batchIsDeterministic(warp, many));
  test::expectBatchRejectsMismatchedSizes(warp, 3, 4);
}

TEST(DeformationGraph, RejectsInvalidParameters) {
  const std::vector<Vec3> points = boxPoints(Vec3(0.0), Vec3(1.0), 500, 13);
  const auto build = [&](double spacing, int k) {
    DeformationGraph g(points, spacingOf(spacing, k));
  };
  EXPECT_THAT(test::messageOf<InvalidInput>([&] { build(0.0, 4); }), HasSubstr("spacing"));
  EXPECT_THAT(test::messageOf<InvalidInput>([&] { build(-1.0, 4); }), HasSubstr("spacing"));
  EXPECT_THAT(
      test::messageOf<InvalidInput>([&] { build(std::numeric_limits<double>::quiet_NaN(), 4); }),
      HasSubstr("spacing"));
  EXPECT_THAT(test::messageOf<InvalidInput>([&] { build(0.1, 0); }), HasSubstr("k = 0"));
  // One cell: a single node, so k = 4 cannot be met.
  EXPECT_THAT(test::messageOf<InvalidInput>([&] { build(10.0, 4); }), HasSubstr("the graph has 1"));
  EXPECT_THAT(test::messageOf<InvalidInput>(
                  [&] { DeformationGraph g(std::vector<Vec3>{}, spacingOf(0.1)); }),
              HasSubstr("no positions"));
  EXPECT_THAT(test::messageOf<InvalidInput>([&] {
                DeformationGraph g(std::vector<Vec3>{}, std::vector<Vec3>{}, spacingOf(0.1));
              }),
              HasSubstr("no nodes"));
  std::vector<Vec3> bad = points;
  bad[17].y = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THAT(test::messageOf<InvalidInput>([&] { DeformationGraph g(bad, spacingOf(0.2)); }),
              HasSubstr("positions[17]"));
  const std::vector<Vec3> five{Vec3(0.0), Vec3(1.0, 0.0, 0.0), Vec3(0.0, 1.0, 0.0),
                               Vec3(0.0, 0.0, 1.0), Vec3(1.0)};
  EXPECT_THAT(
      test::messageOf<InvalidInput>([&] { DeformationGraph g(five, {}, spacingOf(0.0, 5)); }),
      HasSubstr("k = 5"));

  DeformationGraph graph(points, spacingOf(0.25));
  EXPECT_THAT(test::messageOf<InvalidInput>(
                  [&] { graph.solve(std::vector<Vec3>{Vec3(0.0)}, std::vector<Vec3>{}); }),
              HasSubstr("1 handles but 0 targets"));
  EXPECT_THAT(test::messageOf<InvalidInput>([&] {
                graph.solve(std::vector<Vec3>{Vec3(0.0)},
                            std::vector<Vec3>{Vec3(std::numeric_limits<double>::infinity())});
              }),
              HasSubstr("targets[0]"));
  DeformationGraphSolveOptions options;
  options.regularizationWeight = -1.0;
  EXPECT_THAT(test::messageOf<InvalidInput>([&] {
                graph.solve(std::vector<Vec3>{Vec3(0.0)}, std::vector<Vec3>{Vec3(0.0)}, options);
              }),
              HasSubstr("regularizationWeight"));
  EXPECT_THROW(graph.weights(Vec3(std::numeric_limits<double>::quiet_NaN())), InvalidInput);
}

TEST(DeformationGraphWarp, DeformCarriesNormalsThroughTheJacobian) {
  const std::vector<Vec3> points = boxPoints(Vec3(0.0), Vec3(1.0), 1500, 14);
  DeformationGraph graph(points, spacingOf(0.25));
  const Mat3 r = rotation(Vec3(0.0, 0.0, 1.0), 0.5);
  std::vector<Vec3> handles, targets;
  for (std::size_t i = 0; i < points.size(); i += 50) {
    handles.push_back(points[i]);
    targets.push_back(r * points[i]);
  }
  DeformationGraphSolveOptions options;
  options.tolerance = 1e-12;
  graph.solve(handles, targets, options);
  PointSet cloud;
  cloud.positions.assign(points.begin(), points.begin() + 100);
  cloud.normals.assign(100, Vec3(1.0, 0.0, 0.0));
  deform(graph.warp(), cloud);
  // A rigid edit: normals turn with the rotation.
  for (const Vec3& n : cloud.normals) EXPECT_LE(glm::length(n - r * Vec3(1.0, 0.0, 0.0)), 1e-5);
}
