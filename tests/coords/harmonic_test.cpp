#include <spacewarp/coords/harmonic.h>

#include <unistd.h>
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <memory>
#include <ostream>
#include <random>
#include <set>
#include <string>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <tbb/task_arena.h>

#include <spacewarp/coords/mean_value.h>
#include <spacewarp/coords/properties.h>
#include <spacewarp/coords/tet_locator.h>
#include <spacewarp/coords/tet_mesh.h>
#include <spacewarp/core/binding.h>
#include <spacewarp/core/coordinate_warp.h>
#include <spacewarp/core/detail/memory_budget.h>
#include <spacewarp/core/errors.h>
#include <spacewarp/core/io/mesh_io.h>
#include <spacewarp/core/primitives.h>
#include "coords_test_shapes.h"
#include "test_util.h"

namespace spacewarp {
namespace {

using ::testing::HasSubstr;
using CagePtr = std::shared_ptr<const Cage>;
using HarmonicPtr = std::shared_ptr<const HarmonicCoordinates>;

// Small meshes keep the suite fast (a few thousand tets solve in milliseconds).
constexpr std::size_t kTets = 3000;

struct Shape {
  std::string name;
  PolygonSoup soup;
};
void PrintTo(const Shape& shape, std::ostream* os) { *os << shape.name; }

std::vector<Shape> shapes() {
  return {{"tetrahedron", test::tetrahedron()},
          {"box2", makeBoxSurface(Vec3(-1.0, 0.0, 2.0), Vec3(1.0, 2.0, 5.0), {2, 3, 1})},
          {"lPrism", test::lPrism()},
          {"star", test::star()},
          {"icosphere", test::icosphere(1)}};
}

CagePtr makeCage(const PolygonSoup& soup, const std::string& name) {
  return std::make_shared<const Cage>(soup, name);
}

HarmonicPtr solve(const CagePtr& cage, std::size_t tets = kTets,
                  HarmonicOutsidePolicy outside = HarmonicOutsidePolicy::Throw) {
  HarmonicOptions options;
  options.targetTetCount = tets;
  options.outside = outside;
  return std::make_shared<const HarmonicCoordinates>(cage, options);
}

std::vector<double> weightsAt(const Coordinates& c, const Vec3& x) {
  std::vector<double> w(c.columnCount());
  c.weights(x, w);
  return w;
}

// n random points inside the cage (the mesh covers exactly the cage's interior).
std::vector<Vec3> insidePoints(const HarmonicCoordinates& h, std::size_t n, std::uint64_t seed) {
  const BoundingBox box = boundingBox(h.cage().vertices());
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::vector<Vec3> points;
  while (points.size() < n) {
    const Vec3 x = box.min + box.extent() * Vec3(unit(rng), unit(rng), unit(rng));
    if (h.locate(x).found) points.push_back(x);
  }
  return points;
}

bool insideLPrism(const Vec3& x) {
  return x.z > 0.0 && x.z < 1.0 && x.x > 0.0 && x.y > 0.0 &&
         ((x.x < 2.0 && x.y < 1.0) || (x.x < 1.0 && x.y < 2.0));
}

class HarmonicShapes : public ::testing::TestWithParam<Shape> {
 protected:
  void SetUp() override {
    // One solve per shape for the whole suite.
    static std::map<std::string, std::pair<CagePtr, HarmonicPtr>> cache;
    auto& entry = cache[GetParam().name];
    if (!entry.second) {
      entry.first = makeCage(GetParam().soup, GetParam().name);
      entry.second = solve(entry.first);
    }
    cage_ = entry.first;
    harmonic_ = entry.second;
  }
  CagePtr cage_;
  HarmonicPtr harmonic_;
};

TEST_P(HarmonicShapes, MeshConformsToTheCage) {
  const TetMesh& mesh = harmonic_->mesh();
  ASSERT_GE(mesh.vertices.size(), cage_->vertexCount());
  for (std::size_t i = 0; i < cage_->vertexCount(); ++i)
    EXPECT_EQ(mesh.vertices[i], cage_->vertices()[i]);
  double volume = 0.0;
  for (const auto& tet : mesh.tets) {
    const Vec3 p0 = mesh.vertices[tet[0]];
    const double det = glm::dot(mesh.vertices[tet[1]] - p0,
                                glm::cross(mesh.vertices[tet[2]] - p0, mesh.vertices[tet[3]] - p0));
    EXPECT_GT(det, 0.0);
    volume += det / 6.0;
  }
  EXPECT_NEAR(volume, cage_->volume(), 1e-12 * cage_->volume());
  // Roughly the requested size.
  EXPECT_GT(mesh.tets.size(), kTets / 3);
  EXPECT_LT(mesh.tets.size(), kTets * 3);
}

TEST_P(HarmonicShapes, PropertyKitReport) {
  const std::vector<Vec3> samples = insidePoints(*harmonic_, 500, 41);
  const PropertyReport report = measureProperties(*harmonic_, *cage_, samples);
  EXPECT_LE(report.partitionOfUnity, 1e-10);
  EXPECT_LE(report.linearReproduction, 1e-9);
  EXPECT_GE(report.minWeight, -1e-12);
  EXPECT_LE(report.lagrange, 1e-12);
  EXPECT_LE(report.faceInterpolation, 1e-12);
  EXPECT_LE(report.similarityReproduction, 1e-9);
  double most = 0.0;
  for (const Vec3& x : samples) {
    const std::vector<double> w = weightsAt(*harmonic_, x);
    most = std::max(most, *std::max_element(w.begin(), w.end()));
  }
  EXPECT_LE(most, 1.0 + 1e-12);
}

TEST_P(HarmonicShapes, VertexValuesAreBoundedAndLinearlyPrecise) {
  const std::size_t k = cage_->vertexCount();
  const auto values = harmonic_->vertexValues();
  const TetMesh& mesh = harmonic_->mesh();
  ASSERT_EQ(values.size(), mesh.vertices.size() * k);
  for (std::size_t v = 0; v < mesh.vertices.size(); ++v) {
    double sum = 0.0;
    Vec3 x(0.0);
    for (std::size_t c = 0; c < k; ++c) {
      const double w = values[v * k + c];
      ASSERT_GE(w, -1e-12) << "mesh vertex " << v;
      ASSERT_LE(w, 1.0 + 1e-12) << "mesh vertex " << v;
      sum += w;
      x += w * cage_->vertices()[c];
    }
    ASSERT_NEAR(sum, 1.0, 1e-10) << "mesh vertex " << v;
    ASSERT_LE(glm::length(x - mesh.vertices[v]), 1e-9 * cage_->diagonal()) << "mesh vertex " << v;
  }
}

TEST_P(HarmonicShapes, LagrangeAtVerticesAndLinearOnFaces) {
  const std::size_t k = cage_->vertexCount();
  for (std::size_t i = 0; i < k; ++i) {
    const std::vector<double> w = weightsAt(*harmonic_, cage_->vertices()[i]);
    for (std::size_t j = 0; j < k; ++j) EXPECT_NEAR(w[j], i == j ? 1.0 : 0.0, 1e-12);
  }
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  for (std::size_t t = 0; t < cage_->triangleCount(); ++t) {
    const Triangle& tri = cage_->triangles()[t];
    double b[3] = {unit(rng), unit(rng), unit(rng)};
    const double s = b[0] + b[1] + b[2];
    for (double& v : b) v /= s;
    const Vec3 x = b[0] * cage_->vertices()[tri.x] + b[1] * cage_->vertices()[tri.y] +
                   b[2] * cage_->vertices()[tri.z];
    std::vector<double> expected(k, 0.0);
    expected[tri.x] += b[0];
    expected[tri.y] += b[1];
    expected[tri.z] += b[2];
    const std::vector<double> w = weightsAt(*harmonic_, x);
    for (std::size_t j = 0; j < k; ++j) EXPECT_NEAR(w[j], expected[j], 1e-12) << "triangle " << t;
  }
}

TEST_P(HarmonicShapes, BatchRowsAreBitIdenticalToSingleRowsForAnyThreadCount) {
  const std::vector<Vec3> points = insidePoints(*harmonic_, 2000, 5);
  const std::size_t k = cage_->vertexCount();
  auto batch = [&](int threads) {
    std::vector<double> rows(points.size() * k);
    tbb::task_arena arena(threads);
    arena.execute([&] { harmonic_->weightsBatch(points, rows); });
    return rows;
  };
  const std::vector<double> one = batch(1), two = batch(2);
  EXPECT_EQ(std::memcmp(one.data(), two.data(), one.size() * sizeof(double)), 0);
  for (std::size_t i = 0; i < points.size(); i += 97) {
    const std::vector<double> w = weightsAt(*harmonic_, points[i]);
    EXPECT_EQ(std::memcmp(w.data(), one.data() + i * k, k * sizeof(double)), 0) << i;
  }
}

TEST_P(HarmonicShapes, AffinePosesAreReproducedWithTheirJacobian) {
  const Mat3 a(Vec3(1.2, 0.1, -0.2), Vec3(0.3, 0.9, 0.1), Vec3(-0.1, 0.2, 1.1));
  const Vec3 t(0.3, -0.4, 0.5);
  std::vector<Vec3> posed;
  for (const Vec3& p : cage_->vertices()) posed.push_back(a * p + t);
  const std::vector<Vec3> points = insidePoints(*harmonic_, 300, 9);
  const Binding binding(harmonic_, points);
  EXPECT_FALSE(binding.isSparse());
  const std::vector<Vec3> out = binding.deform(posed);
  const CoordinateWarp warp(harmonic_, posed);
  for (std::size_t i = 0; i < points.size(); ++i) {
    EXPECT_LE(glm::length(out[i] - (a * points[i] + t)), 1e-9 * cage_->diagonal());
    EXPECT_LE(test::frobenius(warp.jacobian(points[i]) - a), 1e-8);
  }
}

INSTANTIATE_TEST_SUITE_P(Cages, HarmonicShapes, ::testing::ValuesIn(shapes()),
                         [](const ::testing::TestParamInfo<Shape>& info) {
                           return info.param.name;
                         });

TEST(HarmonicCoordinates, RejectsANullCageAndBadOptions) {
  EXPECT_THAT(test::messageOf<InvalidInput>([] { HarmonicCoordinates h(nullptr); }),
              HasSubstr("null"));
  const CagePtr cage = makeCage(test::tetrahedron(), "tet");
  HarmonicOptions options;
  options.maxTetVolumeFraction = 2.0;
  EXPECT_THAT(test::messageOf<InvalidInput>([&] { HarmonicCoordinates h(cage, options); }),
              HasSubstr("maxTetVolumeFraction"));
  options = {};
  options.targetTetCount = 0;
  EXPECT_THAT(test::messageOf<InvalidInput>([&] { HarmonicCoordinates h(cage, options); }),
              HasSubstr("targetTetCount"));
  options = {};
  options.radiusEdgeRatio = 0.5;
  EXPECT_THAT(test::messageOf<InvalidInput>([&] { HarmonicCoordinates h(cage, options); }),
              HasSubstr("radiusEdgeRatio"));
}

// The memory estimate grows with the tet count and the cage, and refuses before meshing: a
// billion tets would take TetGen hours and terabytes.
TEST(HarmonicCoordinates, RefusesAMeshTooLargeForTheMemoryBeforeMeshing) {
  const CagePtr cage = makeCage(test::icosphere(1), "icosphere");
  HarmonicOptions small, large, absurd;
  small.targetTetCount = kTets;
  large.targetTetCount = 2000000;
  absurd.targetTetCount = 1000000000;
  const double smallBytes = HarmonicCoordinates::memoryEstimate(*cage, small);
  EXPECT_GT(smallBytes, 1e6);
  EXPECT_LT(smallBytes, 2e8);  // with OpenBLAS's 135 MB work buffer
  EXPECT_GT(HarmonicCoordinates::memoryEstimate(*cage, large), 2e9);
  EXPECT_GT(HarmonicCoordinates::memoryEstimate(*cage, absurd), 1e13);
  const auto start = std::chrono::steady_clock::now();
  const std::string message =
      test::messageOf<InvalidInput>([&] { HarmonicCoordinates h(cage, absurd); });
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(), 5.0);
  EXPECT_THAT(message, HasSubstr("HarmonicCoordinates: meshing the cage (42 vertices) into about "
                                 "1000000"));
  EXPECT_THAT(message, HasSubstr("TB of memory, more than the"));
  // Under a cap, a mesh that fits runs and one that does not is refused.
  detail::setMemoryCap(std::size_t{400} << 20);
  EXPECT_NO_THROW(HarmonicCoordinates(cage, small));
  EXPECT_THAT(test::messageOf<InvalidInput>([&] { HarmonicCoordinates h(cage, large); }),
              HasSubstr("needs about"));
  detail::setMemoryCap(std::numeric_limits<std::size_t>::max());
}

TEST(HarmonicCoordinates, MaxTetVolumeFractionControlsTheResolution) {
  const CagePtr cage = makeCage(test::icosphere(1), "icosphere");
  HarmonicOptions options;
  options.maxTetVolumeFraction = 1e-3;
  const HarmonicCoordinates h(cage, options);
  EXPECT_DOUBLE_EQ(h.meshVolumeBound(), 1e-3 * cage->volume());
  for (const auto& tet : h.mesh().tets) {
    const Vec3 p0 = h.mesh().vertices[tet[0]];
    const double volume =
        glm::dot(h.mesh().vertices[tet[1]] - p0,
                 glm::cross(h.mesh().vertices[tet[2]] - p0, h.mesh().vertices[tet[3]] - p0)) /
        6.0;
    ASSERT_LE(volume, 1e-3 * cage->volume() * (1 + 1e-9));
  }
  EXPECT_GT(h.mesh().tets.size(), 1000u);
}

// At fixed interior points, successive refinements change the coordinates less and less.
TEST(HarmonicCoordinates, RefinementConverges) {
  const CagePtr cage = makeCage(test::lPrism(), "lPrism");
  std::vector<Vec3> points;
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> unit(0.0, 2.0);
  while (points.size() < 200) {
    const Vec3 x(unit(rng), unit(rng), 0.5 * unit(rng));
    if (insideLPrism(x)) points.push_back(x);
  }
  std::vector<std::vector<double>> rows;
  for (const std::size_t tets : {500u, 4000u, 32000u}) {
    const HarmonicPtr h = solve(cage, tets);
    rows.emplace_back(points.size() * cage->vertexCount());
    h->weightsBatch(points, rows.back());
  }
  auto difference = [](const std::vector<double>& a, const std::vector<double>& b) {
    double d = 0.0;
    for (std::size_t i = 0; i < a.size(); ++i) d += (a[i] - b[i]) * (a[i] - b[i]);
    return std::sqrt(d / static_cast<double>(a.size()));
  };
  const double coarse = difference(rows[0], rows[1]), fine = difference(rows[1], rows[2]);
  EXPECT_LT(fine, 0.75 * coarse) << coarse << " then " << fine;
}

// Mean-value coordinates go negative inside the L-shaped prism; harmonic ones do not.
TEST(HarmonicCoordinates, NonNegativeWhereMeanValueCoordinatesAreNegative) {
  const CagePtr cage = makeCage(test::lPrism(), "lPrism");
  const MeanValueCoordinates mvc(cage);
  const HarmonicPtr h = solve(cage);
  std::mt19937_64 rng(37);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  int negative = 0;
  for (int i = 0; i < 2000; ++i) {
    Vec3 x(2.0 * unit(rng), 2.0 * unit(rng), unit(rng));
    if (x.x > 1.0 && x.y > 1.0) x.x -= 1.0;
    if (!insideLPrism(x)) continue;
    const std::vector<double> m = weightsAt(mvc, x);
    if (*std::min_element(m.begin(), m.end()) >= -1e-4) continue;
    ++negative;
    const std::vector<double> w = weightsAt(*h, x);
    EXPECT_GE(*std::min_element(w.begin(), w.end()), -1e-12) << test::toString(x);
  }
  EXPECT_GT(negative, 10);
}

TEST(HarmonicCoordinates, RejectsASelfIntersectingCage) {
  // A box whose corner (1, 1, 1) is pushed through its bottom face: closed, oriented, with a
  // positive volume, but its faces intersect.
  PolygonSoup soup = makeBoxSurface(Vec3(0.0), Vec3(1.0), {1, 1, 1});
  std::size_t corner = 0;
  for (std::size_t i = 0; i < soup.positions.size(); ++i)
    if (soup.positions[i] == Vec3(1.0)) corner = i;
  soup.positions[corner] = Vec3(0.2, 0.2, -0.5);
  const CagePtr cage = makeCage(soup, "crossed box");
  const std::string message =
      test::messageOf<InvalidInput>([&] { HarmonicCoordinates h(cage, HarmonicOptions{}); });
  EXPECT_THAT(message, HasSubstr("intersects itself"));
  EXPECT_THAT(message, HasSubstr("triangle"));
}

TEST(HarmonicCoordinates, TetGenDyingIsASolverErrorNamingTheCage) {
  // Debian's TetGen 1.5.0 fails an assertion (and would abort the process) on this cage at 10k
  // tets; it runs in a child process, so the caller gets an exception and can go on.
  const CagePtr cage = makeCage(test::pinchedBox(0.4), "pinched.obj");
  HarmonicOptions options;
  options.targetTetCount = 10000;
  try {
    const HarmonicCoordinates harmonic(cage, options);
    GTEST_SKIP() << "this TetGen meshes the cage: nothing to test";
  } catch (const SolverError& e) {
    EXPECT_THAT(e.what(), HasSubstr("pinched.obj: tetrahedralising the cage: TetGen died"));
    EXPECT_THAT(e.what(), HasSubstr("Assertion"));
    EXPECT_THAT(e.what(), HasSubstr("tet count"));
  }
  options.targetTetCount = 5000;
  const HarmonicCoordinates next(cage, options);
  EXPECT_GT(next.mesh().tets.size(), 1000u);
}

TEST(HarmonicCoordinates, OutsidePointsRaiseWithTheirCount) {
  const CagePtr cage = makeCage(test::lPrism(), "lPrism");
  const HarmonicPtr h = solve(cage);
  std::vector<double> row(cage->vertexCount());
  EXPECT_THAT(test::messageOf<InvalidInput>([&] { h->weights(Vec3(1.5, 1.5, 0.5), row); }),
              HasSubstr("1 point is outside the cage"));
  const std::vector<Vec3> points = {Vec3(0.5, 0.5, 0.5), Vec3(1.5, 1.5, 0.5), Vec3(0.5), Vec3(5.0),
                                    Vec3(-1.0, 0.5, 0.5)};
  std::vector<double> rows(points.size() * cage->vertexCount());
  const std::string message = test::messageOf<InvalidInput>([&] { h->weightsBatch(points, rows); });
  EXPECT_THAT(message, HasSubstr("3 of 5 points are outside the cage"));
  EXPECT_THAT(message, HasSubstr("point 1"));
  std::vector<Vec3> gradients(cage->vertexCount());
  EXPECT_FALSE(h->weightGradients(Vec3(5.0), gradients));
  EXPECT_TRUE(h->weightGradients(Vec3(0.5), gradients));
}

TEST(HarmonicCoordinates, OutsidePointsCanTakeTheNearestPointsCoordinates) {
  const CagePtr cage = makeCage(test::lPrism(), "lPrism");
  const HarmonicPtr h = solve(cage, kTets, HarmonicOutsidePolicy::NearestPoint);
  const std::pair<Vec3, Vec3> cases[] = {
      {Vec3(0.5, 0.25, -0.3), Vec3(0.5, 0.25, 0.0)},   // below the bottom face
      {Vec3(1.5, 1.25, 0.5), Vec3(1.5, 1.0, 0.5)},     // in the notch, nearest the notch wall
      {Vec3(3.0, -1.0, 0.25), Vec3(2.0, 0.0, 0.25)},   // beyond a vertical edge
      {Vec3(-1.0, -1.0, -1.0), Vec3(0.0, 0.0, 0.0)}};  // beyond a corner
  for (const auto& [x, nearest] : cases) {
    const std::vector<double> w = weightsAt(*h, x), expected = weightsAt(*h, nearest);
    for (std::size_t j = 0; j < w.size(); ++j) EXPECT_NEAR(w[j], expected[j], 1e-12) << j;
    Vec3 reproduced(0.0);
    for (std::size_t j = 0; j < w.size(); ++j) reproduced += w[j] * cage->vertices()[j];
    EXPECT_LE(glm::length(reproduced - nearest), 1e-12);
  }
}

TEST(HarmonicCoordinates, SolveIsIndependentOfTheThreadCount) {
  const CagePtr cage = makeCage(test::star(), "star");
  auto run = [&](int threads) {
    HarmonicPtr h;
    tbb::task_arena arena(threads);
    arena.execute([&] { h = solve(cage); });
    return h;
  };
  const HarmonicPtr one = run(1), two = run(2);
  ASSERT_EQ(one->vertexValues().size(), two->vertexValues().size());
  EXPECT_EQ(std::memcmp(one->vertexValues().data(), two->vertexValues().data(),
                        one->vertexValues().size() * sizeof(double)),
            0);
  const std::vector<Vec3> points = insidePoints(*one, 500, 8);
  std::vector<double> a(points.size() * cage->vertexCount()), b(a.size());
  one->weightsBatch(points, a);
  two->weightsBatch(points, b);
  EXPECT_EQ(std::memcmp(a.data(), b.data(), a.size() * sizeof(double)), 0);
}

TEST(HarmonicCoordinates, SolveIsIndependentOfTheBlasThreadCount) {
  const test::OpenBlasThreads blas;
  if (!blas.available()) GTEST_SKIP() << "the BLAS in this process is not OpenBLAS";
  // Big enough for OpenBLAS to split the supernodes' work between threads.
  const CagePtr cage = makeCage(test::icosphere(2), "icosphere");
  HarmonicOptions options;
  options.targetTetCount = 60000;
  const int previous = blas.get();
  auto run = [&](int threads) {
    blas.set(threads);
    auto h = std::make_shared<const HarmonicCoordinates>(cage, options);
    EXPECT_EQ(blas.get(), threads);  // the caller's setting is restored
    return h;
  };
  const auto one = run(1), two = run(2), four = run(4);
  blas.set(previous);
  ASSERT_EQ(one->vertexValues().size(), two->vertexValues().size());
  EXPECT_EQ(std::memcmp(one->vertexValues().data(), two->vertexValues().data(),
                        one->vertexValues().size() * sizeof(double)),
            0);
  EXPECT_EQ(std::memcmp(one->vertexValues().data(), four->vertexValues().data(),
                        one->vertexValues().size() * sizeof(double)),
            0);
}

TEST(HarmonicCoordinates, ReportsProgressAndCancels) {
  const CagePtr cage = makeCage(test::star(), "star");
  std::set<std::string> stages;
  HarmonicOptions options;
  options.targetTetCount = kTets;
  const HarmonicCoordinates h(cage, options, [&](std::string_view stage, double) {
    stages.insert(std::string(stage));
    return true;
  });
  EXPECT_EQ(stages, (std::set<std::string>{"tetrahedralise", "factorise", "solve"}));
  for (const std::string cancelAt : {"tetrahedralise", "factorise", "solve"}) {
    EXPECT_THROW(
        HarmonicCoordinates(cage, options,
                            [&](std::string_view stage, double) { return stage != cancelAt; }),
        Cancelled)
        << cancelAt;
  }
}

// A cancel while TetGen meshes (in its own process) is seen by the parent's polls: the child is
// killed, not waited for. The mesh asked for here (about 5M tets) would take a minute or more;
// the cancel comes at the fourth report of the meshing stage, i.e. within its first second.
TEST(TetMesh, CancelStopsTetGenWhileItMeshes) {
  const CagePtr cage = makeCage(test::star(), "star");
  int reports = 0;
  EXPECT_THROW(tetrahedraliseCage(*cage, {2.0, cage->volume() / 5e6},
                                  [&](std::string_view, double) { return ++reports < 4; }),
               Cancelled);
  EXPECT_EQ(reports, 4);
}

TEST(TetLocator, FindsTheContainingTetOrNone) {
  const std::vector<Vec3> vertices = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0), Vec3(0, 0, 1),
                                      Vec3(1, 1, 1)};
  const std::vector<std::array<std::uint32_t, 4>> tets = {{0, 1, 2, 3}, {1, 2, 3, 4}};
  // The second tet: orient it positively.
  std::vector<std::array<std::uint32_t, 4>> oriented = tets;
  {
    const Vec3 p0 = vertices[1];
    if (glm::dot(vertices[2] - p0, glm::cross(vertices[3] - p0, vertices[4] - p0)) < 0)
      std::swap(oriented[1][2], oriented[1][3]);
  }
  const TetLocator locator(vertices, oriented);
  const TetLocator::Hit a = locator.locate(Vec3(0.1, 0.2, 0.3));
  ASSERT_TRUE(a.found);
  EXPECT_EQ(a.tet, 0u);
  EXPECT_NEAR(a.barycentric[0], 0.4, 1e-15);
  EXPECT_NEAR(a.barycentric[1], 0.1, 1e-15);
  const TetLocator::Hit b = locator.locate(Vec3(0.5, 0.5, 0.5));
  ASSERT_TRUE(b.found);
  EXPECT_EQ(b.tet, 1u);
  EXPECT_FALSE(locator.locate(Vec3(-0.1, 0.2, 0.3)).found);
  EXPECT_FALSE(locator.locate(Vec3(2.0)).found);
}

