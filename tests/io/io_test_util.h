#pragma once
// Shared helpers of the file I/O tests: random soups whose coordinates stress decimal round
// trips, bit-exact comparisons, round trips through memory, reading from strings, temporary
// directories and files. Error messages: test::messageOf<IoError> in test_util.h.

#include <bit>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>
#include <limits>
#include <random>
#include <set>
#include <sstream>
#include <string>
#include <system_error>
#include <vector>

#include <gtest/gtest.h>

#include <spacewarp/core/geometry.h>
#include "test_util.h"

namespace spacewarp::test {

/// Doubles that stress decimal round trips: wide exponents, subnormals, extremes, -0.
inline double randomCoordinate(std::mt19937_64& rng) {
  std::uniform_int_distribution<int> kind(0, 9);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  switch (kind(rng)) {
    case 0:
      return std::ldexp(unit(rng), std::uniform_int_distribution<int>(-1070, 1020)(rng));
    case 1:
      return -0.0;
    case 2:
      return std::numeric_limits<double>::denorm_min() *
             std::uniform_int_distribution<int>(1, 1000)(rng);
    case 3:
      return std::numeric_limits<double>::max() * unit(rng);
    default:
      return 1000.0 * unit(rng);
  }
}

/// A soup of `vertexCount` vertices with randomCoordinate() positions (and random unit normals
/// if `withNormals`) and `polygonCount` polygons of 3 to 7 random corners, from `seed`.
inline PolygonSoup randomSoup(std::uint64_t seed, std::size_t vertexCount, std::size_t polygonCount,
                              bool withNormals) {
  std::mt19937_64 rng(seed);
  PolygonSoup soup;
  for (std::size_t v = 0; v < vertexCount; ++v) {
    soup.positions.emplace_back(randomCoordinate(rng), randomCoordinate(rng),
                                randomCoordinate(rng));
    if (withNormals) {
      std::normal_distribution<double> gauss;
      const Vec3 n(gauss(rng), gauss(rng), gauss(rng));
      soup.normals.push_back(glm::normalize(n));
    }
  }
  std::uniform_int_distribution<std::uint32_t> size(3, 7);
  std::uniform_int_distribution<std::uint32_t> vertex(0,
                                                      static_cast<std::uint32_t>(vertexCount - 1));
  std::vector<std::uint32_t> polygon;
  for (std::size_t p = 0; p < polygonCount; ++p) {
    polygon.resize(size(rng));
    for (std::uint32_t& v : polygon) v = vertex(rng);
    soup.addPolygon(polygon);
  }
  return soup;
}

/// The two arrays hold the same vectors, bit for bit (so -0.0 != +0.0).
inline void expectBitEqual(const std::vector<Vec3>& a, const std::vector<Vec3>& b) {
  ASSERT_EQ(a.size(), b.size());
  for (std::size_t i = 0; i < a.size(); ++i) {
    for (int c = 0; c < 3; ++c) {
      ASSERT_EQ(std::bit_cast<std::uint64_t>(a[i][c]), std::bit_cast<std::uint64_t>(b[i][c]))
          << "element " << i << " component " << c << ": " << a[i][c] << " vs " << b[i][c];
    }
  }
}

/// Positions and normals bit for bit, and the same polygons (attributes are not compared).
inline void expectSameSoup(const PolygonSoup& a, const PolygonSoup& b) {
  expectBitEqual(a.positions, b.positions);
  expectBitEqual(a.normals, b.normals);
  EXPECT_EQ(a.faceOffsets, b.faceOffsets);
  EXPECT_EQ(a.faceIndices, b.faceIndices);
}

/// A reader such as readObj: the soup in the stream, `name` naming it in messages.
using SoupReader = std::function<PolygonSoup(std::istream& in, const std::string& name)>;
/// A writer such as writeObj.
using SoupWriter = std::function<void(const PolygonSoup& soup, std::ostream& out)>;

/// Reads `text` (a file's bytes) with `read`, as the file `name`.
inline PolygonSoup readString(const SoupReader& read, const std::string& text,
                              const std::string& name) {
  std::istringstream in(text);
  return read(in, name);
}

/// Writes `soup` with `write` to memory and reads it back with `read`, as the file `name`.
inline PolygonSoup roundTrip(const SoupWriter& write, const SoupReader& read,
                             const PolygonSoup& soup, const std::string& name) {
  std::stringstream stream;
  write(soup, stream);
  return read(stream, name);
}

/// Which random soups expectExactRoundTrips writes and reads: randomSoup(seed, vertexCount,
/// polygonCount, withNormals) for every seed in [firstSeed, lastSeed].
struct RandomSoups {
  std::uint64_t firstSeed = 1;
  std::uint64_t lastSeed = 1;
  std::size_t vertexCount = 0;
  std::size_t polygonCount = 0;
  bool withNormals = false;
};

/// Every soup of `soups` comes back from `roundTrip` (a write and a read) the same bit for bit,
/// with as many polygons and with normals exactly when it had them.
inline void expectExactRoundTrips(const std::function<PolygonSoup(const PolygonSoup&)>& roundTrip,
                                  const RandomSoups& soups) {
  for (std::uint64_t seed = soups.firstSeed; seed <= soups.lastSeed; ++seed) {
    SCOPED_TRACE("seed " + std::to_string(seed));
    const PolygonSoup soup =
        randomSoup(seed, soups.vertexCount, soups.polygonCount, soups.withNormals);
    const PolygonSoup back = roundTrip(soup);
    ASSERT_EQ(back.hasNormals(), soups.withNormals);
    EXPECT_EQ(back.polygonCount(), soup.polygonCount());
    expectSameSoup(back, soup);
  }
}

/// The empty soup comes back from `roundTrip` empty: no vertices, no polygons.
inline void expectEmptyRoundTrip(const std::function<PolygonSoup(const PolygonSoup&)>& roundTrip) {
  const PolygonSoup back = roundTrip(PolygonSoup{});
  EXPECT_EQ(back.size(), 0u);
  EXPECT_EQ(back.polygonCount(), 0u);
}

/// A fresh directory under the system temp directory, removed with everything in it. Its name
/// is "spacewarp_<suite>_<test>_" (the running GoogleTest test) and a random suffix.
class TempDir {
 public:
  TempDir() {
    const ::testing::TestInfo* test = ::testing::UnitTest::GetInstance()->current_test_info();
    std::string prefix =
        test ? std::string("spacewarp_") + test->test_suite_name() + "_" + test->name() + "_"
             : std::string("spacewarp_test_");
    for (char& c : prefix)
      if (c == '/') c = '_';  // Parameterised tests are named "Prefix/Suite.Name/0".
    std::random_device device;
    path_ = std::filesystem::temp_directory_path() /
            (prefix + std::to_string(device()) + "_" + std::to_string(device()));
    std::filesystem::create_directories(path_);
  }
  ~TempDir() {
    std::error_code ignored;
    std::filesystem::remove_all(path_, ignored);
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;

  const std::filesystem::path& path() const { return path_; }

 private:
  std::filesystem::path path_;
};

/// The names of the entries of `directory`.
inline std::set<std::string> listDirectory(const std::filesystem::path& directory) {
  std::set<std::string> names;
  for (const auto& entry : std::filesystem::directory_iterator(directory))
    names.insert(entry.path().filename().string());
  return names;
}

/// The bytes of the file at `path` ("" if it cannot be opened).
inline std::string readFile(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

/// Creates or replaces the file at `path` with the bytes `text`.
inline void writeFile(const std::filesystem::path& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary);
  out << text;
}

}  // namespace spacewarp::test
