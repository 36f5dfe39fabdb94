#include <spacewarp/core/io/off.h>

#include <cstdint>
#include <sstream>
#include <string>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <spacewarp/core/errors.h>
#include "io_test_util.h"

namespace spacewarp {
namespace {

using ::testing::ElementsAre;
using ::testing::HasSubstr;

PolygonSoup roundTrip(const PolygonSoup& soup) {
  return test::roundTrip(writeOff, readOff, soup, "roundtrip.off");
}

PolygonSoup readText(const std::string& text) {
  return test::readString(readOff, text, "mesh.off");
}

/// The message of the IoError that reading `text` throws ("" if none).
std::string errorOf(const std::string& text) {
  return test::messageOf<IoError>([&] { readText(text); });
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
  test::expectExactRoundTrips(
      roundTrip, {.firstSeed = 1, .lastSeed = 5, .vertexCount = 200, .polygonCount = 150});
}

TEST(OffTest, RoundTripWithNormalsIsExact) {
  test::expectExactRoundTrips(roundTrip, {.firstSeed = 10,
                                          .lastSeed = 14,
                                          .vertexCount = 100,
                                          .polygonCount = 80,
                                          .withNormals = true});
}

TEST(OffTest, RoundTripPointCloud) {
  for (bool withNormals : {false, true}) {
    test::expectExactRoundTrips(
        roundTrip,
        {.firstSeed = 20, .lastSeed = 20, .vertexCount = 64, .withNormals = withNormals});
  }
}

TEST(OffTest, RoundTripEmptySoup) { test::expectEmptyRoundTrip(roundTrip); }

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
  EXPECT_TRUE(soup.faceAttributes.empty()) << "colours of different sizes are dropped";
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
  ASSERT_EQ(coff.attributes.size(), 4u);
  const char* names[] = {"red", "green", "blue", "alpha"};
  for (std::size_t c = 0; c < 4; ++c) {
    EXPECT_EQ(coff.attributes[c].name, names[c]);
    EXPECT_EQ(coff.attributes[c].type, ScalarType::UInt8);
  }
  EXPECT_THAT(coff.attributes[1].values, ElementsAre(0, 255, 0));
  EXPECT_THAT(coff.attributes[3].values, ElementsAre(255, 255, 255));
}

TEST(OffTest, ColoursRoundTripWithTheirTypes) {
  // Float vertex colours (RGB, some integral) on NOFF, uchar RGBA face colours.
  const PolygonSoup soup = readText(
      "CNOFF\n3 2 0\n0 0 0 0 0 1 0.25 1 0\n1 0 0 0 0 1 0.5 0.125 1\n0 1 0 0 0 1 1 1 1\n"
      "3 0 1 2 10 20 30 40\n3 2 1 0 0 0 0 255\n");
  ASSERT_TRUE(soup.hasNormals());
  ASSERT_EQ(soup.attributes.size(), 3u);
  EXPECT_EQ(soup.attributes[0].type, ScalarType::Float32);
  EXPECT_THAT(soup.attributes[0].values, ElementsAre(0.25, 0.5, 1));
  ASSERT_EQ(soup.faceAttributes.size(), 4u);
  EXPECT_EQ(soup.faceAttributes[3].name, "alpha");
  EXPECT_EQ(soup.faceAttributes[3].type, ScalarType::UInt8);
  EXPECT_THAT(soup.faceAttributes[0].values, ElementsAre(10, 0));

  const PolygonSoup back = roundTrip(soup);
  test::expectSameSoup(back, soup);
  const auto expectSame = [](const std::vector<ScalarAttribute>& a,
                             const std::vector<ScalarAttribute>& b) {
    ASSERT_EQ(a.size(), b.size());
    for (std::size_t k = 0; k < a.size(); ++k) {
      EXPECT_EQ(a[k].name, b[k].name);
      EXPECT_EQ(a[k].type, b[k].type) << b[k].name;
      EXPECT_EQ(a[k].values, b[k].values) << b[k].name;
    }
  };
  expectSame(back.attributes, soup.attributes);
  expectSame(back.faceAttributes, soup.faceAttributes);
}

TEST(OffTest, RejectsCoffVerticesWithoutColours) {
  EXPECT_THAT(errorOf("COFF\n3 1 0\n0 0 0 1 1 1\n1 0 0\n0 1 0 1 1 1\n3 0 1 2\n"),
              HasSubstr("mesh.off: COFF vertices need 3 or 4 colour values each"));
  EXPECT_THAT(errorOf("COFF\n2 0 0\n0 0 0 1 1 1\n1 0 0 1 1 1 1\n"),
              HasSubstr("the same count on every vertex"));
  EXPECT_THAT(errorOf("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2 1 1e999 1\n"),
              HasSubstr("mesh.off:6: face 0: '1e999' is not a finite colour value"));
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

// A binary or corrupt file's bytes never reach the message raw: control characters as \uXXXX,
// bytes that are not UTF-8 as \xXX (UTF-8 text is kept), in every kind of token.
TEST(OffTest, MessagesEscapeTheFilesBytes) {
  const std::string vertex = errorOf("OFF\n3 0 0\n0 0 0\n1 0 \x01\xff\n0 1 0\n");
  EXPECT_THAT(vertex, HasSubstr("mesh.off:4: vertex 1: '\\u0001\\xff' is not a number"));
  const std::string face = errorOf("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 \xc3\xa9\x80\n");
  EXPECT_THAT(face, HasSubstr("face 0: '\xc3\xa9\\x80' is not an integer"));
  const std::string header = errorOf("\x89PNG\r\n\x1a\n");
  EXPECT_THAT(header, HasSubstr("found '\\x89PNG"));
  for (const std::string& message : {vertex, face, header})
    for (const char c : message) {
      const auto byte = static_cast<unsigned char>(c);
      EXPECT_TRUE(byte >= 0x20 && byte != 0x7f && byte != 0xff && byte != 0x80 && byte != 0x89)
          << message;
    }
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
