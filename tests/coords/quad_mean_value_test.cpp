#include <spacewarp/coords/quad_mean_value.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <memory>
#include <ostream>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <tbb/task_arena.h>

#include <spacewarp/coords/mean_value.h>
#include <spacewarp/coords/properties.h>
#include <spacewarp/core/archive.h>
#include <spacewarp/core/binding.h>
#include <spacewarp/core/detail/simd.h>
#include <spacewarp/core/errors.h>
#include <spacewarp/core/io/mesh_io.h>
#include <spacewarp/core/primitives.h>
#include "convex_test_shapes.h"
#include "coords_test_shapes.h"
#include "test_util.h"

namespace spacewarp {
namespace {

using CagePtr = std::shared_ptr<const Cage>;

struct Shape {
  std::string name;
  PolygonSoup soup;
};
void PrintTo(const Shape& shape, std::ostream* os) { *os << shape.name; }

// A box of 2 × 2 × 2 quads per side whose top ring is turned by `twist` radians about the
// vertical axis through the box's centre (0: the plain box; otherwise the side quads touching
// the top are non-planar).
PolygonSoup twistedBox(double twist) {
  PolygonSoup s = makeBoxSurface(Vec3(-1.0), Vec3(1.0), {2, 2, 2});
  for (Vec3& p : s.positions) {
    const double angle = twist * (p.z + 1.0) / 2.0;
    const double c = std::cos(angle), sn = std::sin(angle);
    p = Vec3(c * p.x - sn * p.y, sn * p.x + c * p.y, p.z);
  }
  return s;
}

// A mixed cage: a unit cube (5 quads) with a pyramid roof of 4 triangles, one of its sides
// non-planar (a top corner lifted).
PolygonSoup house() {
  PolygonSoup s;
  s.positions = {Vec3(0, 0, 0),   Vec3(1, 0, 0), Vec3(1, 1, 0), Vec3(0, 1, 0),      Vec3(0, 0, 1),
                 Vec3(1, 0, 1.2), Vec3(1, 1, 1), Vec3(0, 1, 1), Vec3(0.5, 0.5, 1.8)};
  s.addPolygon({3, 2, 1, 0});
  s.addPolygon({0, 1, 5, 4});
  s.addPolygon({1, 2, 6, 5});
  s.addPolygon({2, 3, 7, 6});
  s.addPolygon({3, 0, 4, 7});
  s.addPolygon({4, 5, 8});
  s.addPolygon({5, 6, 8});
  s.addPolygon({6, 7, 8});
  s.addPolygon({7, 4, 8});
  return s;
}

// The procedural polygon cages: convex quads, a concave L-prism with hexagon caps, non-planar
// quads, and a mixed triangle/quad cage.
std::vector<Shape> shapes() {
  return {{"quadBox", makeBoxSurface(Vec3(0.0), Vec3(1.0, 2.0, 1.5), {2, 3, 2})},
          {"lPrism", test::lPrism()},
          {"twistedBox", twistedBox(0.6)},
          {"house", house()}};
}

// The soup with every polygon's vertex list rotated by `shift` (the same faces, other starts).
PolygonSoup rotateFaces(const PolygonSoup& soup, std::size_t shift) {
  PolygonSoup out;
  out.positions = soup.positions;
  for (std::size_t f = 0; f < soup.polygonCount(); ++f) {
    const std::size_t begin = soup.faceOffsets[f], n = soup.faceOffsets[f + 1] - begin;
    std::vector<std::uint32_t> face(n);
    for (std::size_t i = 0; i < n; ++i) face[i] = soup.faceIndices[begin + (i + shift) % n];
    out.addPolygon(face);
  }
  return out;
}

// The soup with every quad split along the diagonal from its corner `first` (0 or 1).
PolygonSoup triangulateQuads(const PolygonSoup& soup, std::size_t first) {
  PolygonSoup out;
  out.positions = soup.positions;
  for (std::size_t f = 0; f < soup.polygonCount(); ++f) {
    const std::size_t begin = soup.faceOffsets[f], n = soup.faceOffsets[f + 1] - begin;
    const auto at = [&](std::size_t i) { return soup.faceIndices[begin + (first + i) % n]; };
    if (n == 4) {
      out.addPolygon({at(0), at(1), at(2)});
      out.addPolygon({at(0), at(2), at(3)});
    } else {
      std::vector<std::uint32_t> face(
          soup.faceIndices.begin() + static_cast<std::ptrdiff_t>(begin),
          soup.faceIndices.begin() + static_cast<std::ptrdiff_t>(begin + n));
      out.addPolygon(face);
    }
  }
  return out;
}

std::vector<double> weightsAt(const Coordinates& c, const Vec3& x) {
  std::vector<double> w(c.columnCount());
  c.weights(x, w);
  return w;
}

double reproductionError(const Cage& cage, const std::vector<double>& w, const Vec3& x) {
  Vec3 sum(0.0);
  for (std::size_t i = 0; i < w.size(); ++i) sum += w[i] * cage.vertices()[i];
  return glm::length(sum - x) / cage.diagonal();
}

double unityError(const std::vector<double>& w) {
  double sum = 0.0;
  for (double v : w) sum += v;
  return std::abs(sum - 1.0);
}

double maxDifference(const std::vector<double>& a, const std::vector<double>& b) {
  double d = 0.0;
  for (std::size_t i = 0; i < a.size(); ++i) d = std::max(d, std::abs(a[i] - b[i]));
  return d;
}

// The bilinear patch of a quad face and its basis.
Vec3 patchPoint(const Cage& cage, std::span<const std::uint32_t> q, double u, double v) {
  const auto& p = cage.vertices();
  return (1 - u) * (1 - v) * p[q[0]] + u * (1 - v) * p[q[1]] + u * v * p[q[2]] +
         (1 - u) * v * p[q[3]];
}
std::vector<double> bilinearRow(const Cage& cage, std::span<const std::uint32_t> q, double u,
                                double v) {
  std::vector<double> row(cage.vertexCount(), 0.0);
  row[q[0]] += (1 - u) * (1 - v);
  row[q[1]] += u * (1 - v);
  row[q[2]] += u * v;
  row[q[3]] += (1 - u) * v;
  return row;
}
Vec3 patchNormal(const Cage& cage, std::span<const std::uint32_t> q, double u, double v) {
  const double h = 1e-6;
  return glm::normalize(glm::cross(patchPoint(cage, q, u + h, v) - patchPoint(cage, q, u - h, v),
                                   patchPoint(cage, q, u, v + h) - patchPoint(cage, q, u, v - h)));
}

// Interior samples, points outside up to 3 diagonals away, points 1e-6 and 1e-10 diagonals off
// every face (both sides), and points 1e-5 to 1e-12 diagonals from every edge.
std::vector<Vec3> testPoints(const Cage& cage, std::mt19937_64& rng) {
  std::vector<Vec3> points = interiorSamples(cage, 150, 7);
  std::normal_distribution<double> normal;
  std::uniform_real_distribution<double> unit(0.05, 0.95);
  const BoundingBox box = boundingBox(cage.vertices());
  const Vec3 centre = 0.5 * (box.min + box.max);
  for (int i = 0; i < 60; ++i) {
    const Vec3 dir = glm::normalize(Vec3(normal(rng), normal(rng), normal(rng)));
    points.push_back(centre + (0.6 + 2.4 * (i % 10) / 9.0) * cage.diagonal() * dir);
  }
  for (std::size_t f = 0; f < cage.faceCount(); ++f) {
    const auto face = cage.face(f);
    Vec3 onFace, n;
    if (face.size() == 4) {
      const double u = unit(rng), v = unit(rng);
      onFace = patchPoint(cage, face, u, v);
      n = patchNormal(cage, face, u, v);
    } else {
      Vec3 c(0.0);
      for (auto i : face) c += cage.vertices()[i];
      onFace = c / static_cast<double>(face.size());
      const auto& p = cage.vertices();
      n = glm::normalize(glm::cross(p[face[1]] - p[face[0]], p[face[2]] - p[face[0]]));
    }
    for (const double off : {1e-6, -1e-6, 1e-10, -1e-10})
      points.push_back(onFace + off * cage.diagonal() * n);
    // Near the face's edges, in random directions.
    for (std::size_t k = 0; k < face.size(); ++k) {
      const Vec3 onEdge =
          0.7 * cage.vertices()[face[k]] + 0.3 * cage.vertices()[face[(k + 1) % face.size()]];
      const Vec3 dir = glm::normalize(Vec3(normal(rng), normal(rng), normal(rng)));
      for (const double off : {1e-5, 1e-9, 1e-12})
        points.push_back(onEdge + off * cage.diagonal() * dir);
    }
  }
  return points;
}

class QuadMeanValueShapes : public ::testing::TestWithParam<Shape> {
 protected:
  void SetUp() override {
    cage_ = std::make_shared<const Cage>(GetParam().soup, GetParam().name);
    qmvc_ = std::make_shared<const QuadMeanValueCoordinates>(cage_);
  }
  CagePtr cage_;
  std::shared_ptr<const QuadMeanValueCoordinates> qmvc_;
};

TEST_P(QuadMeanValueShapes, PartitionOfUnityAndLinearPrecisionEverywhere) {
  std::mt19937_64 rng(3);
  double unity = 0.0, repro = 0.0;
  for (const Vec3& x : testPoints(*cage_, rng)) {
    const std::vector<double> w = weightsAt(*qmvc_, x);
    unity = std::max(unity, unityError(w));
    repro = std::max(repro, reproductionError(*cage_, w, x));
  }
  EXPECT_LE(unity, 1e-12);
  EXPECT_LE(repro, 1e-12);
}

TEST_P(QuadMeanValueShapes, PropertyKitReport) {
  const std::vector<Vec3> samples = interiorSamples(*cage_, 300, 11);
  const PropertyReport report = measureProperties(*qmvc_, *cage_, samples);
  EXPECT_LE(report.partitionOfUnity, 1e-12);
  EXPECT_LE(report.linearReproduction, 1e-12);
  EXPECT_LE(report.similarityReproduction, 1e-12);
  EXPECT_LE(report.lagrange, 1e-12);
  // The kit's faceInterpolation compares with the barycentric coordinates of the cage's
  // triangulation, which the bilinear quads do not have; the faces are checked below.
}

TEST_P(QuadMeanValueShapes, LagrangeAtVerticesAndLinearOnEdges) {
  const Cage& cage = *cage_;
  for (std::size_t i = 0; i < cage.vertexCount(); ++i) {
    std::vector<double> delta(cage.vertexCount(), 0.0);
    delta[i] = 1.0;
    EXPECT_LE(maxDifference(weightsAt(*qmvc_, cage.vertices()[i]), delta), 1e-12) << i;
  }
  for (std::size_t f = 0; f < cage.faceCount(); ++f) {
    const auto face = cage.face(f);
    for (std::size_t k = 0; k < face.size(); ++k) {
      const std::uint32_t a = face[k], b = face[(k + 1) % face.size()];
      for (const double t : {0.25, 0.5, 0.8}) {
        const Vec3 x = (1 - t) * cage.vertices()[a] + t * cage.vertices()[b];
        std::vector<double> expected(cage.vertexCount(), 0.0);
        expected[a] = 1 - t;
        expected[b] = t;
        EXPECT_LE(maxDifference(weightsAt(*qmvc_, x), expected), 1e-12)
            << "face " << f << " edge " << a << "-" << b << " t " << t;
      }
    }
  }
}

// On a quad the bilinear interpolant; on a polygon weights only on its vertices that reproduce
// the point; on a triangle its barycentric coordinates. Continuous onto the face: 1e-9
// diagonals off the face the row is within 1e-6 of the face's (the approach is ~linear).
TEST_P(QuadMeanValueShapes, InterpolatesOnFacesAndIsContinuousOntoThem) {
  const Cage& cage = *cage_;
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> unit(0.05, 0.95);
  for (std::size_t f = 0; f < cage.faceCount(); ++f) {
    const auto face = cage.face(f);
    if (face.size() == 4) {
      for (int s = 0; s < 4; ++s) {
        const double u = unit(rng), v = unit(rng);
        const Vec3 x = patchPoint(cage, face, u, v);
        const std::vector<double> expected = bilinearRow(cage, face, u, v);
        EXPECT_LE(maxDifference(weightsAt(*qmvc_, x), expected), 1e-12) << "quad " << f;
        const Vec3 n = patchNormal(cage, face, u, v);
        for (const double side : {1.0, -1.0}) {
          const Vec3 near = x + side * 1e-9 * cage.diagonal() * n;
          EXPECT_LE(maxDifference(weightsAt(*qmvc_, near), expected), 1e-6) << "quad " << f;
        }
      }
    } else {
      Vec3 x(0.0);
      for (auto i : face) x += cage.vertices()[i];
      x /= static_cast<double>(face.size());
      const std::vector<double> w = weightsAt(*qmvc_, x);
      double off = 0.0;
      for (std::size_t i = 0; i < w.size(); ++i)
        if (std::find(face.begin(), face.end(), static_cast<std::uint32_t>(i)) == face.end())
          off = std::max(off, std::abs(w[i]));
      EXPECT_EQ(off, 0.0) << "face " << f;
      EXPECT_LE(reproductionError(cage, w, x), 1e-14) << "face " << f;
      EXPECT_LE(unityError(w), 1e-14) << "face " << f;
    }
  }
}

TEST_P(QuadMeanValueShapes, IndependentOfEachFacesStartingVertex) {
  const std::vector<Vec3> points = interiorSamples(*cage_, 100, 13);
  for (std::size_t shift = 1; shift < 4; ++shift) {
    const auto rotated = std::make_shared<const Cage>(rotateFaces(GetParam().soup, shift));
    const QuadMeanValueCoordinates other(rotated);
    double worst = 0.0;
    for (const Vec3& x : points)
      worst = std::max(worst, maxDifference(weightsAt(*qmvc_, x), weightsAt(other, x)));
    EXPECT_LE(worst, 1e-14) << "shift " << shift;
  }
}

TEST_P(QuadMeanValueShapes, DifferFromMeanValueCoordinatesOnEitherTriangulation) {
  const std::vector<Vec3> points = interiorSamples(*cage_, 100, 17);
  for (std::size_t first : {0u, 1u}) {
    const auto triangles = std::make_shared<const Cage>(triangulateQuads(GetParam().soup, first));
    if (triangles->maxFaceSize() > 3) continue;  // the L-prism keeps its hexagons
    const MeanValueCoordinates mvc(triangles);
    double worst = 0.0;
    for (const Vec3& x : points)
      worst = std::max(worst, maxDifference(weightsAt(*qmvc_, x), weightsAt(mvc, x)));
    EXPECT_GE(worst, 1e-4) << "diagonal from corner " << first;
  }
}

TEST_P(QuadMeanValueShapes, BatchRowsAreBitIdenticalToSingleRowsForAnyThreadCount) {
  std::mt19937_64 rng(19);
  const std::vector<Vec3> points = testPoints(*cage_, rng);
  const std::size_t n = qmvc_->columnCount();
  std::vector<double> one(points.size() * n), two(points.size() * n);
  tbb::task_arena(1).execute([&] { qmvc_->weightsBatch(points, one); });
  tbb::task_arena(2).execute([&] { qmvc_->weightsBatch(points, two); });
  EXPECT_EQ(std::memcmp(one.data(), two.data(), one.size() * sizeof(double)), 0);
  for (std::size_t i = 0; i < points.size(); i += 7) {
    const std::vector<double> w = weightsAt(*qmvc_, points[i]);
    EXPECT_EQ(std::memcmp(w.data(), one.data() + i * n, n * sizeof(double)), 0) << i;
  }
}

TEST_P(QuadMeanValueShapes, SaveAndLoadGiveTheSameRows) {
  QuadMeanValueOptions options;
  options.snapTolerance = 1e-12;
  const QuadMeanValueCoordinates original(cage_, options);
  ArchiveWriter out;
  original.save(out);
  static const ArchiveLoaders loaders;
  ArchiveReader in(out.bytes(), loaders);
  EXPECT_EQ(in.string(), "quad-mean-value");
  const auto loaded = QuadMeanValueCoordinates::load(in);
  EXPECT_TRUE(in.atEnd());
  EXPECT_EQ(loaded->options().snapTolerance, 1e-12);
  for (const Vec3& x : interiorSamples(*cage_, 20, 23)) {
    const std::vector<double> a = weightsAt(original, x), b = weightsAt(*loaded, x);
    EXPECT_EQ(std::memcmp(a.data(), b.data(), a.size() * sizeof(double)), 0);
  }
}

INSTANTIATE_TEST_SUITE_P(Cages, QuadMeanValueShapes, ::testing::ValuesIn(shapes()),
                         [](const auto& info) { return info.param.name; });

TEST(QuadMeanValueCoordinates, EqualMeanValueCoordinatesBitForBitOnTriangleCages) {
  for (const PolygonSoup& soup : {test::tetrahedron(), test::star(), test::icosphere(1)}) {
    const auto cage = std::make_shared<const Cage>(soup);
    const QuadMeanValueCoordinates qmvc(cage);
    const MeanValueCoordinates mvc(cage);
    std::vector<Vec3> points = interiorSamples(*cage, 64, 29);
    points.push_back(cage->vertices()[0] + Vec3(3.0, -2.0, 1.0));
    points.push_back(0.5 * (cage->vertices()[0] + cage->vertices()[1]));
    const std::size_t n = mvc.columnCount();
    std::vector<double> a(points.size() * n), b(points.size() * n);
    qmvc.weightsBatch(points, a);
    mvc.weightsBatch(points, b);
    EXPECT_EQ(std::memcmp(a.data(), b.data(), a.size() * sizeof(double)), 0);
    const std::vector<double> wa = weightsAt(qmvc, points[3]), wb = weightsAt(mvc, points[3]);
    EXPECT_EQ(std::memcmp(wa.data(), wb.data(), n * sizeof(double)), 0);
  }
}

TEST(QuadMeanValueCoordinates, PositiveInsideAConvexQuadCage) {
  const auto cage =
      std::make_shared<const Cage>(makeBoxSurface(Vec3(0.0), Vec3(1.0, 2.0, 1.5), {2, 3, 2}));
  const QuadMeanValueCoordinates qmvc(cage);
  double minWeight = 1.0;
  for (const Vec3& x : interiorSamples(*cage, 300, 31))
    for (double w : weightsAt(qmvc, x)) minWeight = std::min(minWeight, w);
  EXPECT_GT(minWeight, 0.0);
}

TEST(QuadMeanValueCoordinates, RejectsBadInput) {
  EXPECT_THROW(QuadMeanValueCoordinates(nullptr), InvalidInput);
  const auto cage = std::make_shared<const Cage>(test::lPrism(), "lPrism");
  QuadMeanValueOptions bad;
  bad.snapTolerance = -1.0;
  EXPECT_THROW(QuadMeanValueCoordinates(cage, bad), InvalidInput);
  bad = {};
  bad.polygonPlanarity = std::nan("");
  EXPECT_THROW(QuadMeanValueCoordinates(cage, bad), InvalidInput);
  const QuadMeanValueCoordinates qmvc(cage);
  std::vector<double> row(cage->vertexCount());
  EXPECT_THROW(qmvc.weights(Vec3(std::nan(""), 0.0, 0.0), row), InvalidInput);
  std::vector<double> shortRow(3);
  EXPECT_THROW(qmvc.weights(Vec3(0.5), shortRow), InvalidInput);
  EXPECT_THROW(qmvc.weights(Vec3(1e6), row), InvalidInput);  // beyond 3000 diagonals
}

TEST(QuadMeanValueCoordinates, RefusesANonPlanarHexagonNamingIt) {
  PolygonSoup soup = test::lPrism();
  soup.positions[7].z += 0.05;  // a vertex of the top cap (face 1) lifted
  const auto cage = std::make_shared<const Cage>(soup, "bent");
  try {
    QuadMeanValueCoordinates qmvc(cage);
    FAIL() << "a non-planar hexagon was accepted";
  } catch (const InvalidInput& e) {
    EXPECT_NE(std::string(e.what()).find("face 1 (6 vertices)"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("bent"), std::string::npos) << e.what();
  }
}

// A planar concave quad's bilinear patch folds over its notch: points beside the notch would see
// surface that is not there (weights ~1 / distance, reproduction lost), so it is refused, naming
// the cage, the face and its vertices. A convex quad twisted out of its plane does not fold.
TEST(QuadMeanValueCoordinates, RefusesAQuadWhosePatchFoldsNamingIt) {
  const auto dart = std::make_shared<const Cage>(test::dartPrism(), "dart");
  const std::string message =
      test::messageOf<InvalidInput>([&] { QuadMeanValueCoordinates qmvc(dart); });
  EXPECT_NE(message.find("dart: QuadMeanValueCoordinates: face 0 (vertices 3, 2, 1, 0)"),
            std::string::npos)
      << message;
  EXPECT_NE(message.find("split it into triangles"), std::string::npos) << message;
  // The same prism with its caps cut into triangles at the reflex corner is a valid cage.
  PolygonSoup split = test::dartPrism();
  split.faceIndices.clear();
  split.faceOffsets = {0};
  split.addPolygon({3, 2, 1});
  split.addPolygon({3, 1, 0});
  split.addPolygon({4, 5, 7});
  split.addPolygon({5, 6, 7});
  for (std::uint32_t i = 0; i < 4; ++i) split.addPolygon({i, (i + 1) % 4, (i + 1) % 4 + 4, i + 4});
  EXPECT_NO_THROW(QuadMeanValueCoordinates(std::make_shared<const Cage>(split, "splitDart")));
  const auto twisted = std::make_shared<const Cage>(twistedBox(1.2), "twisted");
  EXPECT_NO_THROW(QuadMeanValueCoordinates{twisted});
}

// snapTolerance 0 still gives a point on a face (up to the round-off of its distance to the face)
// the face's bilinear interpolant, and keeps points just off a face accurate: planar and twisted
// quads, points at random parameters on every face and 1e-15 … 1e-9 diagonals off it.
TEST(QuadMeanValueCoordinates, SnapToleranceZeroKeepsPointsOnAndNearFacesExact) {
  for (const double twist : {0.0, 0.6}) {
    const auto cage = std::make_shared<const Cage>(twistedBox(twist));
    QuadMeanValueOptions options;
    options.snapTolerance = 0.0;
    const QuadMeanValueCoordinates qmvc(cage, options);
    const double diagonal = cage->diagonal();
    const auto vertices = cage->vertices();
    std::mt19937 rng(20);
    std::uniform_real_distribution<double> param(0.02, 0.98);
    std::vector<double> row(cage->vertexCount());
    for (std::size_t f = 0; f < cage->faceCount(); ++f) {
      const auto face = cage->face(f);
      const Vec3 q0 = vertices[face[0]], q1 = vertices[face[1]], q2 = vertices[face[2]],
                 q3 = vertices[face[3]];
      for (int k = 0; k < 4; ++k) {
        const double u = param(rng), v = param(rng);
        const std::array<double, 4> phi = {(1 - u) * (1 - v), u * (1 - v), u * v, (1 - u) * v};
        const Vec3 x = phi[0] * q0 + phi[1] * q1 + phi[2] * q2 + phi[3] * q3;
        qmvc.weights(x, row);
        for (int c = 0; c < 4; ++c)
          EXPECT_NEAR(row[face[c]], phi[c], 1e-12) << "twist " << twist << " face " << f;
        const Vec3 normal = glm::normalize(
            glm::cross((1 - v) * (q1 - q0) + v * (q2 - q3), (1 - u) * (q3 - q0) + u * (q2 - q1)));
        for (const double h : {1e-15, -1e-15, 1e-12, -1e-12, 1e-9, -1e-9}) {
          const Vec3 y = x + h * diagonal * normal;
          qmvc.weights(y, row);
          Vec3 image(0.0);
          double sum = 0.0;
          for (std::size_t i = 0; i < row.size(); ++i) {
            image += row[i] * vertices[i];
            sum += row[i];
          }
          EXPECT_NEAR(sum, 1.0, 1e-13) << "twist " << twist << " face " << f << " h " << h;
          EXPECT_LE(glm::length(image - y), 1e-13 * diagonal)
              << "twist " << twist << " face " << f << " h " << h;
        }
      }
    }
  }
}

// Far outside, where the weights cancel, reproduction stays within the header's measured bounds
// (cage diagonals): 1e-12 (the bar) out to 30 diagonals and 5e-12 at 100, on planar and
// twisted quads, and within 10 times MVC's on the same cage cut into triangles plus 5e-13.
TEST(QuadMeanValueCoordinates, ReproducesFarOutsideAsTheHeaderSays) {
  for (const double twist : {0.0, 0.6}) {
    const auto cage = std::make_shared<const Cage>(twistedBox(twist));
    const QuadMeanValueCoordinates qmvc(cage);
    const MeanValueCoordinates mvc(
        std::make_shared<const Cage>(triangulateQuads(twistedBox(twist), 0)));
    const double diagonal = cage->diagonal();
    std::mt19937 rng(18);
    std::normal_distribution<double> normal;
    std::vector<double> row(cage->vertexCount());
    const auto error = [&](const Coordinates& c, const Vec3& x) {
      c.weights(x, row);
      Vec3 image(0.0);
      for (std::size_t i = 0; i < row.size(); ++i) image += row[i] * cage->vertices()[i];
      return glm::length(image - x) / diagonal;
    };
    for (const double r : {10.0, 30.0, 100.0}) {
      double worst = 0.0, worstMvc = 0.0;
      for (int i = 0; i < 200; ++i) {
        const Vec3 x = r * diagonal * glm::normalize(Vec3(normal(rng), normal(rng), normal(rng)));
        worst = std::max(worst, error(qmvc, x));
        worstMvc = std::max(worstMvc, error(mvc, x));
      }
      EXPECT_LE(worst, r <= 30.0 ? 1e-12 : 5e-12) << "twist " << twist << " at " << r;
      EXPECT_LE(worst, 10.0 * worstMvc + 5e-13) << "twist " << twist << " at " << r;
    }
  }
}

// F11: a rotated hexagonal prism written in float32 or with 6 decimals (its hexagons non-planar
// by ~1e-8 diagonals) is accepted with the default polygonPlanarity and reproduces x to about
// that; a hexagon bent by 1e-4 diagonals is still refused.
TEST(QuadMeanValueCoordinates, AcceptRoundedPolygonsAndReproduceToTheRounding) {
  double worst = 0.0;
  for (unsigned seed = 1; seed <= 10; ++seed) {
    for (const PolygonSoup& soup :
         {test::rotatedAndRounded(test::hexagonalPrism(), seed, test::sixDecimals),
          test::rotatedAndRounded(test::hexagonalPrism(), seed, test::float32)}) {
      const auto cage = std::make_shared<const Cage>(soup);
      const QuadMeanValueCoordinates qmvc(cage);
      const PropertyReport r = measureProperties(qmvc, *cage, interiorSamples(*cage, 100, seed));
      EXPECT_LE(r.partitionOfUnity, 1e-12);
      worst = std::max(worst, r.linearReproduction);
    }
  }
  EXPECT_LE(worst, 1e-6);
  std::printf("rounded hexagonal prisms: linear reproduction %.3g diagonals\n", worst);
  PolygonSoup bent = test::hexagonalPrism();
  bent.positions[0].z += 1e-4 * Cage(bent).diagonal();
  EXPECT_THROW(QuadMeanValueCoordinates(std::make_shared<const Cage>(bent)), InvalidInput);
}

// ---- the quads' integral against a brute-force one ----

// Gauss-Legendre nodes and weights of order n on [0, 1], in long double (Newton on P_n).
void gaussLegendre(int n, std::vector<long double>& node, std::vector<long double>& weight) {
  node.resize(static_cast<std::size_t>(n));
  weight.resize(static_cast<std::size_t>(n));
  const long double pi = 3.141592653589793238462643383279502884L;
  for (int i = 0; i < n; ++i) {
    long double z = std::cos(pi * (i + 0.75L) / (n + 0.5L)), dp = 0;
    for (int it = 0; it < 100; ++it) {
      long double p0 = 1, p1 = z;
      for (int k = 2; k <= n; ++k) {
        const long double p2 = ((2 * k - 1) * z * p1 - (k - 1) * p0) / k;
        p0 = p1;
        p1 = p2;
      }
      dp = n * (z * p1 - p0) / (z * z - 1);
      const long double step = p1 / dp;
      z -= step;
      if (std::fabs(step) < 1e-21L) break;
    }
    node[static_cast<std::size_t>(i)] = (1 - z) / 2;
    weight[static_cast<std::size_t>(i)] = 1 / ((1 - z * z) * dp * dp);
  }
}

// The row of x by the definition, independently of the library's quadrature: every quad's
// W_k = ∫∫ B_k (ξ − x)·(ξ_u × ξ_v) / |ξ − x|⁴ du dv in long double, by recursive subdivision of
// the parameter square until x is 5 radii of a square's corners from its centre, then a
// 16 × 16 Gauss rule (2.5 times QMVC's admissibility margin). All-quad cages only.
std::vector<double> bruteForceRow(const Cage& cage, const Vec3& x) {
  using L = long double;
  using V = glm::vec<3, L>;
  std::vector<L> node, weight;
  gaussLegendre(16, node, weight);
  std::vector<L> acc(cage.vertexCount(), 0);
  for (std::size_t f = 0; f < cage.faceCount(); ++f) {
    const auto face = cage.face(f);
    std::array<V, 4> q;
    for (int k = 0; k < 4; ++k) q[static_cast<std::size_t>(k)] = V(cage.vertices()[face[k]]) - V(x);
    const auto at = [&](L u, L v) {
      return (1 - u) * (1 - v) * q[0] + u * (1 - v) * q[1] + u * v * q[2] + (1 - u) * v * q[3];
    };
    struct Square {
      L u0, v0, s;
    };
    std::vector<Square> stack = {{0, 0, 1}};
    while (!stack.empty()) {
      const Square sq = stack.back();
      stack.pop_back();
      const V centre = at(sq.u0 + sq.s / 2, sq.v0 + sq.s / 2);
      L radius = 0;
      for (int k = 0; k < 4; ++k) {
        const V corner = at(sq.u0 + (k % 2) * sq.s, sq.v0 + (k / 2) * sq.s);
        radius = std::max(radius, glm::length(corner - centre));
      }
      if (glm::length(centre) < 5 * radius) {
        const L h = sq.s / 2;
        stack.insert(stack.end(), {{sq.u0, sq.v0, h},
                                   {sq.u0 + h, sq.v0, h},
                                   {sq.u0, sq.v0 + h, h},
                                   {sq.u0 + h, sq.v0 + h, h}});
        continue;
      }
      for (std::size_t i = 0; i < node.size(); ++i) {
        for (std::size_t j = 0; j < node.size(); ++j) {
          const L u = sq.u0 + sq.s * node[i], v = sq.v0 + sq.s * node[j];
          const V r = at(u, v);
          const V du = (1 - v) * (q[1] - q[0]) + v * (q[2] - q[3]);
          const V dv = (1 - u) * (q[3] - q[0]) + u * (q[2] - q[1]);
          const L r2 = glm::dot(r, r);
          const L g =
              sq.s * sq.s * weight[i] * weight[j] * glm::dot(r, glm::cross(du, dv)) / (r2 * r2);
          acc[face[0]] += (1 - u) * (1 - v) * g;
          acc[face[1]] += u * (1 - v) * g;
          acc[face[2]] += u * v * g;
          acc[face[3]] += (1 - u) * v * g;
        }
      }
    }
  }
  L sum = 0;
  for (L w : acc) sum += w;
  std::vector<double> row(acc.size());
  for (std::size_t i = 0; i < acc.size(); ++i) row[i] = static_cast<double>(acc[i] / sum);
  return row;
}

// The quads' free direction is an integral, not an approximation of one: rows equal the
// brute-force integral to 1e-13 (measured: 3e-16; the quadrature it replaced, a tessellation of
// the patch extrapolated, was 1e-3 off) inside, outside and at 1e-3 … 1e-11 diagonals from faces,
// edges and vertices of planar and warped quads, on both sides of the faces.
TEST(QuadMeanValueCoordinates, MatchesTheIntegralComputedByBruteForce) {
  for (const double twist : {0.0, 0.6}) {
    const auto cage = std::make_shared<const Cage>(twistedBox(twist));
    const QuadMeanValueCoordinates qmvc(cage);
    const double diag = cage->diagonal();
    std::vector<Vec3> points = interiorSamples(*cage, 6, 41);
    points.push_back(Vec3(2.5, -1.0, 0.7));  // outside
    std::mt19937_64 rng(5);
    std::normal_distribution<double> normal;
    for (const std::size_t f : {std::size_t{2}, std::size_t{21}}) {
      const auto face = cage->face(f);
      const Vec3 onFace = patchPoint(*cage, face, 0.3, 0.6);
      const Vec3 onEdge = patchPoint(*cage, face, 0.4, 0.0);
      const Vec3& vertex = cage->vertices()[face[2]];
      const Vec3 n = patchNormal(*cage, face, 0.3, 0.6);
      for (const double off : {1e-3, 1e-7, 1e-11}) {
        const Vec3 dir = glm::normalize(Vec3(normal(rng), normal(rng), normal(rng)));
        points.push_back(onFace + off * diag * n);
        points.push_back(onFace - off * diag * n);
        points.push_back(onEdge + off * diag * dir);
        points.push_back(vertex + off * diag * dir);
      }
    }
    for (std::size_t i = 0; i < points.size(); ++i) {
      EXPECT_LE(maxDifference(weightsAt(qmvc, points[i]), bruteForceRow(*cage, points[i])), 1e-13)
          << "twist " << twist << ", point " << i;
    }
  }
}

TEST(QuadMeanValueCoordinates, EverySimdPathGivesTheSameBits) {
  const auto cage = std::make_shared<const Cage>(twistedBox(0.6));
  const QuadMeanValueCoordinates qmvc(cage);
  std::vector<Vec3> points = interiorSamples(*cage, 30, 43);
  for (int i = 0; i < 10; ++i) points.push_back(Vec3(1.3 + 0.4 * i, -0.7, 0.2 * i - 1.0));
  std::vector<double> reference;
  for (int p = 0; p < detail::simd::kPathCount; ++p) {
    const auto path = static_cast<detail::simd::Path>(p);
    if (!detail::simd::pathSupported(path)) continue;
    detail::simd::forcePath(path);
    std::vector<double> rows(points.size() * qmvc.columnCount());
    qmvc.weightsBatch(points, rows);
    detail::simd::forcePath(std::nullopt);
    if (reference.empty()) reference = rows;
    EXPECT_EQ(rows, reference) << detail::simd::pathName(path);
  }
}

// ---- the Ju et al. armadillo (optional shared data): an all-triangle cage ----

TEST(QuadMeanValueArmadillo, EqualsMeanValueCoordinatesAndReproducesTheModel) {
  const auto dir = std::filesystem::path(SPACEWARP_SHARED_DATA_DIR) / "ju2005-armadillo";
  if (!std::filesystem::exists(dir / "bounding_mesh.obj"))
    GTEST_SKIP() << "shared data not found: " << dir;
  const auto cage = std::make_shared<const Cage>(Cage::fromFile(dir / "bounding_mesh.obj"));
  const PolygonSoup model = readSoup(dir / "armadilloman.obj");
  const Binding qmvc(std::make_shared<const QuadMeanValueCoordinates>(cage), model.positions);
  const Binding mvc(std::make_shared<const MeanValueCoordinates>(cage), model.positions);
  const auto& a = qmvc.dense();
  const auto& b = mvc.dense();
  ASSERT_EQ(a.size(), b.size());
  EXPECT_EQ(std::memcmp(a.data(), b.data(), static_cast<std::size_t>(a.size()) * sizeof(double)),
            0);
  double worst = 0.0;
  for (std::size_t i = 0; i < model.positions.size(); ++i) {
    const auto r = a.row(static_cast<Eigen::Index>(i));
    std::vector<double> row(static_cast<std::size_t>(r.size()));
    for (Eigen::Index c = 0; c < r.size(); ++c) row[static_cast<std::size_t>(c)] = r(c);
    worst = std::max({worst, reproductionError(*cage, row, model.positions[i]), unityError(row)});
  }
  EXPECT_LE(worst, 1e-12);
}

}  // namespace
}  // namespace spacewarp
