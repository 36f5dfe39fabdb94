#include <spacewarp/core/io/obj.h>

#include <cmath>
#include <cstdint>
#include <random>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <spacewarp/core/errors.h>
#include "io_test_util.h"

namespace spacewarp {
namespace {

using ::testing::HasSubstr;

using test::expectSameSoup;

PolygonSoup roundTrip(const PolygonSoup& soup) {
  return test::roundTrip(writeObj, readObj, soup, "roundtrip.obj");
}

PolygonSoup readText(const std::string& text) {
  return test::readString(readObj, text, "model.obj");
}

/// The message of the IoError that reading `text` throws ("" if none).
std::string errorOf(const std::string& text) {
  return test::messageOf<IoError>([&] { readText(text); });
}

// What a soup does not keep is named once per kind, in file order, so that the CLI can say it.
TEST(ObjTest, NamesWhatItReadsButDoesNotKeep) {
  const PolygonSoup soup = readText(
      "# comment\nv 0 0 0 1 0 0\nv 1 0 0 0 1 0\nv 0 1 0 0 0 1\nv 1 1 1\nf 1 2 3\nl 1 4\n"
      "p 4\nl 2 4\ncurv 0 1 1 2\ng part\n");
  EXPECT_EQ(soup.notKept, (std::vector<std::string>{"vertex colours", "line elements (l)",
                                                    "point elements (p)", "'curv' statements"}));
  EXPECT_TRUE(readText("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\ng a\ns 1\n").notKept.empty());
}

TEST(ObjTest, RoundTripMixedPolygonsIsExact) {
  test::expectExactRoundTrips(
      roundTrip, {.firstSeed = 1, .lastSeed = 5, .vertexCount = 200, .polygonCount = 150});
}

TEST(ObjTest, RoundTripWithNormalsIsExact) {
  test::expectExactRoundTrips(roundTrip, {.firstSeed = 10,
                                          .lastSeed = 14,
                                          .vertexCount = 100,
                                          .polygonCount = 80,
                                          .withNormals = true});
}

TEST(ObjTest, RoundTripPointCloud) {
  test::expectExactRoundTrips(roundTrip, {.firstSeed = 20, .lastSeed = 20, .vertexCount = 64});
  test::expectExactRoundTrips(
      roundTrip, {.firstSeed = 21, .lastSeed = 21, .vertexCount = 64, .withNormals = true});
}

TEST(ObjTest, RoundTripEmptySoup) { test::expectEmptyRoundTrip(roundTrip); }

TEST(ObjTest, RoundTripPolygonWithMoreThan255Vertices) {
  PolygonSoup soup;
  std::vector<std::uint32_t> ring;
  for (std::uint32_t i = 0; i < 300; ++i) {
    const double angle = 2.0 * 3.141592653589793 * i / 300.0;
    soup.positions.emplace_back(std::cos(angle), std::sin(angle), 0.0);
    ring.push_back(i);
  }
  soup.addPolygon(ring);
  soup.addPolygon({0, 100, 200});
  expectSameSoup(roundTrip(soup), soup);
}

TEST(ObjTest, ReadsCubeWithCommentsGroupsAndTextureCoordinates) {
  const PolygonSoup cube = readText(
      "# a unit cube\n"
      "mtllib cube.mtl\n"
      "o cube\n"
      "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n"
      "v 0 0 1\nv 1 0 1\nv 1 1 1\nv 0 1 1   # trailing comment\n"
      "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n"
      "g bottom\nusemtl red\n"
      "f 1/1 4/4 3/3 2/2\n"
      "g top\n"
      "f 5/1 6/2 7/3 8/4\n"
      "s off\n"
      "f 1 2 6 5\nf 2 3 7 6\nf 3 4 8 7\nf 4 1 5 8\n"
      "l 1 2\np 3\n");
  ASSERT_EQ(cube.size(), 8u);
  EXPECT_EQ(cube.positions[6], Vec3(1, 1, 1));
  EXPECT_EQ(cube.positions[7], Vec3(0, 1, 1));
  ASSERT_EQ(cube.polygonCount(), 6u);
  EXPECT_THAT(cube.polygon(0), ::testing::ElementsAre(0, 3, 2, 1));
  EXPECT_THAT(cube.polygon(1), ::testing::ElementsAre(4, 5, 6, 7));
  EXPECT_THAT(cube.polygon(5), ::testing::ElementsAre(3, 0, 4, 7));
  EXPECT_FALSE(cube.hasNormals());
  EXPECT_EQ(cube.texcoords.values.size(), 4u);
  std::vector<std::uint32_t> texcoords = {0, 3, 2, 1, 0, 1, 2, 3};
  texcoords.resize(24, CornerAttribute::kNone);  // The four side quads have none.
  EXPECT_EQ(cube.texcoords.indices, texcoords);
  ASSERT_EQ(cube.objStatements.size(), 6u);
  const std::pair<std::uint32_t, std::string> statements[] = {
      {0, "mtllib cube.mtl"}, {0, "o cube"}, {0, "g bottom"},
      {0, "usemtl red"},      {1, "g top"},  {2, "s off"}};
  for (std::size_t k = 0; k < 6; ++k) {
    EXPECT_EQ(cube.objStatements[k].polygon, statements[k].first) << k;
    EXPECT_EQ(cube.objStatements[k].text, statements[k].second) << k;
  }
  EXPECT_NO_THROW(cube.validate());

  // Written back, every statement precedes the same polygon.
  const PolygonSoup back = roundTrip(cube);
  expectSameSoup(back, cube);
  ASSERT_EQ(back.objStatements.size(), cube.objStatements.size());
  for (std::size_t k = 0; k < 6; ++k) {
    EXPECT_EQ(back.objStatements[k].polygon, cube.objStatements[k].polygon) << k;
    EXPECT_EQ(back.objStatements[k].text, cube.objStatements[k].text) << k;
  }
  EXPECT_EQ(back.texcoords.indices, cube.texcoords.indices);
}

TEST(ObjTest, StatementsAfterTheLastPolygonAreKept) {
  const PolygonSoup soup = readText("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\ng tail # why\n");
  ASSERT_EQ(soup.objStatements.size(), 1u);
  EXPECT_EQ(soup.objStatements[0].polygon, 1u);
  EXPECT_EQ(soup.objStatements[0].text, "g tail");
  std::ostringstream out;
  writeObj(soup, out);
  EXPECT_THAT(out.str(), ::testing::EndsWith("f 1 2 3\ng tail\n"));
}

TEST(ObjTest, WriteRejectsStatementsOutOfOrder) {
  PolygonSoup soup;
  soup.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
  soup.addPolygon({0, 1, 2});
  soup.objStatements = {{1, "g a"}, {0, "g b"}};
  std::ostringstream out;
  EXPECT_THROW(writeObj(soup, out), InvalidInput);
  soup.objStatements = {{2, "g a"}};
  EXPECT_THROW(writeObj(soup, out), InvalidInput);
  soup.objStatements = {{0, "g a\nf 1 2 3"}};
  EXPECT_THROW(writeObj(soup, out), InvalidInput);
}

TEST(ObjTest, KeepsUnreferencedVerticesInFileOrder) {
  const PolygonSoup soup = readText("v 9 9 9\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 2 3 4\nv 5 5 5\n");
  ASSERT_EQ(soup.size(), 5u);
  EXPECT_EQ(soup.positions[0], Vec3(9, 9, 9));
  EXPECT_EQ(soup.positions[4], Vec3(5, 5, 5));
  EXPECT_THAT(soup.polygon(0), ::testing::ElementsAre(1, 2, 3));
}

TEST(ObjTest, ResolvesRelativeIndices) {
  const PolygonSoup soup = readText("v 0 0 0\nv 1 0 0\nv 0 1 0\nf -3 -2 -1\nv 1 1 0\nf -3 -2 -1\n");
  ASSERT_EQ(soup.polygonCount(), 2u);
  EXPECT_THAT(soup.polygon(0), ::testing::ElementsAre(0, 1, 2));
  EXPECT_THAT(soup.polygon(1), ::testing::ElementsAre(1, 2, 3));
}

TEST(ObjTest, ReadsWindowsLineEndingsAndVertexColours) {
  const PolygonSoup soup =
      readText("v 0 0 0 1 0 0\r\nv 1 0 0 0 1 0\r\nv 0 1 0 0 0 1\r\nf 1 2 3\r\n");
  ASSERT_EQ(soup.size(), 3u);
  EXPECT_EQ(soup.positions[1], Vec3(1, 0, 0));
  EXPECT_EQ(soup.polygonCount(), 1u);
}

TEST(ObjTest, MapsSharedNormalsToVertices) {
  // Two triangles sharing an edge; the normal indices differ from the vertex indices, but each
  // vertex always gets the same normal.
  const PolygonSoup soup = readText(
      "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\n"
      "vn 0 0 1\nvn 0 1 0\nvn 1 0 0\n"
      "f 1//1 2//2 3//3\nf 2//2 4//1 3//3\n");
  ASSERT_TRUE(soup.hasNormals());
  EXPECT_EQ(soup.normals[0], Vec3(0, 0, 1));
  EXPECT_EQ(soup.normals[1], Vec3(0, 1, 0));
  EXPECT_EQ(soup.normals[2], Vec3(1, 0, 0));
  EXPECT_EQ(soup.normals[3], Vec3(0, 0, 1));
}

TEST(ObjTest, KeepsNormalsThatDifferPerCornerPerCorner) {
  // Flat shading: vertex 2 gets two different normals.
  const PolygonSoup soup = readText(
      "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\n"
      "vn 0 0 1\nvn 0 1 0\n"
      "f 1//1 2//1 3//1\nf 2//2 4//2 3//2\n");
  EXPECT_FALSE(soup.hasNormals());
  EXPECT_EQ(soup.polygonCount(), 2u);
  EXPECT_EQ(soup.cornerNormals.values, (std::vector<Vec3>{{0, 0, 1}, {0, 1, 0}}));
  EXPECT_EQ(soup.cornerNormals.indices, (std::vector<std::uint32_t>{0, 0, 0, 1, 1, 1}));
  EXPECT_TRUE(soup.texcoords.empty());
}

TEST(ObjTest, KeepsNormalsPerCornerWhenSomeCornersHaveNone) {
  const PolygonSoup soup =
      readText("v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nvn 0 0 1\nvn 0 0 1\nf 1//1 2 3//3\n");
  EXPECT_FALSE(soup.hasNormals());
  EXPECT_EQ(soup.cornerNormals.values.size(), 3u);
  EXPECT_EQ(soup.cornerNormals.indices, (std::vector<std::uint32_t>{0, CornerAttribute::kNone, 2}));
}

TEST(ObjTest, KeepsNormalsPerCornerWhenAVertexHasNone) {
  // Vertex 4 is not referenced and there is no vn per v.
  const PolygonSoup soup =
      readText("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 5 5 5\nvn 0 0 1\nf 1//1 2//1 3//1\n");
  EXPECT_FALSE(soup.hasNormals());
  EXPECT_EQ(soup.size(), 4u);
  EXPECT_EQ(soup.cornerNormals.indices, (std::vector<std::uint32_t>{0, 0, 0}));
}

TEST(ObjTest, ReadsTextureCoordinatesPerCorner) {
  // A seam: vertex 2 has texture coordinate 2 in one face and 4 in the other; the second
  // face shares coordinate 1 with vertex 1's corner of the first.
  const PolygonSoup soup = readText(
      "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\n"
      "vt 0.25 0.5\nvt 1 0\nvt 0 1\nvt 0.75 0.125\nvn 0 0 1\n"
      "f 1/1/1 2/2/1 3/3/1\nf 2/4 4/1 3/3\nf 1 2 4\n");
  EXPECT_EQ(soup.texcoordDimension, 2);
  EXPECT_EQ(soup.texcoords.values,
            (std::vector<Vec3>{{0.25, 0.5, 0}, {1, 0, 0}, {0, 1, 0}, {0.75, 0.125, 0}}));
  constexpr std::uint32_t kNone = CornerAttribute::kNone;
  EXPECT_EQ(soup.texcoords.indices,
            (std::vector<std::uint32_t>{0, 1, 2, 3, 0, 2, kNone, kNone, kNone}));
  EXPECT_EQ(soup.cornerNormals.indices,
            (std::vector<std::uint32_t>{0, 0, 0, kNone, kNone, kNone, kNone, kNone, kNone}));
}

TEST(ObjTest, TextureCoordinateDimensionIsTheLongestLine) {
  const PolygonSoup soup =
      readText("v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0.5\nvt 0.1 0.2 0.3\nf 1/1 2/2 3/1\n");
  EXPECT_EQ(soup.texcoordDimension, 3);
  EXPECT_EQ(soup.texcoords.values, (std::vector<Vec3>{{0.5, 0, 0}, {0.1, 0.2, 0.3}}));
  std::ostringstream out;
  writeObj(soup, out);
  EXPECT_THAT(out.str(), HasSubstr("vt 0.5 0 0\nvt 0.1 0.2 0.3\n"));
  EXPECT_THAT(out.str(), HasSubstr("f 1/1 2/2 3/1\n"));
}

TEST(ObjTest, RejectsBadTextureCoordinates) {
  EXPECT_THAT(errorOf("vt\n"), HasSubstr("model.obj:1: texture coordinate has no values"));
  EXPECT_THAT(errorOf("v 0 0 0\nvt 0 nan\n"),
              HasSubstr("model.obj:2: texture coordinate has a non-finite value"));
  EXPECT_THAT(errorOf("vt 0 x\n"), HasSubstr("model.obj:1: texture coordinate: 'x' is not"));
}

/// A soup with every kind of corner data: random positions, texture coordinates shared across
/// seams, flat-shaded normals (shared by corners of different vertices, several per vertex),
/// and corners without either.
PolygonSoup soupWithCornerData(std::uint64_t seed) {
  PolygonSoup soup = test::randomSoup(seed, 60, 50, false);
  std::mt19937_64 rng(seed);
  for (int k = 0; k < 40; ++k)
    soup.texcoords.values.emplace_back(test::randomCoordinate(rng), test::randomCoordinate(rng),
                                       test::randomCoordinate(rng));
  std::mt19937 unitRng(static_cast<std::mt19937::result_type>(seed));
  for (int k = 0; k < 20; ++k) soup.cornerNormals.values.push_back(test::randomUnit(unitRng));
  soup.texcoordDimension = 3;
  std::uniform_int_distribution<std::uint32_t> texcoord(0, 39);
  std::uniform_int_distribution<std::uint32_t> normal(0, 19);
  for (std::size_t p = 0; p < soup.polygonCount(); ++p) {
    // Whole faces with or without each kind, as OBJ writes them.
    const bool withTexcoords = p % 3 != 0;
    const bool withNormals = p % 4 != 1;
    for (std::size_t k = 0; k < soup.polygon(p).size(); ++k) {
      soup.texcoords.indices.push_back(withTexcoords ? texcoord(rng) : CornerAttribute::kNone);
      soup.cornerNormals.indices.push_back(withNormals ? normal(rng) : CornerAttribute::kNone);
    }
  }
  return soup;
}

TEST(ObjTest, RoundTripWithTextureCoordinatesAndCornerNormalsIsExact) {
  for (std::uint64_t seed = 30; seed <= 33; ++seed) {
    SCOPED_TRACE("seed " + std::to_string(seed));
    const PolygonSoup soup = soupWithCornerData(seed);
    ASSERT_NO_THROW(soup.validate());
    const PolygonSoup back = roundTrip(soup);
    expectSameSoup(back, soup);
    EXPECT_EQ(back.texcoordDimension, 3);
    test::expectBitEqual(back.texcoords.values, soup.texcoords.values);
    EXPECT_EQ(back.texcoords.indices, soup.texcoords.indices);
    test::expectBitEqual(back.cornerNormals.values, soup.cornerNormals.values);
    EXPECT_EQ(back.cornerNormals.indices, soup.cornerNormals.indices);
  }
}

TEST(ObjTest, PointCloudWithOneNormalPerVertex) {
  const PolygonSoup soup = readText("v 0 0 0\nvn 0 0 1\nv 1 0 0\nvn 1 0 0\n");
  ASSERT_TRUE(soup.hasNormals());
  EXPECT_EQ(soup.normals[1], Vec3(1, 0, 0));
}

// The stream reader accepts an empty file; readSoup() refuses it (see mesh_io_test).
TEST(ObjTest, EmptyInputIsAnEmptySoup) {
  const PolygonSoup soup = readText("");
  EXPECT_EQ(soup.size(), 0u);
  EXPECT_EQ(soup.polygonCount(), 0u);
}

TEST(ObjTest, WritesOneBasedFacesWithNormalReferences) {
  PolygonSoup soup;
  soup.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
  soup.addPolygon({0, 1, 2});
  std::ostringstream plain;
  writeObj(soup, plain);
  EXPECT_THAT(plain.str(), HasSubstr("v 1 0 0\n"));
  EXPECT_THAT(plain.str(), HasSubstr("f 1 2 3\n"));
  soup.normals = {{0, 0, 1}, {0, 0, 1}, {0, 0, 1}};
  std::ostringstream withNormals;
  writeObj(soup, withNormals);
  EXPECT_THAT(withNormals.str(), HasSubstr("vn 0 0 1\n"));
  EXPECT_THAT(withNormals.str(), HasSubstr("f 1//1 2//2 3//3\n"));
}

TEST(ObjTest, WriteRejectsInvalidSoup) {
  PolygonSoup soup;
  soup.positions = {{0, 0, 0}};
  soup.addPolygon({0, 1, 2});
  std::ostringstream out;
  EXPECT_THROW(writeObj(soup, out), InvalidInput);
}

TEST(ObjTest, RejectsNanCoordinate) {
  EXPECT_THAT(errorOf("v 0 0 0\n# c\nv nan 0 0\n"),
              HasSubstr("model.obj:3: vertex has a non-finite coordinate"));
  EXPECT_THAT(errorOf("v 0 inf 0\n"), HasSubstr("model.obj:1: vertex has a non-finite"));
  EXPECT_THAT(errorOf("v 0 0 1e999\n"), HasSubstr("model.obj:1: vertex has a non-finite"));
  EXPECT_THAT(errorOf("v 0 0 0\nvn 0 nan 0\n"), HasSubstr("model.obj:2: normal has a non-finite"));
}

TEST(ObjTest, RejectsNonNumericToken) {
  EXPECT_THAT(errorOf("v 0 0 0\nv 1 abc 2\n"),
              HasSubstr("model.obj:2: vertex: 'abc' is not a number"));
  EXPECT_THAT(errorOf("v 0 0 0 x\n"), HasSubstr("model.obj:1:"));
  EXPECT_THAT(errorOf("v 1,5 0 0\n"), HasSubstr("model.obj:1:"));
  EXPECT_THAT(errorOf("v +-1 0 0\n"), HasSubstr("model.obj:1: vertex: '+-1' is not a number"));
  EXPECT_EQ(readText("v +1 -0 +.5e1\n").positions[0], Vec3(1, 0, 5));
}

TEST(ObjTest, RejectsTooFewCoordinates) {
  EXPECT_THAT(errorOf("v 1 2\n"), HasSubstr("model.obj:1: vertex has fewer than 3 coordinates"));
  EXPECT_THAT(errorOf("\n\nv\n"), HasSubstr("model.obj:3: vertex has fewer than 3"));
}

TEST(ObjTest, RejectsOutOfRangeAndZeroFaceIndices) {
  const std::string triangle = "v 0 0 0\nv 1 0 0\nv 0 1 0\n";
  EXPECT_THAT(errorOf(triangle + "f 1 2 4\n"),
              HasSubstr("model.obj:4: face vertex index 4 is out of range (3 vertices so far)"));
  EXPECT_THAT(errorOf(triangle + "f 0 1 2\n"),
              HasSubstr("model.obj:4: face vertex index 0 is invalid"));
  EXPECT_THAT(errorOf(triangle + "f -4 1 2\n"), HasSubstr("model.obj:4: face vertex index -4"));
  EXPECT_THAT(errorOf(triangle + "f 1//2 2//1 3//1\nvn 0 0 1\n"),
              HasSubstr("model.obj:4: face normal index 2"));
  EXPECT_THAT(errorOf(triangle + "f 1 2 99999999999999999999\n"), HasSubstr("model.obj:4:"));
}

TEST(ObjTest, RejectsMalformedFaces) {
  const std::string triangle = "v 0 0 0\nv 1 0 0\nv 0 1 0\n";
  EXPECT_THAT(errorOf(triangle + "f 1 2\n"), HasSubstr("model.obj:4: face has fewer than 3"));
  EXPECT_THAT(errorOf(triangle + "f 1 2 x\n"), HasSubstr("model.obj:4: malformed face corner 'x'"));
  EXPECT_THAT(errorOf(triangle + "f 1/ 2 3\n"), HasSubstr("model.obj:4: malformed"));
  EXPECT_THAT(errorOf(triangle + "f 1/1/1/1 2 3\n"), HasSubstr("model.obj:4: malformed"));
  EXPECT_THAT(errorOf(triangle + "f +-1 2 3\n"), HasSubstr("model.obj:4: malformed"));
  EXPECT_THAT(errorOf(triangle + "f ++1 2 3\n"), HasSubstr("model.obj:4: malformed"));
  EXPECT_EQ(errorOf(triangle + "f +1 2 3\n"), "");
  EXPECT_THAT(errorOf(std::string("v 0 0 0\0\n", 10)), HasSubstr("model.obj:1: unexpected NUL"));
}

}  // namespace
}  // namespace spacewarp
