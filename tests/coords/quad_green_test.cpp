#include <spacewarp/coords/quad_green.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <tbb/task_arena.h>

#include <spacewarp/coords/green.h>
#include <spacewarp/core/archive.h>
#include <spacewarp/core/binding.h>
#include <spacewarp/core/detail/simd.h>
#include <spacewarp/core/errors.h>
#include <spacewarp/core/io/mesh_io.h>
#include <spacewarp/core/primitives.h>
#include "coords_test_shapes.h"
#include "test_util.h"

namespace spacewarp {
namespace {

std::shared_ptr<const Cage> makeCage(const PolygonSoup& soup, const std::string& name) {
  return std::make_shared<const Cage>(soup, name);
}

// The L-prism of coords_test_shapes.h with each hexagonal cap cut into two convex quads; with
// `triangles`, the bottom cap's second quad is cut into two triangles (a tri-quad cage).
PolygonSoup lPrismQuads(bool triangles) {
  const PolygonSoup hexagons = test::lPrism();
  PolygonSoup s;
  s.positions = hexagons.positions;
  s.addPolygon({3, 2, 1, 0});
  if (triangles) {
    s.addPolygon({5, 4, 3});
    s.addPolygon({5, 3, 0});
  } else {
    s.addPolygon({5, 4, 3, 0});
  }
  s.addPolygon({6, 7, 8, 9});
  s.addPolygon({6, 9, 10, 11});
  for (std::uint32_t i = 0; i < 6; ++i) {
    const std::uint32_t j = (i + 1) % 6;
    s.addPolygon({i, j, j + 6, i + 6});
  }
  return s;
}

// The box [−1, 1]³ in 2 × 2 × 2 quads per side with every vertex moved by up to `jitter`
// (deterministic): non-planar quads.
PolygonSoup jitteredBox(double jitter) {
  PolygonSoup s = makeBoxSurface(Vec3(-1), Vec3(1), {2, 2, 2});
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-jitter, jitter);
  for (Vec3& p : s.positions) p += Vec3(u(rng), u(rng), u(rng));
  return s;
}

// jitteredBox with every third quad cut into two triangles: non-planar quads beside triangles.
PolygonSoup jitteredTriQuadBox(double jitter) {
  const PolygonSoup quads = jitteredBox(jitter);
  PolygonSoup s;
  s.positions = quads.positions;
  for (std::size_t f = 0; f < quads.polygonCount(); ++f) {
    const std::uint32_t* q = quads.faceIndices.data() + quads.faceOffsets[f];
    if (f % 3 == 0) {
      s.addPolygon({q[0], q[1], q[2]});
      s.addPolygon({q[0], q[2], q[3]});
    } else {
      s.addPolygon({q[0], q[1], q[2], q[3]});
    }
  }
  return s;
}

struct NamedCage {
  std::string name;
  std::shared_ptr<const Cage> cage;
};

std::vector<NamedCage> quadCages() {
  return {
      {"quadBox", makeCage(makeBoxSurface(Vec3(-1), Vec3(1), {2, 2, 2}), "quadBox")},
      {"lPrismQuads", makeCage(lPrismQuads(false), "lPrismQuads")},
      {"lPrismTriQuad", makeCage(lPrismQuads(true), "lPrismTriQuad")},
      {"nonPlanarBox", makeCage(jitteredBox(0.2), "nonPlanarBox")},
      {"nonPlanarTriQuadBox", makeCage(jitteredTriQuadBox(0.2), "nonPlanarTriQuadBox")},
  };
}

// Σ_c w_c C_c for the column controls C of `posed`.
Vec3 mapPoint(const Coordinates& c, std::span<const double> row, std::span<const Vec3> posed) {
  std::vector<Vec3> controls(c.columnCount());
  c.columnControls(posed, controls);
  Vec3 sum(0.0);
  for (std::size_t i = 0; i < controls.size(); ++i) sum += row[i] * controls[i];
  return sum;
}

double phiSum(const Coordinates& c, std::span<const double> row) {
  double sum = 0.0;
  for (std::size_t i = 0; i < c.controlPointCount(); ++i) sum += row[i];
  return sum;
}

std::vector<double> rowOf(const Coordinates& c, const Vec3& x) {
  std::vector<double> row(c.columnCount());
  c.weights(x, row);
  return row;
}

// A rotation, uniform scale and translation.
struct Similarity {
  Mat3 rotation;
  double scale;
  Vec3 shift;
  Vec3 operator()(const Vec3& x) const { return scale * (rotation * x) + shift; }
};

Similarity someSimilarity() {
  const Vec3 axis = glm::normalize(Vec3(0.3, -0.5, 0.8));
  const double a = 0.7, c = std::cos(a), s = std::sin(a);
  const Mat3 k(0, axis.z, -axis.y, -axis.z, 0, axis.x, axis.y, -axis.x, 0);
  const Mat3 r = Mat3(1.0) + s * k + (1 - c) * (k * k);
  return {r, 1.7, Vec3(0.4, -2.0, 3.5)};
}

// Points inside (winding number over ½) and outside the cage, within its box grown by half.
std::vector<Vec3> samplePoints(const Cage& cage, bool inside, std::size_t n, unsigned seed) {
  Vec3 lo(1e300), hi(-1e300);
  for (const Vec3& p : cage.vertices()) {
    lo = glm::min(lo, p);
    hi = glm::max(hi, p);
  }
  const Vec3 grow = 0.5 * (hi - lo);
  std::mt19937 rng(seed);
  std::vector<Vec3> points;
  while (points.size() < n) {
    Vec3 t = test::randomPoint(rng, 0.0, 1.0);
    const Vec3 x = lo - grow + t * (hi - lo + 2.0 * grow);
    if (cage.contains(x) == inside) points.push_back(x);
  }
  return points;
}

TEST(QuadGreen, EqualsGreenOnTriangleCagesBitForBit) {
  for (const auto& soup : {test::tetrahedron(), test::star(), test::icosphere(2)}) {
    const auto cage = makeCage(soup, "triangles");
    const QuadGreenCoordinates qgc(cage);
    const GreenCoordinates green(cage);
    ASSERT_EQ(qgc.columnCount(), green.columnCount());
    std::mt19937 rng(3);
    const std::vector<Vec3> points = test::randomPoints(rng, 203, -2.5, 2.5);
    std::vector<double> a(points.size() * qgc.columnCount()), b(a.size());
    qgc.weightsBatch(points, a);
    green.weightsBatch(points, b);
    EXPECT_EQ(a, b);
    EXPECT_EQ(rowOf(qgc, points[5]), rowOf(green, points[5]));
    std::vector<Vec3> posed(cage->vertices().begin(), cage->vertices().end());
    for (Vec3& p : posed) p = p * 1.3 + Vec3(0.1 * p.y, 0, 0);
    std::vector<Vec3> ca(qgc.columnCount()), cb(qgc.columnCount());
    qgc.columnControls(posed, ca);
    green.columnControls(posed, cb);
    EXPECT_EQ(ca, cb);
  }
}

TEST(QuadGreen, ColumnsAndNames) {
  const auto cage = makeCage(lPrismQuads(true), "lPrismTriQuad");
  const QuadGreenCoordinates qgc(cage);
  // 12 vertices; faces: quad, 2 triangles, 2 quads, 6 quads.
  EXPECT_EQ(qgc.columnCount(), 12u + 4 + 1 + 1 + 4 * 8);
  EXPECT_EQ(qgc.columnName(0), "v0");
  EXPECT_EQ(qgc.columnName(12), "f0.0");
  EXPECT_EQ(qgc.columnName(15), "f0.3");
  EXPECT_EQ(qgc.columnName(16), "f1");
  EXPECT_EQ(qgc.columnName(17), "f2");
  EXPECT_EQ(qgc.columnName(18), "f3.0");
}

TEST(QuadGreen, RejectsLargerPolygonsNamingTheFace) {
  const auto cage = makeCage(test::lPrism(), "hexagons");
  const std::string message =
      test::messageOf<InvalidInput>([&] { QuadGreenCoordinates qgc(cage); });
  EXPECT_NE(message.find("face 0 has 6 vertices"), std::string::npos) << message;
  EXPECT_THROW(QuadGreenCoordinates(nullptr), InvalidInput);
  QuadGreenOptions bad;
  bad.surfaceTolerance = 0.1;
  EXPECT_THROW(QuadGreenCoordinates(makeCage(lPrismQuads(false), "l"), bad), InvalidInput);
}

// A quad whose bilinear patch folds over (a planar dart) is refused, naming the cage, the face and
// its vertices (coords/detail/quad_fold.h); a convex quad twisted out of its plane is not.
TEST(QuadGreen, RefusesAQuadWhosePatchFoldsNamingIt) {
  const auto dart = makeCage(test::dartPrism(), "dart");
  const std::string message =
      test::messageOf<InvalidInput>([&] { QuadGreenCoordinates qgc(dart); });
  EXPECT_NE(message.find("dart: QuadGreenCoordinates: face 0 (vertices 3, 2, 1, 0)"),
            std::string::npos)
      << message;
  EXPECT_NE(message.find("split it into triangles"), std::string::npos) << message;
  EXPECT_NO_THROW(QuadGreenCoordinates{makeCage(jitteredBox(0.2), "nonPlanarBox")});
}

// At rest Σ φ_i v_i + Σ ψ C = x and Σ φ = 1, inside and outside (through the extension).
TEST(QuadGreen, ReproducesLinearFunctionsAtRest) {
  for (const NamedCage& nc : quadCages()) {
    const QuadGreenCoordinates qgc(nc.cage);
    const double diag = nc.cage->diagonal();
    for (bool inside : {true, false}) {
      double worst = 0.0, worstSum = 0.0;
      for (const Vec3& x : samplePoints(*nc.cage, inside, 150, 11)) {
        const std::vector<double> row = rowOf(qgc, x);
        worst = std::max(worst, glm::length(mapPoint(qgc, row, nc.cage->vertices()) - x) / diag);
        worstSum = std::max(worstSum, std::abs(phiSum(qgc, row) - 1.0));
      }
      EXPECT_LE(worst, 1e-12) << nc.name << (inside ? " inside" : " outside");
      EXPECT_LE(worstSum, 1e-12) << nc.name << (inside ? " inside" : " outside");
    }
  }
}

// A closed form for the quadrature: on a parallelogram du dv = dσ / A, so A Σ_k ψ_{f,k} is the
// single layer ∫ dσ / 4π|ξ − x| of face f, which is triangle Green's ψ of its two triangles.
// Checked inside the box cage, down to 1e-9 of the diagonal from its faces.
TEST(QuadGreen, SingleLayerOfParallelogramsMatchesTriangleGreen) {
  const auto cage = makeCage(makeBoxSurface(Vec3(-1), Vec3(1), {2, 2, 2}), "box");
  const QuadGreenCoordinates qgc(cage);
  const GreenCoordinates green(cage);  // on the cage's triangulation
  const std::size_t nv = cage->vertexCount();
  std::mt19937 rng(12);
  std::vector<Vec3> points = test::randomPoints(rng, 100, -0.999, 0.999);
  for (double gap : {1e-3, 1e-6, 1e-9}) points.push_back(Vec3(0.3, -0.2, 1.0 - gap));
  double worst = 0.0;
  for (const Vec3& x : points) {
    const std::vector<double> q = rowOf(qgc, x), g = rowOf(green, x);
    std::vector<double> single(cage->faceCount(), 0.0);
    for (std::size_t t = 0; t < cage->triangleCount(); ++t)
      single[cage->triangleSource()[t]] += g[nv + t];
    for (std::size_t f = 0; f < cage->faceCount(); ++f) {
      const Vec3 a = cage->vertices()[cage->face(f)[0]], b = cage->vertices()[cage->face(f)[1]],
                 c = cage->vertices()[cage->face(f)[3]];
      const double area = glm::length(glm::cross(b - a, c - a));
      const double sum =
          area * (q[nv + 4 * f] + q[nv + 4 * f + 1] + q[nv + 4 * f + 2] + q[nv + 4 * f + 3]);
      worst = std::max(worst, std::abs(sum - single[f]) / single[f]);
    }
  }
  EXPECT_LE(worst, 1e-14);
  std::printf("largest relative difference of the single layers: %.2e\n", worst);
}

// A similarity S of the cage moves every point x to S(x), inside and outside.
TEST(QuadGreen, ReproducesSimilarities) {
  const Similarity s = someSimilarity();
  for (const NamedCage& nc : quadCages()) {
    const QuadGreenCoordinates qgc(nc.cage);
    std::vector<Vec3> posed;
    for (const Vec3& v : nc.cage->vertices()) posed.push_back(s(v));
    const double diag = nc.cage->diagonal() * s.scale;
    for (bool inside : {true, false}) {
      double worst = 0.0;
      for (const Vec3& x : samplePoints(*nc.cage, inside, 100, 5))
        worst = std::max(worst, glm::length(mapPoint(qgc, rowOf(qgc, x), posed) - s(x)) / diag);
      EXPECT_LE(worst, 1e-10) << nc.name << (inside ? " inside" : " outside");
    }
  }
}

// Starting a quad at another corner permutes its four normal columns and changes nothing else.
TEST(QuadGreen, IndependentOfEachQuadsStartingVertex) {
  const PolygonSoup soup = jitteredBox(0.2);
  PolygonSoup rotated = soup;
  std::vector<int> shift(soup.polygonCount());
  for (std::size_t f = 0; f < soup.polygonCount(); ++f) {
    shift[f] = static_cast<int>(f % 4);
    for (int k = 0; k < 4; ++k)
      rotated.faceIndices[soup.faceOffsets[f] + k] =
          soup.faceIndices[soup.faceOffsets[f] + (k + shift[f]) % 4];
  }
  const auto a = makeCage(soup, "a"), b = makeCage(rotated, "b");
  const QuadGreenCoordinates qa(a), qb(b);
  const std::size_t nv = a->vertexCount();
  double worst = 0.0;
  for (bool inside : {true, false}) {
    for (const Vec3& x : samplePoints(*a, inside, 60, 9)) {
      const std::vector<double> ra = rowOf(qa, x), rb = rowOf(qb, x);
      for (std::size_t i = 0; i < nv; ++i) worst = std::max(worst, std::abs(ra[i] - rb[i]));
      for (std::size_t f = 0; f < soup.polygonCount(); ++f)
        for (int k = 0; k < 4; ++k)
          worst =
              std::max(worst, std::abs(ra[nv + 4 * f + (k + shift[f]) % 4] - rb[nv + 4 * f + k]));
    }
  }
  EXPECT_LE(worst, 1e-13);
}

// Approaching a quad from inside and outside gives the same coordinates as the point on it.
TEST(QuadGreen, ContinuousAcrossTheSurface) {
  for (const NamedCage& nc : quadCages()) {
    const QuadGreenCoordinates qgc(nc.cage);
    const Cage& cage = *nc.cage;
    for (std::size_t f = 0; f < cage.faceCount(); f += 3) {
      const auto face = cage.face(f);
      if (face.size() != 4) continue;
      Vec3 q[4];
      for (int k = 0; k < 4; ++k) q[k] = cage.vertices()[face[k]];
      const double u = 0.37, v = 0.61;
      const Vec3 x0 =
          (1 - u) * (1 - v) * q[0] + u * (1 - v) * q[1] + u * v * q[2] + (1 - u) * v * q[3];
      const Vec3 n = glm::normalize(glm::cross((1 - v) * (q[1] - q[0]) + v * (q[2] - q[3]),
                                               (1 - u) * (q[3] - q[0]) + u * (q[2] - q[1])));
      const std::vector<double> on = rowOf(qgc, x0);
      for (double delta : {1e-6, 1e-9, 1e-12}) {
        const std::vector<double> in = rowOf(qgc, x0 - delta * cage.diagonal() * n);
        const std::vector<double> out = rowOf(qgc, x0 + delta * cage.diagonal() * n);
        double worstIn = 0.0, worstOut = 0.0;
        for (std::size_t c = 0; c < on.size(); ++c) {
          worstIn = std::max(worstIn, std::abs(in[c] - on[c]));
          worstOut = std::max(worstOut, std::abs(out[c] - on[c]));
        }
        // O(δ log δ) in the coordinates.
        EXPECT_LE(worstIn, 50 * delta) << nc.name << " face " << f << " δ " << delta;
        EXPECT_LE(worstOut, 50 * delta) << nc.name << " face " << f << " δ " << delta;
      }
      EXPECT_NEAR(phiSum(qgc, on), 1.0, 1e-12) << nc.name << " face " << f;
      EXPECT_LE(glm::length(mapPoint(qgc, on, cage.vertices()) - x0), 1e-12 * cage.diagonal())
          << nc.name << " face " << f;
    }
  }
}

// On a vertex and an edge (shared by quads or by a quad and a triangle) the coordinates are the
// limits from inside: they reproduce the point and sum to 1.
TEST(QuadGreen, VerticesAndEdgesAreSurfacePoints) {
  for (const NamedCage& nc : quadCages()) {
    const QuadGreenCoordinates qgc(nc.cage);
    const Cage& cage = *nc.cage;
    for (std::size_t f = 0; f < cage.faceCount(); ++f) {
      const auto face = cage.face(f);
      const Vec3 a = cage.vertices()[face[0]], b = cage.vertices()[face[1]];
      for (const Vec3& x : {a, 0.5 * (a + b)}) {
        const std::vector<double> row = rowOf(qgc, x);
        EXPECT_NEAR(phiSum(qgc, row), 1.0, 1e-12) << nc.name << " face " << f;
        EXPECT_LE(glm::length(mapPoint(qgc, row, cage.vertices()) - x), 1e-12 * cage.diagonal())
            << nc.name << " face " << f;
      }
    }
  }
}

// Close to an edge or a vertex (1e-9 of the diagonal towards the centre of a box cage) the
// coordinates still reproduce x and approach the surface values there (near a vertex only to
// 1e-6: rows there carry a cancellation round-off ~1e-18 diag / δ; see quad_green.cpp).
TEST(QuadGreen, AccurateNearEdgesAndVertices) {
  for (const bool warped : {false, true}) {
    const auto cage =
        makeCage(warped ? jitteredBox(0.2) : makeBoxSurface(Vec3(-1), Vec3(1), {2, 2, 2}), "box");
    const QuadGreenCoordinates qgc(cage);
    const double diag = cage->diagonal();
    for (std::size_t f = 0; f < cage->faceCount(); f += 5) {
      const auto face = cage->face(f);
      const Vec3 a = cage->vertices()[face[0]], b = cage->vertices()[face[1]];
      const std::vector<Vec3> near = {0.5 * (a + b), 0.9 * a + 0.1 * b, a};
      for (const Vec3& p : near) {
        const Vec3 x = p - 1e-9 * diag * glm::normalize(p);
        const std::vector<double> row = rowOf(qgc, x), on = rowOf(qgc, p);
        EXPECT_NEAR(phiSum(qgc, row), 1.0, 1e-12) << "face " << f;
        EXPECT_LE(glm::length(mapPoint(qgc, row, cage->vertices()) - x), 1e-12 * diag)
            << "face " << f << " at " << test::toString(p);
        double worst = 0.0;
        for (std::size_t c = 0; c < on.size(); ++c)
          worst = std::max(worst, std::abs(row[c] - on[c]));
        EXPECT_LE(worst, 1e-6) << "face " << f;
      }
    }
  }
}

// Next to every vertex and edge of a planar and of a warped box (1e-14 to 1e-6 of the diagonal,
// random directions, inside and outside) and far outside (10 to 1000 diagonals), Σ φ = 1 and x
// is reproduced to 1e-12 (of the diagonal) and a similarity to 1e-10 (of its scale times the
// diagonal): the rows' affine constraints are enforced (see enforceAffine() in quad_green.cpp).
// Without that, |Σ φ − 1| was 2e-4 at 1e-14 of the diagonal from a vertex of the planar box and
// reproduction lost ~r³ far away (3.7e-9 at 144 diagonals).
TEST(QuadGreen, AffineExactNearVerticesAndEdgesAndFarAway) {
  const Similarity sim = someSimilarity();
  for (const bool warped : {false, true}) {
    const auto cage =
        makeCage(warped ? jitteredBox(0.15) : makeBoxSurface(Vec3(-1), Vec3(1), {2, 2, 2}), "box");
    const QuadGreenCoordinates qgc(cage);
    const double diag = cage->diagonal();
    std::vector<Vec3> posed;
    for (const Vec3& v : cage->vertices()) posed.push_back(sim(v));
    std::vector<Vec3> rest(qgc.columnCount()), moved(qgc.columnCount());
    qgc.columnControls(cage->vertices(), rest);
    qgc.columnControls(posed, moved);
    std::mt19937 rng(11);
    std::normal_distribution<double> normal;
    const auto direction = [&] {
      return glm::normalize(Vec3(normal(rng), normal(rng), normal(rng)));
    };
    std::vector<Vec3> anchors(cage->vertices().begin(), cage->vertices().end());
    for (std::size_t f = 0; f < cage->faceCount(); ++f) {
      const auto face = cage->face(f);
      for (std::size_t k = 0; k < face.size(); ++k)
        anchors.push_back(0.7 * cage->vertices()[face[k]] +
                          0.3 * cage->vertices()[face[(k + 1) % face.size()]]);
    }
    std::vector<std::pair<Vec3, double>> points;  // point, reproduction bound (world units)
    for (const Vec3& a : anchors)
      for (const double off : {1e-14, 1e-12, 1e-10, 1e-8, 1e-6})
        for (int d = 0; d < 2; ++d) points.push_back({a + off * diag * direction(), 1e-12 * diag});
    for (const double r : {10.0, 100.0, 1000.0})
      for (int d = 0; d < 10; ++d) points.push_back({r * diag * direction(), 1e-10 * diag});
    for (const auto& [x, bound] : points) {
      const std::vector<double> row = rowOf(qgc, x);
      Vec3 at(0.0), to(0.0);
      for (std::size_t c = 0; c < row.size(); ++c) {
        at += row[c] * rest[c];
        to += row[c] * moved[c];
      }
      EXPECT_NEAR(phiSum(qgc, row), 1.0, 1e-12)
          << (warped ? "warped " : "planar ") << test::toString(x);
      EXPECT_LE(glm::length(at - x), bound)
          << (warped ? "warped " : "planar ") << test::toString(x);
      EXPECT_LE(glm::length(to - sim(x)), 1e-10 * sim.scale * diag)
          << (warped ? "warped " : "planar ") << test::toString(x);
    }
  }
}

TEST(QuadGreen, BatchIsBitIdenticalToSinglePointsForAnyThreadCount) {
  const auto cage = makeCage(lPrismQuads(true), "lPrismTriQuad");
  const QuadGreenCoordinates qgc(cage);
  std::mt19937 rng(2);
  const std::vector<Vec3> points = test::randomPoints(rng, 150, -0.5, 2.5);
  const std::size_t m = qgc.columnCount();
  std::vector<double> one(points.size() * m), two(one.size());
  tbb::task_arena(1).execute([&] { qgc.weightsBatch(points, one); });
  tbb::task_arena(2).execute([&] { qgc.weightsBatch(points, two); });
  EXPECT_EQ(one, two);
  for (std::size_t i = 0; i < points.size(); i += 17) {
    const std::vector<double> row = rowOf(qgc, points[i]);
    EXPECT_TRUE(std::equal(row.begin(), row.end(), one.begin() + i * m)) << i;
  }
}

// The quadrature runs vectorised on every simd::Path with the same bits.
TEST(QuadGreen, EverySimdPathGivesTheSameBits) {
  const auto cage = makeCage(lPrismQuads(true), "lPrismTriQuad");
  const QuadGreenCoordinates qgc(cage);
  std::mt19937 rng(4);
  const std::vector<Vec3> points = test::randomPoints(rng, 40, -0.5, 2.5);
  std::vector<double> reference;
  for (int p = 0; p < detail::simd::kPathCount; ++p) {
    const auto path = static_cast<detail::simd::Path>(p);
    if (!detail::simd::pathSupported(path)) continue;
    detail::simd::forcePath(path);
    std::vector<double> rows(points.size() * qgc.columnCount());
    qgc.weightsBatch(points, rows);
    detail::simd::forcePath(std::nullopt);
    if (reference.empty()) reference = rows;
    EXPECT_EQ(rows, reference) << detail::simd::pathName(path);
  }
}

TEST(QuadGreen, SaveLoadRoundTrips) {
  const auto cage = makeCage(jitteredBox(0.1), "box");
  QuadGreenOptions options;
  options.surfaceTolerance = 1e-12;
  const QuadGreenCoordinates qgc(cage, options);
  ArchiveWriter out;
  qgc.save(out);
  const ArchiveLoaders loaders;
  ArchiveReader in(out.bytes(), loaders);
  EXPECT_EQ(in.string(), "quad-green");
  const auto loaded = QuadGreenCoordinates::load(in);
  EXPECT_TRUE(in.atEnd());
  EXPECT_EQ(loaded->options().surfaceTolerance, 1e-12);
  const Vec3 x(0.1, -0.2, 0.3);
  EXPECT_EQ(rowOf(*loaded, x), rowOf(qgc, x));
}

// The Ju et al. armadillo cage is all triangles: QGC binds the model exactly as Green does.
TEST(QuadGreen, ArmadilloBindsAsGreen) {
  const auto dir = std::filesystem::path(SPACEWARP_SHARED_DATA_DIR) / "ju2005-armadillo";
  if (!std::filesystem::exists(dir / "bounding_mesh.obj"))
    GTEST_SKIP() << "no shared data at " << dir;
  const auto cage = std::make_shared<const Cage>(Cage::fromFile(dir / "bounding_mesh.obj"));
  PolygonSoup model = readSoup(dir / "armadilloman.obj");
  model.positions.resize(3000);
  const Binding qgc(std::make_shared<const QuadGreenCoordinates>(cage), model.positions);
  const Binding green(std::make_shared<const GreenCoordinates>(cage), model.positions);
  const std::vector<Vec3> posed = cage->posedVerticesFromFile(dir / "deformed_fixed_7.obj");
  EXPECT_EQ(qgc.deform(posed), green.deform(posed));
}

}  // namespace
}  // namespace spacewarp
