#include <spacewarp/coords/mean_value.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <limits>
#include <memory>
#include <ostream>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <tbb/task_arena.h>

#include <spacewarp/coords/properties.h>
#include <spacewarp/core/binding.h>
#include <spacewarp/core/coordinate_warp.h>
#include <spacewarp/core/errors.h>
#include <spacewarp/core/io/mesh_io.h>
#include <spacewarp/core/primitives.h>
#include "coords_test_shapes.h"

namespace spacewarp {
namespace {

using CagePtr = std::shared_ptr<const Cage>;

struct Shape {
  std::string name;
  PolygonSoup soup;
};
void PrintTo(const Shape& shape, std::ostream* os) { *os << shape.name; }

// The procedural test cages; box2 has subdivided faces (coplanar neighbouring triangles).
std::vector<Shape> shapes() {
  return {{"tetrahedron", test::tetrahedron()},
          {"box", makeBoxSurface(Vec3(0.0), Vec3(1.0), {1, 1, 1})},
          {"box2", makeBoxSurface(Vec3(-1.0, 0.0, 2.0), Vec3(1.0, 2.0, 5.0), {2, 3, 1})},
          {"lPrism", test::lPrism()},
          {"star", test::star()},
          {"icosphere", test::icosphere(2)}};
}

CagePtr makeCage(const PolygonSoup& soup, const std::string& name) {
  return std::make_shared<const Cage>(soup, name);
}

std::vector<double> weightsAt(const MeanValueCoordinates& mvc, const Vec3& x) {
  std::vector<double> w(mvc.columnCount());
  mvc.weights(x, w);
  return w;
}

// |Σ_i w_i p_i − x| / diagonal.
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

Vec3 randomDirection(std::mt19937_64& rng) {
  std::normal_distribution<double> normal;
  return glm::normalize(Vec3(normal(rng), normal(rng), normal(rng)));
}

Vec3 corner(const Cage& cage, std::size_t t, int c) {
  return cage.vertices()[cage.triangles()[t][c]];
}

// Expects that the weights of x sum to one and reproduce x, to 1e-12.
void expectLinearPrecision(const MeanValueCoordinates& mvc, const Vec3& x,
                           const std::string& what) {
  const std::vector<double> w = weightsAt(mvc, x);
  EXPECT_LE(unityError(w), 1e-12) << what;
  EXPECT_LE(reproductionError(mvc.cage(), w, x), 1e-12) << what;
}

class MeanValueShapes : public ::testing::TestWithParam<Shape> {
 protected:
  void SetUp() override {
    cage_ = makeCage(GetParam().soup, GetParam().name);
    mvc_ = std::make_shared<const MeanValueCoordinates>(cage_);
  }
  CagePtr cage_;
  std::shared_ptr<const MeanValueCoordinates> mvc_;
};

TEST(MeanValueCoordinates, DescribesTheCage) {
  const CagePtr cage = makeCage(test::lPrism(), "lPrism");
  const MeanValueCoordinates mvc(cage);
  EXPECT_EQ(mvc.controlPointCount(), cage->vertexCount());
  EXPECT_EQ(mvc.columnCount(), cage->vertexCount());
  EXPECT_EQ(mvc.maxNonZeros(), cage->vertexCount());
  ASSERT_EQ(mvc.restControlPoints().size(), cage->vertexCount());
  for (std::size_t i = 0; i < cage->vertexCount(); ++i)
    EXPECT_EQ(mvc.restControlPoints()[i], cage->vertices()[i]);
  EXPECT_EQ(&mvc.cage(), cage.get());
  EXPECT_EQ(mvc.options().snapTolerance, MeanValueOptions{}.snapTolerance);
}

TEST(MeanValueCoordinates, RejectsANullCageAndBadOptions) {
  EXPECT_THROW(MeanValueCoordinates(nullptr), InvalidInput);
  const CagePtr cage = makeCage(test::tetrahedron(), "tetrahedron");
  for (double bad : {-1e-12, 0.1, std::numeric_limits<double>::quiet_NaN()}) {
    MeanValueOptions options;
    options.snapTolerance = bad;
    EXPECT_THROW(MeanValueCoordinates(cage, options), InvalidInput) << bad;
  }
}

TEST(MeanValueCoordinates, RejectsInvalidQueries) {
  const MeanValueCoordinates mvc(makeCage(test::tetrahedron(), "tetrahedron"));
  std::vector<double> row(4), shortRow(3);
  const double nan = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(mvc.weights(Vec3(nan, 0.0, 0.0), row), InvalidInput);
  EXPECT_THROW(mvc.weights(Vec3(0.0, std::numeric_limits<double>::infinity(), 0.0), row),
               InvalidInput);
  EXPECT_THROW(mvc.weights(Vec3(0.2), shortRow), InvalidInput);
  const std::vector<Vec3> points = {Vec3(0.2), Vec3(0.1, nan, 0.1)};
  std::vector<double> rows(8);
  try {
    mvc.weightsBatch(points, rows);
    ADD_FAILURE() << "no exception for a NaN point";
  } catch (const InvalidInput& e) {
    EXPECT_NE(std::string(e.what()).find("point 1"), std::string::npos) << e.what();
  }
  std::vector<double> wrongRows(7);
  EXPECT_THROW(mvc.weightsBatch(std::vector<Vec3>{Vec3(0.2), Vec3(0.3)}, wrongRows), InvalidInput);
}

TEST_P(MeanValueShapes, PartitionOfUnityAndLinearPrecisionEverywhere) {
  const Cage& cage = *cage_;
  const BoundingBox box = boundingBox(cage.vertices());
  const Vec3 center = 0.5 * (box.min + box.max), half = 0.5 * box.extent();
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  for (int i = 0; i < 400; ++i) {
    // Inside and around the cage (up to three times its box), and 10 diagonals away.
    const double scale = i < 200 ? 1.0 : 3.0;
    const Vec3 x = center + scale * half * Vec3(unit(rng), unit(rng), unit(rng));
    expectLinearPrecision(*mvc_, x, "near point " + std::to_string(i));
  }
  for (int i = 0; i < 50; ++i) {
    const Vec3 x = center + 10.0 * cage.diagonal() * randomDirection(rng);
    expectLinearPrecision(*mvc_, x, "far point " + std::to_string(i));
  }
}

TEST_P(MeanValueShapes, LagrangePropertyAtVertices) {
  const Cage& cage = *cage_;
  for (std::size_t v = 0; v < cage.vertexCount(); ++v) {
    for (const double offset : {0.0, 1e-16}) {  // exactly on it, and within the snap distance
      const Vec3 x = cage.vertices()[v] + offset * cage.diagonal() * Vec3(0.6, -0.8, 0.0);
      const std::vector<double> w = weightsAt(*mvc_, x);
      for (std::size_t j = 0; j < w.size(); ++j)
        EXPECT_NEAR(w[j], j == v ? 1.0 : 0.0, 1e-14) << "vertex " << v << ", weight " << j;
    }
  }
}

TEST_P(MeanValueShapes, LinearOnFacesAndEdges) {
  const Cage& cage = *cage_;
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  for (std::size_t t = 0; t < cage.triangleCount(); ++t) {
    const Triangle tri = cage.triangles()[t];
    for (int k = 0; k < 3; ++k) {
      double b0 = unit(rng), b1 = unit(rng);
      if (b0 + b1 > 1.0) {
        b0 = 1.0 - b0;
        b1 = 1.0 - b1;
      }
      const double b[3] = {b0, b1, 1.0 - b0 - b1};
      const Vec3 x =
          b[0] * corner(cage, t, 0) + b[1] * corner(cage, t, 1) + b[2] * corner(cage, t, 2);
      const std::vector<double> w = weightsAt(*mvc_, x);
      std::vector<double> expected(w.size(), 0.0);
      for (int c = 0; c < 3; ++c) expected[tri[c]] += b[c];
      EXPECT_LE(maxDifference(w, expected), 1e-12) << "face " << t;

      // On the edge from corner k to corner k+1.
      const double s = unit(rng);
      const Vec3 y = (1.0 - s) * corner(cage, t, k) + s * corner(cage, t, (k + 1) % 3);
      const std::vector<double> we = weightsAt(*mvc_, y);
      std::vector<double> expectedEdge(we.size(), 0.0);
      expectedEdge[tri[k]] += 1.0 - s;
      expectedEdge[tri[(k + 1) % 3]] += s;
      EXPECT_LE(maxDifference(we, expectedEdge), 1e-12) << "edge of face " << t;
    }
  }
}

TEST_P(MeanValueShapes, ContinuousAcrossFaces) {
  const Cage& cage = *cage_;
  std::mt19937_64 rng(9);
  std::uniform_real_distribution<double> unit(0.1, 0.45);
  const double delta = 1e-9 * cage.diagonal();
  for (std::size_t t = 0; t < cage.triangleCount(); ++t) {
    const double b0 = unit(rng), b1 = unit(rng);
    const Vec3 x =
        b0 * corner(cage, t, 0) + b1 * corner(cage, t, 1) + (1.0 - b0 - b1) * corner(cage, t, 2);
    const Vec3 n = cage.normal(t);
    const std::vector<double> on = weightsAt(*mvc_, x);
    const std::vector<double> inside = weightsAt(*mvc_, x - delta * n);
    const std::vector<double> outside = weightsAt(*mvc_, x + delta * n);
    EXPECT_LE(maxDifference(on, inside), 1e-8) << "face " << t;
    EXPECT_LE(maxDifference(on, outside), 1e-8) << "face " << t;
    expectLinearPrecision(*mvc_, x - delta * n, "just inside face " + std::to_string(t));
    expectLinearPrecision(*mvc_, x + delta * n, "just outside face " + std::to_string(t));
  }
}

// Points in the plane of a face but outside it, and a tiny distance off that plane: the face's
// contribution degenerates to 0/0 in the textbook formula.
TEST_P(MeanValueShapes, AccurateNearExtendedFacePlanes) {
  const Cage& cage = *cage_;
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> unit(-2.0, 3.0);
  for (std::size_t t = 0; t < cage.triangleCount(); ++t) {
    const Vec3 p0 = corner(cage, t, 0), e1 = corner(cage, t, 1) - p0, e2 = corner(cage, t, 2) - p0;
    const Vec3 n = cage.normal(t);
    for (int k = 0; k < 4; ++k) {
      double a = unit(rng), b = unit(rng);
      if (a >= 0.0 && b >= 0.0 && a + b <= 1.0) a += 1.5;  // outside the face itself
      // Every fourth point on the line of an edge, beyond the edge.
      const Vec3 x = k == 3 ? p0 + (1.0 + std::abs(a)) * e1 : p0 + a * e1 + b * e2;
      const std::vector<double> onPlane = weightsAt(*mvc_, x);
      for (const double rel : {1e-9, 1e-12, 1e-15}) {
        for (const double side : {-1.0, 1.0}) {
          const Vec3 y = x + side * rel * cage.diagonal() * n;
          const std::string what =
              "face " + std::to_string(t) + ", offset " + std::to_string(side * rel);
          const std::vector<double> w = weightsAt(*mvc_, y);
          EXPECT_LE(unityError(w), 1e-12) << what;
          EXPECT_LE(reproductionError(cage, w, y), 1e-12) << what;
          // Lipschitz in the offset: the weights approach those on the plane.
          EXPECT_LE(maxDifference(w, onPlane), 50.0 * rel + 2e-14) << what;
        }
      }
      expectLinearPrecision(*mvc_, x, "on the plane of face " + std::to_string(t));
    }
  }
}

TEST(MeanValueCoordinates, UnitBoxExtendedPlanes) {
  const CagePtr cage = makeCage(makeBoxSurface(Vec3(0.0), Vec3(1.0), {1, 1, 1}), "box");
  const MeanValueCoordinates mvc(cage);
  // On one face plane, on two (an edge line), on three planes (a corner's axis lines).
  for (const Vec3& x :
       {Vec3(2.0, 0.5, 1.0), Vec3(2.0, 0.5, 0.0), Vec3(0.5, -1.0, 1.0), Vec3(2.0, 0.0, 1.0),
        Vec3(-3.0, 1.0, 1.0), Vec3(0.0, 0.0, 5.0), Vec3(1.0, 1.0, -0.25), Vec3(1.0, 20.0, 0.5)}) {
    const std::vector<double> w = weightsAt(mvc, x);
    EXPECT_LE(unityError(w), 1e-12);
    EXPECT_LE(reproductionError(*cage, w, x), 1e-12);
    for (const double rel : {1e-9, 1e-12, 1e-15}) {
      for (const Vec3& dir : {Vec3(0, 0, 1), Vec3(0, 1, 0), Vec3(1, 0, 0), Vec3(0.6, 0, -0.8)}) {
        const Vec3 y = x + rel * cage->diagonal() * dir;
        const std::vector<double> wy = weightsAt(mvc, y);
        EXPECT_LE(unityError(wy), 1e-12);
        EXPECT_LE(reproductionError(*cage, wy, y), 1e-12);
        EXPECT_LE(maxDifference(wy, w), 50.0 * rel + 2e-14);
      }
    }
  }
}

TEST(MeanValueCoordinates, NonNegativeInsideConvexCages) {
  std::mt19937_64 rng(17);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  for (const Shape& shape : shapes()) {
    if (shape.name != "tetrahedron" && shape.name != "box" && shape.name != "icosphere") continue;
    const CagePtr cage = makeCage(shape.soup, shape.name);
    const MeanValueCoordinates mvc(cage);
    int tested = 0;
    while (tested < 300) {
      const Vec3 x(2.0 * unit(rng) - 1.0, 2.0 * unit(rng) - 1.0, 2.0 * unit(rng) - 1.0);
      const bool inside = shape.name == "tetrahedron"
                              ? x.x > 0 && x.y > 0 && x.z > 0 && x.x + x.y + x.z < 1
                          : shape.name == "box" ? x.x > 0 && x.y > 0 && x.z > 0
                                                : glm::length(x) < 0.95;
      if (!inside) continue;
      ++tested;
      const std::vector<double> w = weightsAt(mvc, x);
      EXPECT_GE(*std::min_element(w.begin(), w.end()), 0.0) << shape.name;
    }
  }
}

// MVC can be negative inside a concave cage. (Inside test::star(), whose spikes are blunt, they
// happen to stay non-negative; a spikier star shows them, as does the L-shaped prism.)
TEST(MeanValueCoordinates, NegativeWeightsExistInsideConcaveCages) {
  PolygonSoup spiky = test::star();
  for (std::size_t v = 6; v < spiky.positions.size(); ++v) spiky.positions[v] *= 5.0 / 3.0;
  std::mt19937_64 rng(37);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  for (const Shape& shape : {Shape{"spiky star", spiky}, Shape{"lPrism", test::lPrism()}}) {
    const CagePtr cage = makeCage(shape.soup, shape.name);
    const MeanValueCoordinates mvc(cage);
    double most = 0.0;
    for (int i = 0; i < 400; ++i) {
      Vec3 x;
      if (shape.name == "lPrism") {  // inside the L: [0,2]x[0,1] ∪ [0,1]x[1,2], z in [0,1]
        x = Vec3(2.0 * unit(rng), 2.0 * unit(rng), unit(rng));
        if (x.x > 1.0 && x.y > 1.0) x.x -= 1.0;
      } else {  // the star is star-shaped about the origin: blend a surface point towards it
        const std::size_t t = static_cast<std::size_t>(i) % cage->triangleCount();
        double b[3] = {unit(rng), unit(rng), unit(rng)};
        const double sum = b[0] + b[1] + b[2], toward = 0.05 + 0.9 * unit(rng);
        for (double& v : b) v *= toward / sum;
        x = b[0] * corner(*cage, t, 0) + b[1] * corner(*cage, t, 1) + b[2] * corner(*cage, t, 2);
      }
      const std::vector<double> w = weightsAt(mvc, x);
      EXPECT_LE(reproductionError(*cage, w, x), 1e-12) << shape.name;
      most = std::min(most, *std::min_element(w.begin(), w.end()));
    }
    EXPECT_LT(most, -1e-4) << shape.name;
  }
}

// Far from the cage the weights grow like the distance and cancel in Σ w_i p_i: they must stay
// accurate relative to the distance, or the point is refused (InvalidInput naming it), never
// returned wrong (they were 11% off at 1e9 diagonals and summed to 3 at 1e16).
TEST_P(MeanValueShapes, FarPointsAreAccurateOrRefused) {
  const Cage& cage = *cage_;
  const BoundingBox box = boundingBox(cage.vertices());
  const Vec3 center = 0.5 * (box.min + box.max);
  std::mt19937_64 rng(5);
  std::vector<Vec3> directions = {Vec3(1, 0, 0), Vec3(0, -1, 0), Vec3(0, 0, 1)};
  for (int i = 0; i < 4; ++i) directions.push_back(randomDirection(rng));
  for (const double distance : {10.0, 1e3, 2.9e3}) {
    for (const Vec3& direction : directions) {
      const Vec3 x = center + distance * cage.diagonal() * direction;
      const std::vector<double> w = weightsAt(*mvc_, x);
      Vec3 sum(0.0);
      for (std::size_t k = 0; k < w.size(); ++k) sum += w[k] * (cage.vertices()[k] - center);
      // The weights are O(distance), so their sum is exact to about ε times that.
      EXPECT_LE(unityError(w), 1e-10 * distance) << distance;
      EXPECT_LE(glm::length(sum - (x - center)), 1e-10 * glm::length(x - center)) << distance;
    }
  }
  for (const double distance : {3.1e3, 1e6, 1e9, 1e12, 1e16, 1e30, 1e100}) {
    const Vec3 x = center + distance * cage.diagonal() * directions[3];
    std::vector<double> w(mvc_->columnCount());
    try {
      mvc_->weights(x, w);
      ADD_FAILURE() << "no error at " << distance << " diagonals";
    } catch (const InvalidInput& e) {
      EXPECT_NE(std::string(e.what()).find("cage diagonals from the cage"), std::string::npos)
          << e.what();
    }
    // The batch path refuses it too, among near points.
    const std::vector<Vec3> points = {center, x, center};
    std::vector<double> rows(points.size() * mvc_->columnCount());
    EXPECT_THROW(mvc_->weightsBatch(points, rows), InvalidInput) << distance;
  }
}

TEST_P(MeanValueShapes, PropertyKitReport) {
  const BoundingBox box = boundingBox(cage_->vertices());
  const std::vector<Vec3> samples =
      makeRandomPoints(box.min - 0.5 * box.extent(), box.max + 0.5 * box.extent(), 500, 41)
          .positions;
  const PropertyReport report = measureProperties(*mvc_, *cage_, samples);
  EXPECT_LE(report.partitionOfUnity, 1e-12);
  EXPECT_LE(report.linearReproduction, 1e-12);
  EXPECT_LE(report.lagrange, 1e-14);
  EXPECT_LE(report.faceInterpolation, 1e-12);
  EXPECT_LE(report.similarityReproduction, 1e-12);
}

TEST_P(MeanValueShapes, BatchRowsAreBitIdenticalToSingleRows) {
  const Cage& cage = *cage_;
  std::vector<Vec3> points;
  std::mt19937_64 rng(23);
  std::uniform_real_distribution<double> unit(-1.5, 1.5);
  const BoundingBox box = boundingBox(cage.vertices());
  const Vec3 center = 0.5 * (box.min + box.max);
  for (int i = 0; i < 37; ++i)
    points.push_back(center + 0.5 * box.extent() * Vec3(unit(rng), unit(rng), unit(rng)));
  for (std::size_t v = 0; v < cage.vertexCount(); v += 3) points.push_back(cage.vertices()[v]);
  points.push_back(0.5 * (corner(cage, 0, 0) + corner(cage, 0, 1)));
  points.push_back((corner(cage, 1, 0) + corner(cage, 1, 1) + corner(cage, 1, 2)) / 3.0);
  points.push_back(corner(cage, 2, 0) + 2.0 * (corner(cage, 2, 1) - corner(cage, 2, 0)) +
                   1e-13 * cage.normal(2));
  points.push_back(center + 20.0 * cage.diagonal() * Vec3(0.3, -0.5, 0.8));
  const std::size_t m = mvc_->columnCount();
  std::vector<double> batch(points.size() * m);
  mvc_->weightsBatch(points, batch);
  for (std::size_t i = 0; i < points.size(); ++i) {
    const std::vector<double> single = weightsAt(*mvc_, points[i]);
    EXPECT_EQ(std::memcmp(single.data(), batch.data() + i * m, m * sizeof(double)), 0)
        << "point " << i;
  }
}

// A well-conditioned affine map: posed = A p + t.
struct Affine {
  Mat3 a{Vec3(1.2, 0.1, -0.2), Vec3(-0.3, 0.9, 0.15), Vec3(0.05, 0.2, 1.1)};
  Vec3 t{0.5, -2.0, 3.0};
  Vec3 operator()(const Vec3& p) const { return a * p + t; }
};

TEST_P(MeanValueShapes, BindingReproducesRestAndAffinePoses) {
  const Cage& cage = *cage_;
  std::mt19937_64 rng(29);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  const BoundingBox box = boundingBox(cage.vertices());
  const Vec3 center = 0.5 * (box.min + box.max);
  std::vector<Vec3> points;
  for (int i = 0; i < 500; ++i)
    points.push_back(center + box.extent() * Vec3(unit(rng), unit(rng), unit(rng)));
  for (const Vec3& p : cage.vertices()) points.push_back(p);
  const Binding binding(mvc_, points);
  ASSERT_FALSE(binding.isSparse());

  const std::vector<Vec3> rest(cage.vertices().begin(), cage.vertices().end());
  const std::vector<Vec3> same = binding.deform(rest);
  for (std::size_t i = 0; i < points.size(); ++i)
    EXPECT_LE(glm::length(same[i] - points[i]) / cage.diagonal(), 1e-12) << i;

  const Affine map;
  std::vector<Vec3> posed;
  for (const Vec3& p : cage.vertices()) posed.push_back(map(p));
  const std::vector<Vec3> moved = binding.deform(posed);
  const CoordinateWarp warp(mvc_, posed);
  for (std::size_t i = 0; i < points.size(); ++i) {
    EXPECT_LE(glm::length(moved[i] - map(points[i])) / cage.diagonal(), 1e-12) << i;
    if (i % 10 == 0) {
      EXPECT_LE(glm::length(warp.apply(points[i]) - moved[i]) / cage.diagonal(), 1e-12) << i;
    }
  }
}

TEST_P(MeanValueShapes, BindingIsIndependentOfTheThreadCount) {
  const Cage& cage = *cage_;
  std::mt19937_64 rng(31);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  const BoundingBox box = boundingBox(cage.vertices());
  std::vector<Vec3> points;
  for (int i = 0; i < 3000; ++i)
    points.push_back(0.5 * (box.min + box.max) +
                     box.extent() * Vec3(unit(rng), unit(rng), unit(rng)));
  std::vector<Vec3> posed;
  for (const Vec3& p : cage.vertices())
    posed.push_back(p + 0.1 * Vec3(unit(rng), unit(rng), unit(rng)));

  auto run = [&](int threads, Binding::DenseMatrix& w, std::vector<Vec3>& out) {
    tbb::task_arena arena(threads);
    arena.execute([&] {
      const Binding binding(mvc_, points);
      w = binding.dense();
      out = binding.deform(posed);
    });
  };
  Binding::DenseMatrix w1, w2;
  std::vector<Vec3> out1, out2;
  run(1, w1, out1);
  run(2, w2, out2);
  ASSERT_EQ(w1.size(), w2.size());
  EXPECT_EQ(std::memcmp(w1.data(), w2.data(), static_cast<std::size_t>(w1.size()) * sizeof(double)),
            0);
  ASSERT_EQ(out1.size(), out2.size());
  EXPECT_EQ(std::memcmp(out1.data(), out2.data(), out1.size() * sizeof(Vec3)), 0);
}

INSTANTIATE_TEST_SUITE_P(Cages, MeanValueShapes, ::testing::ValuesIn(shapes()),
                         [](const ::testing::TestParamInfo<Shape>& info) {
                           return info.param.name;
                         });

// ---- the Ju et al. armadillo (optional shared data) ----

std::filesystem::path armadilloDir() {
  return std::filesystem::path(SPACEWARP_SHARED_DATA_DIR) / "ju2005-armadillo";
}

TEST(MeanValueArmadillo, ModelWeightsReproduceTheModel) {
  const auto dir = armadilloDir();
  if (!std::filesystem::exists(dir / "bounding_mesh.obj"))
    GTEST_SKIP() << "shared data not found: " << dir;
  const auto cage = std::make_shared<const Cage>(Cage::fromFile(dir / "bounding_mesh.obj"));
  const auto mvc = std::make_shared<const MeanValueCoordinates>(cage);
  const PolygonSoup model = readSoup(dir / "armadilloman.obj");
  const Binding binding(mvc, model.positions);
  const auto& w = binding.dense();
  double worstUnity = 0.0, worstRepro = 0.0;
  for (std::size_t i = 0; i < model.positions.size(); ++i) {
    const std::vector<double> row(w.row(static_cast<Eigen::Index>(i)).data(),
                                  w.row(static_cast<Eigen::Index>(i)).data() + w.cols());
    worstUnity = std::max(worstUnity, unityError(row));
    worstRepro = std::max(worstRepro, reproductionError(*cage, row, model.positions[i]));
  }
  EXPECT_LE(worstUnity, 1e-12);
  EXPECT_LE(worstRepro, 1e-12);
}

TEST(MeanValueArmadillo, PosedCagesGiveFinitePositions) {
  const auto dir = armadilloDir();
  if (!std::filesystem::exists(dir / "bounding_mesh.obj"))
    GTEST_SKIP() << "shared data not found: " << dir;
  const auto cage = std::make_shared<const Cage>(Cage::fromFile(dir / "bounding_mesh.obj"));
  const auto mvc = std::make_shared<const MeanValueCoordinates>(cage);
  const PolygonSoup model = readSoup(dir / "armadilloman.obj");
  const Binding binding(mvc, model.positions);
  const std::vector<std::string> poses = {
      "deformed_bounding_mesh2.obj", "deformed_bounding_mesh3.obj", "deformed_bounding_mesh4.obj",
      "deformed_bounding_mesh5.obj", "deformed_bounding_mesh6.obj", "deformed_bounding_mesh8.obj",
      "deformed_bounding_mesh9.obj", "deformed_fixed_1.obj",        "deformed_fixed_7.obj",
      "deformed_fixed_10.obj"};
  for (const std::string& pose : poses) {
    const std::vector<Vec3> posed = cage->posedVerticesFromFile(dir / pose);
    const std::vector<Vec3> out = binding.deform(posed);
    ASSERT_EQ(out.size(), model.positions.size());
    BoundingBox posedBox;
    for (const Vec3& p : posed) {
      posedBox.min = glm::min(posedBox.min, p);
      posedBox.max = glm::max(posedBox.max, p);
    }
    std::size_t bad = 0;
    for (const Vec3& p : out) {
      // Finite, and not thrown far outside the posed cage.
      if (!isFinite(p) ||
          glm::length(glm::clamp(p, posedBox.min, posedBox.max) - p) > 0.5 * posedBox.diagonal())
        ++bad;
    }
    EXPECT_EQ(bad, 0u) << pose;
  }
}

}  // namespace
}  // namespace spacewarp
