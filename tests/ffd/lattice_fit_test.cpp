// Tests of ffd/lattice_fit.h: direct manipulation in least squares, and lattices fitted around
// geometry.

#include <spacewarp/ffd/lattice_fit.h>

#include <cmath>
#include <random>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <spacewarp/core/errors.h>
#include <spacewarp/core/geometry.h>
#include <spacewarp/ffd/lattice_warp.h>
#include "ffd_test_shapes.h"
#include "test_util.h"

namespace spacewarp {
namespace {

using ::testing::HasSubstr;

// A smooth, non-polynomial target map of the unit cube.
Vec3 smoothTarget(const Vec3& x) {
  return x + 0.1 * Vec3(std::sin(2.0 * x.y), std::cos(1.5 * x.z) * x.x, std::sin(x.x + x.y));
}

TEST(FitControlPoints, ReachesReachableTargetsExactly) {
  // Targets produced by a posed lattice are met (up to the small regulariser).
  std::mt19937 rng(30);
  for (LatticeBasis basis : test::kAllBases) {
    const Lattice lattice(test::orientedParams(basis));
    const LatticeWarp truth(lattice, test::randomPose(lattice, rng, 0.3));
    const std::vector<Vec3> from = test::boxPoints(lattice, rng, 3000);
    std::vector<Vec3> to(from.size());
    truth.applyBatch(from, to);
    LatticeFitOptions options;
    options.smoothness = 1e-10;
    test::ProgressLog progress{"fit lattice"};
    options.progress = progress.callback();
    const ControlPointFit fit = fitControlPoints(lattice, from, to, options);
    EXPECT_LE(fit.maxResidual, 1e-6) << test::basisName(basis);
    progress.expectFromZeroToOne();
    EXPECT_EQ(progress.fractions, (std::vector<double>{0.0, 0.5, 1.0}));
    EXPECT_LE(fit.rmsResidual, fit.maxResidual);
    // The reported residuals are those of the returned controls.
    const LatticeWarp warp(lattice, fit.controlPoints);
    double worst = 0.0;
    for (std::size_t k = 0; k < from.size(); ++k)
      worst = std::max(worst, glm::length(warp.apply(from[k]) - to[k]));
    EXPECT_DOUBLE_EQ(worst, fit.maxResidual);
  }
}

TEST(FitControlPoints, AnAffineTargetIsMetAtAnySmoothness) {
  // The regulariser only penalises differences of displacements, and a translation has none.
  std::mt19937 rng(31);
  const Lattice lattice(test::orientedParams(LatticeBasis::BSpline));
  const std::vector<Vec3> from = test::boxPoints(lattice, rng, 500);
  std::vector<Vec3> to;
  for (const Vec3& x : from) to.push_back(x + Vec3(0.5, -0.25, 1.0));
  LatticeFitOptions options;
  options.smoothness = 10.0;
  EXPECT_LE(fitControlPoints(lattice, from, to, options).maxResidual, 1e-10);
}

TEST(FitControlPoints, ResidualsDecreaseAsTheResolutionGrows) {
  std::mt19937 rng(32);
  std::vector<Vec3> from = test::randomPoints(rng, 4000, 0.0, 1.0);
  std::vector<Vec3> to;
  for (const Vec3& x : from) to.push_back(smoothTarget(x));
  for (LatticeBasis basis : {LatticeBasis::Trilinear, LatticeBasis::BSpline}) {
    double previous = std::numeric_limits<double>::infinity();
    for (int n : {4, 6, 10}) {
      LatticeOptions p;
      p.resolution = {n, n, n};
      p.basis = basis;
      const ControlPointFit fit = fitControlPoints(Lattice(p), from, to);
      EXPECT_LT(fit.rmsResidual, 0.6 * previous) << test::basisName(basis) << " n " << n;
      previous = fit.rmsResidual;
    }
    EXPECT_LT(previous, 2e-3) << test::basisName(basis);
  }
  // Trilinear from the coarsest lattice, as the issue names it: 3 → 5 → 9.
  double previous = std::numeric_limits<double>::infinity();
  for (int n : {3, 5, 9}) {
    LatticeOptions p;
    p.resolution = {n, n, n};
    const ControlPointFit fit = fitControlPoints(Lattice(p), from, to);
    EXPECT_LT(fit.rmsResidual, 0.6 * previous) << "trilinear n " << n;
    previous = fit.rmsResidual;
  }
}

TEST(FitControlPoints, RejectsBadInput) {
  const Lattice lattice(LatticeOptions{});
  const std::vector<Vec3> a = {Vec3(0.5)}, b = {Vec3(0.6), Vec3(0.7)};
  const std::vector<Vec3> nan = {Vec3(std::numeric_limits<double>::quiet_NaN())};
  const std::vector<Vec3> outside = {Vec3(5.0)};
  EXPECT_THAT(test::messageOf<InvalidInput>([&] { fitControlPoints(lattice, a, b); }),
              HasSubstr("1 points but 2 targets"));
  EXPECT_THAT(test::messageOf<InvalidInput>([&] { fitControlPoints(lattice, {}, {}); }),
              HasSubstr("no constraints"));
  EXPECT_THAT(test::messageOf<InvalidInput>([&] { fitControlPoints(lattice, nan, a); }),
              HasSubstr("point 0 is not finite"));
  EXPECT_THAT(test::messageOf<InvalidInput>([&] { fitControlPoints(lattice, a, nan); }),
              HasSubstr("target 0 is not finite"));
  EXPECT_THAT(test::messageOf<InvalidInput>([&] { fitControlPoints(lattice, outside, a); }),
              HasSubstr("no constraint point lies where the lattice moves points"));
  LatticeFitOptions options;
  options.smoothness = -1.0;
  EXPECT_THAT(test::messageOf<InvalidInput>([&] { fitControlPoints(lattice, a, a, options); }),
              HasSubstr("smoothness"));
  // Without the regulariser, one constraint cannot fix 8 controls.
  options.smoothness = 0.0;
  EXPECT_THROW(fitControlPoints(lattice, a, a, options), SolverError);
}

TEST(FitLattice, BoundsThePointsWithPadding) {
  std::mt19937 rng(33);
  std::vector<Vec3> points = test::randomPoints(rng, 100, -1.0, 2.0);
  const BoundingBox box = boundingBox(points);
  const Lattice lattice = fitLattice(points, 0.1, {3, 4, 5}, LatticeBasis::Bernstein);
  EXPECT_EQ(lattice.basis(), LatticeBasis::Bernstein);
  EXPECT_EQ(lattice.resolution(), (std::array<int, 3>{3, 4, 5}));
  const double grow = 0.1 * box.diagonal();
  EXPECT_LE(test::relativeError(lattice.params().origin, box.min - Vec3(grow)), 1e-15);
  EXPECT_LE(test::relativeError(lattice.params().extents, box.extent() + Vec3(2 * grow)), 1e-15);
  EXPECT_EQ(lattice.params().axes[0], Vec3(1, 0, 0));
  for (const Vec3& p : points) {
    const Vec3 u = lattice.toLocal(p);
    for (int a = 0; a < 3; ++a) {
      EXPECT_GT(u[a], 0.0);
      EXPECT_LT(u[a], 1.0);
    }
  }
}

TEST(FitLattice, RejectsBadInput) {
  const std::vector<Vec3> flat = {Vec3(0, 0, 0), Vec3(1, 1, 0)};
  EXPECT_THAT(test::messageOf<InvalidInput>([&] {
                fitLattice({}, 0.1, {2, 2, 2});
              }),
              HasSubstr("no points"));
  EXPECT_THAT(test::messageOf<InvalidInput>([&] {
                fitLattice(flat, 0.0, {2, 2, 2});
              }),
              HasSubstr("flat along axis 2"));
  EXPECT_THAT(test::messageOf<InvalidInput>([&] {
                fitLattice(flat, -1.0, {2, 2, 2});
              }),
              HasSubstr("padding"));
  EXPECT_NO_THROW(fitLattice(flat, 0.1, {2, 2, 2}));
  EXPECT_THAT(test::messageOf<InvalidInput>([&] {
                fitLattice(flat, 0.1, {2, 2, 2}, LatticeBasis::BSpline);
              }),
              HasSubstr("at least 4"));
}

}  // namespace
}  // namespace spacewarp
