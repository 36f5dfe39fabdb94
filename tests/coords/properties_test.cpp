#include <spacewarp/coords/properties.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <random>
#include <string_view>

#include <gtest/gtest.h>

#include <spacewarp/coords/green.h>
#include <spacewarp/coords/mean_value.h>
#include <spacewarp/coords/quad_mean_value.h>
#include <spacewarp/coords/wachspress.h>
#include <spacewarp/core/binding.h>
#include <spacewarp/core/errors.h>
#include <spacewarp/core/primitives.h>
#include "coords_test_shapes.h"

namespace spacewarp {
namespace {

// Barycentric coordinates of a tetrahedron: the one cage whose coordinates are known in closed
// form, with every property exact. `skew` breaks partition of unity on purpose, `shuffle`
// breaks the Lagrange property while keeping partition of unity.
class TetBarycentric final : public Coordinates {
 public:
  TetBarycentric(const Cage& cage, double skew = 0.0, bool shuffle = false)
      : cage_(cage), skew_(skew), shuffle_(shuffle) {}
  std::size_t controlPointCount() const override { return 4; }
  std::span<const Vec3> restControlPoints() const override { return cage_.vertices(); }
  void weights(const Vec3& x, std::span<double> row) const override {
    checkWeightsArguments(x, row.size());
    const auto& v = cage_.vertices();
    const Mat3 m(v[1] - v[0], v[2] - v[0], v[3] - v[0]);
    const Vec3 l = glm::inverse(m) * (x - v[0]);
    row[0] = 1.0 - l.x - l.y - l.z;
    row[1] = l.x + skew_;  // v1 is not the origin, so the skew also breaks reproduction
    row[2] = l.y;
    row[3] = l.z;
    if (shuffle_) std::swap(row[0], row[1]);
  }

