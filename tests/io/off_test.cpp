#include "core/io/off.h"

#include <bit>
#include <cmath>
#include <cstdint>
#include <limits>
#include <random>
#include <sstream>
#include <string>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "core/errors.h"

namespace spacewarp {
namespace {

using ::testing::ElementsAre;
using ::testing::HasSubstr;

/// Doubles that stress decimal round trips: wide exponents, subnormals, extremes, -0.
double randomCoordinate(std::mt19937_64& rng) {
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

PolygonSoup randomSoup(std::uint64_t seed, std::size_t vertexCount, std::size_t polygonCount,
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

void expectBitEqual(const std::vector<Vec3>& a, const std::vector<Vec3>& b) {
  ASSERT_EQ(a.size(), b.size());
  for (std::size_t i = 0; i < a.size(); ++i) {
    for (int c = 0; c < 3; ++c) {
      ASSERT_EQ(std::bit_cast<std::uint64_t>(a[i][c]), std::bit_cast<std::uint64_t>(b[i][c]))
          << "element " << i << " component " << c << ": " << a[i][c] << " vs " << b[i][c];
    }
  }
}

void expectSameSoup(const PolygonSoup& a, const PolygonSoup& b) {
  expectBitEqual(a.positions, b.positions);
  expectBitEqual(a.normals, b.normals);
  EXPECT_EQ(a.faceOffsets, b.faceOffsets);
  EXPECT_EQ(a.faceIndices, b.faceIndices);
}

PolygonSoup roundTrip(const PolygonSoup& soup) {
  std::stringstream stream;
  writeOff(soup, stream);
  return readOff(stream, "roundtrip.off");
}

PolygonSoup readText(const std::string& text, const std::string& name = "mesh.off") {
  std::istringstream in(text);
  return readOff(in, name);
}

/// The message of the IoError that reading `text` throws ("" if none).
std::string errorOf(const std::string& text, const std::string& name = "mesh.off") {
  try {
    readText(text, name);
  } catch (const IoError& e) {
    return e.what();
  }
  return "";
}

const std::string kCube =
    "OFF\n"
    "# a unit cube\n"
    "8 6 12\n"
    "0 0 0\n1 0 0\n1 1 0\n0 1 0\n"
    "0 0 1\n1 0 1\n1 1 1\n0 1 1  # last vertex\n"
    "\n"
    "4 0 3 2 1\n4 4 5 6 7\n4 0 1 5 4\n4 1 2 6 5\n4 2 3 7 6\n4 3 0 4 7\n";

TEST(OffTest, RoundTripMixedPolygonsIsExact) {
  for (std::uint64_t seed = 1; seed <= 5; ++seed) {
    const PolygonSoup soup = randomSoup(seed, 200, 150, false);
    expectSameSoup(roundTrip(soup), soup);
  }
}

TEST(OffTest, RoundTripWithNormalsIsExact) {
  for (std::uint64_t seed = 10; seed <= 14; ++seed) {
    const PolygonSoup soup = randomSoup(seed, 100, 80, true);
    const PolygonSoup back = roundTrip(soup);
    ASSERT_TRUE(back.hasNormals());
    expectSameSoup(back, soup);
  }
}

TEST(OffTest, RoundTripPointCloud) {
  for (bool withNormals : {false, true}) {
    const PolygonSoup cloud = randomSoup(20, 64, 0, withNormals);
    const PolygonSoup back = roundTrip(cloud);
    EXPECT_EQ(back.polygonCount(), 0u);
    expectSameSoup(back, cloud);
  }
}

TEST(OffTest, RoundTripEmptySoup) {
  const PolygonSoup back = roundTrip(PolygonSoup{});
  EXPECT_EQ(back.size(), 0u);
  EXPECT_EQ(back.polygonCount(), 0u);
}

TEST(OffTest, ReadsCube) {
  const PolygonSoup cube = readText(kCube);
  ASSERT_EQ(cube.size(), 8u);
  EXPECT_EQ(cube.positions[6], Vec3(1, 1, 1));
  EXPECT_EQ(cube.positions[7], Vec3(0, 1, 1));
  ASSERT_EQ(cube.polygonCount(), 6u);
  EXPECT_THAT(cube.polygon(0), ElementsAre(0, 3, 2, 1));
  EXPECT_THAT(cube.polygon(5), ElementsAre(3, 0, 4, 7));
  EXPECT_FALSE(cube.hasNormals());
  EXPECT_NO_THROW(cube.validate());
}

TEST(OffTest, ReadsCountsOnHeaderLineFaceColoursAndCrLf) {
  const PolygonSoup soup = readText(
      "OFF 4 2 0\r\n"
      "0 0 0\r\n1 0 0\r\n0 1 0\r\n1 1 0\r\n"
      "3 0 1 2 255 0 0\r\n"
      "3 1 3 2 0.5 0.5 0.5 1\r\n");
  ASSERT_EQ(soup.size(), 4u);
  ASSERT_EQ(soup.polygonCount(), 2u);
  EXPECT_THAT(soup.polygon(1), ElementsAre(1, 3, 2));
}

TEST(OffTest, ReadsNoffNormalsAndCoffColours) {
  const PolygonSoup noff =
      readText("NOFF\n3 1 0\n0 0 0 0 0 1\n1 0 0 0 0 1\n0 1 0 0 0 -1\n3 0 1 2\n");
  ASSERT_TRUE(noff.hasNormals());
  EXPECT_EQ(noff.normals[2], Vec3(0, 0, -1));
  const PolygonSoup coff =
      readText("COFF\n3 1 0\n0 0 0 255 0 0 255\n1 0 0 0 255 0 255\n0 1 0 0 0 255 255\n3 0 1 2\n");
  EXPECT_FALSE(coff.hasNormals());
  EXPECT_EQ(coff.positions[1], Vec3(1, 0, 0));
}

TEST(OffTest, ReadsPointCloudWithZeroFaces) {
  const PolygonSoup cloud = readText("OFF\n2 0 0\n1 2 3\n4 5 6\n");
  ASSERT_EQ(cloud.size(), 2u);
  EXPECT_EQ(cloud.positions[1], Vec3(4, 5, 6));
  EXPECT_EQ(cloud.polygonCount(), 0u);
}

TEST(OffTest, WritesHeaderCountsAndZeroBasedFaces) {
  PolygonSoup soup;
  soup.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
  soup.addPolygon({0, 1, 2});
  std::ostringstream out;
  writeOff(soup, out);
  EXPECT_EQ(out.str(), "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n");
}

TEST(OffTest, RejectsFewerVerticesThanDeclared) {
  EXPECT_THAT(errorOf("OFF\n4 0 0\n0 0 0\n1 0 0\n0 1 0\n"),
              HasSubstr("mesh.off:5: unexpected end of file: declared 4 vertices, found 3"));
}

TEST(OffTest, RejectsFewerFacesThanDeclared) {
  EXPECT_THAT(errorOf("OFF\n3 2 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n"),
              HasSubstr("mesh.off:6: unexpected end of file: declared 2 faces, found 1"));
}

TEST(OffTest, RejectsOutOfRangeIndex) {
  EXPECT_THAT(errorOf("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n"),
              HasSubstr("mesh.off:6: face 0: vertex index 3 is out of range (3 vertices)"));
  EXPECT_THAT(errorOf("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 -1 2\n"),
              HasSubstr("mesh.off:6: face 0: vertex index -1"));
}

TEST(OffTest, RejectsDegenerateAndShortFaces) {
  const std::string head = "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n";
  EXPECT_THAT(errorOf(head + "2 0 1\n"),
              HasSubstr("mesh.off:6: face 0 has 2 vertices, at least 3"));
  EXPECT_THAT(errorOf(head + "4 0 1 2\n"),
              HasSubstr("mesh.off:6: face 0 declares 4 vertices but lists 3"));
}

TEST(OffTest, RejectsNanAndNonNumericTokens) {
  EXPECT_THAT(errorOf("OFF\n3 0 0\n0 0 0\nnan 0 0\n0 1 0\n"),
              HasSubstr("mesh.off:4: vertex 1 has a non-finite coordinate"));
  EXPECT_THAT(errorOf("OFF\n3 0 0\n0 0 0\n1 0 0\n0 1e999 0\n"),
              HasSubstr("mesh.off:5: vertex 2 has a non-finite coordinate"));
  EXPECT_THAT(errorOf("OFF\n3 0 0\n0 0 0\n1 zero 0\n0 1 0\n"),
              HasSubstr("mesh.off:4: vertex 1: 'zero' is not a number"));
  EXPECT_THAT(errorOf("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 two\n"),
              HasSubstr("mesh.off:6: face 0: 'two' is not an integer"));
  EXPECT_THAT(errorOf("OFF\n1 0 0\n+-1 0 0\n"),
              HasSubstr("mesh.off:3: vertex 0: '+-1' is not a number"));
  EXPECT_THAT(errorOf("OFF\nthree 1 0\n"), HasSubstr("mesh.off:2: vertex count: 'three'"));
  EXPECT_THAT(errorOf("NOFF\n1 0 0\n0 0 0 0 nan 1\n"),
              HasSubstr("mesh.off:3: vertex 0 has a non-finite normal"));
  EXPECT_THAT(errorOf("OFF\n1 0 0\n0 0\n"),
              HasSubstr("mesh.off:3: vertex 0 has 2 values, expected 3"));
}

TEST(OffTest, RejectsBadHeaderAndCounts) {
  EXPECT_THAT(errorOf(""), HasSubstr("mesh.off: empty file"));
  EXPECT_THAT(errorOf("# only a comment\nPLY\n"), HasSubstr("mesh.off:2: not an OFF file"));
  EXPECT_THAT(errorOf("STOFF\n1 0 0\n0 0 0 0 0\n"), HasSubstr("mesh.off:1: not an OFF file"));
  EXPECT_THAT(errorOf("OFF\n"), HasSubstr("mesh.off:1: unexpected end of file"));
  EXPECT_THAT(errorOf("OFF\n3\n"), HasSubstr("mesh.off:2: expected the counts line"));
  EXPECT_THAT(errorOf("OFF\n-3 0 0\n"), HasSubstr("mesh.off:2: negative count"));
}

TEST(OffTest, RejectsContentAfterTheLastFace) {
  EXPECT_THAT(errorOf("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n3 0 1 2\n"),
              HasSubstr("mesh.off:7: unexpected content after the last"));
}

TEST(OffTest, HugeDeclaredCountsFailCleanly) {
  EXPECT_THAT(errorOf("OFF\n4000000000 4000000000000000000 0\n0 0 0\n"),
              HasSubstr("mesh.off:3: unexpected end of file: declared 4000000000 vertices"));
  EXPECT_THAT(errorOf("OFF\n40000000000 1 0\n"), HasSubstr("mesh.off:2: too many vertices"));
}

}  // namespace
}  // namespace spacewarp
