#include <spacewarp/coords/wachspress.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <tbb/task_arena.h>

#include <spacewarp/coords/discrete_harmonic.h>
#include <spacewarp/coords/properties.h>
#include <spacewarp/core/archive.h>
#include <spacewarp/core/errors.h>
#include "convex_test_shapes.h"
#include "test_util.h"

namespace spacewarp {
namespace {

using ::testing::HasSubstr;

std::shared_ptr<const WachspressCoordinates> wachspress(const PolygonSoup& soup,
                                                        const WachspressOptions& options = {}) {
  return std::make_shared<const WachspressCoordinates>(std::make_shared<const Cage>(soup), options);
}

TEST(Wachspress, PropertiesOnConvexCages) {
  for (const auto& [name, soup] : test::convexCases()) {
    SCOPED_TRACE(name);
    const auto coordinates = wachspress(soup);
    const Cage& cage = coordinates->cage();
    const PropertyReport r = measureProperties(*coordinates, cage, interiorSamples(cage, 2000, 3));
    EXPECT_LE(r.partitionOfUnity, 1e-12);
    EXPECT_LE(r.linearReproduction, 1e-12);
    EXPECT_LE(r.lagrange, 1e-12);
    EXPECT_GT(r.minWeight, 0.0);  // positive inside a convex cage
    EXPECT_EQ(r.negativeFraction, 0.0);
    EXPECT_LE(test::edgeLinearityError(*coordinates, cage), 1e-12);
    // On triangle faces the coordinates are barycentric (the kit's face check applies).
    if (cage.maxFaceSize() == 3 && std::string(name) != "triangulated box") {
      EXPECT_LE(r.faceInterpolation, 1e-12);
    }
  }
}

// F11: cages rounded as exporters write them (rotated, 6 decimals or float32) are accepted; their
// nearly planar faces lie in their best-fit planes, so the rows reproduce x to about the rounding
// (1.3e-7 diagonals measured over these 30 cages), within the planarity of 1e-6; points on the
// cage's own faces, off those planes by up to the rounding, are not "outside".
TEST(Wachspress, AcceptRoundedCagesAndReproduceToTheRounding) {
  double worst = 0.0;
  for (unsigned seed = 1; seed <= 5; ++seed) {
    for (const PolygonSoup& shape : {test::hexagonalPrism(), test::truncatedOctahedron(),
                                     test::convexBox(Vec3(-1.0), Vec3(1.0))}) {
      for (const PolygonSoup& soup : {test::rotatedAndRounded(shape, seed, test::sixDecimals),
                                      test::rotatedAndRounded(shape, seed, test::float32)}) {
        const auto coordinates = wachspress(soup);
        const Cage& cage = coordinates->cage();
        const PropertyReport r =
            measureProperties(*coordinates, cage, interiorSamples(cage, 300, seed));
        EXPECT_LE(r.partitionOfUnity, 1e-12);
        EXPECT_GT(r.minWeight, 0.0);
        worst = std::max(worst, r.linearReproduction);
      }
    }
  }
  EXPECT_LE(worst, 1e-6);
  std::printf("rounded cages: linear reproduction %.3g diagonals\n", worst);
}

// Both convex-polyhedron coordinates are the barycentric coordinates on a tetrahedron.
TEST(Wachspress, EqualsDiscreteHarmonicAndBarycentricOnATetrahedron) {
  PolygonSoup soup = test::tetrahedron();
  soup.positions = {Vec3(0.3, -0.2, 0.1), Vec3(2.0, 0.1, -0.3), Vec3(0.4, 1.7, 0.2),
                    Vec3(0.1, 0.3, 1.4)};
  const auto cage = std::make_shared<const Cage>(soup);
  const WachspressCoordinates wp(cage);
  const DiscreteHarmonicCoordinates dh(cage);
  const auto p = cage->vertices();
  const double volume = glm::dot(p[1] - p[0], glm::cross(p[2] - p[0], p[3] - p[0]));
  std::vector<double> a(4), b(4);
  double worst = 0.0;
  for (const Vec3& x : interiorSamples(*cage, 500, 9)) {
    wp.weights(x, a);
    dh.weights(x, b);
    // λ_i = volume of the tetrahedron with x in place of p_i, over the whole.
    for (int i = 0; i < 4; ++i) {
      Vec3 q[4] = {p[0], p[1], p[2], p[3]};
      q[i] = x;
      const double lambda = glm::dot(q[1] - q[0], glm::cross(q[2] - q[0], q[3] - q[0])) / volume;
      worst = std::max({worst, std::fabs(a[i] - lambda), std::fabs(b[i] - lambda)});
    }
  }
  EXPECT_LE(worst, 1e-14);
}

// Wachspress coordinates of a box are the trilinear ones (a product of 1D coordinates), on the
// quads and on any triangulation of them.
TEST(Wachspress, AreTrilinearInABox) {
  const Vec3 lo(-1.0, -0.5, 0.0), hi(2.0, 1.0, 1.5);
  for (const PolygonSoup& soup :
       {test::convexBox(lo, hi), test::triangulated(test::convexBox(lo, hi))}) {
    const auto coordinates = wachspress(soup);
    const auto p = coordinates->cage().vertices();
    std::vector<double> row(8);
    std::mt19937 rng(4);
    double worst = 0.0;
    for (int i = 0; i < 500; ++i) {
      Vec3 t = test::randomPoint(rng, 0.0, 1.0);
      if (i % 3 == 0) t.x = 1.0;  // on a face
      const Vec3 x = lo + t * (hi - lo);
      coordinates->weights(x, row);
      for (std::size_t v = 0; v < 8; ++v) {
        const Vec3 s = (p[v] - lo) / (hi - lo);  // 0 or 1 per axis
        const double expected = (s.x > 0.5 ? t.x : 1.0 - t.x) * (s.y > 0.5 ? t.y : 1.0 - t.y) *
                                (s.z > 0.5 ? t.z : 1.0 - t.z);
        worst = std::max(worst, std::fabs(row[v] - expected));
      }
    }
    EXPECT_LE(worst, 1e-14);
  }
}

// On a face the coordinates are the face's 2D Wachspress coordinates (w_j ∝ C_j / (A_{j−1} A_j),
// evaluated here directly), and points approaching the face tend to them continuously.
TEST(Wachspress, ReduceToTheFaceCoordinatesOnAndNearAFace) {
  const auto coordinates = wachspress(test::pentagonalPrism());
  const Cage& cage = coordinates->cage();
  const auto p = cage.vertices();
  std::vector<std::uint32_t> cap;  // the bottom pentagon, counter-clockwise from below
  for (std::uint32_t v = 0; v < p.size(); ++v)
    if (p[v].z == 0.0) cap.push_back(v);
  ASSERT_EQ(cap.size(), 5u);
  std::reverse(cap.begin(), cap.end());  // the prism's base was given counter-clockwise from above
  const Vec3 n(0.0, 0.0, -1.0);
  auto area = [&](const Vec3& a, const Vec3& b, const Vec3& c) {
    return 0.5 * glm::dot(n, glm::cross(b - a, c - a));
  };
  std::vector<double> row(cage.vertexCount());
  double worst = 0.0, nearWorst = 0.0;
  for (const glm::dvec2 t :
       {glm::dvec2(0.5, 0.5), glm::dvec2(0.1, 0.2), glm::dvec2(1.5, 0.8), glm::dvec2(0.65, 1.45)}) {
    const Vec3 y(t.x, t.y, 0.0);
    std::vector<double> w(5);
    double sum = 0.0;
    for (std::size_t j = 0; j < 5; ++j) {
      const Vec3 a = p[cap[(j + 4) % 5]], b = p[cap[j]], c = p[cap[(j + 1) % 5]];
      w[j] = area(a, b, c) / (area(y, a, b) * area(y, b, c));
      sum += w[j];
    }
    coordinates->weights(y, row);
    for (std::size_t j = 0; j < 5; ++j)
      worst = std::max(worst, std::fabs(row[cap[j]] - w[j] / sum));
    for (double delta : {1e-4, 1e-8, 1e-12, 1e-15}) {
      const double distance = test::rowDistance(*coordinates, y, y + Vec3(0.0, 0.0, delta));
      nearWorst = std::max(nearWorst, distance / (delta / cage.diagonal() + 1e-14));
    }
  }
  EXPECT_LE(worst, 1e-14);
  EXPECT_LE(nearWorst, 100.0);  // O(distance) and a few ulp, however close
}

// Near edges and corners, where two or three heights vanish together, the rows stay accurate.
TEST(Wachspress, StayAccurateNearEdgesAndCorners) {
  for (const PolygonSoup& soup : {test::truncatedOctahedron(), test::randomSphereHull(40, 11)}) {
    const auto coordinates = wachspress(soup);
    const test::NearSurfaceReport r = test::nearSurface(*coordinates, coordinates->cage());
    EXPECT_LE(r.error, 1e-13);  // measured 2.7e-14 on the hull
    EXPECT_GE(r.minWeight, 0.0);
  }
}

// CGAL's Wachspress_coordinates_3, restated independently on the triangles: per vertex, the fan
// of det(n_f / h_f) over its triangles in order around it.
TEST(Wachspress, MatchCgalsTriangleMeshFormula) {
  const auto coordinates = wachspress(test::randomSphereHull(40, 11, 2.0, Vec3(5.0, -3.0, 1.0)));
  const Cage& cage = coordinates->cage();
  const auto p = cage.vertices();
  std::map<std::pair<std::uint32_t, std::uint32_t>, std::size_t> edgeTriangle;
  for (std::size_t t = 0; t < cage.triangleCount(); ++t)
    for (int c = 0; c < 3; ++c)
      edgeTriangle[{cage.triangles()[t][c], cage.triangles()[t][(c + 1) % 3]}] = t;
  std::vector<double> row(cage.vertexCount()), expected(cage.vertexCount());
  double worst = 0.0;
  for (const Vec3& x : interiorSamples(cage, 200, 5)) {
    auto polar = [&](std::size_t t) {
      const Triangle tri = cage.triangles()[t];
      const Vec3 n = glm::normalize(glm::cross(p[tri.y] - p[tri.x], p[tri.z] - p[tri.x]));
      return n / glm::dot(p[tri.x] - x, n);
    };
    double sum = 0.0;
    for (std::uint32_t v = 0; v < cage.vertexCount(); ++v) {
      std::vector<std::size_t> ring;  // triangles around v: after (…, u, v, …) the one of v → u
      std::size_t t = 0;
      while (cage.triangles()[t][0] != v && cage.triangles()[t][1] != v &&
             cage.triangles()[t][2] != v)
        ++t;
      do {
        ring.push_back(t);
        const Triangle tri = cage.triangles()[t];
        const std::uint32_t u = tri[0] == v ? tri[2] : (tri[1] == v ? tri[0] : tri[1]);
        t = edgeTriangle.at({v, u});
      } while (t != ring[0]);
      double w = 0.0;
      for (std::size_t i = 1; i + 1 < ring.size(); ++i)
        w += glm::dot(polar(ring[0]), glm::cross(polar(ring[i]), polar(ring[i + 1])));
      expected[v] = w;
      sum += w;
    }
    coordinates->weights(x, row);
    for (std::size_t v = 0; v < row.size(); ++v)
      worst = std::max(worst, std::fabs(row[v] - expected[v] / sum));
  }
  EXPECT_LE(worst, 1e-13);
}

// The analytic gradients are the derivatives (see test::gradientErrors); none at the surface.
TEST(Wachspress, GradientsAreExactDerivatives) {
  for (const PolygonSoup& soup : {test::truncatedOctahedron(), test::randomSphereHull(40, 11)}) {
    const auto coordinates = wachspress(soup);
    const test::GradientReport r = test::gradientErrors(*coordinates, coordinates->cage());
    EXPECT_LE(r.identities, 1e-11);
    EXPECT_LE(r.differences, 1e-6);
    std::vector<Vec3> gradients(coordinates->columnCount());
    EXPECT_FALSE(coordinates->weightGradients(coordinates->cage().vertices()[0], gradients));
  }
}

TEST(Wachspress, OutsidePointsThrowNamingTheFirstUnderThrow) {
  const auto coordinates = wachspress(test::convexBox(Vec3(0.0), Vec3(1.0)));
  std::vector<double> row(8);
  EXPECT_THAT(
      test::messageOf<InvalidInput>([&] { coordinates->weights(Vec3(0.5, 0.5, 1.25), row); }),
      HasSubstr("1 of 1 points are outside the convex cage"));
  const std::vector<Vec3> points = {Vec3(0.5), Vec3(2.0, 0.5, 0.5), Vec3(0.2),
                                    Vec3(-1.0, 0.0, 0.0)};
  std::vector<double> rows(points.size() * 8);
  const std::string message =
      test::messageOf<InvalidInput>([&] { coordinates->weightsBatch(points, rows); });
  EXPECT_THAT(message, HasSubstr("WachspressCoordinates: 2 of 4 points are outside"));
  EXPECT_THAT(message, HasSubstr("the first is point 1 at (2, 0.5, 0.5)"));
  // Within the snap distance of the surface a point is on it.
  WachspressOptions options;
  options.snapTolerance = 1e-9;
  const auto snapping = wachspress(test::convexBox(Vec3(0.0), Vec3(1.0)), options);
  snapping->weights(Vec3(0.5, 0.5, 1.0 + 1e-10), row);
  for (double w : row) EXPECT_TRUE(w == 0.0 || std::fabs(w - 0.25) <= 1e-15);
}

// The error names the remedy in every front end, and the caller's point: its index and count
// are of the whole batch even where the batch is cut into blocks (a warp's ranges, progress).
TEST(Wachspress, OutsideErrorsNameTheCallersPointAndTheRemedy) {
  const auto coordinates = wachspress(test::convexBox(Vec3(0.0), Vec3(1.0)));
  std::vector<Vec3> points(10000, Vec3(0.5));
  points[7777] = Vec3(0.5, 0.5, 5.0);
  const auto expectNamed = [](const std::string& message) {
    EXPECT_THAT(message, HasSubstr("1 of 10000 points are outside"));
    EXPECT_THAT(message, HasSubstr("the first is point 7777 at (0.5, 0.5, 5)"));
    EXPECT_THAT(message, HasSubstr("--outside nearest in the CLI"));
    EXPECT_THAT(message, HasSubstr("\"outside\": \"nearest\" in a rig"));
    EXPECT_THAT(message, HasSubstr("outside=\"nearest\" in Python"));
  };
  std::vector<double> rows(4096 * 8);
  expectNamed(
      test::messageOf<InvalidInput>([&] { coordinates->weightsBatch(points, 4096, 8192, rows); }));
  const auto warp = makeWarp(coordinates, coordinates->restControlPoints());
  std::vector<Vec3> moved(points.size());
  expectNamed(test::messageOf<InvalidInput>([&] { warp->applyBatch(points, moved); }));
  expectNamed(test::messageOf<InvalidInput>([&] { warp->applyBatch(points, moved, 4096, 8192); }));
  // A block without the outside point is weighed, in its own rows.
  coordinates->weightsBatch(points, 0, 4096, rows);
  EXPECT_DOUBLE_EQ(rows[0], 0.125);
}

TEST(Wachspress, OutsidePointsGetTheNearestSurfacePointUnderNearestPoint) {
  WachspressOptions options;
  options.outside = ConvexOutsidePolicy::NearestPoint;
  const auto coordinates = wachspress(test::truncatedOctahedron(), options);
  const auto strict = wachspress(test::truncatedOctahedron());
  std::vector<double> row(24);
  // Beyond the square x = 2 the nearest point is straight down; beyond a corner it is the corner.
  EXPECT_EQ(test::rowDistance(*coordinates, Vec3(3.0, 0.2, -0.3), Vec3(2.0, 0.2, -0.3)), 0.0);
  EXPECT_LE(test::rowDistance(*strict, Vec3(2.0, 0.2, -0.3), Vec3(2.0 - 1e-13, 0.2, -0.3)), 1e-12);
  coordinates->weights(Vec3(0.0, 10.0, 20.0), row);
  for (std::size_t v = 0; v < 24; ++v)
    EXPECT_EQ(row[v], coordinates->cage().vertices()[v] == Vec3(0.0, 1.0, 2.0) ? 1.0 : 0.0);
}

TEST(Wachspress, BatchRowsAreTheSingleRowsForAnyThreadCount) {
  const auto coordinates = wachspress(test::randomSphereHull(40, 11));
  const std::size_t m = coordinates->columnCount();
  std::vector<Vec3> points = interiorSamples(coordinates->cage(), 1000, 2);
  std::vector<double> many(points.size() * m), one(points.size() * m), row(m);
  coordinates->weightsBatch(points, many);
  tbb::task_arena(1).execute([&] { coordinates->weightsBatch(points, one); });
  EXPECT_EQ(many, one);
  coordinates->weights(points[17], row);
  EXPECT_TRUE(std::equal(row.begin(), row.end(), many.begin() + 17 * m));
}

TEST(Wachspress, SaveAndLoadRebuildTheSameCoordinates) {
  WachspressOptions options;
  options.snapTolerance = 1e-10;
  options.outside = ConvexOutsidePolicy::NearestPoint;
  const auto coordinates = wachspress(test::hexagonalPrism(), options);
  ArchiveWriter out;
  coordinates->save(out);
  const ArchiveLoaders loaders;
  ArchiveReader in(out.bytes(), loaders);
  EXPECT_EQ(in.string(), "wachspress");
  const auto loaded = WachspressCoordinates::load(in);
  EXPECT_TRUE(in.atEnd());
  EXPECT_EQ(loaded->options().snapTolerance, 1e-10);
  EXPECT_EQ(loaded->options().outside, ConvexOutsidePolicy::NearestPoint);
  std::vector<double> a(12), b(12);
  for (const Vec3& x : {Vec3(0.1, 0.2, 0.3), Vec3(5.0, 0.0, 0.5)}) {
    coordinates->weights(x, a);
    loaded->weights(x, b);
    EXPECT_EQ(a, b);
  }
}

TEST(Wachspress, RejectsBadInputNamingIt) {
  EXPECT_THAT(test::messageOf<InvalidInput>([] { WachspressCoordinates(nullptr); }),
              HasSubstr("the cage is null"));
  WachspressOptions options;
  options.snapTolerance = 0.1;
  EXPECT_THAT(test::messageOf<InvalidInput>([&] { wachspress(test::tetrahedron(), options); }),
              HasSubstr("snapTolerance must be in [0, 1e-3]"));
  EXPECT_THAT(test::messageOf<InvalidInput>([] { wachspress(test::lPrism()); }),
              HasSubstr("WachspressCoordinates: cage: the cage is not convex: the edge between "
                        "vertices 3 and 9"));
}

}  // namespace
}  // namespace spacewarp
