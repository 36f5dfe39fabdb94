#include <spacewarp/coords/green.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <limits>
#include <memory>
#include <numbers>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <tbb/task_arena.h>

#include <spacewarp/coords/detail/green_kernels.h>
#include <spacewarp/coords/properties.h>
#include <spacewarp/core/binding.h>
#include <spacewarp/core/coordinate_warp.h>
#include <spacewarp/core/errors.h>
#include <spacewarp/core/io/mesh_io.h>
#include <spacewarp/core/primitives.h>
#include "coords_test_shapes.h"
#include "test_util.h"

namespace spacewarp {
namespace {

using Region = GreenCoordinates::Region;

struct NamedCage {
  std::string name;
  std::shared_ptr<const Cage> cage;
};

std::shared_ptr<const Cage> makeCage(const PolygonSoup& soup, const std::string& name) {
  return std::make_shared<const Cage>(soup, name);
}

std::vector<NamedCage> testCages() {
  return {
      {"tetrahedron", makeCage(test::tetrahedron(), "tetrahedron")},
      {"box", makeCage(makeBoxSurface(Vec3(0), Vec3(1), {1, 1, 1}), "box")},
      {"box222", makeCage(makeBoxSurface(Vec3(0), Vec3(1), {2, 2, 2}), "box222")},
      {"lPrism", makeCage(test::lPrism(), "lPrism")},
      {"star", makeCage(test::star(), "star")},
      {"icosphere", makeCage(test::icosphere(2), "icosphere")},
  };
}

// The winding number of the cage around x, independently of the code under test: the sum of
// the triangles' solid angles (Van Oosterom and Strackee) over 4π.
double windingNumber(const Cage& cage, const Vec3& x) {
  double sum = 0.0;
  for (const Triangle& t : cage.triangles()) {
    const Vec3 a = cage.vertices()[t.x] - x, b = cage.vertices()[t.y] - x,
               c = cage.vertices()[t.z] - x;
    const double la = glm::length(a), lb = glm::length(b), lc = glm::length(c);
    const double num = glm::dot(a, glm::cross(b, c));
    const double den =
        la * lb * lc + glm::dot(a, b) * lc + glm::dot(b, c) * la + glm::dot(c, a) * lb;
    sum += 2.0 * std::atan2(num, den);
  }
  return sum / (4.0 * std::numbers::pi);
}

BoundingBox cageBox(const Cage& cage) { return boundingBox(cage.vertices()); }

// Random points of the cage's bounding box enlarged by `grow` × its extent on each side, kept
// when inside == (winding number > 1/2).
std::vector<Vec3> randomPoints(const Cage& cage, std::size_t n, bool inside, double grow,
                               std::mt19937& rng) {
  const BoundingBox box = cageBox(cage);
  const Vec3 lo = box.min - grow * box.extent(), hi = box.max + grow * box.extent();
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<Vec3> points;
  while (points.size() < n) {
    const double a = u(rng), b = u(rng), c = u(rng);
    const Vec3 x = lo + Vec3(a, b, c) * (hi - lo);
    if ((windingNumber(cage, x) > 0.5) == inside) points.push_back(x);
  }
  return points;
}

// Σφ_i v_i + Σψ_j n_j with the rest cage.
Vec3 reproduce(const Cage& cage, const std::vector<double>& row) {
  Vec3 sum(0.0);
  const std::size_t nv = cage.vertexCount();
  for (std::size_t i = 0; i < nv; ++i) sum += row[i] * cage.vertices()[i];
  for (std::size_t j = 0; j < cage.triangleCount(); ++j) sum += row[nv + j] * cage.normal(j);
  return sum;
}

double phiSum(const Cage& cage, const std::vector<double>& row) {
  double sum = 0.0;
  for (std::size_t i = 0; i < cage.vertexCount(); ++i) sum += row[i];
  return sum;
}

bool allFinite(const std::vector<double>& row) {
  for (double w : row)
    if (!std::isfinite(w)) return false;
  return true;
}

std::vector<double> weightsOf(const GreenCoordinates& g, const Vec3& x) {
  std::vector<double> row(g.columnCount());
  g.weights(x, row);
  return row;
}

// Checks the raw coordinates of x: finite, Σφ = 1 and Σφv + Σψn = x (relative to the diagonal).
::testing::AssertionResult reproducesPoint(const GreenCoordinates& g, const Vec3& x,
                                           double tolerance = 1e-12) {
  const std::vector<double> row = weightsOf(g, x);
  if (!allFinite(row)) return ::testing::AssertionFailure() << "non-finite weights";
  const double err = glm::length(reproduce(g.cage(), row) - x) / g.cage().diagonal();
  const double unity = std::abs(phiSum(g.cage(), row) - 1.0);
  if (!(err <= tolerance && unity <= tolerance)) {
    return ::testing::AssertionFailure()
           << "at " << test::toString(x) << ": |Σφv + Σψn − x| / diagonal = " << err
           << ", |Σφ − 1| = " << unity;
  }
  return ::testing::AssertionSuccess();
}

// A rotation about a unit axis (Rodrigues).
Mat3 rotation(const Vec3& axis, double angle) {
  const double c = std::cos(angle), s = std::sin(angle);
  Mat3 k(0.0);  // cross-product matrix, column-major
  k[0] = Vec3(0, axis.z, -axis.y);
  k[1] = Vec3(-axis.z, 0, axis.x);
  k[2] = Vec3(axis.y, -axis.x, 0);
  return Mat3(1.0) + s * k + (1.0 - c) * (k * k);
}

std::vector<Vec3> perturbed(const Cage& cage, double amount, std::mt19937& rng) {
  std::vector<Vec3> posed(cage.vertices().begin(), cage.vertices().end());
  for (Vec3& p : posed) p += amount * cage.diagonal() * test::randomUnit(rng);
  return posed;
}

// A random point on triangle t whose barycentric coordinates are all at least `margin`.
Vec3 randomFacePoint(const Cage& cage, std::size_t t, double margin, std::mt19937& rng) {
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (;;) {
    const double a = u(rng), b = u(rng), c = 1.0 - a - b;
    if (a < margin || b < margin || c < margin) continue;
    const Triangle& tri = cage.triangles()[t];
    return a * cage.vertices()[tri.x] + b * cage.vertices()[tri.y] + c * cage.vertices()[tri.z];
  }
}

TEST(GreenCoordinates, ColumnsAreVerticesThenFaces) {
  const auto cage = makeCage(test::tetrahedron(), "tet");
  const GreenCoordinates g(cage);
  EXPECT_EQ(g.controlPointCount(), 4u);
  EXPECT_EQ(g.columnCount(), 8u);
  EXPECT_EQ(g.maxNonZeros(), 8u);
  EXPECT_EQ(g.columnName(3), "v3");
  EXPECT_EQ(g.columnName(4), "f0");
  EXPECT_EQ(g.columnName(7), "f3");
  ASSERT_EQ(g.restControlPoints().size(), 4u);
  EXPECT_EQ(g.restControlPoints()[1], cage->vertices()[1]);
}

TEST(GreenCoordinates, RestControlsAreUnitOutwardNormals) {
  for (const NamedCage& c : testCages()) {
    const GreenCoordinates g(c.cage);
    std::vector<Vec3> controls(g.columnCount());
    g.columnControls(c.cage->vertices(), controls);
    const std::size_t nv = c.cage->vertexCount();
    for (std::size_t i = 0; i < nv; ++i) EXPECT_EQ(controls[i], c.cage->vertices()[i]);
    for (std::size_t j = 0; j < c.cage->triangleCount(); ++j)
      EXPECT_LT(glm::length(controls[nv + j] - c.cage->normal(j)), 1e-14) << c.name << " " << j;
  }
}

TEST(GreenCoordinates, StretchFactorOfASimilarityIsItsScale) {
  const auto cage = makeCage(test::star(), "star");
  const GreenCoordinates g(cage);
  const Mat3 r = rotation(glm::normalize(Vec3(1, 2, -0.5)), 0.7);
  const double k = 2.5;
  std::vector<Vec3> posed;
  for (const Vec3& v : cage->vertices()) posed.push_back(k * (r * v) + Vec3(3, -1, 2));
  std::vector<Vec3> controls(g.columnCount());
  g.columnControls(posed, controls);
  for (std::size_t j = 0; j < cage->triangleCount(); ++j) {
    const Vec3 expected = k * (r * cage->normal(j));
    EXPECT_LT(glm::length(controls[cage->vertexCount() + j] - expected), 1e-13) << j;
  }
}

TEST(GreenCoordinates, StretchFactorOfAnAnisotropicStretch) {
  // Stretching a triangle in z = 0 by (a, b) in x and y: |u'|²|v|² − 2(u'·v')(u·v) + |v'|²|u|²
  // over 8 area² is (a² + b²) / 2 for the right isosceles triangle.
  PolygonSoup s = test::tetrahedron();
  const auto cage = makeCage(s, "tet");
  const GreenCoordinates g(cage);
  const double a = 2.0, b = 0.5;
  std::vector<Vec3> posed;
  for (const Vec3& v : cage->vertices()) posed.push_back(Vec3(a * v.x, b * v.y, v.z));
  std::vector<Vec3> controls(g.columnCount());
  g.columnControls(posed, controls);
  // Triangle 0 is {0, 2, 1}: the bottom face, normal −z.
  EXPECT_LT(glm::length(controls[4] - Vec3(0, 0, -std::sqrt((a * a + b * b) / 2.0))), 1e-14);
}

TEST(GreenCoordinates, CollapsedPosedTriangleGetsZeroNormal) {
  const auto cage = makeCage(test::tetrahedron(), "tet");
  const GreenCoordinates g(cage);
  std::vector<Vec3> posed(cage->vertices().begin(), cage->vertices().end());
  posed[3] = posed[0];  // triangles using vertices 0 and 3 collapse
  std::vector<Vec3> controls(g.columnCount());
  g.columnControls(posed, controls);
  EXPECT_EQ(controls[4 + 1], Vec3(0.0));  // {0, 1, 3}
  EXPECT_EQ(controls[4 + 2], Vec3(0.0));  // {0, 3, 2}
  EXPECT_GT(glm::length(controls[4 + 0]), 0.5);
}

TEST(GreenCoordinates, ReproducesInteriorPointsAtRest) {
  std::mt19937 rng(11);
  for (const NamedCage& c : testCages()) {
    const GreenCoordinates g(c.cage);
    for (const Vec3& x : randomPoints(*c.cage, 300, true, 0.0, rng)) {
      ASSERT_TRUE(reproducesPoint(g, x)) << c.name;
      EXPECT_EQ(g.locate(x).region, Region::Inside) << c.name;
      // ψ_j = (1/4π) ∫ 1/|ξ − x| is positive; inside, the raw values are used.
      const std::vector<double> row = weightsOf(g, x);
      for (std::size_t j = c.cage->vertexCount(); j < row.size(); ++j) ASSERT_GT(row[j], 0.0);
    }
  }
}

TEST(GreenCoordinates, ReproducesExteriorPointsAtRest) {
  std::mt19937 rng(12);
  for (const NamedCage& c : testCages()) {
    const GreenCoordinates g(c.cage);
    for (const Vec3& x : randomPoints(*c.cage, 300, false, 1.0, rng)) {
      ASSERT_TRUE(reproducesPoint(g, x)) << c.name;
      EXPECT_EQ(g.locate(x).region, Region::Outside) << c.name;
    }
  }
}

// Very far points (finite, but ~1e110 world units and beyond) once got NaN rows with no error:
// they are either reproduced (to the distance's scale) or refused naming the point.
TEST(GreenCoordinates, FarPointsAreFiniteOrRefused) {
  const std::vector<Vec3> directions = {Vec3(1, 0, 0), Vec3(0, -1, 0),
                                        glm::normalize(Vec3(1, 2, -3))};
  for (const NamedCage& c : testCages()) {
    const GreenCoordinates g(c.cage);
    for (const double distance : {1e3, 1e9, 1e50, 1e100, 1e120, 1e200, 1e300}) {
      for (const Vec3& direction : directions) {
        const Vec3 x = distance * direction;
        std::vector<double> row(g.columnCount());
        try {
          g.weights(x, row);
        } catch (const InvalidInput& e) {
          EXPECT_GE(distance, 1e100) << c.name;  // nearer points must work
          EXPECT_NE(std::string(e.what()).find("too far from the cage"), std::string::npos)
              << e.what();
          continue;
        }
        ASSERT_TRUE(allFinite(row)) << c.name << " at " << distance;
        EXPECT_LE(glm::length(reproduce(*c.cage, row) - x), 1e-10 * distance)
            << c.name << " at " << distance;
      }
    }
  }
}

TEST(GreenCoordinates, DegenerateConfigurationsAreAccurate) {
  std::mt19937 rng(13);
  // L prism: interior points in the planes of the two faces at the reflex edge (y = 1, x > 1 and
  // x = 1, y > 1), and on the reflex edge's line.
  {
    const GreenCoordinates g(makeCage(test::lPrism(), "L"));
    std::uniform_real_distribution<double> u(0.02, 0.98);
    for (int i = 0; i < 200; ++i) {
      ASSERT_TRUE(reproducesPoint(g, Vec3(u(rng), 1.0, u(rng))));
      ASSERT_TRUE(reproducesPoint(g, Vec3(1.0, u(rng), u(rng))));
      ASSERT_TRUE(reproducesPoint(g, Vec3(1.0, 1.0 - u(rng), 0.5)));
    }
    // Outside, in the plane of a face, and on the line of an edge.
    ASSERT_TRUE(reproducesPoint(g, Vec3(1.5, 1.0, 0.5)));
    ASSERT_TRUE(reproducesPoint(g, Vec3(1.0, 1.5, 1.0 / 3.0)));
    ASSERT_TRUE(reproducesPoint(g, Vec3(3.0, 0.0, 0.0)));
    ASSERT_TRUE(reproducesPoint(g, Vec3(1.0, 1.0, 4.0)));
  }
  // Box: the center projects onto vertices of every face; the grid of points projects onto
  // vertices and edges of the faces.
  {
    const GreenCoordinates g(makeCage(makeBoxSurface(Vec3(0), Vec3(1), {2, 2, 2}), "box"));
    for (double x : {0.25, 0.5, 0.75})
      for (double y : {0.25, 0.5, 0.75})
        for (double z : {0.1, 0.5, 0.9}) ASSERT_TRUE(reproducesPoint(g, Vec3(x, y, z)));
    // Outside, projecting onto vertices and edges, and on an edge's line.
    for (const Vec3& x : {Vec3(0.5, 0.5, 1.5), Vec3(0.25, 0.5, -0.5), Vec3(2.0, 0.0, 0.0),
                          Vec3(1.0, 1.0, 3.0), Vec3(-1.0, -1.0, -1.0)})
      ASSERT_TRUE(reproducesPoint(g, x));
  }
}

TEST(GreenCoordinates, NearSurfacePointsAreAccurate) {
  // Points at distances from 1e-3 down to 1e-15 diagonals from faces, edges and vertices, on
  // both sides and in random directions: the closed forms stay accurate to round-off right up to
  // the surface tolerance (1e-14 diagonals), below which the surface formula takes over.
  std::mt19937 rng(14);
  for (const NamedCage& c : testCages()) {
    const GreenCoordinates g(c.cage);
    const Cage& cage = *c.cage;
    const double diag = cage.diagonal();
    std::uniform_int_distribution<std::size_t> pick(0, cage.triangleCount() - 1);
    for (int i = 0; i < 20; ++i) {
      const std::size_t t = pick(rng);
      const Triangle& tri = cage.triangles()[t];
      const Vec3 onFace = randomFacePoint(cage, t, 0.1, rng);
      std::uniform_real_distribution<double> u(0.05, 0.95);
      const double s = u(rng);
      const Vec3 onEdge = (1.0 - s) * cage.vertices()[tri.x] + s * cage.vertices()[tri.y];
      const Vec3 atVertex = cage.vertices()[tri.z];
      for (double delta = 1e-3; delta >= 1e-15; delta *= 0.1) {
        for (double side : {-1.0, 1.0}) {
          const Vec3 offset = side * delta * diag * cage.normal(t);
          ASSERT_TRUE(reproducesPoint(g, onFace + offset)) << c.name << " face, δ " << delta;
          ASSERT_TRUE(reproducesPoint(g, onEdge + offset)) << c.name << " edge, δ " << delta;
          ASSERT_TRUE(reproducesPoint(g, atVertex + offset)) << c.name << " vertex, δ " << delta;
          const Vec3 random = delta * diag * test::randomUnit(rng);
          ASSERT_TRUE(reproducesPoint(g, onEdge + random)) << c.name << " edge, δ " << delta;
          ASSERT_TRUE(reproducesPoint(g, atVertex + random)) << c.name << " vertex, δ " << delta;
        }
      }
    }
  }
}

TEST(GreenCoordinates, SurfacePointsGetTheInteriorLimit) {
  std::mt19937 rng(15);
  for (const NamedCage& c : testCages()) {
    const GreenCoordinates g(c.cage);
    const Cage& cage = *c.cage;
    const double diag = cage.diagonal();
    // Faces (the interior limit equals the exterior extension through the same face), edges and
    // vertices: on the surface, Σφ = 1 and Σφv + Σψn = x.
    for (std::size_t t = 0; t < cage.triangleCount(); ++t) {
      const Triangle& tri = cage.triangles()[t];
      const Vec3 onFace = randomFacePoint(cage, t, 0.05, rng);
      const Vec3 onEdge = 0.3 * cage.vertices()[tri.x] + 0.7 * cage.vertices()[tri.y];
      for (const Vec3& x : {onFace, onEdge, cage.vertices()[tri.x]}) {
        ASSERT_TRUE(reproducesPoint(g, x)) << c.name << " triangle " << t;
        const GreenCoordinates::Location loc = g.locate(x);
        EXPECT_EQ(loc.region, Region::Surface) << c.name;
        EXPECT_LE(loc.distance, 1e-15 * diag);
      }
      // The principal-value winding number on a face is 1/2.
      EXPECT_NEAR(g.locate(onFace).windingNumber, 0.5, 1e-12) << c.name;
      // Continuity with the interior and exterior values.
      const Vec3 n = cage.normal(t);
      const std::vector<double> on = weightsOf(g, onFace);
      const std::vector<double> in = weightsOf(g, onFace - 1e-10 * diag * n);
      const std::vector<double> out = weightsOf(g, onFace + 1e-10 * diag * n);
      for (std::size_t k = 0; k < on.size(); ++k) {
        const double scale = k < cage.vertexCount() ? 1.0 : diag;
        ASSERT_NEAR(on[k], in[k], 1e-8 * scale) << c.name << " column " << k;
        ASSERT_NEAR(on[k], out[k], 1e-8 * scale) << c.name << " column " << k;
      }
    }
  }
}

TEST(GreenCoordinates, SurfaceValuesAtEdgesAndVerticesAreInteriorLimits) {
  // On convex cages the inward direction at an edge or a vertex is minus the sum of the normals
  // of its triangles; the coordinates there must approach the surface values.
  for (const std::string name : {"tetrahedron", "box", "icosphere"}) {
    std::shared_ptr<const Cage> cage;
    for (const NamedCage& c : testCages())
      if (c.name == name) cage = c.cage;
    const GreenCoordinates g(cage);
    const double diag = cage->diagonal();
    const std::size_t nv = cage->vertexCount();
    std::vector<Vec3> vertexNormal(nv, Vec3(0.0));
    for (std::size_t t = 0; t < cage->triangleCount(); ++t) {
      const Triangle& tri = cage->triangles()[t];
      for (int k = 0; k < 3; ++k) vertexNormal[tri[k]] += cage->normal(t);
    }
    auto check = [&](const Vec3& x0, const Vec3& inward, const std::string& what) {
      const std::vector<double> on = weightsOf(g, x0);
      ASSERT_EQ(g.locate(x0).region, Region::Surface);
      for (double delta : {1e-6, 1e-8}) {
        const std::vector<double> in = weightsOf(g, x0 + delta * diag * inward);
        for (std::size_t k = 0; k < on.size(); ++k) {
          const double scale = k < nv ? 1.0 : diag;
          ASSERT_NEAR(on[k], in[k], 1e3 * delta * scale)
              << name << " " << what << " column " << k << " δ " << delta;
        }
      }
    };
    for (std::size_t i = 0; i < nv; ++i)
      check(cage->vertices()[i], -glm::normalize(vertexNormal[i]), "vertex " + std::to_string(i));
    for (std::size_t t = 0; t < cage->triangleCount(); ++t) {
      const Triangle& tri = cage->triangles()[t];
      // The other triangle of the edge (x, y).
      for (std::size_t o = 0; o < cage->triangleCount(); ++o) {
        const Triangle& other = cage->triangles()[o];
        bool shares = false;
        for (int k = 0; k < 3; ++k)
          shares = shares || (other[k] == tri.y && other[(k + 1) % 3] == tri.x);
        if (!shares) continue;
        const Vec3 inward = -glm::normalize(cage->normal(t) + cage->normal(o));
        const Vec3 x0 = 0.4 * cage->vertices()[tri.x] + 0.6 * cage->vertices()[tri.y];
        check(x0, inward, "edge of triangle " + std::to_string(t));
      }
    }
  }
}

TEST(GreenCoordinates, SurfaceToleranceIsAnOption) {
  const auto cage = makeCage(test::icosphere(1), "sphere");
  const double diag = cage->diagonal();
  const GreenCoordinates loose(cage, GreenOptions{1e-6});
  const GreenCoordinates strict(cage);
  EXPECT_EQ(strict.options().surfaceTolerance, 1e-14);
  std::mt19937 rng(19);
  for (std::size_t t = 0; t < cage->triangleCount(); t += 7) {
    const Vec3 x0 = randomFacePoint(*cage, t, 0.1, rng);
    const Vec3 x = x0 - 1e-7 * diag * cage->normal(t);
    EXPECT_EQ(loose.locate(x).region, Region::Surface);
    EXPECT_EQ(strict.locate(x).region, Region::Inside);
    // A point treated as on the surface is off by O(δ log δ) from the interior value.
    const std::vector<double> a = weightsOf(loose, x), b = weightsOf(strict, x);
    for (std::size_t k = 0; k < a.size(); ++k)
      ASSERT_NEAR(a[k], b[k], 1e-5 * (k < cage->vertexCount() ? 1.0 : diag)) << k;
    EXPECT_TRUE(reproducesPoint(loose, x, 1e-6));
  }
}

TEST(GreenCoordinates, ExteriorFaceChangesAcrossTheBisectorOfAConvexEdge) {
  // Outside a convex edge, the points on either side of the plane bisecting the two faces are
  // extended through different faces (documented: the exterior map may jump there).
  const auto cage = makeCage(makeBoxSurface(Vec3(0), Vec3(1), {1, 1, 1}), "box");
  const GreenCoordinates g(cage);
  const GreenCoordinates::Location nearTop = g.locate(Vec3(1.2, 0.5, 1.3));
  const GreenCoordinates::Location nearSide = g.locate(Vec3(1.3, 0.5, 1.2));
  EXPECT_NEAR(cage->normal(nearTop.triangle).z, 1.0, 1e-15);
  EXPECT_NEAR(cage->normal(nearSide.triangle).x, 1.0, 1e-15);
  EXPECT_TRUE(reproducesPoint(g, Vec3(1.2, 0.5, 1.3)));
  EXPECT_TRUE(reproducesPoint(g, Vec3(1.3, 0.5, 1.2)));
}

TEST(GreenCoordinates, ReproducesSimilaritiesInsideAndOutside) {
  std::mt19937 rng(16);
  const Mat3 r = rotation(glm::normalize(Vec3(0.3, -1, 0.8)), 1.1);
  const double k = 1.7;
  const Vec3 shift(0.4, -2.0, 5.0);
  auto similarity = [&](const Vec3& x) { return k * (r * x) + shift; };
  for (const NamedCage& c : testCages()) {
    const auto g = std::make_shared<const GreenCoordinates>(c.cage);
    std::vector<Vec3> posed;
    for (const Vec3& v : c.cage->vertices()) posed.push_back(similarity(v));
    const CoordinateWarp warp(g, posed);
    const double scale = k * c.cage->diagonal();
    for (bool inside : {true, false}) {
      const std::vector<Vec3> points = randomPoints(*c.cage, 200, inside, 0.5, rng);
      const Binding binding(g, points);
      const std::vector<Vec3> bound = binding.deform(posed);
      for (std::size_t i = 0; i < points.size(); ++i) {
        const Vec3 expected = similarity(points[i]);
        ASSERT_LE(glm::length(warp.apply(points[i]) - expected) / scale, 1e-10)
            << c.name << (inside ? " inside " : " outside ") << test::toString(points[i]);
        ASSERT_LE(glm::length(bound[i] - expected) / scale, 1e-10)
            << c.name << (inside ? " inside " : " outside ") << test::toString(points[i]);
      }
    }
  }
}

TEST(GreenCoordinates, ExteriorExtensionIsContinuousAcrossFaces) {
  std::mt19937 rng(17);
  for (const NamedCage& c : testCages()) {
    const auto g = std::make_shared<const GreenCoordinates>(c.cage);
    const Cage& cage = *c.cage;
    const double diag = cage.diagonal();
    const CoordinateWarp warp(g, perturbed(cage, 0.05, rng));
    std::uniform_int_distribution<std::size_t> pick(0, cage.triangleCount() - 1);
    for (int i = 0; i < 100; ++i) {
      const std::size_t t = pick(rng);
      const Vec3 x0 = randomFacePoint(cage, t, 0.1, rng);
      const Vec3 n = cage.normal(t);
      const Vec3 xIn = x0 - 1e-7 * diag * n, xOut = x0 + 1e-7 * diag * n;
      ASSERT_EQ(g->locate(xIn).region, Region::Inside) << c.name;
      ASSERT_EQ(g->locate(xOut).region, Region::Outside) << c.name;
      ASSERT_EQ(g->locate(xOut).triangle, t) << c.name;
      const Vec3 in = warp.apply(xIn), out = warp.apply(xOut), on = warp.apply(x0);
      ASSERT_LE(glm::length(in - out) / diag, 1e-6) << c.name << " triangle " << t;
      ASSERT_LE(glm::length(on - in) / diag, 1e-6) << c.name << " triangle " << t;
      ASSERT_LE(glm::length(on - out) / diag, 1e-6) << c.name << " triangle " << t;
      // The extension is the analytic continuation: the one-sided normal derivatives agree too
      // (their difference is the second difference, O(h)).
      const double h = 1e-4 * diag;
      const Vec3 dIn = (on - warp.apply(x0 - h * n)) / h;
      const Vec3 dOut = (warp.apply(x0 + h * n) - on) / h;
      ASSERT_LE(glm::length(dIn - dOut), 1e-2) << c.name << " triangle " << t;
    }
  }
}

TEST(GreenCoordinates, ExteriorFaceIsTheNearestTriangle) {
  const auto cage = makeCage(makeBoxSurface(Vec3(0), Vec3(1), {1, 1, 1}), "box");
  const GreenCoordinates g(cage);
  // Above the top face: the triangle that contains (0.3, 0.6, 1).
  const GreenCoordinates::Location above = g.locate(Vec3(0.3, 0.6, 1.5));
  EXPECT_EQ(above.region, Region::Outside);
  EXPECT_NEAR(above.distance, 0.5, 1e-15);
  EXPECT_NEAR(above.windingNumber, 0.0, 1e-14);
  const Triangle& tri = cage->triangles()[above.triangle];
  EXPECT_NEAR(cage->normal(above.triangle).z, 1.0, 1e-15);
  const Vec3 a = cage->vertices()[tri.x], b = cage->vertices()[tri.y], c = cage->vertices()[tri.z];
  const Vec3 p(0.3, 0.6, 1.0);
  const double area = glm::length(glm::cross(b - a, c - a));
  EXPECT_NEAR(glm::length(glm::cross(b - p, c - p)) + glm::length(glm::cross(c - p, a - p)) +
                  glm::length(glm::cross(a - p, b - p)),
              area, 1e-14)
      << "the projection is inside the chosen triangle";
  // Beyond a convex edge and a corner: one of the touching triangles, and x reproduced.
  for (const Vec3& x : {Vec3(1.5, 0.5, 1.5), Vec3(1.2, 0.5, 1.9), Vec3(2, 2, 2)}) {
    const GreenCoordinates::Location loc = g.locate(x);
    EXPECT_EQ(loc.region, Region::Outside);
    const Triangle& t = cage->triangles()[loc.triangle];
    bool touches = false;
    for (int k = 0; k < 3; ++k) touches = touches || cage->vertices()[t[k]].x == 1.0;
    EXPECT_TRUE(touches);
    EXPECT_TRUE(reproducesPoint(g, x));
  }
  // Interior.
  const GreenCoordinates::Location inside = g.locate(Vec3(0.5, 0.4, 0.3));
  EXPECT_EQ(inside.region, Region::Inside);
  EXPECT_NEAR(inside.distance, 0.3, 1e-15);
  EXPECT_NEAR(inside.windingNumber, 1.0, 1e-14);
}

TEST(GreenCoordinates, PropertyKitAgrees) {
  std::mt19937 rng(20);
  for (const NamedCage& c : testCages()) {
    const GreenCoordinates g(c.cage);
    const std::vector<Vec3> samples = randomPoints(*c.cage, 100, true, 0.0, rng);
    const PropertyReport report = measureProperties(g, *c.cage, samples);
    EXPECT_LE(report.partitionOfUnity, 1e-12) << c.name;
    EXPECT_LE(report.linearReproduction, 1e-12) << c.name;
    EXPECT_LE(report.similarityReproduction, 1e-10) << c.name;
    // Green coordinates are not interpolating: no Lagrange property at the cage vertices.
    EXPECT_GT(report.lagrange, 1e-3) << c.name;
  }
}

TEST(GreenCoordinates, BatchIsDeterministicAndMatchesSinglePoints) {
  std::mt19937 rng(18);
  const auto cage = makeCage(test::icosphere(2), "sphere");
  const GreenCoordinates g(cage);
  std::vector<Vec3> points = randomPoints(*cage, 300, true, 0.0, rng);
  for (const Vec3& x : randomPoints(*cage, 200, false, 0.5, rng)) points.push_back(x);
  points.push_back(cage->vertices()[3]);
  const std::size_t m = g.columnCount();
  std::vector<double> one(points.size() * m), two(points.size() * m);
  tbb::task_arena(1).execute([&] { g.weightsBatch(points, one); });
  tbb::task_arena(2).execute([&] { g.weightsBatch(points, two); });
  EXPECT_EQ(std::memcmp(one.data(), two.data(), one.size() * sizeof(double)), 0);
  for (std::size_t i = 0; i < points.size(); ++i) {
    const std::vector<double> row = weightsOf(g, points[i]);
    ASSERT_EQ(std::memcmp(row.data(), one.data() + i * m, m * sizeof(double)), 0) << i;
  }
}

TEST(GreenCoordinates, InvalidInputThrows) {
  const auto cage = makeCage(test::tetrahedron(), "tet");
  EXPECT_THROW(GreenCoordinates(nullptr), InvalidInput);
  EXPECT_THROW(GreenCoordinates(cage, GreenOptions{-1.0}), InvalidInput);
  EXPECT_THROW(GreenCoordinates(cage, GreenOptions{std::nan("")}), InvalidInput);
  const auto g = std::make_shared<const GreenCoordinates>(cage);
  std::vector<double> row(g->columnCount());
  const double nan = std::nan("");
  EXPECT_THROW(g->weights(Vec3(nan, 0, 0), row), InvalidInput);
  EXPECT_THROW(g->weights(Vec3(0, std::numeric_limits<double>::infinity(), 0), row), InvalidInput);
  std::vector<double> shortRow(g->columnCount() - 1);
  EXPECT_THROW(g->weights(Vec3(0.1), shortRow), InvalidInput);
  EXPECT_THROW(g->locate(Vec3(0, 0, nan)), InvalidInput);
  const std::vector<Vec3> points = {Vec3(0.1), Vec3(nan)};
  std::vector<double> rows(points.size() * g->columnCount());
  EXPECT_THROW(g->weightsBatch(points, rows), InvalidInput);
  EXPECT_THROW(g->weightsBatch(points, row), InvalidInput);

  std::vector<Vec3> controls(g->columnCount());
  const std::vector<Vec3> tooFew(3, Vec3(0.0));
  EXPECT_THROW(g->columnControls(tooFew, controls), InvalidInput);
  std::vector<Vec3> posed(cage->vertices().begin(), cage->vertices().end());
  std::vector<Vec3> shortControls(g->columnCount() - 1);
  EXPECT_THROW(g->columnControls(posed, shortControls), InvalidInput);
  posed[2].y = nan;
  EXPECT_THROW(g->columnControls(posed, controls), InvalidInput);
  EXPECT_THROW(CoordinateWarp(g, posed), InvalidInput);
  EXPECT_THROW(CoordinateWarp(g, tooFew), InvalidInput);
  const Binding binding(g, std::vector<Vec3>{Vec3(0.1)});
  EXPECT_THROW(binding.deform(tooFew), InvalidInput);
}

// The kernel's own logarithm and arctangent (no libm in the SIMD passes) against the C++ library
// and long double, over their whole input ranges, in the build the kernel runs on this CPU and
// in the portable one.

// |value − reference| in units of the ulp of the reference rounded to double (the spacing of
// doubles at it: 2^-1074 for subnormals).
double ulpError(double value, long double reference) {
  const double r = std::abs(static_cast<double>(reference));
  const double ulp = std::nextafter(r, std::numeric_limits<double>::infinity()) - r;
  return static_cast<double>(std::abs(static_cast<long double>(value) - reference) / ulp);
}

// v in hexadecimal floating point, exactly.
std::string hex(double v) {
  char text[40];
  std::snprintf(text, sizeof text, "%a", v);
  return text;
}

// A positive double with a uniformly random exponent in [minExponent, maxExponent] (subnormals
// below −1022) and a uniform mantissa.
double randomMagnitude(std::mt19937_64& rng, int minExponent, int maxExponent) {
  std::uniform_real_distribution<double> mantissa(1.0, 2.0);
  std::uniform_int_distribution<int> exponent(minExponent, maxExponent);
  return std::ldexp(mantissa(rng), exponent(rng));
}

TEST(GreenKernelFunctions, LogIsWithinTwoUlps) {
  constexpr double kMax = std::numeric_limits<double>::max();
  constexpr double kMin = std::numeric_limits<double>::min();
  constexpr double kTiny = std::numeric_limits<double>::denorm_min();
  // ln x against std::log: the whole positive range, 1 and its neighbourhood, the reduction's
  // break points √½ and √2, powers of two.
  std::vector<double> x = {1.0,
                           kMax,
                           kMin,
                           kTiny,
                           2 * kTiny,
                           0.5,
                           2.0,
                           std::nextafter(1.0, 0.0),
                           std::nextafter(1.0, 2.0)};
  for (double c : {std::numbers::sqrt2, 0.5 * std::numbers::sqrt2}) {
    double lo = c, hi = c;
    for (int i = 0; i < 20; ++i) {
      x.push_back(lo = std::nextafter(lo, 0.0));
      x.push_back(hi = std::nextafter(hi, 2.0));
    }
  }
  for (int e = -1074; e <= 1023; e += 7) x.push_back(std::ldexp(1.0, e));
  std::mt19937_64 rng(21);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  for (int i = 0; i < 200000; ++i) x.push_back(randomMagnitude(rng, -1074, 1023));
  for (int i = 0; i < 20000; ++i) {
    const double near1 = 1.0 + unit(rng) * std::ldexp(1.0, -(i % 53));
    if (near1 > 0.0) x.push_back(near1);
  }
  // ln(num / den) against long double: num and den anywhere in the range, and close to each
  // other (where the quotient's logarithm is small and a rounded quotient would lose it).
  std::vector<double> num, den;
  for (int i = 0; i < 200000; ++i) {
    den.push_back(randomMagnitude(rng, -1074, 1023));
    num.push_back(i % 2 == 0 ? randomMagnitude(rng, -1074, 1023)
                             : den.back() * (1.0 + unit(rng) * std::ldexp(1.0, -(i % 60))));
    if (!(num.back() > 0.0 && num.back() <= kMax)) num.back() = den.back();
  }
  for (bool baseline : {false, true}) {
    std::vector<double> out(x.size());
    detail::greenLogRatio(x, std::vector<double>(x.size(), 1.0), out, baseline);
    double worst = 0.0;
    for (std::size_t i = 0; i < x.size(); ++i) {
      const double reference = std::log(x[i]);
      if (reference == 0.0) {
        ASSERT_EQ(out[i], 0.0) << hex(x[i]);
        continue;
      }
      const double err = ulpError(out[i], reference);
      worst = std::max(worst, err);
      ASSERT_LE(err, 2.0) << "ln " << hex(x[i]) << (baseline ? " (baseline)" : "");
    }
    std::vector<double> ratio(num.size());
    detail::greenLogRatio(num, den, ratio, baseline);
    double worstRatio = 0.0;
    for (std::size_t i = 0; i < num.size(); ++i) {
      const long double n = num[i], d = den[i];
      const long double q = n / d;
      // Near 1, log1p of the exact difference (num − den is exact there).
      const long double reference = std::abs(q - 1) < 0.5L ? std::log1p((n - d) / d) : std::log(q);
      if (reference == 0.0L) continue;
      const double err = ulpError(ratio[i], reference);
      worstRatio = std::max(worstRatio, err);
      ASSERT_LE(err, 2.0) << "ln(" << hex(num[i]) << " / " << hex(den[i]) << ")"
                          << (baseline ? " (baseline)" : "");
    }
    RecordProperty(baseline ? "worst_ulp_log_baseline" : "worst_ulp_log",
                   std::to_string(worst) + ", ratio " + std::to_string(worstRatio));
  }
}

TEST(GreenKernelFunctions, Atan2IsWithinTwoUlps) {
  // Every quadrant and sign of zero, the axes and diagonals, the neighbourhoods of the sector
  // bounds, arguments of similar size and anywhere in the range (subnormal to the largest).
  std::vector<double> y, x;
  auto add = [&](double a, double b) {
    for (double sy : {1.0, -1.0})
      for (double sx : {1.0, -1.0}) {
        y.push_back(sy * a);
        x.push_back(sx * b);
        y.push_back(sy * b);
        x.push_back(sx * a);
      }
  };
  const double kMax = std::numeric_limits<double>::max();
  for (double b : {1.0, kMax, std::numeric_limits<double>::denorm_min()}) {
    add(0.0, b);
    add(b, b);
  }
  for (double t : {0.0625, 0.0626, 0.125, 0.18679502309911022, 0.25, 0.36992407621548123, 0.5,
                   0.7207592200561265, 1.0}) {
    double lo = t, hi = t;
    for (int i = 0; i < 20; ++i) {
      add(lo = std::nextafter(lo, 0.0), 1.0);
      add(hi = std::nextafter(hi, 2.0), 1.0);
    }
  }
  std::mt19937_64 rng(22);
  for (int i = 0; i < 50000; ++i) {
    const double b = randomMagnitude(rng, -1074, 1023);
    add(randomMagnitude(rng, -1074, 1023), b);
    add(b * std::uniform_real_distribution<double>(0.0, 1.0)(rng), b);
  }
  for (bool baseline : {false, true}) {
    std::vector<double> out(y.size());
    detail::greenAtan2(y, x, out, baseline);
    double worst = 0.0;
    for (std::size_t i = 0; i < y.size(); ++i) {
      const double reference = std::atan2(y[i], x[i]);
      const double err = reference == 0.0
                             ? (out[i] == reference ? 0.0 : std::numeric_limits<double>::infinity())
                             : ulpError(out[i], reference);
      worst = std::max(worst, err);
      ASSERT_LE(err, 2.0) << "atan2(" << hex(y[i]) << ", " << hex(x[i]) << ") = " << hex(out[i])
                          << ", not " << hex(reference) << (baseline ? " (baseline)" : "");
      ASSERT_EQ(std::signbit(out[i]), std::signbit(reference)) << hex(y[i]) << ", " << hex(x[i]);
    }
    RecordProperty(baseline ? "worst_ulp_atan2_baseline" : "worst_ulp_atan2",
                   std::to_string(worst));
  }
  // Both zero: 0 (the solid angle of a triangle seen from one of its points).
  std::vector<double> zero = {0.0, -0.0, 0.0, -0.0}, signedZero = {0.0, 0.0, -0.0, -0.0}, out(4);
  detail::greenAtan2(zero, signedZero, out);
  for (double a : out) EXPECT_EQ(a, 0.0);
}

// The Armadillo of Ju, Schaefer and Warren (2005) with its cage and posed cages, when the shared
// data is present.
class GreenArmadillo : public ::testing::Test {
 protected:
  static std::filesystem::path dir() {
    return std::filesystem::path(SPACEWARP_SHARED_DATA_DIR) / "ju2005-armadillo";
  }
  void SetUp() override {
    if (!std::filesystem::exists(dir() / "bounding_mesh.obj"))
      GTEST_SKIP() << "no shared data at " << dir();
  }
};

TEST_F(GreenArmadillo, PosedCagesGiveFinitePositions) {
  const auto cage = std::make_shared<const Cage>(Cage::fromFile(dir() / "bounding_mesh.obj"));
  const PolygonSoup model = readSoup(dir() / "armadilloman.obj");
  const auto g = std::make_shared<const GreenCoordinates>(cage);
  const Binding binding(g, model.positions);
  ASSERT_FALSE(binding.isSparse());

  // At rest the raw coordinates reproduce every model vertex.
  const std::size_t m = g->columnCount();
  double worst = 0.0, worstUnity = 0.0;
  for (std::size_t i = 0; i < model.positions.size(); ++i) {
    std::vector<double> row(binding.dense().data() + i * m, binding.dense().data() + (i + 1) * m);
    ASSERT_TRUE(allFinite(row)) << i;
    worst = std::max(worst, glm::length(reproduce(*cage, row) - model.positions[i]));
    worstUnity = std::max(worstUnity, std::abs(phiSum(*cage, row) - 1.0));
  }
  EXPECT_LE(worst / cage->diagonal(), 1e-12);
  EXPECT_LE(worstUnity, 1e-12);

  for (const char* pose :
       {"deformed_bounding_mesh2.obj", "deformed_bounding_mesh3.obj", "deformed_bounding_mesh4.obj",
        "deformed_bounding_mesh5.obj", "deformed_bounding_mesh6.obj", "deformed_bounding_mesh8.obj",
        "deformed_bounding_mesh9.obj", "deformed_fixed_1.obj", "deformed_fixed_7.obj",
        "deformed_fixed_10.obj"}) {
    const std::vector<Vec3> posed = cage->posedVerticesFromFile(dir() / pose);
    const std::vector<Vec3> deformed = binding.deform(posed);
    ASSERT_EQ(deformed.size(), model.positions.size());
    const BoundingBox posedBox = boundingBox(posed);
    for (std::size_t i = 0; i < deformed.size(); ++i) {
      ASSERT_TRUE(isFinite(deformed[i])) << pose << " vertex " << i;
      // Sanity: the model stays near its posed cage.
      ASSERT_LE(glm::length(deformed[i] - 0.5 * (posedBox.min + posedBox.max)),
                2.0 * posedBox.diagonal())
          << pose << " vertex " << i;
    }
  }
}

}  // namespace
}  // namespace spacewarp