 private:
  const Cage& cage_;
  double skew_;
  bool shuffle_;
};

std::vector<Vec3> samplesInBox(const Vec3& lo, const Vec3& hi, int n) {
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<Vec3> s;
  for (int i = 0; i < n; ++i) s.push_back(lo + (hi - lo) * Vec3(u(rng), u(rng), u(rng)));
  return s;
}

TEST(Properties, ExactCoordinatesHaveEveryProperty) {
  const Cage cage(test::tetrahedron());
  const TetBarycentric exact(cage);
  const auto samples = samplesInBox(Vec3(-1), Vec3(2), 500);  // inside and outside
  const PropertyReport r = measureProperties(exact, cage, samples);
  EXPECT_EQ(r.sampleCount, 500u);
  EXPECT_LE(r.partitionOfUnity, 1e-14);
  EXPECT_LE(r.linearReproduction, 1e-14);
  EXPECT_LE(r.lagrange, 1e-15);
  EXPECT_LE(r.faceInterpolation, 1e-14);
  EXPECT_LE(r.similarityReproduction, 1e-14);
  // Barycentric coordinates go negative outside the tetrahedron, and most of this box is
  // outside it.
  EXPECT_LT(r.minWeight, -1.0);
  EXPECT_GT(r.samplesWithNegative, 0.5);
  EXPECT_GT(r.negativeFraction, 0.1);
  EXPECT_LE(r.negativeFraction, r.samplesWithNegative);
}

TEST(Properties, InsideConvexCageWeightsArePositive) {
  const Cage cage(test::tetrahedron());
  std::vector<Vec3> inside;
  for (const Vec3& p : samplesInBox(Vec3(0), Vec3(1), 2000))
    if (p.x + p.y + p.z < 1.0) inside.push_back(p);
  const PropertyReport r = measureProperties(TetBarycentric(cage), cage, inside);
  EXPECT_GE(r.minWeight, 0.0);
  EXPECT_EQ(r.negativeFraction, 0.0);
}

TEST(Properties, DetectsBrokenPartitionOfUnity) {
  const Cage cage(test::tetrahedron());
  const auto samples = samplesInBox(Vec3(0), Vec3(0.3), 100);
  const PropertyReport r = measureProperties(TetBarycentric(cage, 1e-3), cage, samples);
  EXPECT_NEAR(r.partitionOfUnity, 1e-3, 1e-12);
  EXPECT_GT(r.linearReproduction, 1e-4);
  EXPECT_NEAR(r.lagrange, 1e-3, 1e-12);
  EXPECT_NEAR(r.faceInterpolation, 1e-3, 1e-12);
  EXPECT_GT(r.similarityReproduction, 1e-4);
}

TEST(Properties, DetectsBrokenInterpolation) {
  const Cage cage(test::tetrahedron());
  const auto samples = samplesInBox(Vec3(0), Vec3(0.3), 100);
  const PropertyReport r = measureProperties(TetBarycentric(cage, 0.0, true), cage, samples);
  EXPECT_LE(r.partitionOfUnity, 1e-14);  // still sums to one
  EXPECT_NEAR(r.lagrange, 1.0, 1e-14);
  EXPECT_GT(r.faceInterpolation, 0.1);
  EXPECT_GT(r.linearReproduction, 0.01);
}

// On a cube of quads, coordinates that interpolate on faces score 0 whether their face
// interpolant is bilinear (QMVC), 2D Wachspress or the triangles' (MVC); comparing with the
// triangulation's barycentric rows gave QMVC and Wachspress 0.249. Green's vertex weights do not
// interpolate, and are caught.
TEST(Properties, FaceInterpolationOnQuadsIsJudgedByTheFacesOwnInterpolant) {
  const auto cage =
      std::make_shared<const Cage>(makeBoxSurface(Vec3(-1.0), Vec3(1.0), {1, 1, 1}), "cube");
  ASSERT_EQ(cage->maxFaceSize(), 4u);
  const auto samples = samplesInBox(Vec3(-0.9), Vec3(0.9), 50);
  EXPECT_LE(measureProperties(QuadMeanValueCoordinates(cage), *cage, samples).faceInterpolation,
            1e-12);
  EXPECT_LE(measureProperties(WachspressCoordinates(cage), *cage, samples).faceInterpolation,
            1e-12);
  EXPECT_LE(measureProperties(MeanValueCoordinates(cage), *cage, samples).faceInterpolation, 1e-12);
  EXPECT_GT(measureProperties(GreenCoordinates(cage), *cage, samples).faceInterpolation, 1e-3);
}

// TetBarycentric with `extra` more columns whose weights and column controls are zero (like
// Green coordinates' face columns, in number): the figures are the same, but a weight row is
// long, so the kit has to form the rows in blocks. It records the largest batch it is given.
class Padded final : public Coordinates {
 public:
  Padded(const Coordinates& inner, std::size_t extra) : inner_(inner), extra_(extra) {}
  std::size_t controlPointCount() const override { return inner_.controlPointCount(); }
  std::span<const Vec3> restControlPoints() const override { return inner_.restControlPoints(); }
  std::size_t columnCount() const override { return inner_.columnCount() + extra_; }
  void weights(const Vec3& x, std::span<double> row) const override {
    checkWeightsArguments(x, row.size());
    std::fill(row.begin(), row.end(), 0.0);
    inner_.weights(x, row.first(inner_.columnCount()));
  }
  void columnControls(std::span<const Vec3> posed, std::span<Vec3> out) const override {
    std::fill(out.begin(), out.end(), Vec3(0.0));
    inner_.columnControls(posed, out.first(inner_.columnCount()));
  }
  mutable std::atomic<std::size_t> largestBatch{0};

 protected:
  // `points` is the whole batch that weightsBatch() was given.
  UnmappedPoints weightsRange(std::span<const Vec3> points, std::span<double> rows,
                              std::size_t begin, std::size_t end) const override {
    std::size_t seen = largestBatch.load();
    while (points.size() > seen && !largestBatch.compare_exchange_weak(seen, points.size())) {
    }
    return Coordinates::weightsRange(points, rows, begin, end);
  }

