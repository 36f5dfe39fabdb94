// Tests of ffd/lattice_coordinates.h: dense and sparse rows agree, partition of unity, analytic
// gradients, and binding equals the warp.

#include <spacewarp/ffd/lattice_coordinates.h>

#include <memory>
#include <random>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <spacewarp/coords/properties.h>
#include <spacewarp/core/binding.h>
#include <spacewarp/core/coordinate_warp.h>
#include <spacewarp/core/errors.h>
#include <spacewarp/ffd/lattice_warp.h>
#include "ffd_test_shapes.h"
#include "placement.h"
#include "test_util.h"

namespace spacewarp {
namespace {

using ::testing::HasSubstr;

TEST(LatticeCoordinates, SparseRowsEqualDenseRowsAndSumToOneInside) {
  std::mt19937 rng(20);
  for (LatticeBasis basis : test::kAllBases) {
    const LatticeCoordinates coords{Lattice(test::orientedParams(basis, LatticeOutside::Clamp))};
    EXPECT_EQ(coords.columnCount(), coords.controlPointCount());
    std::vector<double> dense(coords.columnCount());
    std::vector<SparseWeight> sparse(coords.maxNonZeros());
    const auto inside = test::boxPoints(coords.lattice(), rng, 100);
    for (const Vec3& x : test::boxPoints(coords.lattice(), rng, 100, -0.5, 1.5)) {
      coords.weights(x, dense);
      std::vector<double> fromSparse(coords.columnCount(), 0.0);
      const std::size_t n = coords.sparseWeights(x, sparse);
      for (std::size_t e = 0; e < n; ++e) fromSparse[sparse[e].column] = sparse[e].weight;
      EXPECT_EQ(fromSparse, dense) << test::basisName(basis);
    }
    for (const Vec3& x : inside) {
      coords.weights(x, dense);
      double sum = 0.0;
      for (double w : dense) sum += w;
      EXPECT_NEAR(sum, 1.0, 1e-14) << test::basisName(basis);
    }
  }
}

TEST(LatticeCoordinates, WeightGradientsMatchFiniteDifferences) {
  std::mt19937 rng(21);
  for (LatticeBasis basis : test::kAllBases) {
    for (LatticeOutside outside :
         {LatticeOutside::Identity, LatticeOutside::Clamp, LatticeOutside::Falloff}) {
      const LatticeCoordinates coords{Lattice(test::orientedParams(basis, outside))};
      const std::size_t m = coords.columnCount();
      std::vector<Vec3> gradients(m);
      std::vector<double> plus(m), minus(m);
      std::vector<Vec3> points;
      // Cell interiors (trilinear weights have kinks at cell boundaries): u = (c + 0.5 ±
      // 0.3)/cells.
      for (int i = 0; i < 30; ++i) {
        Vec3 local;
        for (int a = 0; a < 3; ++a) {
          const int cells = coords.lattice().resolution()[a] - 1;
          local[a] = (static_cast<int>(rng() % static_cast<unsigned>(cells)) + 0.5 +
                      test::randomPoint(rng, -0.3, 0.3).x) /
                     cells;
        }
        points.push_back(coords.lattice().toWorld(local));
      }
      if (outside != LatticeOutside::Identity)  // beyond +u (in the falloff shell)
        for (int i = 0; i < 10; ++i)
          points.push_back(coords.lattice().toWorld(Vec3(1.05, 0.3 + 0.04 * i, 0.55)));
      for (const Vec3& x : points) {
        ASSERT_TRUE(coords.weightGradients(x, gradients));
        const double h = 1e-6;
        for (int a = 0; a < 3; ++a) {
          Vec3 e(0.0);
          e[a] = h;
          coords.weights(x + e, plus);
          coords.weights(x - e, minus);
          for (std::size_t c = 0; c < m; ++c) {
            const double fd = (plus[c] - minus[c]) / (2.0 * h);
            EXPECT_NEAR(gradients[c][a], fd, 1e-6 * std::max(1.0, std::abs(fd)))
                << test::basisName(basis) << " column " << c << " axis " << a;
          }
        }
      }
    }
  }
}

TEST(LatticeCoordinates, BindingDeformEqualsTheWarp) {
  std::mt19937 rng(22);
  for (LatticeBasis basis : test::kAllBases) {
    for (LatticeOutside outside :
         {LatticeOutside::Identity, LatticeOutside::Clamp, LatticeOutside::Falloff}) {
      const Lattice lattice(test::orientedParams(basis, outside));
      auto coords = std::make_shared<LatticeCoordinates>(lattice);
      const std::vector<Vec3> posed = test::randomPose(lattice, rng, 0.4);
      const std::vector<Vec3> points = test::boxPoints(lattice, rng, 2000, -0.3, 1.3);
      const Binding binding(coords, points);
      EXPECT_EQ(binding.isSparse(), 4 * coords->maxNonZeros() <= coords->columnCount());
      const std::vector<Vec3> bound = binding.deform(posed);
      const LatticeWarp warp(lattice, posed);
      std::vector<Vec3> direct(points.size());
      warp.applyBatch(points, direct);
      const CoordinateWarp generic(coords, posed);
      for (std::size_t i = 0; i < points.size(); ++i) {
        EXPECT_LE(test::relativeError(bound[i], direct[i]), 1e-12) << test::basisName(basis) << i;
        EXPECT_LE(test::relativeError(generic.apply(points[i]), direct[i]), 1e-12);
      }
      // And the generic coordinate Jacobian (from the weight gradients) equals the warp's.
      for (std::size_t i = 0; i < 20; ++i)
        EXPECT_LE(test::relativeError(generic.jacobian(points[i]), warp.jacobian(points[i])),
                  1e-12);
    }
  }
}

TEST(LatticeCoordinates, LargeBSplineLatticesBindSparsely) {
  std::mt19937 rng(23);
  LatticeOptions p;
  p.basis = LatticeBasis::BSpline;
  p.resolution = {8, 8, 9};
  const Lattice lattice(p);
  auto coords = std::make_shared<LatticeCoordinates>(lattice);
  const std::vector<Vec3> points = test::boxPoints(lattice, rng, 1000);
  const Binding binding(coords, points);
  ASSERT_TRUE(binding.isSparse());
  const std::vector<Vec3> posed = test::randomPose(lattice, rng, 0.5);
  const std::vector<Vec3> bound = binding.deform(posed);
  const LatticeWarp warp(lattice, posed);
  for (std::size_t i = 0; i < points.size(); ++i)
    EXPECT_LE(test::relativeError(bound[i], warp.apply(points[i])), 1e-12) << i;
}

TEST(LatticeCoordinates, RejectsBadArguments) {
  const LatticeCoordinates coords{Lattice(LatticeOptions{})};
  std::vector<double> row(7);
  EXPECT_THAT(test::messageOf<InvalidInput>([&] { coords.weights(Vec3(0.5), row); }),
              HasSubstr("7 entries but there are 8 columns"));
  std::vector<Vec3> gradients(9);
  EXPECT_THAT(test::messageOf<InvalidInput>([&] { coords.weightGradients(Vec3(0.5), gradients); }),
              HasSubstr("9 entries, 8 expected"));
}

// Issue 12: a lattice far from the origin and of any size has the weights of the lattice at the
// origin (box coordinates are relative to the lattice's corner), and keeps partition of unity
// and linear precision relative to its size. Bound: see tests/placement.h.
class LatticePlaced : public ::testing::TestWithParam<test::Placement> {};

TEST_P(LatticePlaced, WeightsAndPropertiesDoNotDependOnOffsetOrScale) {
  const test::Placement at = GetParam();
  for (const LatticeBasis basis : {LatticeBasis::Trilinear, LatticeBasis::Bernstein}) {
    const LatticeOptions params = test::orientedParams(basis);
    LatticeOptions placedParams = params;
    placedParams.origin = test::place(params.origin, at);
    placedParams.extents = params.extents * at.scale;
    const LatticeCoordinates base{Lattice(params)}, placed{Lattice(placedParams)};
    std::mt19937 rng(41);
    const std::vector<Vec3> samples = test::boxPoints(base.lattice(), rng, 60, 0.01, 0.99);
    std::vector<Vec3> placedSamples;
    for (const Vec3& x : samples) placedSamples.push_back(test::place(x, at));
    const double diagonal = placed.lattice().diagonal();
    const double tolerance = 1e-12 + 10.0 * test::placementResolution(at, diagonal);
    EXPECT_LE(test::placedWeightError(base, placed, samples, at), tolerance)
        << test::basisName(basis);
    const PropertyReport report = measureProperties(placed, placedSamples, diagonal);
    EXPECT_LE(report.partitionOfUnity, tolerance) << test::basisName(basis);
    EXPECT_LE(report.linearReproduction, tolerance) << test::basisName(basis);
    EXPECT_LE(report.similarityReproduction, tolerance) << test::basisName(basis);
  }
}

INSTANTIATE_TEST_SUITE_P(Placements, LatticePlaced, ::testing::ValuesIn(test::placements()),
                         [](const auto& info) { return test::placementName(info.param); });

// makeWarp gives the lattice's own warp; a CoordinateWarp over the same (sparse) coordinates
// sums only the non-zero weights, and its batch is bit-identical to its apply().
TEST(LatticeCoordinates, MakeWarpGivesTheLatticeWarpAndTheGenericWarpSumsSparsely) {
  std::mt19937 rng(24);
  for (LatticeBasis basis : test::kAllBases) {
    const Lattice lattice(test::orientedParams(basis, LatticeOutside::Clamp));
    auto coords = std::make_shared<LatticeCoordinates>(lattice);
    const std::vector<Vec3> posed = test::randomPose(lattice, rng, 0.4);
    const std::vector<Vec3> points = test::boxPoints(lattice, rng, 3000, -0.3, 1.3);
    const std::shared_ptr<const Warp> made = makeWarp(coords, posed);
    ASSERT_NE(dynamic_cast<const LatticeWarp*>(made.get()), nullptr);
    const LatticeWarp direct(lattice, posed);
    const CoordinateWarp generic(coords, posed);
    std::vector<Vec3> batch(points.size());
    generic.applyBatch(points, batch);
    for (std::size_t i = 0; i < points.size(); ++i) {
      EXPECT_EQ(made->apply(points[i]), direct.apply(points[i]));
      EXPECT_EQ(batch[i], generic.apply(points[i])) << test::basisName(basis) << i;
      EXPECT_LE(test::relativeError(batch[i], direct.apply(points[i])), 1e-12);
    }
  }
}

}  // namespace
}  // namespace spacewarp
