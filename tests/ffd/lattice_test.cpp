// Tests of ffd/lattice.h: validation, the rest grid, and the weights on, inside and outside the
// box for every basis and outside policy.

#include <spacewarp/ffd/lattice.h>

#include <random>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <spacewarp/core/errors.h>
#include "ffd_test_shapes.h"
#include "test_util.h"

namespace spacewarp {
namespace {

using ::testing::HasSubstr;

// Σ w_c and Σ w_c P⁰_c of a point.
struct Moments {
  double sum = 0.0;
  Vec3 reproduced{0.0};
};

Moments momentsOf(const Lattice& lattice, const Vec3& x) {
  std::vector<SparseWeight> row(lattice.maxNonZeros());
  const std::size_t n = lattice.sparseWeights(x, row);
  Moments m;
  for (std::size_t e = 0; e < n; ++e) {
    m.sum += row[e].weight;
    m.reproduced += row[e].weight * lattice.restControlPoints()[row[e].column];
  }
  return m;
}

TEST(Lattice, RestGridIsRegularWithIFastest) {
  const Lattice lattice(test::orientedParams(LatticeBasis::Trilinear));
  const auto [l, m, n] = lattice.resolution();
  ASSERT_EQ(lattice.controlPointCount(), static_cast<std::size_t>(l * m * n));
  EXPECT_EQ(lattice.index(1, 0, 0), 1u);
  EXPECT_EQ(lattice.index(0, 1, 0), static_cast<std::size_t>(l));
  EXPECT_EQ(lattice.index(0, 0, 1), static_cast<std::size_t>(l * m));
  for (int k = 0; k < n; ++k)
    for (int j = 0; j < m; ++j)
      for (int i = 0; i < l; ++i) {
        const Vec3 local = lattice.toLocal(lattice.restControlPoints()[lattice.index(i, j, k)]);
        EXPECT_NEAR(local.x, double(i) / (l - 1), 1e-15);
        EXPECT_NEAR(local.y, double(j) / (m - 1), 1e-15);
        EXPECT_NEAR(local.z, double(k) / (n - 1), 1e-15);
      }
  EXPECT_NEAR(lattice.diagonal(), std::sqrt(14.0), 1e-15);
}

TEST(Lattice, WeightsArePartitionOfUnityAndReproduceXInsideAndOnTheFaces) {
  std::mt19937 rng(1);
  for (LatticeBasis basis : test::kAllBases) {
    const Lattice lattice(test::orientedParams(basis));
    std::vector<Vec3> points = test::boxPoints(lattice, rng, 300);
    for (const Vec3& local : test::facePointsLocal(rng, 20))
      points.push_back(lattice.toWorld(local));
    for (std::size_t i = 0; i < points.size(); ++i) {
      const Moments m = momentsOf(lattice, points[i]);
      EXPECT_NEAR(m.sum, 1.0, 1e-14) << test::basisName(basis) << " point " << i;
      EXPECT_LE(test::relativeError(m.reproduced, points[i]), 1e-13)
          << test::basisName(basis) << " point " << i << " " << test::toString(points[i]);
    }
  }
}

TEST(Lattice, TheUpperFaceUsesTheLastCell) {
  // PyGeM issue #272: u = 1 must not fall outside the last cell.
  for (LatticeBasis basis : test::kAllBases) {
    LatticeOptions p;
    p.resolution = {4, 4, 4};
    p.basis = basis;
    const Lattice lattice(p);
    std::vector<SparseWeight> row(lattice.maxNonZeros());
    const std::size_t n = lattice.sparseWeights(Vec3(1.0), row);
    ASSERT_GT(n, 0u) << test::basisName(basis);
    // Every basis interpolates the corner control points.
    double corner = 0.0;
    for (std::size_t e = 0; e < n; ++e)
      if (row[e].column == lattice.index(3, 3, 3)) corner = row[e].weight;
    EXPECT_NEAR(corner, 1.0, 1e-15) << test::basisName(basis);
  }
}

TEST(Lattice, SparseWeightsAreSortedAndBounded) {
  std::mt19937 rng(2);
  for (LatticeBasis basis : test::kAllBases) {
    const Lattice lattice(test::orientedParams(basis));
    EXPECT_EQ(lattice.maxNonZeros(), basis == LatticeBasis::Trilinear ? 8u
                                     : basis == LatticeBasis::BSpline
                                         ? 64u
                                         : lattice.controlPointCount());
    std::vector<SparseWeight> row(lattice.maxNonZeros());
    for (const Vec3& x : test::boxPoints(lattice, rng, 50)) {
      const std::size_t n = lattice.sparseWeights(x, row);
      EXPECT_EQ(n, lattice.maxNonZeros());
      for (std::size_t e = 1; e < n; ++e) EXPECT_LT(row[e - 1].column, row[e].column);
    }
  }
}

TEST(Lattice, OutsideWeightsFollowThePolicy) {
  std::mt19937 rng(3);
  for (LatticeBasis basis : test::kAllBases) {
    for (LatticeOutside outside :
         {LatticeOutside::Identity, LatticeOutside::Clamp, LatticeOutside::Falloff}) {
      const Lattice lattice(test::orientedParams(basis, outside));
      std::vector<SparseWeight> row(lattice.maxNonZeros());
      // Far outside: nothing moves except with Clamp, whose weights sum to 1.
      const Vec3 far = lattice.toWorld(Vec3(3.0, 0.5, -2.0));
      const std::size_t n = lattice.sparseWeights(far, row);
      if (outside == LatticeOutside::Clamp) {
        EXPECT_NEAR(momentsOf(lattice, far).sum, 1.0, 1e-14);
      } else {
        EXPECT_EQ(n, 0u) << test::basisName(basis);
      }
    }
  }
}

TEST(Lattice, RejectsDegenerateInput) {
  auto message = [](const LatticeOptions& p) {
    return test::messageOf<InvalidInput>([&] { Lattice lattice(p); });
  };
  const double nan = std::numeric_limits<double>::quiet_NaN();
  LatticeOptions p;
  p.resolution = {1, 2, 2};
  EXPECT_THAT(message(p), HasSubstr("resolution[0] is 1"));
  p.resolution = {4, 3, 4};
  p.basis = LatticeBasis::BSpline;
  EXPECT_THAT(message(p),
              HasSubstr("resolution[1] is 3, the cubic B-spline basis needs at least 4"));
  p.resolution = {2, 2, 33};
  p.basis = LatticeBasis::Bernstein;
  EXPECT_THAT(message(p), HasSubstr("resolution[2] is 33"));
  p = {};
  p.axes[1] = Vec3(1.0, 0.0, 0.0);
  EXPECT_THAT(message(p), HasSubstr("axes[0] and axes[1] are not orthogonal"));
  p = {};
  p.axes[2] = Vec3(0.0, 0.0, 2.0);
  EXPECT_THAT(message(p), HasSubstr("axes[2] is not a unit vector"));
  p = {};
  p.axes[2] = Vec3(0.0);
  EXPECT_THAT(message(p), HasSubstr("axes[2] is not a unit vector"));
  p = {};
  p.axes[0] = Vec3(nan, 0.0, 0.0);
  EXPECT_THAT(message(p), HasSubstr("axes[0] is not finite"));
  p = {};
  p.extents = Vec3(1.0, 0.0, 1.0);
  EXPECT_THAT(message(p), HasSubstr("extent 1 is 0"));
  p = {};
  p.extents = Vec3(1.0, 1.0, -1.0);
  EXPECT_THAT(message(p), HasSubstr("extent 2"));
  p = {};
  p.extents = Vec3(1.0, std::numeric_limits<double>::infinity(), 1.0);
  EXPECT_THAT(message(p), HasSubstr("extents are not finite"));
  p = {};
  p.origin = Vec3(nan);
  EXPECT_THAT(message(p), HasSubstr("origin is not finite"));
  p = {};
  p.falloff = 0.0;
  EXPECT_THAT(message(p), HasSubstr("falloff"));

  const Lattice lattice(LatticeOptions{});
  std::vector<SparseWeight> row(8), shortRow(7);
  EXPECT_THAT(test::messageOf<InvalidInput>([&] { lattice.sparseWeights(Vec3(nan), row); }),
              HasSubstr("not finite"));
  EXPECT_THAT(test::messageOf<InvalidInput>([&] { lattice.sparseWeights(Vec3(0.5), shortRow); }),
              HasSubstr("fewer than 8"));
}

}  // namespace
}  // namespace spacewarp
