// Tests of ffd/lattice_warp.h: identity at rest, affine precision, continuity (C² for the
// cubic B-spline), the outside policies, the analytic Jacobian and the batch kernel.

#include <spacewarp/ffd/lattice_warp.h>

#include <cmath>
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

const std::vector<LatticeOutside> kAllOutside = {LatticeOutside::Identity, LatticeOutside::Clamp,
                                                 LatticeOutside::Falloff};

LatticeWarp posedWarp(LatticeBasis basis, LatticeOutside outside, std::mt19937& rng,
                      double amount = 0.3) {
  const Lattice lattice(test::orientedParams(basis, outside));
  return LatticeWarp(lattice, test::randomPose(lattice, rng, amount));
}

// Points in the interiors of the cells (≥ 5% of a cell from every cell boundary), where even
// the trilinear warp is smooth.
std::vector<Vec3> cellInteriorPoints(const Lattice& lattice, std::mt19937& rng, std::size_t n) {
  std::uniform_real_distribution<double> frac(0.05, 0.95);
  std::vector<Vec3> points(n);
  for (Vec3& p : points) {
    Vec3 local;
    for (int a = 0; a < 3; ++a) {
      const int cells = lattice.resolution()[a] - 1;
      const int c = static_cast<int>(rng() % static_cast<unsigned>(cells));
      local[a] = (c + frac(rng)) / cells;
    }
    p = lattice.toWorld(local);
  }
  return points;
}

TEST(LatticeWarp, IdentityAtRestEverywhere) {
  std::mt19937 rng(10);
  for (LatticeBasis basis : test::kAllBases) {
    for (LatticeOutside outside : kAllOutside) {
      const Lattice lattice(test::orientedParams(basis, outside));
      const LatticeWarp warp(lattice, lattice.restControlPoints());
      std::vector<Vec3> points = test::boxPoints(lattice, rng, 200, -0.5, 1.5);
      for (const Vec3& local : test::facePointsLocal(rng, 10))
        points.push_back(lattice.toWorld(local));
      std::vector<Vec3> batch(points.size());
      warp.applyBatch(points, batch);
      for (std::size_t i = 0; i < points.size(); ++i) {
        EXPECT_LE(test::relativeError(warp.apply(points[i]), points[i]), 1e-13)
            << test::basisName(basis) << " point " << i;
        EXPECT_LE(test::relativeError(batch[i], points[i]), 1e-13);
      }
    }
  }
}

TEST(LatticeWarp, ReproducesAffineMapsOfItsControls) {
  std::mt19937 rng(11);
  // x -> A x + t with a general (non-orthogonal) A.
  Mat3 a;
  for (int c = 0; c < 3; ++c) a[c] = test::randomPoint(rng, -1.0, 1.0);
  a += Mat3(1.5);
  const Vec3 t(0.3, -0.7, 1.1);
  for (LatticeBasis basis : test::kAllBases) {
    const Lattice lattice(test::orientedParams(basis));
    std::vector<Vec3> posed;
    for (const Vec3& p : lattice.restControlPoints()) posed.push_back(a * p + t);
    const LatticeWarp warp(lattice, posed);
    std::vector<Vec3> points = test::boxPoints(lattice, rng, 300);
    for (const Vec3& local : test::facePointsLocal(rng, 10))
      points.push_back(lattice.toWorld(local));
    for (std::size_t i = 0; i < points.size(); ++i) {
      const Vec3 expected = a * points[i] + t;
      EXPECT_LE(test::relativeError(warp.apply(points[i]), expected), 1e-12)
          << test::basisName(basis) << " point " << i;
    }
    // The Jacobian of an affine pose is A everywhere inside.
    for (std::size_t i = 0; i < 20; ++i)
      EXPECT_LE(test::relativeError(warp.jacobian(points[i]), a), 1e-12) << test::basisName(basis);
  }
}

TEST(LatticeWarp, BSplineIsC2AcrossCellBoundaries) {
  std::mt19937 rng(12);
  const LatticeWarp warp = posedWarp(LatticeBasis::BSpline, LatticeOutside::Identity, rng, 0.8);
  const Lattice& lattice = warp.lattice();
  const auto& params = lattice.params();
  for (int axis = 0; axis < 3; ++axis) {
    const int cells = lattice.resolution()[axis] - 1;
    for (int boundary = 1; boundary < cells; ++boundary) {
      Vec3 local = test::randomPoint(rng, 0.1, 0.9);
      local[axis] = double(boundary) / cells;
      const Vec3 x = lattice.toWorld(local);
      const Vec3 e = params.axes[axis];
      // One-sided second differences from either side converge to the same second derivative:
      // their gap shrinks like h (it would stay O(1) for a C¹ spline).
      double previousGap = 0.0;
      for (double h : {1e-2, 1e-3}) {
        const Vec3 above =
            (warp.apply(x + 2.0 * h * e) - 2.0 * warp.apply(x + h * e) + warp.apply(x)) / (h * h);
        const Vec3 below =
            (warp.apply(x) - 2.0 * warp.apply(x - h * e) + warp.apply(x - 2.0 * h * e)) / (h * h);
        const double gap = glm::length(above - below);
        const double size = std::max(1.0, glm::length(above));
        EXPECT_LE(gap, 50.0 * h * size)
            << "axis " << axis << " boundary " << boundary << " h " << h;
        if (previousGap > 1e-6) {
          EXPECT_LT(gap, 0.3 * previousGap) << "axis " << axis;
        }
        previousGap = gap;
      }
    }
  }
}