TEST(TetLocator, NeverFindsAFlatTet) {
  // Tet 0 is flat (its fourth corner 1e-300 above the plane of the others, so its determinant
  // is positive but pure round-off); tet 1 is a real tet below that plane. A point on the plane
  // inside both is in tet 1.
  const std::vector<Vec3> vertices = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0),
                                      Vec3(0.3, 0.3, 1e-300), Vec3(0, 0, -1)};
  const std::vector<std::array<std::uint32_t, 4>> tets = {{0, 1, 2, 3}, {0, 2, 1, 4}};
  EXPECT_TRUE(isFlatTet(vertices[0], vertices[1], vertices[2], vertices[3]));
  EXPECT_FALSE(isFlatTet(vertices[0], vertices[2], vertices[1], vertices[4]));
  const TetLocator locator(vertices, tets);
  const TetLocator::Hit hit = locator.locate(Vec3(0.2, 0.1, 0.0));
  ASSERT_TRUE(hit.found);
  EXPECT_EQ(hit.tet, 1u);
  EXPECT_NEAR(hit.barycentric[0], 0.7, 1e-15);
  EXPECT_NEAR(hit.barycentric[1], 0.1, 1e-15);
  EXPECT_NEAR(hit.barycentric[2], 0.2, 1e-15);
  EXPECT_EQ(hit.barycentric[3], 0.0);
}

