#include <spacewarp/coords/discrete_harmonic.h>

#include <cmath>
#include <memory>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <tbb/task_arena.h>

#include <spacewarp/coords/properties.h>
#include <spacewarp/core/archive.h>
#include <spacewarp/core/errors.h>
#include "convex_test_shapes.h"
#include "test_util.h"

namespace spacewarp {
namespace {

using ::testing::HasSubstr;

std::shared_ptr<const DiscreteHarmonicCoordinates> harmonic(
    const PolygonSoup& soup, const DiscreteHarmonicOptions& options = {}) {
  return std::make_shared<const DiscreteHarmonicCoordinates>(std::make_shared<const Cage>(soup),
                                                             options);
}

TEST(DiscreteHarmonic, PropertiesOnConvexCages) {
  for (const auto& [name, soup] : test::convexCases()) {
    SCOPED_TRACE(name);
    const auto coordinates = harmonic(soup);
    const Cage& cage = coordinates->cage();
    const PropertyReport r = measureProperties(*coordinates, cage, interiorSamples(cage, 2000, 3));
    EXPECT_LE(r.partitionOfUnity, 1e-12);
    EXPECT_LE(r.linearReproduction, 1e-12);
    EXPECT_LE(r.lagrange, 1e-12);
    EXPECT_LE(test::edgeLinearityError(*coordinates, cage), 1e-12);
    if (cage.maxFaceSize() == 3 && std::string(name) != "triangulated box") {
      EXPECT_LE(r.faceInterpolation, 1e-12);
    }
  }
}

// CGAL's Discrete_harmonic_coordinates_3, restated on the triangles: corner c of every triangle
// (a, b, c) gets ½ |ab| cot θ, θ the dihedral angle at ab between the triangle and the plane
// through x and ab.
TEST(DiscreteHarmonic, MatchCgalsTriangleMeshFormula) {
  for (const PolygonSoup& soup :
       {test::randomSphereHull(40, 11, 2.0, Vec3(5.0, -3.0, 1.0)), test::icosphere(1)}) {
    const auto coordinates = harmonic(soup);
    const Cage& cage = coordinates->cage();
    const auto p = cage.vertices();
    std::vector<double> row(cage.vertexCount()), expected(cage.vertexCount());
    double worst = 0.0;
    for (const Vec3& x : interiorSamples(cage, 200, 5)) {
      std::fill(expected.begin(), expected.end(), 0.0);
      double sum = 0.0;
      for (const Triangle& tri : cage.triangles()) {
        for (int c = 0; c < 3; ++c) {
          const Vec3 a = p[tri[(c + 1) % 3]], b = p[tri[(c + 2) % 3]], corner = p[tri[c]];
          const Vec3 e = glm::normalize(b - a);
          // Directions, perpendicular to the edge, towards the corner and towards x.
          const Vec3 toCorner = glm::normalize((corner - a) - glm::dot(corner - a, e) * e);
          const Vec3 toX = glm::normalize((x - a) - glm::dot(x - a, e) * e);
          const double theta =
              std::atan2(glm::length(glm::cross(toCorner, toX)), glm::dot(toCorner, toX));
          const double w = 0.5 * glm::length(b - a) / std::tan(theta);
          expected[tri[c]] += w;
          sum += w;
        }
      }
      coordinates->weights(x, row);
      for (std::size_t v = 0; v < row.size(); ++v)
        worst = std::max(worst, std::fabs(row[v] - expected[v] / sum));
    }
    EXPECT_LE(worst, 1e-12);
  }
}

// The largest difference between the row at points y of a face (its corners `cap`,
// counter-clockwise seen from outside) and the face's 2D discrete harmonic coordinates, w_j = the
// cotangents of the two angles facing the segment y v_j, evaluated directly; and the largest
// change of the row, over the distance, as y moves into the cage along `inward`.
std::pair<double, double> faceError(const Coordinates& coordinates, std::span<const Vec3> p,
                                    const std::vector<std::uint32_t>& cap,
                                    std::initializer_list<Vec3> points, const Vec3& inward) {
  auto cot = [](const Vec3& apex, const Vec3& a, const Vec3& b) {
    const Vec3 u = a - apex, v = b - apex;
    return glm::dot(u, v) / glm::length(glm::cross(u, v));
  };
  const std::size_t m = cap.size();
  std::vector<double> row(p.size()), w(m);
  double worst = 0.0, nearWorst = 0.0;
  for (const Vec3& y : points) {
    double sum = 0.0;
    for (std::size_t j = 0; j < m; ++j) {
      const Vec3 prev = p[cap[(j + m - 1) % m]], v = p[cap[j]], next = p[cap[(j + 1) % m]];
      w[j] = cot(prev, y, v) + cot(next, v, y);
      sum += w[j];
    }
    coordinates.weights(y, row);
    for (std::size_t j = 0; j < m; ++j)
      worst = std::max(worst, std::fabs(row[cap[j]] - w[j] / sum));
    for (double delta : {1e-4, 1e-8, 1e-12}) {
      const double distance = test::rowDistance(coordinates, y, y + delta * inward);
      nearWorst = std::max(nearWorst, distance / (delta + 1e-14));
    }
  }
  return {worst, nearWorst};
}

// On a face the coordinates are the face's 2D discrete harmonic coordinates: on a pentagon that
// is not cyclic, and on a regular hexagon, whose coordinates are computed in the (equal)
// Wachspress form; points approaching the face tend to them. On the squares of a box they are
// bilinear. A triangulated box has the box's coordinates.
TEST(DiscreteHarmonic, ReduceToTheFaceCoordinatesOnAFace) {
  const auto pentagon = harmonic(test::pentagonalPrism());
  const auto [worst, nearWorst] =
      faceError(*pentagon, pentagon->cage().vertices(), {4, 3, 2, 1, 0},
                {Vec3(0.5, 0.5, 0.0), Vec3(0.1, 0.2, 0.0), Vec3(1.5, 0.8, 0.0)}, Vec3(0, 0, 1));
  EXPECT_LE(worst, 1e-14);
  EXPECT_LE(nearWorst, 100.0);
  const auto hexagon = harmonic(test::hexagonalPrism());
  const auto [hexWorst, hexNear] =
      faceError(*hexagon, hexagon->cage().vertices(), {6, 7, 8, 9, 10, 11},
                {Vec3(0.2, 0.3, 1.0), Vec3(-0.5, 0.1, 1.0), Vec3(0.6, -0.6, 1.0)}, Vec3(0, 0, -1));
  EXPECT_LE(hexWorst, 1e-14);
  EXPECT_LE(hexNear, 100.0);

  const auto quads = harmonic(test::convexBox(Vec3(0.0), Vec3(1.0)));
  const auto triangles = harmonic(test::triangulated(test::convexBox(Vec3(0.0), Vec3(1.0))));
  std::vector<double> a(8);
  quads->weights(Vec3(0.3, 0.8, 1.0), a);
  for (std::size_t v = 0; v < 8; ++v) {
    const Vec3 c = quads->cage().vertices()[v];
    const double expected = c.z * (c.x > 0.5 ? 0.3 : 0.7) * (c.y > 0.5 ? 0.8 : 0.2);
    EXPECT_NEAR(a[v], expected, 1e-15);
  }
  double triangulation = 0.0;
  std::vector<double> b(8);
  for (const Vec3& x : interiorSamples(quads->cage(), 200, 8)) {
    quads->weights(x, a);
    triangles->weights(x, b);
    for (std::size_t v = 0; v < 8; ++v)
      triangulation = std::max(triangulation, std::fabs(a[v] - b[v]));
  }
  EXPECT_LE(triangulation, 1e-15);
}

// Faces that are neither triangles nor rectangles: interior points of a sheared box project
// outside its parallelograms, where their continued 2D coordinates grow large (weights of a few
// hundred measured, see discrete_harmonic.cpp), yet every row stays a partition of unity that
// reproduces x, and the row is still Lagrange and linear on the edges.
TEST(DiscreteHarmonic, StayLinearlyPreciseOnParallelogramFaces) {
  PolygonSoup soup = test::convexBox(Vec3(0.0), Vec3(1.0));
  const Mat3 shear(1.0, 0.2, -0.1, 0.6, 1.1, 0.3, -0.4, 0.5, 0.9);
  for (Vec3& p : soup.positions) p = shear * p;
  const auto coordinates = harmonic(soup);
  const Cage& cage = coordinates->cage();
  const PropertyReport r = measureProperties(*coordinates, cage, interiorSamples(cage, 4000, 3));
  EXPECT_LE(r.partitionOfUnity, 1e-12);
  EXPECT_LE(r.linearReproduction, 1e-12);
  EXPECT_LE(r.lagrange, 1e-12);
  EXPECT_LE(test::edgeLinearityError(*coordinates, cage), 1e-12);
  EXPECT_LT(r.minWeight, -1.0);  // the documented caveat: not bounded like Wachspress's
}

// Near edges and corners, where two or three heights vanish together, the rows stay accurate.
TEST(DiscreteHarmonic, StayAccurateNearEdgesAndCorners) {
  for (const PolygonSoup& soup :
       {test::truncatedOctahedron(), test::randomSphereHull(40, 11), test::pentagonalPrism()}) {
    const auto coordinates = harmonic(soup);
    EXPECT_LE(test::nearSurface(*coordinates, coordinates->cage()).error, 1e-14);
  }
}

// The analytic gradients are the derivatives (see test::gradientErrors), on triangle and polygon
// faces (cyclic and not); none at the surface.
TEST(DiscreteHarmonic, GradientsAreExactDerivatives) {
  for (const PolygonSoup& soup :
       {test::truncatedOctahedron(), test::randomSphereHull(40, 11), test::pentagonalPrism()}) {
    const auto coordinates = harmonic(soup);
    const test::GradientReport r = test::gradientErrors(*coordinates, coordinates->cage());
    EXPECT_LE(r.identities, 1e-11);
    EXPECT_LE(r.differences, 1e-6);
    std::vector<Vec3> gradients(coordinates->columnCount());
    EXPECT_FALSE(coordinates->weightGradients(coordinates->cage().vertices()[0], gradients));
  }
}

TEST(DiscreteHarmonic, OutsidePolicies) {
  const auto strict = harmonic(test::truncatedOctahedron());
  std::vector<Vec3> points = {Vec3(0.0), Vec3(0.0, 0.0, 2.5)};
  std::vector<double> rows(points.size() * 24);
  const std::string message =
      test::messageOf<InvalidInput>([&] { strict->weightsBatch(points, rows); });
  EXPECT_THAT(message, HasSubstr("DiscreteHarmonicCoordinates: 1 of 2 points are outside"));
  EXPECT_THAT(message, HasSubstr("point 1 at (0, 0, 2.5)"));
  DiscreteHarmonicOptions options;
  options.outside = ConvexOutsidePolicy::NearestPoint;
  const auto nearest = harmonic(test::truncatedOctahedron(), options);
  EXPECT_EQ(test::rowDistance(*nearest, Vec3(0.1, -0.2, 2.5), Vec3(0.1, -0.2, 2.0)), 0.0);
  EXPECT_LE(test::rowDistance(*strict, Vec3(0.1, -0.2, 2.0), Vec3(0.1, -0.2, 2.0 - 1e-13)), 1e-12);
}

TEST(DiscreteHarmonic, BatchRowsAreTheSingleRowsForAnyThreadCount) {
  const auto coordinates = harmonic(test::truncatedOctahedron());
  const std::size_t m = coordinates->columnCount();
  std::vector<Vec3> points = interiorSamples(coordinates->cage(), 1000, 2);
  std::vector<double> many(points.size() * m), one(points.size() * m), row(m);
  coordinates->weightsBatch(points, many);
  tbb::task_arena(1).execute([&] { coordinates->weightsBatch(points, one); });
  EXPECT_EQ(many, one);
  coordinates->weights(points[17], row);
  EXPECT_TRUE(std::equal(row.begin(), row.end(), many.begin() + 17 * m));
}

TEST(DiscreteHarmonic, SaveAndLoadRebuildTheSameCoordinates) {
  DiscreteHarmonicOptions options;
  options.snapTolerance = 1e-11;
  options.outside = ConvexOutsidePolicy::NearestPoint;
  const auto coordinates = harmonic(test::pentagonalPrism(), options);
  ArchiveWriter out;
  coordinates->save(out);
  const ArchiveLoaders loaders;
  ArchiveReader in(out.bytes(), loaders);
  EXPECT_EQ(in.string(), "discrete-harmonic");
  const auto loaded = DiscreteHarmonicCoordinates::load(in);
  EXPECT_TRUE(in.atEnd());
  EXPECT_EQ(loaded->options().snapTolerance, 1e-11);
  EXPECT_EQ(loaded->options().outside, ConvexOutsidePolicy::NearestPoint);
  std::vector<double> a(10), b(10);
  for (const Vec3& x : {Vec3(0.5, 0.5, 0.3), Vec3(5.0, 0.0, 0.5)}) {
    coordinates->weights(x, a);
    loaded->weights(x, b);
    EXPECT_EQ(a, b);
  }
}

TEST(DiscreteHarmonic, RejectsBadInputNamingIt) {
  EXPECT_THAT(test::messageOf<InvalidInput>([] { DiscreteHarmonicCoordinates(nullptr); }),
              HasSubstr("the cage is null"));
  DiscreteHarmonicOptions options;
  options.snapTolerance = -1.0;
  EXPECT_THAT(test::messageOf<InvalidInput>([&] { harmonic(test::tetrahedron(), options); }),
              HasSubstr("snapTolerance must be in [0, 1e-3]"));
  EXPECT_THAT(test::messageOf<InvalidInput>([] { harmonic(test::pinchedBox(0.5)); }),
              HasSubstr("DiscreteHarmonicCoordinates: cage: the cage is not convex"));
}

}  // namespace
}  // namespace spacewarp