TEST(LatticeWarp, TrilinearIsOnlyC0AcrossCellBoundaries) {
  // The contrast that makes the C² test meaningful: the trilinear warp's first derivative jumps.
  std::mt19937 rng(13);
  const LatticeWarp warp = posedWarp(LatticeBasis::Trilinear, LatticeOutside::Identity, rng, 0.8);
  const Lattice& lattice = warp.lattice();
  const Vec3 x = lattice.toWorld(Vec3(0.5, 0.4, 0.3));  // u = 0.5 is a cell boundary (5 controls)
  const Vec3 e = lattice.params().axes[0];
  const double h = 1e-6;
  const Vec3 above = (warp.apply(x + h * e) - warp.apply(x)) / h;
  const Vec3 below = (warp.apply(x) - warp.apply(x - h * e)) / h;
  EXPECT_GT(glm::length(above - below), 1e-3);
  EXPECT_LE(glm::length(warp.apply(x + 1e-12 * e) - warp.apply(x - 1e-12 * e)), 1e-11);
}

TEST(LatticeWarp, PointsOnTheFacesDeformLikeTheirNeighbours) {
  std::mt19937 rng(14);
  for (LatticeBasis basis : test::kAllBases) {
    for (LatticeOutside outside : kAllOutside) {
      const LatticeWarp warp = posedWarp(basis, outside, rng);
      const Lattice& lattice = warp.lattice();
      for (const Vec3& local : test::facePointsLocal(rng, 10)) {
        // The neighbour 1e-9 box extents inside.
        const Vec3 inward = local + 1e-9 * (Vec3(0.5) - local) / glm::length(Vec3(0.5) - local);
        const Vec3 x = lattice.toWorld(local);
        EXPECT_LE(glm::length(warp.apply(x) - warp.apply(lattice.toWorld(inward))), 1e-8)
            << test::basisName(basis) << " " << test::toString(local);
      }
    }
  }
}

TEST(LatticeWarp, IdentityOutsidePolicyLeavesOutsidePointsAlone) {
  std::mt19937 rng(15);
  for (LatticeBasis basis : test::kAllBases) {
    const LatticeWarp warp = posedWarp(basis, LatticeOutside::Identity, rng);
    for (const Vec3& x : test::randomPointsWhere(rng, 200, -10.0, 10.0, [&](const Vec3& p) {
           const Vec3 u = warp.lattice().toLocal(p);
           return u.x < -1e-9 || u.x > 1 + 1e-9 || u.y < -1e-9 || u.y > 1 + 1e-9 || u.z < -1e-9 ||
                  u.z > 1 + 1e-9;
         }))
      EXPECT_EQ(warp.apply(x), x);
  }
}

// The point of the box surface nearest to x.
Vec3 nearestOnBox(const Lattice& lattice, const Vec3& x) {
  return lattice.toWorld(glm::clamp(lattice.toLocal(x), Vec3(0.0), Vec3(1.0)));
}

TEST(LatticeWarp, ClampMovesOutsidePointsWithTheNearestSurfacePoint) {
  std::mt19937 rng(16);
  for (LatticeBasis basis : test::kAllBases) {
    const LatticeWarp warp = posedWarp(basis, LatticeOutside::Clamp, rng);
    const Lattice& lattice = warp.lattice();
    for (const Vec3& x : test::boxPoints(lattice, rng, 200, -1.0, 2.0)) {
      const Vec3 p = nearestOnBox(lattice, x);
      EXPECT_LE(glm::length((warp.apply(x) - x) - (warp.apply(p) - p)), 1e-12)
          << test::basisName(basis) << " " << test::toString(x);
    }
    // Continuous across the surface (for any pose).
    for (const Vec3& local : test::facePointsLocal(rng, 10)) {
      const Vec3 out = local + 1e-10 * (local - Vec3(0.5));
      const Vec3 in = local - 1e-10 * (local - Vec3(0.5));
      EXPECT_LE(glm::length(warp.apply(lattice.toWorld(out)) - warp.apply(lattice.toWorld(in))),
                1e-8);
    }
  }
}