TEST(TetLocator, FlatnessIsRelativeToTheTetsSizeAndPlace) {
  // The same thin tet (height 1e-9 of its size) is real at any scale and offset; its height
  // at the round-off of its coordinates (1e-16 of them) is flat.
  for (const double scale : {1e-6, 1.0, 1e6}) {
    for (const double offset : {0.0, 1e3}) {
      auto at = [&](double x, double y, double z) { return scale * (Vec3(x, y, z) + offset); };
      EXPECT_FALSE(isFlatTet(at(0, 0, 0), at(1, 0, 0), at(0, 1, 0), at(0.3, 0.3, 1e-9)))
          << scale << " " << offset;
      EXPECT_TRUE(
          isFlatTet(at(0, 0, 0), at(1, 0, 0), at(0, 1, 0), at(0.3, 0.3, 1e-16 * (1.0 + offset))))
          << scale << " " << offset;
    }
  }
}

// ---- concave cages: the Lagrange property at every vertex ----
//
// TetGen rounds the Steiner points it puts on a slanted cage face off the face's plane, and
// leaves flat tets (volume at round-off) between them. Barycentric coordinates in those are
// round-off too: the locator found points of the face in them, and the pinched box's waist
// vertex 5 (waist 0.4, at 5000 and 200k tets) got vertex 6's row.

