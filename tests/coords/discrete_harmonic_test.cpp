#include <spacewarp/coords/discrete_harmonic.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <tbb/task_arena.h>

#include <spacewarp/coords/detail/convex_polyhedron.h>
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

// A random hull under a shearing, stretching linear map: still simplicial, with long thin
// triangles and dihedral angles far from the sphere's.
PolygonSoup stretchedHull() {
  PolygonSoup soup = test::randomSphereHull(60, 23);
  const Mat3 map(3.0, 0.4, -0.2, 0.9, 1.0, 0.3, -0.5, 0.2, 0.4);
  for (Vec3& p : soup.positions) p = map * p;
  return soup;
}

// The simplicial convex cages discrete harmonic coordinates are tested on.
std::vector<test::ConvexCase> simplicialCases() {
  return {{"tetrahedron", test::tetrahedron()},
          {"octahedron", test::octahedron()},
          {"icosphere", test::icosphere(2)},
          {"random hull", test::randomSphereHull(40, 11, 2.0, Vec3(5.0, -3.0, 1.0))},
          {"random hull of 100", test::randomSphereHull(100, 3)},
          {"stretched hull", stretchedHull()}};
}

TEST(DiscreteHarmonic, PropertiesOnSimplicialCages) {
  for (const auto& [name, soup] : simplicialCases()) {
    SCOPED_TRACE(name);
    const auto coordinates = harmonic(soup);
    const Cage& cage = coordinates->cage();
    const PropertyReport r = measureProperties(*coordinates, cage, interiorSamples(cage, 2000, 3));
    EXPECT_LE(r.partitionOfUnity, 1e-12);
    EXPECT_LE(r.linearReproduction, 1e-12);
    EXPECT_LE(r.lagrange, 1e-12);
    EXPECT_LE(r.faceInterpolation, 1e-12);
    EXPECT_LE(test::edgeLinearityError(*coordinates, cage), 1e-12);
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

// A polytope face that is not a triangle is refused, naming it: a cage face that is a polygon, or
// coplanar triangles that merge into one (whose triangulation would make the coordinates
// discontinuous at its corners).
TEST(DiscreteHarmonic, RefuseCagesWithPolygonFacesNamingThem) {
  const std::string advice =
      ": discrete harmonic coordinates need triangle faces (a simplicial polytope); use "
      "wachspress, which takes polygon faces";
  auto refusal = [](const PolygonSoup& soup) {
    return test::messageOf<InvalidInput>(
        [&] { DiscreteHarmonicCoordinates(std::make_shared<const Cage>(soup, "box.obj")); });
  };
  const PolygonSoup box = test::convexBox(Vec3(0.0), Vec3(1.0));
  const auto first = box.polygon(0);
  const std::string quad = "face 0 (vertices " + detail::vertexList(first) + ") is a planar quad";
  EXPECT_EQ(refusal(box), "DiscreteHarmonicCoordinates: box.obj: " + quad + advice);

  const PolygonSoup triangles = test::triangulated(box);  // faces 2f and 2f + 1 from quad f
  const std::string merged = "the coplanar faces 0, 1 merge into a planar quad (vertices " +
                             detail::vertexList(first) + ")";
  EXPECT_EQ(refusal(triangles), "DiscreteHarmonicCoordinates: box.obj: " + merged + advice);

  EXPECT_THAT(refusal(test::pentagonalPrism()), HasSubstr("is a planar pentagon"));
  EXPECT_THAT(refusal(test::truncatedOctahedron()), HasSubstr("is a planar"));
}

// On a face the row is the barycentric coordinates there; approaching the face from inside it
// tends to them continuously: the row changes in proportion to the distance, at the same rate from
// 1e-8 and from 1e-12 away (a jump would show as a rate growing like 1 / distance).
TEST(DiscreteHarmonic, TendToBarycentricCoordinatesNearAFace) {
  const auto coordinates = harmonic(test::randomSphereHull(40, 11));
  const Cage& cage = coordinates->cage();
  const auto p = cage.vertices();
  std::vector<double> row(cage.vertexCount());
  double onFace = 0.0, rateGrowth = 0.0;
  for (const Triangle& tri : cage.triangles()) {
    const Vec3 a = p[tri[0]], b = p[tri[1]], c = p[tri[2]];
    const Vec3 inward = -glm::normalize(glm::cross(b - a, c - a));
    const Vec3 y = 0.2 * a + 0.5 * b + 0.3 * c;
    coordinates->weights(y, row);
    for (std::size_t v = 0; v < row.size(); ++v) {
      const double expected = v == tri[0] ? 0.2 : (v == tri[1] ? 0.5 : (v == tri[2] ? 0.3 : 0.0));
      onFace = std::max(onFace, std::fabs(row[v] - expected));
    }
    const double far = test::rowDistance(*coordinates, y, y + 1e-8 * inward) / 1e-8;
    const double near = test::rowDistance(*coordinates, y, y + 1e-12 * inward) / 1e-12;
    rateGrowth = std::max(rateGrowth, near / (far + 1.0));
  }
  EXPECT_LE(onFace, 1e-14);
  EXPECT_LE(rateGrowth, 1.1);
}

// Weights are negative only where x sees a dihedral angle above 90°; on simplicial cages they stay
// far above −1. Measured at these 10,000 points: tetrahedron ≥ 0, icosphere −0.0018, octahedron
// −0.021, random hulls −0.25 and −0.19, stretched hull −0.18; over 20 random hulls of 20 to 200
// sphere points the lowest was −0.36. Polygon faces' continued 2D coordinates (the code this
// replaced) gave −198 to −4956 at interior points, so a regression to poles fails here.
TEST(DiscreteHarmonic, StayAboveMinusOneOnSimplicialCages) {
  for (const auto& [name, soup] : simplicialCases()) {
    SCOPED_TRACE(name);
    const auto coordinates = harmonic(soup);
    const Cage& cage = coordinates->cage();
    const PropertyReport r =
        measureProperties(*coordinates, cage, interiorSamples(cage, 10000, 17));
    EXPECT_GE(r.minWeight, -1.0);
    EXPECT_LE(r.partitionOfUnity, 1e-12);
  }
}

// Near edges and corners, where two or three heights vanish together, the rows stay accurate.
TEST(DiscreteHarmonic, StayAccurateNearEdgesAndCorners) {
  for (const PolygonSoup& soup :
       {test::octahedron(), test::randomSphereHull(40, 11), test::icosphere(1)}) {
    const auto coordinates = harmonic(soup);
    EXPECT_LE(test::nearSurface(*coordinates, coordinates->cage()).error, 1e-14);
  }
}

// The analytic gradients are the derivatives (see test::gradientErrors); none at the surface. On
// the stretched hull the central differences' own truncation error is larger (measured 7e-2, 7e-4,
// 7e-6 at steps of 1e-5, 1e-6, 1e-7 diagonals: quadratic in the step, as it is for exact
// gradients).
TEST(DiscreteHarmonic, GradientsAreExactDerivatives) {
  for (const auto& [soup, tolerance] :
       {std::pair{test::octahedron(), 1e-6}, std::pair{test::randomSphereHull(40, 11), 1e-6},
        std::pair{stretchedHull(), 1e-5}}) {
    const auto coordinates = harmonic(soup);
    const test::GradientReport r = test::gradientErrors(*coordinates, coordinates->cage());
    EXPECT_LE(r.identities, 1e-11);
    EXPECT_LE(r.differences, tolerance);
    std::vector<Vec3> gradients(coordinates->columnCount());
    EXPECT_FALSE(coordinates->weightGradients(coordinates->cage().vertices()[0], gradients));
  }
}

TEST(DiscreteHarmonic, OutsidePolicies) {
  const auto strict = harmonic(test::octahedron());
  std::vector<Vec3> points = {Vec3(0.0), Vec3(0.0, 0.0, 2.5)};
  std::vector<double> rows(points.size() * 6);
  const std::string message =
      test::messageOf<InvalidInput>([&] { strict->weightsBatch(points, rows); });
  EXPECT_THAT(message, HasSubstr("DiscreteHarmonicCoordinates: 1 of 2 points are outside"));
  EXPECT_THAT(message, HasSubstr("point 1 at (0, 0, 2.5)"));
  DiscreteHarmonicOptions options;
  options.outside = ConvexOutsidePolicy::NearestPoint;
  const auto nearest = harmonic(test::octahedron(), options);
  // Nearest to the corner +e_z (vertex 4), and to a point of the face x − y + z = 1.
  EXPECT_EQ(test::rowDistance(*nearest, Vec3(0.1, -0.2, 2.5), Vec3(0.0, 0.0, 1.0)), 0.0);
  const Vec3 onFace(0.1, -0.2, 0.7), normal = glm::normalize(Vec3(1.0, -1.0, 1.0));
  EXPECT_LE(test::rowDistance(*nearest, onFace + 0.5 * normal, onFace), 1e-15);
  EXPECT_LE(test::rowDistance(*strict, onFace, onFace - 1e-13 * normal), 1e-12);
}

TEST(DiscreteHarmonic, BatchRowsAreTheSingleRowsForAnyThreadCount) {
  const auto coordinates = harmonic(test::randomSphereHull(40, 11));
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
  const auto coordinates = harmonic(test::octahedron(), options);
  ArchiveWriter out;
  coordinates->save(out);
  const ArchiveLoaders loaders;
  ArchiveReader in(out.bytes(), loaders);
  EXPECT_EQ(in.string(), "discrete-harmonic");
  const auto loaded = DiscreteHarmonicCoordinates::load(in);
  EXPECT_TRUE(in.atEnd());
  EXPECT_EQ(loaded->options().snapTolerance, 1e-11);
  EXPECT_EQ(loaded->options().outside, ConvexOutsidePolicy::NearestPoint);
  std::vector<double> a(6), b(6);
  for (const Vec3& x : {Vec3(0.1, 0.2, 0.3), Vec3(5.0, 0.0, 0.5)}) {
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