 private:
  const Coordinates& inner_;
  std::size_t extra_;
};

// With 20,000 columns, the 600 samples' rows (96 MB) and the 1,200 face samples' rows
// (192 MB) used to be formed at once; now in blocks of 256 rows (41 MB), with the same report.
TEST(Properties, WeightRowsAreFormedInBoundedBlocks) {
  const Cage cage(test::tetrahedron());
  const TetBarycentric exact(cage);
  const Padded padded(exact, 20000);
  const auto samples = samplesInBox(Vec3(-1), Vec3(2), 600);
  PropertyOptions options;
  options.faceSamplesPerTriangle = 300;
  const PropertyReport expected = measureProperties(exact, cage, samples, options);
  const PropertyReport r = measureProperties(padded, cage, samples, options);
  EXPECT_EQ(padded.largestBatch.load(), 256u);
  EXPECT_GE(measurePropertiesMemory(padded.columnCount(), cage.triangleCount(), options),
            256.0 * 20004 * sizeof(double));
  EXPECT_LT(measurePropertiesMemory(padded.columnCount(), cage.triangleCount(), options), 50e6);
  EXPECT_EQ(r.sampleCount, expected.sampleCount);
  EXPECT_EQ(r.partitionOfUnity, expected.partitionOfUnity);
  EXPECT_EQ(r.linearReproduction, expected.linearReproduction);
  EXPECT_EQ(r.similarityReproduction, expected.similarityReproduction);
  EXPECT_EQ(r.minWeight, expected.minWeight);
  EXPECT_EQ(r.negativeFraction, expected.negativeFraction);
  EXPECT_EQ(r.samplesWithNegative, expected.samplesWithNegative);
  EXPECT_EQ(r.lagrange, expected.lagrange);
  EXPECT_EQ(r.faceInterpolation, expected.faceInterpolation);
}

TEST(Properties, RejectsMismatchedCageAndEmptySamples) {
  const Cage tet(test::tetrahedron());
  const Cage star(test::star());
  const auto samples = samplesInBox(Vec3(0), Vec3(0.3), 10);
  EXPECT_THROW(measureProperties(TetBarycentric(tet), star, samples), InvalidInput);
  EXPECT_THROW(measureProperties(TetBarycentric(tet), tet, std::span<const Vec3>()), InvalidInput);
}

}  // namespace
}  // namespace spacewarp

namespace spacewarp {
namespace {

TEST(WindingNumber, IsOneInsideAndZeroOutside) {
  const Cage cage(test::lPrism());
  EXPECT_NEAR(cage.windingNumber(Vec3(0.5, 0.5, 0.5)), 1.0, 1e-12);
  EXPECT_NEAR(cage.windingNumber(Vec3(1.5, 1.5, 0.5)), 0.0, 1e-12);  // the L's notch
  EXPECT_NEAR(cage.windingNumber(Vec3(5, -3, 2)), 0.0, 1e-12);
  EXPECT_TRUE(cage.contains(Vec3(1.5, 0.5, 0.5)));
  EXPECT_FALSE(cage.contains(Vec3(1.5, 1.5, 0.5)));
}

TEST(InteriorSamples, AreInsideDeterministicAndFillTheShape) {
  const Cage cage(test::lPrism());
  const std::vector<Vec3> a = interiorSamples(cage, 3000, 9);
  EXPECT_EQ(a, interiorSamples(cage, 3000, 9));
  EXPECT_NE(a, interiorSamples(cage, 3000, 10));
  std::size_t inArm = 0;
  for (const Vec3& x : a) {
    ASSERT_TRUE(cage.contains(x));
    inArm += x.y > 1.0;
  }
  // The upper arm is a third of the L's volume.
  EXPECT_NEAR(static_cast<double>(inArm) / a.size(), 1.0 / 3.0, 0.03);
}

TEST(MeasureProperties, WithoutACageMeasuresOnlyWhatApplies) {
  auto cage = std::make_shared<const Cage>(test::lPrism());
  const MeanValueCoordinates mvc(cage);
  const std::vector<Vec3> samples = interiorSamples(*cage, 200, 2);
  const PropertyReport withCage = measureProperties(mvc, *cage, samples);
  const PropertyReport without = measureProperties(mvc, samples, cage->diagonal());
  EXPECT_EQ(without.partitionOfUnity, withCage.partitionOfUnity);
  EXPECT_EQ(without.linearReproduction, withCage.linearReproduction);
  EXPECT_EQ(without.minWeight, withCage.minWeight);
  EXPECT_EQ(without.similarityReproduction, withCage.similarityReproduction);
  EXPECT_TRUE(std::isnan(without.lagrange));
  EXPECT_TRUE(std::isnan(without.faceInterpolation));
  EXPECT_THROW(measureProperties(mvc, samples, 0.0), InvalidInput);
}

TEST(Binding, ProgressDoesNotChangeTheWeightsAndCancelThrows) {
  auto cage = std::make_shared<const Cage>(test::lPrism());
  auto mvc = std::make_shared<const MeanValueCoordinates>(cage);
  const std::vector<Vec3> points = interiorSamples(*cage, 40000, 3);
  int calls = 0;
  const Binding reported(mvc, points, [&](std::string_view stage, double) {
    EXPECT_EQ(stage, "bind");
    ++calls;
    return true;
  });
  const Binding plain(mvc, points);
  EXPECT_GE(calls, 3);
  EXPECT_TRUE(reported.dense() == plain.dense());
  EXPECT_THROW(Binding(mvc, points, [](std::string_view, double f) { return f < 0.2; }), Cancelled);
}

}  // namespace
}  // namespace spacewarp