struct ConcaveCase {
  std::string name;
  PolygonSoup soup;
  std::size_t tets;
};
void PrintTo(const ConcaveCase& c, std::ostream* os) { *os << c.name << "_" << c.tets; }

std::vector<ConcaveCase> concaveCases() {
  const std::vector<Shape> cages = {{"pinched04", test::pinchedBox(0.4)},
                                    {"pinched03", test::pinchedBox(0.3)},
                                    {"pinched055", test::pinchedBox(0.55)},
                                    {"pinched065", test::pinchedBox(0.65)},
                                    {"lPrism", test::lPrism()},
                                    {"star", test::star()}};
  std::vector<ConcaveCase> cases;
  for (const Shape& cage : cages)
    for (const std::size_t tets : {1000u, 3000u, 5000u, 8000u})
      cases.push_back({cage.name, cage.soup, tets});
  return cases;
}

class HarmonicConcave : public ::testing::TestWithParam<ConcaveCase> {
 protected:
  void SetUp() override {
    static std::map<std::string, std::pair<CagePtr, HarmonicPtr>> cache;
    const std::string key = GetParam().name + "_" + std::to_string(GetParam().tets);
    auto& entry = cache[key];
    if (!entry.second) {
      entry.first = makeCage(GetParam().soup, GetParam().name);
      entry.second = solve(entry.first, GetParam().tets);
    }
    cage_ = entry.first;
    harmonic_ = entry.second;
  }
  CagePtr cage_;
  HarmonicPtr harmonic_;
};

