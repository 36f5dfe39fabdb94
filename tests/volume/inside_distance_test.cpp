#include <spacewarp/volume/inside_distance.h>

#include <cmath>
#include <memory>
#include <random>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <tbb/task_arena.h>

#include <spacewarp/core/errors.h>
#include <spacewarp/core/inverse.h>
#include <spacewarp/core/primitives.h>
#include <spacewarp/nonlinear/mls.h>
#include "test_util.h"

namespace spacewarp {
namespace {

using ::testing::HasSubstr;
using ::testing::Not;

// A slab of unit cells, one thick in z, from (x, y) cells.
PolygonSoup slab(const std::vector<glm::ivec2>& xy) {
  std::vector<glm::ivec3> cells;
  for (const glm::ivec2& c : xy) cells.emplace_back(c.x, c.y, 0);
  return makeBlocksSurface(cells, Vec3(0.0), 1.0);
}

// An L: arms of 3 cells along x and y sharing the cell (0, 0).
PolygonSoup lShape() { return slab({{0, 0}, {1, 0}, {2, 0}, {0, 1}, {0, 2}}); }

// Two fingers of 4 cells (x = 0 and x = 4, y = 1..4) on a palm of 5 cells (y = 0): a U.
PolygonSoup twoFingers() {
  std::vector<glm::ivec2> xy;
  for (int x = 0; x <= 4; ++x) xy.emplace_back(x, 0);
  for (int y = 1; y <= 4; ++y) {
    xy.emplace_back(0, y);
    xy.emplace_back(4, y);
  }
  return slab(xy);
}

std::vector<double> distancesAt(const InsideDistances& d, const Vec3& x) {
  std::vector<double> out(d.handles().size());
  d.distances(x, out);
  return out;
}

TEST(InsideDistances, ConvexBoxGivesEuclideanDistances) {
  // In a convex model the inside distance is the Euclidean one. Second-order fast marching from
  // the exact seeds: measured within 0.16 voxel everywhere (first order was off by 2% + 0.5 voxel
  // diagonally).
  const PolygonSoup box = makeBoxSurface(Vec3(0.0), Vec3(4.0, 2.0, 1.0), glm::ivec3(1));
  const std::vector<Vec3> handles = {{0.5, 0.5, 0.5}, {3.2, 1.4, 0.6}};
  const InsideDistances d(box, handles);
  const double h = d.voxelSize();
  EXPECT_DOUBLE_EQ(h, std::sqrt(21.0) / 128.0);
  std::mt19937 rng(1);
  double worst = 0.0;
  for (int s = 0; s < 2000; ++s) {
    const Vec3 x = Vec3(4.0, 2.0, 1.0) * test::randomPoint(rng, 0.0, 1.0);
    const std::vector<double> got = distancesAt(d, x);
    for (std::size_t i = 0; i < handles.size(); ++i) {
      const double exact = glm::length(x - handles[i]);
      EXPECT_NEAR(got[i], exact, 0.25 * h) << test::toString(x);
      worst = std::max(worst, std::abs(got[i] - exact));
    }
  }
  // Along an axis from the handle it is exact up to interpolation.
  for (double t : {0.3, 1.0, 2.1, 3.3}) {
    const Vec3 x = handles[0] + Vec3(t, 0.0, 0.0);
    EXPECT_NEAR(distancesAt(d, x)[0], t, 0.05 * h);
  }
  EXPECT_GT(worst, 0.0);  // the error is real and measured, not zero by accident
}

TEST(InsideDistances, LShapeDistanceGoesAroundTheCorner) {
  // From the end of one arm to the end of the other the straight line leaves the model; the
  // shortest path inside bends at the reflex corner (1, 1): two legs of sqrt(1.5² + 0.5²).
  const std::vector<Vec3> handles = {{2.5, 0.5, 0.5}};
  const InsideDistances d(lShape(), handles);
  const Vec3 x(0.5, 2.5, 0.5);
  const double aroundCorner = 2.0 * std::sqrt(2.5);
  const double straight = glm::length(x - handles[0]);
  const double got = distancesAt(d, x)[0];
  EXPECT_NEAR(got, aroundCorner, 0.5 * d.voxelSize());  // measured: 0.06 voxel
  EXPECT_GT(got, straight + 0.5 * (aroundCorner - straight));
  // A point the handle sees directly: Euclidean.
  const Vec3 seen(0.5, 0.5, 0.5);
  EXPECT_NEAR(distancesAt(d, seen)[0], 2.0, 0.05 * d.voxelSize());
}

TEST(InsideDistances, ZeroAtHandlesAndContinuousEverywhere) {
  const std::vector<Vec3> handles = {{0.5, 0.5, 0.5}, {0.5, 4.5, 0.5}, {4.5, 4.5, 0.5}};
  const InsideDistances d(twoFingers(), handles);
  for (std::size_t i = 0; i < handles.size(); ++i) EXPECT_EQ(distancesAt(d, handles[i])[i], 0.0);
  // Along lines through the near-field blend, the surface, the edge of the grid and far out, no
  // jump larger than the step (|∇d| <= 1 up to the discretisation). Except in the middle of the
  // gap between the fingers, where the nearest inside voxel switches fingers (a steep cell).
  const Vec3 starts[] = {{0.5, 4.5, 0.5}, {2.0, 0.5, 0.5}, {4.5, 4.5, 0.5}};
  const Vec3 dirs[] = {{1.0, 0.3, 0.2}, {0.1, 1.0, -0.4}, {0.3, 0.2, 1.0}};
  for (int l = 0; l < 3; ++l) {
    const Vec3 dir = glm::normalize(dirs[l]);
    const double step = 1e-3;
    std::vector<double> prev = distancesAt(d, starts[l]);
    for (int s = 1; s < 8000; ++s) {
      const Vec3 x = starts[l] + (s * step) * dir;
      const std::vector<double> now = distancesAt(d, x);
      const bool midGap = x.x > 1.5 && x.x < 3.5 && x.y > 1.5;
      for (std::size_t i = 0; i < now.size() && !midGap; ++i) {
        ASSERT_TRUE(std::isfinite(now[i]));
        ASSERT_LE(std::abs(now[i] - prev[i]), 2.1 * step)
            << "line " << l << " " << test::toString(x) << " handle " << i << " " << prev[i]
            << " -> " << now[i];
      }
      prev = now;
    }
  }
  // Far away the distance grows like the Euclidean distance.
  const Vec3 far(1e6, 2.0, 0.5);
  EXPECT_NEAR(distancesAt(d, far)[0] / glm::length(far - handles[0]), 1.0, 1e-4);
  // Non-finite points give non-finite distances.
  EXPECT_TRUE(std::isnan(distancesAt(d, Vec3(std::nan(""), 0.0, 0.0))[0]));
}

TEST(InsideDistances, GradientsMatchFiniteDifferencesWithinAVoxel) {
  const std::vector<Vec3> handles = {{0.5, 0.5, 0.5}, {0.5, 4.5, 0.5}, {4.5, 4.5, 0.5}};
  const InsideDistances d(twoFingers(), handles);
  const double h = d.voxelSize();
  const std::size_t n = handles.size();
  std::mt19937 rng(3);
  std::vector<Vec3> points;
  for (int s = 0; s < 200; ++s) {
    // Near voxel centres (the grid's voxels are centred at multiples of h), so that the
    // differences stay in one cell of the interpolation: at least 0.3 h from its faces.
    // Some outside the model, and beyond the grid's edge too.
    const Vec3 x = Vec3(7.0, 7.0, 3.0) * test::randomPoint(rng, 0.0, 1.0) - Vec3(1.0);
    points.push_back((glm::floor(x / h) + 0.5) * h + test::randomPoint(rng, -0.2, 0.2) * h);
  }
  for (const Vec3& p : handles) points.push_back(p + Vec3(0.7, 0.4, 0.2) * h);  // the blend
  std::vector<double> dist(n), plain(n), a(n), b(n);
  std::vector<Vec3> grad(n);
  const double step = 1e-3 * h;
  for (const Vec3& x : points) {
    d.distancesAndGradients(x, dist, grad);
    d.distances(x, plain);
    for (std::size_t i = 0; i < n; ++i) {
      EXPECT_EQ(dist[i], plain[i]);  // bit-identical
      Vec3 fd;
      for (int axis = 0; axis < 3; ++axis) {
        Vec3 e(0.0);
        e[axis] = step;
        d.distances(x + e, a);
        d.distances(x - e, b);
        fd[axis] = (a[i] - b[i]) / (2.0 * step);
      }
      EXPECT_LE(glm::length(fd - grad[i]), 1e-4)
          << test::toString(x) << " handle " << i << " fd " << test::toString(fd) << " grad "
          << test::toString(grad[i]) << " d " << dist[i];
      EXPECT_LE(glm::length(grad[i]), 2.1) << test::toString(x);  // outside: up to 2
    }
  }
  std::vector<double> wrong(n + 1);
  EXPECT_THROW(d.distances(Vec3(0.0), wrong), InvalidInput);
}

TEST(InsideDistances, BuildIsTheSameForAnyThreadCount) {
  const std::vector<Vec3> handles = {{0.5, 0.5, 0.5}, {0.5, 4.5, 0.5}, {4.5, 4.5, 0.5}};
  std::unique_ptr<InsideDistances> one, two;
  tbb::task_arena(1).execute(
      [&] { one = std::make_unique<InsideDistances>(twoFingers(), handles); });
  tbb::task_arena(2).execute(
      [&] { two = std::make_unique<InsideDistances>(twoFingers(), handles); });
  std::mt19937 rng(9);
  for (int s = 0; s < 2000; ++s) {
    const Vec3 x = Vec3(7.0, 7.0, 3.0) * test::randomPoint(rng, 0.0, 1.0) - Vec3(1.0);
    const std::vector<double> a = distancesAt(*one, x), b = distancesAt(*two, x);
    for (std::size_t i = 0; i < a.size(); ++i) ASSERT_EQ(a[i], b[i]) << test::toString(x);
  }
}

TEST(InsideDistances, RejectsBadInput) {
  const PolygonSoup fingers = twoFingers();
  const auto message = [&](const PolygonSoup& model, std::vector<Vec3> handles, double voxel) {
    InsideDistanceOptions o;
    o.voxelSize = voxel;
    return test::messageOf<InvalidInput>([&] { InsideDistances(model, handles, o); });
  };
  const Vec3 in(0.5, 0.5, 0.5);
  // Between the fingers: outside, named by index.
  EXPECT_THAT(message(fingers, {in, Vec3(2.0, 3.0, 0.5)}, 0.0),
              HasSubstr("handle 1 (2, 3, 0.5) is outside the model"));
  EXPECT_THAT(message(fingers, {Vec3(50.0, 0.0, 0.0)}, 0.0), HasSubstr("handle 0"));
  // Just outside the surface (within two voxels) is accepted.
  EXPECT_NO_THROW(InsideDistances(fingers, {Vec3(0.5, 0.5, 1.0 + 0.05)}, {0.05}));
  EXPECT_THAT(message(fingers, {in}, -1.0), HasSubstr("voxelSize"));
  EXPECT_THAT(message(fingers, {in}, std::nan("")), HasSubstr("voxelSize"));
  EXPECT_THAT(message(fingers, {}, 0.0), HasSubstr("no handles"));
  EXPECT_THAT(message(fingers, {Vec3(0.5, std::nan(""), 0.5)}, 0.0),
              HasSubstr("handle 0 is not finite"));
  EXPECT_THAT(message(PolygonSoup{}, {in}, 0.0), HasSubstr("no polygons"));
  // A box between the voxel centres encloses none of them.
  const PolygonSoup tiny = makeBoxSurface(Vec3(0.02), Vec3(0.03), glm::ivec3(1));
  EXPECT_THAT(message(tiny, {Vec3(0.025)}, 0.1), HasSubstr("encloses no voxel of 0.1"));
  // Voxel indices beyond OpenVDB's 32-bit coordinates.
  PolygonSoup far = fingers;
  for (Vec3& p : far.positions) p += Vec3(1e12, 0.0, 0.0);
  EXPECT_THAT(message(far, {Vec3(1e12 + 0.5, 0.5, 0.5)}, 0.0),
              HasSubstr("too far from the origin"));
  // Too large for the memory: named by the voxel size.
  EXPECT_THAT(message(fingers, {in}, 1e-5), HasSubstr("'voxelSize'"));
  // Far too large: the true voxel counts, no byte count beyond exabytes.
  const std::string huge = message(fingers, {in}, 1e-300);
  EXPECT_THAT(huge, HasSubstr("'voxelSize' 1e-300 (5e+300 x 5e+300 x 1e+300 voxels, 1 handles)"));
  EXPECT_THAT(huge, HasSubstr("far more memory than any machine has"));
  EXPECT_THAT(huge, Not(HasSubstr("inf")));
}

// A handle beyond the 2-voxel rule is reported with that rule's distance, not the band's.
TEST(InsideDistances, OutsideHandleMessageStatesTheRule) {
  const PolygonSoup box = makeBoxSurface(Vec3(0.0), Vec3(1.0), glm::ivec3(1));
  const auto message = [&](double z) {
    return test::messageOf<InvalidInput>(
        [&] { InsideDistances(box, {Vec3(0.5, 0.5, z)}, InsideDistanceOptions{0.05}); });
  };
  EXPECT_THAT(message(1.12), HasSubstr("(0.12 from its surface; handles must be inside or "
                                       "within 2 voxels (0.1) of it)"));
  EXPECT_THAT(message(1.5), HasSubstr("(more than 0.1 from its surface"));
}

// A box missing a face encloses nothing: refused as open, naming an edge, not the handles.
TEST(InsideDistances, RejectsAnOpenModel) {
  PolygonSoup closed = makeBoxSurface(Vec3(0.0), Vec3(1.0), glm::ivec3(1));
  ASSERT_EQ(closed.polygonCount(), 6u);
  EXPECT_NO_THROW(InsideDistances(closed, {Vec3(0.2)}, InsideDistanceOptions{0.05}));
  PolygonSoup open;
  open.positions = closed.positions;
  for (std::size_t f = 0; f + 1 < closed.polygonCount(); ++f) {
    const auto p = closed.polygon(f);
    open.addPolygon(std::vector<std::uint32_t>(p.begin(), p.end()));
  }
  const std::string m = test::messageOf<InvalidInput>(
      [&] { InsideDistances(open, {Vec3(0.2)}, InsideDistanceOptions{0.05}); });
  EXPECT_THAT(m, HasSubstr("the model is not closed (4 boundary edges, e.g. between vertices"));
  EXPECT_THAT(m, HasSubstr("inside distances need a closed surface"));
  EXPECT_THAT(m, Not(HasSubstr("handle")));
  // The same box with every polygon on its own vertices (an unwelded soup) is closed.
  PolygonSoup unwelded;
  for (std::size_t f = 0; f < closed.polygonCount(); ++f) {
    std::vector<std::uint32_t> corners;
    for (const std::uint32_t v : closed.polygon(f)) {
      corners.push_back(static_cast<std::uint32_t>(unwelded.positions.size()));
      unwelded.positions.push_back(closed.positions[v]);
    }
    unwelded.addPolygon(corners);
  }
  EXPECT_NO_THROW(InsideDistances(unwelded, {Vec3(0.2)}, InsideDistanceOptions{0.05}));
}

// MLS with distances measured inside the two-finger model.
struct FingerRig {
  std::vector<Vec3> handles = {{0.5, 4.5, 0.5},  // tip of finger A: moved
                               {0.5, 0.5, 0.5}, {2.5, 0.5, 0.8}, {4.5, 0.5, 0.5},  // palm
                               {4.5, 2.5, 0.5}, {4.5, 4.5, 0.5}};                  // finger B
  std::vector<Vec3> targets;
  FingerRig() {
    targets = handles;
    targets[0] += Vec3(1.5, 0.0, 0.0);  // bend finger A towards B
  }
};

TEST(MlsInsideDistances, TheOtherFingerStaysPut) {
  const PolygonSoup model = twoFingers();
  const FingerRig rig;
  MlsOptions inside;
  inside.distances = std::make_shared<InsideDistances>(model, rig.handles);
  const MlsWarp withInside(rig.handles, rig.targets, inside);
  const MlsWarp euclidean(rig.handles, rig.targets);
  // The vertices of finger B (x >= 4, y >= 1).
  double insideMax = 0.0, euclideanMax = 0.0;
  for (const Vec3& v : model.positions) {
    if (v.x < 4.0 || v.y < 1.0) continue;
    insideMax = std::max(insideMax, glm::length(withInside.apply(v) - v));
    euclideanMax = std::max(euclideanMax, glm::length(euclidean.apply(v) - v));
  }
  const double moved = 1.5;
  // Measured: 1.5% and 5.7% of the tip's move.
  EXPECT_LT(insideMax, 0.02 * moved);
  EXPECT_GT(euclideanMax, 0.05 * moved);
  EXPECT_GT(euclideanMax, 3.0 * insideMax);
  // Finger A itself follows its tip either way.
  EXPECT_GT(glm::length(withInside.apply(Vec3(0.5, 3.5, 0.5)) - Vec3(0.5, 3.5, 0.5)), 0.5);
}

TEST(MlsInsideDistances, KeepsTheMlsProperties) {
  const PolygonSoup model = twoFingers();
  const FingerRig rig;
  MlsOptions o;
  o.distances = std::make_shared<InsideDistances>(model, rig.handles);
  std::mt19937 rng(5);
  const double h = std::static_pointer_cast<const InsideDistances>(o.distances)->voxelSize();
  std::vector<Vec3> points;
  for (int s = 0; s < 300; ++s) {
    const Vec3 x = Vec3(5.0, 5.0, 1.0) * test::randomPoint(rng, 0.0, 1.0);
    points.push_back((glm::floor(x / h) + 0.5) * h + test::randomPoint(rng, -0.2, 0.2) * h);
  }
  for (MlsMode mode : {MlsMode::Affine, MlsMode::Similarity, MlsMode::Rigid}) {
    o.mode = mode;
    const MlsWarp warp(rig.handles, rig.targets, o);
    for (std::size_t i = 0; i < rig.handles.size(); ++i)
      EXPECT_EQ(warp.apply(rig.handles[i]), rig.targets[i]) << mlsModeName(mode);
    // A common rigid motion of all handles is reproduced everywhere.
    const Mat3 r = Mat3(Vec3(0.36, 0.48, -0.8), Vec3(-0.8, 0.6, 0.0), Vec3(0.48, 0.64, 0.6));
    const Vec3 t(3.0, -1.0, 2.0);
    std::vector<Vec3> moved;
    for (const Vec3& p : rig.handles) moved.push_back(r * p + t);
    const MlsWarp rigid(rig.handles, moved, o);
    for (const Vec3& x : points)
      EXPECT_LE(glm::length(rigid.apply(x) - (r * x + t)), 1e-12 * 5.0) << test::toString(x);
    // Jacobian against finite differences inside a voxel (the differences step 2e-3 h).
    std::vector<Vec3> some(points.begin(), points.begin() + 60);
    for (const Vec3& x : some) {
      const Mat3 fd = test::finiteDifferenceJacobian(warp, x, 1e-3 * h);
      EXPECT_LE(test::relativeError(warp.jacobian(x), fd), 1e-5)
          << mlsModeName(mode) << " " << test::toString(x);
    }
    EXPECT_TRUE(test::batchIsDeterministic(warp, points)) << mlsModeName(mode);
  }
}

TEST(MlsInsideDistances, InvertsAndTransformsNormals) {
  const FingerRig rig;
  MlsOptions o;
  o.distances = std::make_shared<InsideDistances>(twoFingers(), rig.handles);
  const MlsWarp warp(rig.handles, rig.targets, o);
  std::mt19937 rng(6);
  // Inside the palm and both fingers.
  std::vector<Vec3> points;
  for (int s = 0; s < 40; ++s) {
    const Vec3 u = test::randomPoint(rng, 0.1, 0.9);
    points.push_back(s % 3 == 0 ? Vec3(5.0 * u.x, u.y, u.z)
                                : Vec3((s % 3 == 1 ? 0.0 : 4.0) + u.x, 1.0 + 4.0 * u.y, u.z));
  }
  EXPECT_TRUE(test::inverseRecovers(warp, points, 1e-8));
  EXPECT_TRUE(test::normalsStayPerpendicular(warp, points, rng, 1e-10));
}

TEST(MlsInsideDistances, RejectsDistancesOfOtherHandles) {
  const FingerRig rig;
  MlsOptions o;
  o.distances = std::make_shared<InsideDistances>(twoFingers(), rig.handles);
  std::vector<Vec3> fewer(rig.handles.begin(), rig.handles.end() - 1);
  std::vector<Vec3> fewerTargets(rig.targets.begin(), rig.targets.end() - 1);
  EXPECT_THAT(test::messageOf<InvalidInput>([&] { MlsWarp(fewer, fewerTargets, o); }),
              HasSubstr("built for 6 handles, not 5"));
  std::vector<Vec3> other = rig.handles;
  other[2].x += 0.1;
  EXPECT_THAT(test::messageOf<InvalidInput>([&] { MlsWarp(other, rig.targets, o); }),
              HasSubstr("another handle 2"));
}

}  // namespace
}  // namespace spacewarp