TEST(LatticeWarp, FalloffFadesToIdentityOverTheDocumentedDistance) {
  std::mt19937 rng(17);
  for (LatticeBasis basis : test::kAllBases) {
    const LatticeWarp warp = posedWarp(basis, LatticeOutside::Falloff, rng);
    const Lattice& lattice = warp.lattice();
    const double radius = lattice.params().falloff * lattice.diagonal();
    for (const Vec3& x : test::boxPoints(lattice, rng, 400, -0.5, 1.5)) {
      const Vec3 p = nearestOnBox(lattice, x);
      const double r = glm::length(x - p);
      const double t = std::min(r / radius, 1.0);
      const double s = 1.0 - t * t * (3.0 - 2.0 * t);
      const Vec3 expected = x + s * (warp.apply(p) - p);
      EXPECT_LE(glm::length(warp.apply(x) - expected), 1e-12) << test::toString(x);
      if (r >= radius) {
        EXPECT_EQ(warp.apply(x), x);
      }
    }
    // Continuous across the surface, and at the falloff distance.
    for (const Vec3& local : test::facePointsLocal(rng, 10)) {
      const Vec3 dir = (local - Vec3(0.5)) / glm::length(local - Vec3(0.5));
      const Vec3 out = local + 1e-10 * dir;
      const Vec3 in = local - 1e-10 * dir;
      EXPECT_LE(glm::length(warp.apply(lattice.toWorld(out)) - warp.apply(lattice.toWorld(in))),
                1e-8);
    }
    const Vec3 face = lattice.toWorld(Vec3(1.0, 0.5, 0.5));
    const Vec3 normal = lattice.params().axes[0];
    const Vec3 nearLimit = face + (radius - 1e-7) * normal;
    EXPECT_LE(glm::length(warp.apply(nearLimit) - nearLimit), 1e-9);
  }
}

TEST(LatticeWarp, JacobianMatchesFiniteDifferences) {
  std::mt19937 rng(18);
  for (LatticeBasis basis : test::kAllBases) {
    for (LatticeOutside outside : kAllOutside) {
      const LatticeWarp warp = posedWarp(basis, outside, rng);
      const Lattice& lattice = warp.lattice();
      std::vector<Vec3> points = cellInteriorPoints(lattice, rng, 100);
      if (outside != LatticeOutside::Identity) {
        // Outside, in the face region of +u and the edge region of (−v, +w), away from the
        // region boundaries and (for Falloff) inside the falloff shell.
        for (std::size_t i = 0; i < 20; ++i) {
          Vec3 local = lattice.toLocal(cellInteriorPoints(lattice, rng, 1)[0]);
          local.x = 1.0 + 0.01 + 0.02 * (i % 3);
          points.push_back(lattice.toWorld(local));
          local.y = -0.02;
          local.z = 1.03;
          points.push_back(lattice.toWorld(local));
        }
      }
      EXPECT_TRUE(test::jacobianMatchesFiniteDifferences(warp, points))
          << test::basisName(basis) << " outside " << static_cast<int>(outside);
    }
  }
}

TEST(LatticeWarp, BatchIsDeterministicAndEqualsApply) {
  std::mt19937 rng(19);
  for (LatticeBasis basis : test::kAllBases) {
    for (LatticeOutside outside : kAllOutside) {
      const LatticeWarp warp = posedWarp(basis, outside, rng);
      const std::vector<Vec3> points = test::boxPoints(warp.lattice(), rng, 20000, -0.2, 1.2);
      EXPECT_TRUE(test::batchIsDeterministic(warp, points)) << test::basisName(basis);
    }
  }
}

TEST(LatticeWarp, NonFinitePointsGiveNonFiniteResultsWithoutCrashing) {
  std::mt19937 rng(20);
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  for (LatticeBasis basis : test::kAllBases) {
    for (LatticeOutside outside : kAllOutside) {
      const LatticeWarp warp = posedWarp(basis, outside, rng);
      const std::vector<Vec3> points = {Vec3(nan, 0.0, 0.0), Vec3(0.0, inf, 0.0),
                                        Vec3(0.0, 0.0, -inf)};
      std::vector<Vec3> out(points.size());
      warp.applyBatch(points, out);
      for (const Vec3& y : out) EXPECT_FALSE(isFinite(y)) << test::basisName(basis);
    }
  }
}

TEST(LatticeWarp, RejectsBadInput) {
  const Lattice lattice(LatticeOptions{});
  std::vector<Vec3> posed(lattice.restControlPoints().begin(), lattice.restControlPoints().end());
  EXPECT_THAT(test::messageOf<InvalidInput>(
                  [&] { LatticeWarp(lattice, std::span<const Vec3>(posed).first(7)); }),
              HasSubstr("7 posed control points given, the lattice has 8"));
  posed[5].y = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THAT(test::messageOf<InvalidInput>([&] { LatticeWarp(lattice, posed); }),
              HasSubstr("posed control point 5 is not finite"));
  posed[5].y = 0.0;
  const LatticeWarp warp(lattice, posed);
  test::expectBatchRejectsMismatchedSizes(warp, 3, 4);
}

}  // namespace
}  // namespace spacewarp