// The largest |w_j − δ_ij| over j.
double distanceFromVertexRow(const std::vector<double>& w, std::size_t i) {
  double most = 0.0;
  for (std::size_t j = 0; j < w.size(); ++j)
    most = std::max(most, std::abs(w[j] - (i == j ? 1.0 : 0.0)));
  return most;
}

TEST_P(HarmonicConcave, LagrangeAtEveryVertex) {
  for (std::size_t i = 0; i < cage_->vertexCount(); ++i)
    EXPECT_LE(distanceFromVertexRow(weightsAt(*harmonic_, cage_->vertices()[i]), i), 1e-12)
        << "cage vertex " << i;
}

TEST_P(HarmonicConcave, WeightsJustInsideAVertexTendToItsRow) {
  // Towards the centroid of every (non-flat) mesh tet at the vertex, so inside that tet, where
  // the weights are linear in the distance: 1000 times closer, 1000 times nearer δ (up to the
  // round-off of the points, ~1e-16 times the barycentric gradients of small tets).
  const TetMesh& mesh = harmonic_->mesh();
  const double diagonal = cage_->diagonal();
  std::vector<std::size_t> tested(cage_->vertexCount(), 0);
  for (const auto& tet : mesh.tets) {
    const std::array<Vec3, 4> p = {mesh.vertices[tet[0]], mesh.vertices[tet[1]],
                                   mesh.vertices[tet[2]], mesh.vertices[tet[3]]};
    if (isFlatTet(p[0], p[1], p[2], p[3])) continue;
    for (std::size_t a = 0; a < 4; ++a) {
      const std::size_t i = tet[a];
      if (i >= cage_->vertexCount()) continue;
      ++tested[i];
      const Vec3 towards = glm::normalize((p[0] + p[1] + p[2] + p[3]) / 4.0 - p[a]);
      double previous = 0.0;
      for (const double distance : {1e-6, 1e-9}) {
        const Vec3 x = cage_->vertices()[i] + distance * diagonal * towards;
        const double error = distanceFromVertexRow(weightsAt(*harmonic_, x), i);
        EXPECT_LE(error, 1e4 * distance) << "cage vertex " << i << " at " << distance;
        if (distance < 1e-6) {
          EXPECT_LE(error, 1e-3 * previous * (1.0 + 1e-3) + 1e-12)
              << "cage vertex " << i << " at " << distance;
        }
        previous = error;
      }
    }
  }
  for (std::size_t i = 0; i < cage_->vertexCount(); ++i)
    EXPECT_GT(tested[i], 0u) << "cage vertex " << i;
}

