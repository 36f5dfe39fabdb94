#include <spacewarp/coords/harmonic_warp.h>

#include <cstring>
#include <memory>
#include <random>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <tbb/task_arena.h>

#include <spacewarp/core/coordinate_warp.h>
#include <spacewarp/core/errors.h>
#include "coords_test_shapes.h"
#include "test_util.h"

namespace spacewarp {
namespace {

using ::testing::HasSubstr;

std::shared_ptr<const HarmonicCoordinates> solveStar(HarmonicOutsidePolicy outside) {
  HarmonicOptions options;
  options.targetTetCount = 3000;
  options.outside = outside;
  return std::make_shared<const HarmonicCoordinates>(
      std::make_shared<const Cage>(test::star(), "star"), options);
}

std::vector<Vec3> insidePoints(const HarmonicCoordinates& h, std::size_t n) {
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> unit(-3.0, 3.0);
  std::vector<Vec3> points;
  while (points.size() < n) {
    const Vec3 x(unit(rng), unit(rng), unit(rng));
    if (h.locate(x).found) points.push_back(x);
  }
  return points;
}

std::vector<Vec3> posedStar(const Cage& cage) {
  std::vector<Vec3> posed(cage.vertices().begin(), cage.vertices().end());
  for (std::size_t i = 0; i < posed.size(); ++i) {
    const double t = static_cast<double>(i);
    posed[i] += 0.2 * Vec3(std::sin(t), std::cos(3.0 * t), std::sin(2.0 * t));
  }
  return posed;
}

TEST(HarmonicWarp, MatchesTheGenericCoordinateWarp) {
  const auto h = solveStar(HarmonicOutsidePolicy::Throw);
  const std::vector<Vec3> posed = posedStar(h->cage());
  const HarmonicWarp fast(h, posed);
  const CoordinateWarp generic(h, posed);
  const std::vector<Vec3> points = insidePoints(*h, 500);
  std::vector<Vec3> out(points.size());
  fast.applyBatch(points, out);
  for (std::size_t i = 0; i < points.size(); ++i) {
    EXPECT_LE(glm::length(out[i] - generic.apply(points[i])), 1e-12) << i;
    EXPECT_EQ(out[i], fast.apply(points[i])) << i;  // bit-identical
    EXPECT_LE(test::frobenius(fast.jacobian(points[i]) - generic.jacobian(points[i])), 1e-10);
  }
}

TEST(HarmonicWarp, BatchIsIndependentOfTheThreadCount) {
  const auto h = solveStar(HarmonicOutsidePolicy::Throw);
  const HarmonicWarp warp(h, posedStar(h->cage()));
  const std::vector<Vec3> points = insidePoints(*h, 5000);
  auto run = [&](int threads) {
    std::vector<Vec3> out(points.size());
    tbb::task_arena arena(threads);
    arena.execute([&] { warp.applyBatch(points, out); });
    return out;
  };
  const std::vector<Vec3> one = run(1), two = run(2);
  EXPECT_EQ(std::memcmp(one.data(), two.data(), one.size() * sizeof(Vec3)), 0);
}

TEST(HarmonicWarp, OutsidePointsFollowThePolicy) {
  const auto h = solveStar(HarmonicOutsidePolicy::Throw);
  const std::vector<Vec3> posed = posedStar(h->cage());
  const HarmonicWarp warp(h, posed);
  std::vector<Vec3> points = insidePoints(*h, 10);
  points[3] = Vec3(10.0);
  points[7] = Vec3(-10.0);
  std::vector<Vec3> out(points.size());
  EXPECT_THAT(test::messageOf<InvalidInput>([&] { warp.applyBatch(points, out); }),
              HasSubstr("2 of 10 points are outside the cage (the first is point 3)"));
  EXPECT_THAT(test::messageOf<InvalidInput>([&] { warp.apply(Vec3(10.0)); }),
              HasSubstr("1 point is outside"));
  // Nearest point: a point beyond vertex 0 = (1, 0, 0) moves with it.
  const auto nearest = solveStar(HarmonicOutsidePolicy::NearestPoint);
  const HarmonicWarp clamped(nearest, posed);
  const Vec3 x(1.5, 0.0, 0.0);
  EXPECT_LE(glm::length(clamped.apply(x) - (x + posed[0] - Vec3(1.0, 0.0, 0.0))), 1e-12);
}

TEST(HarmonicWarp, RejectsBadArguments) {
  const auto h = solveStar(HarmonicOutsidePolicy::Throw);
  EXPECT_THROW(HarmonicWarp(nullptr, posedStar(h->cage())), InvalidInput);
  EXPECT_THROW(HarmonicWarp(h, std::vector<Vec3>(3)), InvalidInput);
}

TEST(HarmonicWarp, IsWhatMakeWarpGivesForHarmonicCoordinates) {
  const auto h = solveStar(HarmonicOutsidePolicy::Throw);
  const std::vector<Vec3> posed = posedStar(h->cage());
  const std::shared_ptr<const Warp> made = makeWarp(h, posed);
  ASSERT_NE(dynamic_cast<const HarmonicWarp*>(made.get()), nullptr);
  const HarmonicWarp direct(h, posed);
  for (const Vec3& x : insidePoints(*h, 200)) EXPECT_EQ(made->apply(x), direct.apply(x));
  EXPECT_THROW(makeWarp(nullptr, posed), InvalidInput);
  EXPECT_THROW(makeWarp(h, std::vector<Vec3>(3, Vec3(0.0))), InvalidInput);
}

}  // namespace
}  // namespace spacewarp
