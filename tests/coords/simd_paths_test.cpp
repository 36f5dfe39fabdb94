// The mean-value and Green kernels give the same bits on every detail::simd::Path this CPU
// runs (baseline, x86-64-v3, x86-64-v4): coords/CMakeLists.txt compiles them without FMA
// contraction, the only thing that could tell the paths apart.

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include <spacewarp/coords/detail/green_kernels.h>
#include <spacewarp/coords/green.h>
#include <spacewarp/coords/mean_value.h>
#include <spacewarp/core/detail/simd.h>
#include <spacewarp/core/errors.h>
#include <spacewarp/core/io/mesh_io.h>
#include <spacewarp/core/primitives.h>
#include "coords_test_shapes.h"

namespace spacewarp {
namespace {

using detail::simd::Path;

// Restores the default path choice when a test ends, whatever it forced.
struct ForcedPath {
  explicit ForcedPath(Path path) { detail::simd::forcePath(path); }
  ~ForcedPath() { detail::simd::forcePath(std::nullopt); }
  ForcedPath(const ForcedPath&) = delete;
  ForcedPath& operator=(const ForcedPath&) = delete;
};

std::vector<Path> supportedPaths() {
  std::vector<Path> paths;
  for (int p = 0; p < detail::simd::kPathCount; ++p)
    if (detail::simd::pathSupported(static_cast<Path>(p))) paths.push_back(static_cast<Path>(p));
  return paths;
}

// Points that reach every branch of the kernels: uniform in the cage's box grown by half its
// size (inside, outside), the cage's vertices, points on and 1e-9 diagonals off its edge
// midpoints and face centroids (snapping, near-plane and near-edge terms, the careful path),
// and far points (the whole-point fallback).
std::vector<Vec3> probePoints(const Cage& cage, std::size_t random) {
  const BoundingBox box = boundingBox(cage.vertices());
  const Vec3 pad = 0.5 * box.extent();
  std::vector<Vec3> points = makeRandomPoints(box.min - pad, box.max + pad, random, 11).positions;
  const double off = 1e-9 * cage.diagonal();
  for (const Vec3& v : cage.vertices()) points.push_back(v);
  for (const Triangle& t : cage.triangles()) {
    const Vec3 a = cage.vertices()[t.x], b = cage.vertices()[t.y], c = cage.vertices()[t.z];
    const Vec3 n = glm::normalize(glm::cross(b - a, c - a));
    for (const Vec3& p : {0.5 * (a + b), (a + b + c) / 3.0}) {
      points.push_back(p);
      points.push_back(p + off * n);
      points.push_back(p - off * n);
    }
  }
  points.push_back(box.max + 50.0 * box.extent());
  points.push_back(box.min - 2000.0 * box.extent());
  return points;
}

// The first entry where two weight matrices differ in their bits, as text ("" if none).
std::string firstDifference(const std::vector<double>& a, const std::vector<double>& b,
                            std::size_t columns) {
  for (std::size_t i = 0; i < a.size(); ++i) {
    if (std::memcmp(&a[i], &b[i], sizeof(double)) != 0) {
      char values[64];
      std::snprintf(values, sizeof values, "%.17g vs %.17g", a[i], b[i]);
      return "point " + std::to_string(i / columns) + ", column " + std::to_string(i % columns) +
             ": " + values;
    }
  }
  return "";
}

// Every supported path gives the baseline's bits for every point, through weightsBatch
// (four points per pass) and weights (one).
void expectSameBitsOnEveryPath(const Coordinates& coordinates, const std::vector<Vec3>& points) {
  const std::size_t m = coordinates.columnCount();
  std::vector<double> reference(points.size() * m);
  {
    const ForcedPath forced(Path::Baseline);
    coordinates.weightsBatch(points, reference);
  }
  for (const Path path : supportedPaths()) {
    const ForcedPath forced(path);
    std::vector<double> rows(points.size() * m);
    coordinates.weightsBatch(points, rows);
    EXPECT_EQ(firstDifference(reference, rows, m), "") << detail::simd::pathName(path);
    std::vector<double> row(m);
    coordinates.weights(points[points.size() / 2], row);
    const std::vector<double> expected(
        reference.begin() + std::ptrdiff_t(points.size() / 2 * m),
        reference.begin() + std::ptrdiff_t(points.size() / 2 * m + m));
    EXPECT_EQ(firstDifference(expected, row, m), "")
        << detail::simd::pathName(path) << " (one point)";
  }
}

std::vector<std::shared_ptr<const Cage>> testCages() {
  std::vector<std::shared_ptr<const Cage>> cages = {
      std::make_shared<const Cage>(test::tetrahedron()),
      std::make_shared<const Cage>(
          makeBoxSurface(Vec3(-1.0, 0.0, 2.0), Vec3(1.0, 2.0, 5.0), {2, 3, 1}))};
  const auto armadillo = std::filesystem::path(SPACEWARP_SHARED_DATA_DIR) / "ju2005-armadillo";
  if (std::filesystem::exists(armadillo / "bounding_mesh.obj"))
    cages.push_back(std::make_shared<const Cage>(Cage::fromFile(armadillo / "bounding_mesh.obj")));
  return cages;
}

TEST(SimdPaths, BaselineIsAlwaysSupportedAndNamed) {
  EXPECT_TRUE(detail::simd::pathSupported(Path::Baseline));
  EXPECT_STREQ(detail::simd::pathName(Path::Baseline), "baseline");
  EXPECT_STREQ(detail::simd::pathName(Path::V3), "x86-64-v3");
  EXPECT_STREQ(detail::simd::pathName(Path::V4), "x86-64-v4");
  for (const Path path : supportedPaths()) {
    const ForcedPath forced(path);
    EXPECT_EQ(detail::simd::activePath(), path);
  }
  for (int p = 0; p < detail::simd::kPathCount; ++p) {
    if (!detail::simd::pathSupported(static_cast<Path>(p))) {
      EXPECT_THROW(detail::simd::forcePath(static_cast<Path>(p)), InvalidInput);
    }
  }
}

// SPACEWARP_SIMD picks the path when none is forced; a name that is no path is refused, naming
// the variable. (The environment is read when the choice is reset by forcePath(nullopt).)
TEST(SimdPaths, EnvironmentVariableChoosesThePath) {
  ::setenv("SPACEWARP_SIMD", "baseline", 1);
  detail::simd::forcePath(std::nullopt);
  EXPECT_EQ(detail::simd::activePath(), Path::Baseline);
  ::setenv("SPACEWARP_SIMD", "avx9", 1);
  detail::simd::forcePath(std::nullopt);
  try {
    detail::simd::activePath();
    ADD_FAILURE() << "SPACEWARP_SIMD=avx9 was accepted";
  } catch (const InvalidInput& e) {
    EXPECT_NE(std::string(e.what()).find("SPACEWARP_SIMD=avx9"), std::string::npos) << e.what();
  }
  ::unsetenv("SPACEWARP_SIMD");
  detail::simd::forcePath(std::nullopt);
  EXPECT_TRUE(detail::simd::pathSupported(detail::simd::activePath()));
}

TEST(SimdPaths, MeanValueGivesTheSameBitsOnEveryPath) {
  for (const auto& cage : testCages()) {
    SCOPED_TRACE(cage->name());
    const MeanValueCoordinates mvc(cage);
    expectSameBitsOnEveryPath(mvc, probePoints(*cage, 2000));
  }
}

TEST(SimdPaths, GreenGivesTheSameBitsOnEveryPath) {
  for (const auto& cage : testCages()) {
    SCOPED_TRACE(cage->name());
    const GreenCoordinates green(cage);
    expectSameBitsOnEveryPath(green, probePoints(*cage, 2000));
  }
}

// Points so far that Green's weights overflow are refused on every path (their NaN rows once
// differed in the sign bit between paths); the nearest far points still give the same bits.
TEST(SimdPaths, GreenRefusesOverflowingPointsOnEveryPath) {
  for (const auto& cage : testCages()) {
    SCOPED_TRACE(cage->name());
    const GreenCoordinates green(cage);
    expectSameBitsOnEveryPath(green, {Vec3(1e50, 0, 0), Vec3(0, -1e90, 3), Vec3(1e100, 1, 1)});
    for (const Path path : supportedPaths()) {
      const ForcedPath forced(path);
      const std::vector<Vec3> points = {cage->vertices()[0], Vec3(1e300, 0, 0)};
      std::vector<double> rows(points.size() * green.columnCount());
      EXPECT_THROW(green.weightsBatch(points, rows), InvalidInput) << detail::simd::pathName(path);
    }
  }
}

TEST(SimdPaths, ArmadilloModelGivesTheSameBitsOnEveryPath) {
  const auto dir = std::filesystem::path(SPACEWARP_SHARED_DATA_DIR) / "ju2005-armadillo";
  if (!std::filesystem::exists(dir / "armadilloman.obj"))
    GTEST_SKIP() << "shared data not found: " << dir;
  const auto cage = std::make_shared<const Cage>(Cage::fromFile(dir / "bounding_mesh.obj"));
  std::vector<Vec3> model = readSoup(dir / "armadilloman.obj").positions;
  model.resize(std::min<std::size_t>(model.size(), 4000));  // every branch, in test time
  expectSameBitsOnEveryPath(MeanValueCoordinates(cage), model);
  expectSameBitsOnEveryPath(GreenCoordinates(cage), model);
}

TEST(SimdPaths, GreenElementaryFunctionsGiveTheSameBitsOnEveryPath) {
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> exponent(-300.0, 300.0), sign(-1.0, 1.0);
  std::vector<double> a(4099), b(a.size());
  for (std::size_t i = 0; i < a.size(); ++i) {
    a[i] = std::pow(2.0, exponent(rng));
    b[i] = std::pow(2.0, exponent(rng) / 64.0) * (sign(rng) < 0 ? -1.0 : 1.0);
  }
  std::vector<double> logRef(a.size()), atanRef(a.size()), out(a.size());
  detail::greenLogRatio(a, std::vector<double>(a.size(), 1.0), logRef, true);
  detail::greenAtan2(b, a, atanRef, true);
  for (const Path path : supportedPaths()) {
    const ForcedPath forced(path);
    detail::greenLogRatio(a, std::vector<double>(a.size(), 1.0), out);
    EXPECT_EQ(firstDifference(logRef, out, 1), "") << "ln, " << detail::simd::pathName(path);
    detail::greenAtan2(b, a, out);
    EXPECT_EQ(firstDifference(atanRef, out, 1), "") << "atan2, " << detail::simd::pathName(path);
  }
}

}  // namespace
}  // namespace spacewarp
