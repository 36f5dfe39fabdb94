// Tests of LatticeEnds (ffd/lattice.h): the B-spline basis with Blender's repeated end controls
// against the default linear extrapolation: where they differ and agree, by the closed form on
// the faces, partition of unity, the rest lattice, affine poses and the Jacobian.

#include <spacewarp/ffd/lattice.h>
#include <spacewarp/ffd/lattice_warp.h>

#include <random>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "ffd_test_shapes.h"
#include "test_util.h"

namespace spacewarp {
namespace {

using ::testing::HasSubstr;

LatticeOptions bspline(LatticeEnds ends) {
  LatticeOptions o = test::orientedParams(LatticeBasis::BSpline);
  o.ends = ends;
  return o;
}

// Local coordinates whose axis parameters t_a = u_a (n_a − 1) all lie in [lo, hi] (in cells).
std::vector<Vec3> pointsInCells(const Lattice& lattice, std::mt19937& rng, std::size_t count,
                                double lo, double hi) {
  std::uniform_real_distribution<double> t(lo, hi);
  std::vector<Vec3> points(count);
  for (Vec3& p : points) {
    Vec3 local;
    for (int a = 0; a < 3; ++a) {
      const int cells = lattice.resolution()[a] - 1;
      local[a] = std::min(t(rng), double(cells) - lo) / cells;
    }
    p = lattice.toWorld(local);
  }
  return points;
}

TEST(LatticeEnds, RepeatEqualsExtrapolateBeyondTheFirstCellAndDiffersNearTheFaces) {
  std::mt19937 rng(1);
  const Lattice extrapolate(bspline(LatticeEnds::Extrapolate));
  const Lattice repeat(bspline(LatticeEnds::Repeat));
  const std::vector<Vec3> posed = test::randomPose(extrapolate, rng, 0.3);
  const LatticeWarp a(extrapolate, posed), b(repeat, posed);
  // The phantoms weigh only in the first and last cell of each axis: deeper, the same bits.
  for (const Vec3& x : pointsInCells(extrapolate, rng, 200, 1.0, 2.0))
    EXPECT_EQ(a.apply(x), b.apply(x)) << test::toString(x);
  // Within a quarter cell of the lower u face: different, by a visible fraction of the pose.
  double smallest = 1e300;
  for (Vec3 x : pointsInCells(extrapolate, rng, 200, 1.0, 2.0)) {
    Vec3 local = extrapolate.toLocal(x);
    local.x = 0.25 * local.x / 4.0;  // t_u in [0.06, 0.125]
    x = extrapolate.toWorld(local);
    smallest = std::min(smallest, glm::length(a.apply(x) - b.apply(x)));
  }
  EXPECT_GT(smallest, 1e-4);
}

// A pose that moves the controls along u only, by d(i) at column i: on the face u = 0 (deep in
// v and w) extrapolate moves by d(0), repeat by (5 d(0) + d(1)) / 6, Blender's value.
TEST(LatticeEnds, OnAFaceRepeatWeighsTheFaceControlFiveSixths) {
  for (const LatticeEnds ends : {LatticeEnds::Extrapolate, LatticeEnds::Repeat}) {
    const Lattice lattice(bspline(ends));
    const auto rest = lattice.restControlPoints();
    const Vec3 axis = lattice.params().axes[0];
    const double d[5] = {0.3, -0.1, 0.05, 0.2, -0.25};
    std::vector<Vec3> posed(rest.begin(), rest.end());
    for (int k = 0; k < 6; ++k)
      for (int j = 0; j < 4; ++j)
        for (int i = 0; i < 5; ++i) posed[lattice.index(i, j, k)] += d[i] * axis;
    const LatticeWarp warp(lattice, posed);
    const Vec3 onLow = lattice.toWorld(Vec3(0.0, 0.5, 0.5));
    const Vec3 onHigh = lattice.toWorld(Vec3(1.0, 0.5, 0.5));
    const bool repeat = ends == LatticeEnds::Repeat;
    const double low = repeat ? (5.0 * d[0] + d[1]) / 6.0 : d[0];
    const double high = repeat ? (5.0 * d[4] + d[3]) / 6.0 : d[4];
    EXPECT_NEAR(glm::dot(warp.apply(onLow) - onLow, axis), low, 1e-14);
    EXPECT_NEAR(glm::dot(warp.apply(onHigh) - onHigh, axis), high, 1e-14);
  }
}

TEST(LatticeEnds, BothArePartitionsOfUnityAndTheRestLatticeIsTheIdentity) {
  std::mt19937 rng(2);
  for (const LatticeEnds ends : {LatticeEnds::Extrapolate, LatticeEnds::Repeat}) {
    const Lattice lattice(bspline(ends));
    const LatticeWarp rest(lattice, lattice.restControlPoints());
    std::vector<Vec3> points = test::boxPoints(lattice, rng, 300);
    for (const Vec3& corner : {Vec3(0.0), Vec3(1.0), Vec3(1.0, 0.0, 0.5)})
      points.push_back(lattice.toWorld(corner));
    std::vector<SparseWeight> w(lattice.maxNonZeros());
    double worstSum = 0.0, worstRest = 0.0, worstReproduction = 0.0;
    for (const Vec3& x : points) {
      const std::size_t count = lattice.sparseWeights(x, w);
      double sum = 0.0;
      Vec3 combination(0.0);
      for (std::size_t c = 0; c < count; ++c) {
        sum += w[c].weight;
        combination += w[c].weight * lattice.restControlPoints()[w[c].column];
      }
      worstSum = std::max(worstSum, std::abs(sum - 1.0));
      // The warp moves by displacements: the rest lattice is the identity with either end.
      worstRest = std::max(worstRest, glm::length(rest.apply(x) - x));
      worstReproduction = std::max(worstReproduction, glm::length(combination - x));
    }
    EXPECT_LE(worstSum, 1e-14);
    EXPECT_EQ(worstRest, 0.0);
    // The weights themselves reproduce x (Σ w P⁰ = x) only with extrapolated ends: repeated
    // ends pull points near the faces towards the inside by up to a sixth of a cell.
    if (ends == LatticeEnds::Extrapolate)
      EXPECT_LE(worstReproduction, 1e-13);
    else
      EXPECT_GT(worstReproduction, 0.01);
  }
}

// An affine pose (here a shear and a scale) is reproduced everywhere with extrapolated ends and
// only beyond the first cell with repeated ends.
TEST(LatticeEnds, RepeatReproducesAffinePosesOnlyBeyondTheFirstCell) {
  std::mt19937 rng(3);
  Mat3 m(1.0);
  m[0] = Vec3(1.2, 0.1, 0.0);
  m[2] = Vec3(0.2, 0.0, 0.9);
  for (const LatticeEnds ends : {LatticeEnds::Extrapolate, LatticeEnds::Repeat}) {
    const Lattice lattice(bspline(ends));
    std::vector<Vec3> posed;
    for (const Vec3& p : lattice.restControlPoints()) posed.push_back(m * p);
    const LatticeWarp warp(lattice, posed);
    double inner = 0.0, all = 0.0;
    for (const Vec3& x : pointsInCells(lattice, rng, 200, 1.0, 2.0))
      inner = std::max(inner, glm::length(warp.apply(x) - m * x));
    for (const Vec3& x : test::boxPoints(lattice, rng, 300))
      all = std::max(all, glm::length(warp.apply(x) - m * x));
    EXPECT_LE(inner, 1e-13);
    if (ends == LatticeEnds::Extrapolate)
      EXPECT_LE(all, 1e-13);
    else
      EXPECT_GT(all, 0.01);
  }
}

TEST(LatticeEnds, JacobianMatchesFiniteDifferencesForBoth) {
  std::mt19937 rng(4);
  for (const LatticeEnds ends : {LatticeEnds::Extrapolate, LatticeEnds::Repeat}) {
    const Lattice lattice(bspline(ends));
    const LatticeWarp warp(lattice, test::randomPose(lattice, rng, 0.3));
    // Near the faces (the first and last cells) and inside.
    std::vector<Vec3> points = pointsInCells(lattice, rng, 60, 0.05, 0.95);
    const std::vector<Vec3> inner = pointsInCells(lattice, rng, 40, 1.05, 1.95);
    points.insert(points.end(), inner.begin(), inner.end());
    EXPECT_TRUE(test::jacobianMatchesFiniteDifferences(warp, points)) << static_cast<int>(ends);
    EXPECT_TRUE(test::batchIsDeterministic(warp, points));
  }
}

TEST(LatticeEnds, RepeatNeedsTheBSplineBasis) {
  LatticeOptions o = test::orientedParams(LatticeBasis::Trilinear);
  o.ends = LatticeEnds::Repeat;
  EXPECT_THAT(test::messageOf<InvalidInput>([&] { Lattice l(o); }),
              HasSubstr("the ends 'repeat' apply to the bspline basis only"));
  o.basis = LatticeBasis::BSpline;
  o.ends = static_cast<LatticeEnds>(7);
  EXPECT_THAT(test::messageOf<InvalidInput>([&] { Lattice l(o); }), HasSubstr("ends"));
}

}  // namespace
}  // namespace spacewarp
