// The harmonic set-up's precision knob (harmonicPrecisionTets, coords/harmonic.h): its mapping
// to the tet budget and refusals, the property kit at coarse levels, and convergence towards a
// finer solve as the level rises.

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <random>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <spacewarp/coords/harmonic.h>
#include <spacewarp/coords/properties.h>
#include <spacewarp/core/errors.h>
#include <spacewarp/core/geometry.h>
#include "coords_test_shapes.h"

namespace spacewarp {
namespace {

using ::testing::HasSubstr;

std::shared_ptr<const HarmonicCoordinates> atPrecision(const std::shared_ptr<const Cage>& cage,
                                                       int precision) {
  HarmonicOptions options;
  options.targetTetCount = harmonicPrecisionTets(precision);
  return std::make_shared<const HarmonicCoordinates>(cage, options);
}

TEST(HarmonicPrecision, LevelsQuadrupleTheTetBudgetWithTheDefaultAtFive) {
  EXPECT_EQ(harmonicPrecisionTets(5), HarmonicOptions{}.targetTetCount);
  EXPECT_EQ(harmonicPrecisionTets(1), 781u);  // 200000 / 256, rounded down
  EXPECT_EQ(harmonicPrecisionTets(2), 3125u);
  for (int p = 3; p <= kHarmonicMaxPrecision; ++p)
    EXPECT_EQ(harmonicPrecisionTets(p), 4 * harmonicPrecisionTets(p - 1)) << p;
  EXPECT_EQ(harmonicPrecisionTets(kHarmonicMaxPrecision), 3200000u);
}

// Levels between the whole ones follow the same geometric law (rounded to a count): every
// quarter level multiplies the budget by √2, and the whole levels are unchanged among them.
TEST(HarmonicPrecision, FractionalLevelsLieBetweenTheWholeOnes) {
  EXPECT_EQ(harmonicPrecisionTets(5.5), 400000u);  // 200000 · 2
  EXPECT_EQ(harmonicPrecisionTets(2.5), 6250u);    // 200000 / 32, exactly
  for (double p = 1.25; p <= kHarmonicMaxPrecision; p += 0.25) {
    const double ratio = static_cast<double>(harmonicPrecisionTets(p)) /
                         static_cast<double>(harmonicPrecisionTets(p - 0.25));
    EXPECT_NEAR(ratio, std::sqrt(2.0), 1e-3) << p;
  }
}

TEST(HarmonicPrecision, RefusesLevelsOutsideTheRangeNamingTheValue) {
  for (const double p :
       {0.0, -1.0, 0.999, kHarmonicMaxPrecision + 0.5, 100.0, std::nan(""), HUGE_VAL}) {
    try {
      harmonicPrecisionTets(p);
      ADD_FAILURE() << p << " was accepted";
    } catch (const InvalidInput& e) {
      EXPECT_THAT(e.what(), HasSubstr("precision"));
      char text[32];
      std::snprintf(text, sizeof text, "got %.17g", p);
      EXPECT_THAT(e.what(), HasSubstr(text));
    }
  }
}

// The coarsest levels keep every property of the FEM solution: it reproduces linear functions
// exactly (up to round-off), sums to one, is non-negative and interpolates at the cage.
TEST(HarmonicPrecision, CoarseLevelsKeepThePropertyKit) {
  const auto cage = std::make_shared<const Cage>(test::lPrism(), "lPrism");
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> unit(0.0, 2.0);
  std::vector<Vec3> samples;
  while (samples.size() < 400) {
    const Vec3 x(unit(rng), unit(rng), 0.5 * unit(rng));
    const bool inside = x.z > 0.0 && x.z < 1.0 && x.x > 0.0 && x.y > 0.0 &&
                        ((x.x < 2.0 && x.y < 1.0) || (x.x < 1.0 && x.y < 2.0));
    if (inside) samples.push_back(x);
  }
  for (const int p : {1, 2}) {
    const auto h = atPrecision(cage, p);
    const PropertyReport report = measureProperties(*h, *cage, samples);
    EXPECT_LE(report.partitionOfUnity, 1e-12) << p;
    EXPECT_LE(report.linearReproduction, 1e-12) << p;
    EXPECT_GE(report.minWeight, 0.0) << p;
    EXPECT_LE(report.lagrange, 1e-12) << p;
    EXPECT_LE(report.faceInterpolation, 1e-12) << p;
  }
}

// Each level is closer to a fine solve (level 4) than the one below, at fixed interior points.
TEST(HarmonicPrecision, FinerLevelsAreCloserToAFineSolve) {
  const auto cage = std::make_shared<const Cage>(test::star(), "star");
  const auto reference = atPrecision(cage, 4);
  std::mt19937_64 rng(7);
  const BoundingBox box = boundingBox(cage->vertices());
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::vector<Vec3> points;
  while (points.size() < 300) {
    const Vec3 x = box.min + box.extent() * Vec3(unit(rng), unit(rng), unit(rng));
    if (reference->locate(x).found) points.push_back(x);
  }
  const std::size_t k = cage->vertexCount();
  std::vector<double> exact(points.size() * k), rows(points.size() * k);
  reference->weightsBatch(points, exact);
  double previous = INFINITY;
  for (const int p : {1, 2, 3}) {
    const auto h = atPrecision(cage, p);
    ASSERT_TRUE(std::all_of(points.begin(), points.end(),
                            [&](const Vec3& x) { return h->locate(x).found; }));
    h->weightsBatch(points, rows);
    double squares = 0.0;
    for (std::size_t i = 0; i < rows.size(); ++i)
      squares += (rows[i] - exact[i]) * (rows[i] - exact[i]);
    const double error = std::sqrt(squares / static_cast<double>(rows.size()));
    EXPECT_LT(error, 0.8 * previous) << "level " << p << ": " << error << " after " << previous;
    previous = error;
  }
}

// On the coarse meshes of the Ju et al. armadillo cage many mesh vertices dip below zero (339
// of 2,357 at level 2, 1,173 of 4,879 at level 3); every one must be projected back with its
// partition of unity and linear reproduction, none left negative when the projection's line
// search stalls at round-off (223 rows were, at level 3).
TEST(HarmonicPrecision, CoarseArmadilloLevelsProjectEveryNegativeRow) {
  const auto dir = std::filesystem::path(SPACEWARP_SHARED_DATA_DIR) / "ju2005-armadillo";
  if (!std::filesystem::exists(dir / "bounding_mesh.obj"))
    GTEST_SKIP() << "shared data not found: " << dir;
  const auto cage = std::make_shared<const Cage>(Cage::fromFile(dir / "bounding_mesh.obj"));
  const std::size_t k = cage->vertexCount();
  for (const int p : {2, 3}) {
    const auto h = atPrecision(cage, p);
    const auto values = h->vertexValues();
    const TetMesh& mesh = h->mesh();
    for (std::size_t v = 0; v < mesh.vertices.size(); ++v) {
      double sum = 0.0;
      Vec3 x(0.0);
      for (std::size_t c = 0; c < k; ++c) {
        ASSERT_GE(values[v * k + c], 0.0) << "level " << p << ", mesh vertex " << v;
        sum += values[v * k + c];
        x += values[v * k + c] * cage->vertices()[c];
      }
      ASSERT_NEAR(sum, 1.0, 1e-12) << "level " << p << ", mesh vertex " << v;
      ASSERT_LE(glm::length(x - mesh.vertices[v]), 1e-10 * cage->diagonal())
          << "level " << p << ", mesh vertex " << v;
    }
  }
}

}  // namespace
}  // namespace spacewarp