INSTANTIATE_TEST_SUITE_P(HarmonicConcaveCages, HarmonicConcave, ::testing::ValuesIn(concaveCases()),
                         [](const auto& info) {
                           return info.param.name + "_" + std::to_string(info.param.tets);
                         });

TEST(HarmonicPinchedBox, LagrangeAtTheDefaultResolution) {
  // The reported case: default options (about 200k tets), waist 0.4.
  const CagePtr cage = makeCage(test::pinchedBox(0.4), "pinched");
  const HarmonicCoordinates harmonic(cage);
  for (std::size_t i = 0; i < cage->vertexCount(); ++i)
    EXPECT_LE(distanceFromVertexRow(weightsAt(harmonic, cage->vertices()[i]), i), 1e-12)
        << "cage vertex " << i;
}

// ---- saving and loading ----

class HarmonicFiles : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = std::filesystem::temp_directory_path() /
           ("spacewarp_harmonic_" + std::to_string(::getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    std::filesystem::remove_all(dir_);
    std::filesystem::create_directories(dir_);
    cage_ = makeCage(test::star(), "star");
    harmonic_ = solve(cage_, 1500);
    file_ = dir_ / "star.swh";
    harmonic_->save(file_);
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }

  std::string bytes() const {
    std::ifstream in(file_, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  }
  void write(const std::string& data) const {
    std::ofstream(file_, std::ios::binary | std::ios::trunc) << data;
  }

  std::filesystem::path dir_, file_;
  CagePtr cage_;
  HarmonicPtr harmonic_;
};

TEST_F(HarmonicFiles, RoundTripIsBitIdentical) {
  const HarmonicPtr loaded = HarmonicCoordinates::load(file_, cage_);
  ASSERT_EQ(loaded->vertexValues().size(), harmonic_->vertexValues().size());
  EXPECT_EQ(std::memcmp(loaded->vertexValues().data(), harmonic_->vertexValues().data(),
                        loaded->vertexValues().size() * sizeof(double)),
            0);
  EXPECT_EQ(loaded->mesh().vertices, harmonic_->mesh().vertices);
  EXPECT_EQ(loaded->mesh().tets, harmonic_->mesh().tets);
  EXPECT_EQ(loaded->mesh().boundaryTriangle, harmonic_->mesh().boundaryTriangle);
  EXPECT_EQ(loaded->meshVolumeBound(), harmonic_->meshVolumeBound());
  const std::vector<Vec3> points = insidePoints(*harmonic_, 300, 2);
  std::vector<double> a(points.size() * cage_->vertexCount()), b(a.size());
  harmonic_->weightsBatch(points, a);
  loaded->weightsBatch(points, b);
  EXPECT_EQ(std::memcmp(a.data(), b.data(), a.size() * sizeof(double)), 0);
  // Saving the loaded coordinates gives the same file.
  const std::string first = bytes();
  loaded->save(file_);
  EXPECT_EQ(bytes(), first);
  const HarmonicCoordinates::FileInfo info = HarmonicCoordinates::readFileInfo(file_);
  EXPECT_EQ(info.version, 2u);
  EXPECT_EQ(info.cageHash, HarmonicCoordinates::cageHash(*cage_));
  EXPECT_EQ(info.tetCount, harmonic_->mesh().tets.size());
}

TEST_F(HarmonicFiles, RejectsCorruptFiles) {
  const std::string good = bytes();
  auto expectIoError = [&](const std::string& data, const std::string& what) {
    write(data);
    const std::string message =
        test::messageOf<IoError>([&] { HarmonicCoordinates::load(file_, cage_); });
    EXPECT_THAT(message, HasSubstr(file_.string())) << what;
    EXPECT_THAT(message, HasSubstr(what));
  };
  expectIoError(good.substr(0, good.size() - 100), "truncated");
  expectIoError(good.substr(0, 40), "too short");
  expectIoError(good + "x", "trailing");
  std::string flipped = good;
  flipped[good.size() / 2] = static_cast<char>(flipped[good.size() / 2] ^ 0x10);
  expectIoError(flipped, "checksum");
  std::string magic = good;
  magic[0] = 'X';
  expectIoError(magic, "bad magic");
  std::string version = good;
  version[8] = 3;
  expectIoError(version, "unsupported harmonic coordinate file version 3");
  std::string counts = good;
  counts[40 + 7] = 0x7f;  // an absurd mesh vertex count
  expectIoError(counts, "impossible counts");
  EXPECT_THAT(
      test::messageOf<IoError>([&] { HarmonicCoordinates::load(dir_ / "missing.swh", cage_); }),
      HasSubstr("cannot open"));
}

// Version 1 stored the mesh vertices in world units; such caches still load, to the same
// coordinates up to the round-off of moving the vertices into the cage's frame.
TEST_F(HarmonicFiles, ReadsVersionOneFiles) {
  std::string data = bytes();
  data[8] = 1;
  std::size_t offset = 72;
  for (const Vec3& p : harmonic_->mesh().vertices) {
    const double xyz[3] = {p.x, p.y, p.z};
    std::memcpy(data.data() + offset, xyz, sizeof xyz);
    offset += sizeof xyz;
  }
  std::uint64_t fnv = 0xcbf29ce484222325ull;  // FNV-1a of everything but the checksum
  for (std::size_t i = 0; i + 8 < data.size(); ++i)
    fnv = (fnv ^ static_cast<unsigned char>(data[i])) * 0x100000001b3ull;
  std::memcpy(data.data() + data.size() - 8, &fnv, 8);
  write(data);
  const HarmonicPtr loaded = HarmonicCoordinates::load(file_, cage_);
  EXPECT_EQ(loaded->mesh().tets, harmonic_->mesh().tets);
  EXPECT_EQ(loaded->mesh().vertices, harmonic_->mesh().vertices);
  const std::vector<Vec3> points = insidePoints(*harmonic_, 300, 3);
  std::vector<double> a(points.size() * cage_->vertexCount()), b(a.size());
  harmonic_->weightsBatch(points, a);
  loaded->weightsBatch(points, b);
  for (std::size_t i = 0; i < a.size(); ++i) ASSERT_NEAR(a[i], b[i], 1e-13) << i;
}

TEST_F(HarmonicFiles, RejectsAnotherCage) {
  const std::string message = test::messageOf<InvalidInput>(
      [&] { HarmonicCoordinates::load(file_, makeCage(test::lPrism(), "lPrism")); });
  EXPECT_THAT(message, HasSubstr(file_.string()));
  EXPECT_THAT(message, HasSubstr("another cage"));
  // Same counts, one vertex moved.
  PolygonSoup moved = test::star();
  moved.positions[0].x += 1e-9;
  EXPECT_THAT(test::messageOf<InvalidInput>(
                  [&] { HarmonicCoordinates::load(file_, makeCage(moved, "moved star")); }),
              HasSubstr("vertices or triangles differ"));
}

TEST_F(HarmonicFiles, LoadAppliesTheOutsidePolicy) {
  HarmonicOptions options;
  options.outside = HarmonicOutsidePolicy::NearestPoint;
  const HarmonicPtr loaded = HarmonicCoordinates::load(file_, cage_, options);
  const std::vector<double> w = weightsAt(*loaded, Vec3(0.0, 0.0, 10.0));
  EXPECT_NEAR(w[4], 1.0, 1e-12);  // the nearest point is vertex 4, (0, 0, 1)
}

// ---- the Ju et al. armadillo (optional shared data) ----

TEST(HarmonicArmadillo, ModelIsInsideAndReproducedWithNonNegativeWeights) {
  const auto dir = std::filesystem::path(SPACEWARP_SHARED_DATA_DIR) / "ju2005-armadillo";
  if (!std::filesystem::exists(dir / "bounding_mesh.obj"))
    GTEST_SKIP() << "shared data not found: " << dir;
  const auto cage = std::make_shared<const Cage>(Cage::fromFile(dir / "bounding_mesh.obj"));
  const HarmonicPtr h = solve(cage, 20000);
  const PolygonSoup model = readSoup(dir / "armadilloman.obj");
  const PropertyReport report = measureProperties(*h, *cage, model.positions);
  EXPECT_LE(report.partitionOfUnity, 1e-10);
  EXPECT_LE(report.linearReproduction, 1e-9);
  EXPECT_GE(report.minWeight, -1e-12);
  EXPECT_LE(report.lagrange, 1e-12);
  EXPECT_LE(report.faceInterpolation, 1e-12);
}

}  // namespace
}  // namespace spacewarp
