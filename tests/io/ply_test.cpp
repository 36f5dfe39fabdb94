#include <spacewarp/core/io/ply.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <random>
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

using test::expectSameSoup;
using test::randomCoordinate;
using test::randomSoup;

const PlyEncoding kEncodings[] = {PlyEncoding::Ascii, PlyEncoding::BinaryLittleEndian,
                                  PlyEncoding::BinaryBigEndian};

/// One attribute of every type with `count` values that each type holds exactly.
std::vector<ScalarAttribute> randomAttributes(std::size_t count, std::uint64_t seed) {
  std::vector<ScalarAttribute> attributes;
  std::mt19937_64 rng(seed);
  const struct {
    const char* name;
    ScalarType type;
    double low;
    double high;
  } kinds[] = {{"label8", ScalarType::Int8, -128, 127},
               {"red", ScalarType::UInt8, 0, 255},
               {"offset", ScalarType::Int16, -32768, 32767},
               {"count", ScalarType::UInt16, 0, 65535},
               {"id", ScalarType::Int32, -2147483648.0, 2147483647.0},
               {"flags", ScalarType::UInt32, 0, 4294967295.0},
               {"confidence", ScalarType::Float32, 0, 0},
               {"quality", ScalarType::Float64, 0, 0}};
  for (const auto& kind : kinds) {
    ScalarAttribute attribute{kind.name, kind.type, {}};
    for (std::size_t v = 0; v < count; ++v) {
      double value = 0.0;
      if (kind.type == ScalarType::Float32) {
        const std::uint32_t bits = static_cast<std::uint32_t>(rng());
        float f;
        std::memcpy(&f, &bits, sizeof f);
        if (std::isnan(f)) f = -0.0f;
        value = static_cast<double>(f);
      } else if (kind.type == ScalarType::Float64) {
        value = randomCoordinate(rng);
        if (v % 17 == 3) value = -std::numeric_limits<double>::infinity();
      } else {
        // Include the extremes of the range.
        const std::uint64_t pick = rng() % 10;
        value = pick == 0 ? kind.low
                : pick == 1
                    ? kind.high
                    : std::floor(std::uniform_real_distribution<double>(kind.low, kind.high)(rng));
      }
      attribute.values.push_back(value);
    }
    attributes.push_back(std::move(attribute));
  }
  return attributes;
}

void addAttributes(PolygonSoup& soup, std::uint64_t seed) {
  soup.attributes = randomAttributes(soup.size(), seed);
}

void expectSameAttributes(const std::vector<ScalarAttribute>& a,
                          const std::vector<ScalarAttribute>& b) {
  ASSERT_EQ(a.size(), b.size());
  for (std::size_t k = 0; k < a.size(); ++k) {
    const ScalarAttribute& x = a[k];
    const ScalarAttribute& y = b[k];
    EXPECT_EQ(x.name, y.name);
    EXPECT_EQ(x.type, y.type) << x.name;
    ASSERT_EQ(x.values.size(), y.values.size()) << x.name;
    for (std::size_t v = 0; v < x.values.size(); ++v) {
      ASSERT_EQ(std::bit_cast<std::uint64_t>(x.values[v]),
                std::bit_cast<std::uint64_t>(y.values[v]))
          << x.name << " element " << v << ": " << x.values[v] << " vs " << y.values[v];
    }
  }
}

void expectSameAttributes(const PolygonSoup& a, const PolygonSoup& b) {
  expectSameAttributes(a.attributes, b.attributes);
  expectSameAttributes(a.faceAttributes, b.faceAttributes);
}

std::string write(const PolygonSoup& soup, PlyEncoding encoding) {
  std::ostringstream out;
  writePly(soup, out, encoding);
  return out.str();
}

PolygonSoup readBytes(const std::string& bytes, const std::string& name = "cloud.ply") {
  return test::readString(readPly, bytes, name);
}

PolygonSoup roundTrip(const PolygonSoup& soup, PlyEncoding encoding) {
  return readBytes(write(soup, encoding), "roundtrip.ply");
}

/// The message of the IoError that reading `bytes` throws ("" if none).
std::string errorOf(const std::string& bytes) {
  return test::messageOf<IoError>([&] { readBytes(bytes); });
}

/// Appends `value` in big-endian byte order.
template <typename T>
void appendBigEndian(std::string& out, T value) {
  unsigned char bytes[sizeof(T)];
  std::memcpy(bytes, &value, sizeof(T));
  if constexpr (std::endian::native == std::endian::little) std::reverse(bytes, bytes + sizeof(T));
  out.append(reinterpret_cast<const char*>(bytes), sizeof(T));
}

template <typename T>
void appendLittleEndian(std::string& out, T value) {
  unsigned char bytes[sizeof(T)];
  std::memcpy(bytes, &value, sizeof(T));
  if constexpr (std::endian::native == std::endian::big) std::reverse(bytes, bytes + sizeof(T));
  out.append(reinterpret_cast<const char*>(bytes), sizeof(T));
}

TEST(PlyTest, RoundTripIsExactInEveryEncoding) {
  for (PlyEncoding encoding : kEncodings) {
    SCOPED_TRACE(static_cast<int>(encoding));
    test::expectExactRoundTrips(
        [encoding](const PolygonSoup& soup) { return roundTrip(soup, encoding); },
        {.firstSeed = 1, .lastSeed = 3, .vertexCount = 150, .polygonCount = 120});
  }
}

TEST(PlyTest, RoundTripWithNormalsAndAttributesIsExact) {
  for (PlyEncoding encoding : kEncodings) {
    SCOPED_TRACE(static_cast<int>(encoding));
    PolygonSoup soup = randomSoup(7, 120, 90, true);
    addAttributes(soup, 8);
    const PolygonSoup back = roundTrip(soup, encoding);
    ASSERT_TRUE(back.hasNormals());
    expectSameSoup(back, soup);
    expectSameAttributes(back, soup);
  }
}

TEST(PlyTest, RoundTripPointCloudHasNoFaceElement) {
  for (PlyEncoding encoding : kEncodings) {
    SCOPED_TRACE(static_cast<int>(encoding));
    for (bool withNormals : {false, true}) {
      PolygonSoup cloud = randomSoup(30, 80, 0, withNormals);
      addAttributes(cloud, 31);
      const std::string bytes = write(cloud, encoding);
      EXPECT_THAT(bytes, ::testing::Not(HasSubstr("element face")));
      const PolygonSoup back = readBytes(bytes);
      EXPECT_EQ(back.polygonCount(), 0u);
      expectSameSoup(back, cloud);
      expectSameAttributes(back, cloud);
    }
  }
}

TEST(PlyTest, RoundTripEmptySoup) {
  for (PlyEncoding encoding : kEncodings) {
    SCOPED_TRACE(static_cast<int>(encoding));
    test::expectEmptyRoundTrip(
        [encoding](const PolygonSoup& soup) { return roundTrip(soup, encoding); });
  }
}

TEST(PlyTest, NanAttributeValuesPassThrough) {
  for (PlyEncoding encoding : kEncodings) {
    PolygonSoup soup;
    soup.positions = {{0, 0, 0}, {1, 0, 0}};
    soup.attributes.push_back(
        {"confidence", ScalarType::Float32, {std::numeric_limits<double>::quiet_NaN(), 1.0}});
    soup.attributes.push_back(
        {"quality", ScalarType::Float64, {2.0, std::numeric_limits<double>::quiet_NaN()}});
    const PolygonSoup back = roundTrip(soup, encoding);
    ASSERT_EQ(back.attributes.size(), 2u);
    EXPECT_TRUE(std::isnan(back.attributes[0].values[0]));
    EXPECT_EQ(back.attributes[0].values[1], 1.0);
    EXPECT_TRUE(std::isnan(back.attributes[1].values[1]));
  }
}

TEST(PlyTest, LargePolygonsUseWideListCounts) {
  PolygonSoup soup;
  std::vector<std::uint32_t> ring;
  for (std::uint32_t i = 0; i < 300; ++i) {
    soup.positions.emplace_back(std::cos(i * 0.02), std::sin(i * 0.02), 0.0);
    ring.push_back(i);
  }
  soup.addPolygon(ring);
  soup.addPolygon({2, 1, 0});
  for (PlyEncoding encoding : kEncodings) {
    const std::string bytes = write(soup, encoding);
    EXPECT_THAT(bytes, HasSubstr("property list uint int vertex_indices\n"));
    expectSameSoup(readBytes(bytes), soup);
  }
  soup.faceOffsets = {0};
  soup.faceIndices.clear();
  soup.addPolygon({0, 1, 2});
  EXPECT_THAT(write(soup, PlyEncoding::Ascii),
              HasSubstr("property list uchar int vertex_indices\n"));
}

TEST(PlyTest, WritesExpectedAsciiFile) {
  PolygonSoup soup;
  soup.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1.5, 0}};
  soup.addPolygon({0, 1, 2});
  soup.attributes.push_back({"red", ScalarType::UInt8, {255, 0, 7}});
  EXPECT_EQ(write(soup, PlyEncoding::Ascii),
            "ply\nformat ascii 1.0\ncomment written by spacewarp\nelement vertex 3\n"
            "property double x\nproperty double y\nproperty double z\nproperty uchar red\n"
            "element face 1\nproperty list uchar int vertex_indices\nend_header\n"
            "0 0 0 255\n1 0 0 0\n0 1.5 0 7\n3 0 1 2\n");
}

TEST(PlyTest, ReadsAsciiFileWithColoursConfidenceAndExtraElements) {
  const PolygonSoup soup = readBytes(
      "ply\n"
      "format ascii 1.0\n"
      "comment made by hand\n"
      "obj_info nothing\n"
      "element vertex 4\n"
      "property float x\n"
      "property float y\n"
      "property float z\n"
      "property uchar red\n"
      "property uchar green\n"
      "property uchar blue\n"
      "property float confidence\n"
      "element face 2\n"
      "property list uchar int vertex_indices\n"
      "property uchar material\n"
      "element edge 1\n"
      "property int vertex1\n"
      "property int vertex2\n"
      "end_header\n"
      "0 0 0 255 0 0 0.5\n"
      "1 0 0 0 255 0 0.1\n"
      "0 1 0 0 0 255 1\n"
      "1 1 0.3 10 20 30 0.125\n"
      "3 0 1 2 1\n"
      "3 1 3 2 2\n"
      "0 3\n");
  ASSERT_EQ(soup.size(), 4u);
  EXPECT_EQ(soup.positions[3], Vec3(1, 1, static_cast<double>(0.3f)));
  EXPECT_FALSE(soup.hasNormals());
  ASSERT_EQ(soup.polygonCount(), 2u);
  EXPECT_THAT(soup.polygon(1), ElementsAre(1, 3, 2));
  ASSERT_EQ(soup.attributes.size(), 4u);
  EXPECT_EQ(soup.attributes[0].name, "red");
  EXPECT_EQ(soup.attributes[0].type, ScalarType::UInt8);
  EXPECT_THAT(soup.attributes[0].values, ElementsAre(255, 0, 0, 10));
  EXPECT_EQ(soup.attributes[2].name, "blue");
  EXPECT_THAT(soup.attributes[2].values, ElementsAre(0, 0, 255, 30));
  EXPECT_EQ(soup.attributes[3].name, "confidence");
  EXPECT_EQ(soup.attributes[3].type, ScalarType::Float32);
  EXPECT_THAT(soup.attributes[3].values, ElementsAre(0.5, static_cast<double>(0.1f), 1.0, 0.125));
  ASSERT_EQ(soup.faceAttributes.size(), 1u);
  EXPECT_EQ(soup.faceAttributes[0].name, "material");
  EXPECT_EQ(soup.faceAttributes[0].type, ScalarType::UInt8);
  EXPECT_THAT(soup.faceAttributes[0].values, ElementsAre(1, 2));
  EXPECT_NO_THROW(soup.validate());
}

TEST(PlyTest, RoundTripWithFaceAttributesIsExact) {
  for (const PlyEncoding encoding : kEncodings) {
    SCOPED_TRACE(static_cast<int>(encoding));
    PolygonSoup soup = randomSoup(40, 50, 70, true);
    addAttributes(soup, 41);
    soup.faceAttributes = randomAttributes(soup.polygonCount(), 42);
    const PolygonSoup back = roundTrip(soup, encoding);
    expectSameSoup(back, soup);
    expectSameAttributes(back, soup);
  }
}

// What a soup does not keep is named (list properties but the face indices, other elements),
// for the CLI's warning; empty elements drop nothing.
TEST(PlyTest, NamesWhatItReadsButDoesNotKeep) {
  const PolygonSoup soup = readBytes(
      "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
      "property float z\nproperty list uchar int neighbours\nelement face 1\n"
      "property list uchar int vertex_indices\nproperty list uchar float texcoord\n"
      "element edge 1\nproperty int vertex1\nproperty int vertex2\nelement material 0\n"
      "property float shine\nend_header\n0 0 0 0\n1 0 0 0\n0 1 0 0\n3 0 1 2 0\n0 1\n");
  EXPECT_EQ(soup.polygonCount(), 1u);
  EXPECT_EQ(soup.notKept,
            (std::vector<std::string>{"vertex list property 'neighbours'",
                                      "face list property 'texcoord'", "element 'edge'"}));
}

// A point cloud read from a file whose face element is empty keeps that element's
// properties as face attributes without values; writing it must keep them (found by fuzz_ply).
TEST(PlyTest, RoundTripKeepsFaceAttributesOfAnEmptyFaceElement) {
  for (const PlyEncoding encoding : kEncodings) {
    SCOPED_TRACE(static_cast<int>(encoding));
    PolygonSoup soup = randomSoup(5, 6, 0, false);
    soup.faceAttributes = {{"flags", ScalarType::UInt8, {}}, {"quality", ScalarType::Float32, {}}};
    const PolygonSoup back = roundTrip(soup, encoding);
    EXPECT_EQ(back.polygonCount(), 0u);
    expectSameSoup(back, soup);
    expectSameAttributes(back, soup);
  }
}

TEST(PlyTest, ReadsFacePropertiesAroundTheIndexListAndDropsFaceLists) {
  // Binary: a per-face colour before the index list, a quality after it, and a texture
  // coordinate list, which is read through and dropped.
  std::string bytes =
      "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\n"
      "property float y\nproperty float z\nelement face 2\nproperty uchar red\n"
      "property list uchar int vertex_indices\nproperty list uchar float texcoord\n"
      "property float quality\nend_header\n";
  for (int v = 0; v < 3; ++v)
    for (int c = 0; c < 3; ++c) appendLittleEndian(bytes, static_cast<float>(v == c));
  for (int f = 0; f < 2; ++f) {
    appendLittleEndian(bytes, static_cast<std::uint8_t>(200 + f));
    appendLittleEndian(bytes, std::uint8_t{3});
    for (int k = 0; k < 3; ++k) appendLittleEndian(bytes, static_cast<std::int32_t>((k + f) % 3));
    appendLittleEndian(bytes, std::uint8_t{2});
    appendLittleEndian(bytes, 0.5f);
    appendLittleEndian(bytes, 0.25f);
    appendLittleEndian(bytes, f == 0 ? 0.1f : -3.0f);
  }
  const PolygonSoup soup = readBytes(bytes);
  ASSERT_EQ(soup.polygonCount(), 2u);
  EXPECT_THAT(soup.polygon(1), ElementsAre(1, 2, 0));
  ASSERT_EQ(soup.faceAttributes.size(), 2u);
  EXPECT_EQ(soup.faceAttributes[0].name, "red");
  EXPECT_THAT(soup.faceAttributes[0].values, ElementsAre(200, 201));
  EXPECT_EQ(soup.faceAttributes[1].name, "quality");
  EXPECT_EQ(soup.faceAttributes[1].type, ScalarType::Float32);
  EXPECT_THAT(soup.faceAttributes[1].values, ElementsAre(static_cast<double>(0.1f), -3.0));
}

TEST(PlyTest, ReadsBigEndianFileAssembledByteByByte) {
  std::string bytes =
      "ply\n"
      "format binary_big_endian 1.0\n"
      "element vertex 3\n"
      "property float32 x\n"
      "property float32 y\n"
      "property float32 z\n"
      "property uint8 intensity\n"
      "property list uint8 int32 neighbours\n"
      "property int16 nx\n"
      "property int16 ny\n"
      "property int16 nz\n"
      "element face 1\n"
      "property uchar flags\n"
      "property list ushort uint vertex_index\n"
      "element material 2\n"
      "property list uchar float values\n"
      "end_header\n";
  const float xyz[3][3] = {{1.5f, -2.0f, 0.25f}, {3.0f, 4.0f, -5.5f}, {0.0f, 1e-3f, 7.0f}};
  for (int v = 0; v < 3; ++v) {
    for (float c : xyz[v]) appendBigEndian(bytes, c);
    appendBigEndian(bytes, static_cast<std::uint8_t>(10 * v + 1));
    appendBigEndian(bytes, static_cast<std::uint8_t>(2));  // Dropped list.
    appendBigEndian(bytes, static_cast<std::int32_t>(100 + v));
    appendBigEndian(bytes, static_cast<std::int32_t>(-5));
    appendBigEndian(bytes, static_cast<std::int16_t>(0));
    appendBigEndian(bytes, static_cast<std::int16_t>(-1));
    appendBigEndian(bytes, static_cast<std::int16_t>(v));
  }
  appendBigEndian(bytes, static_cast<std::uint8_t>(9));
  appendBigEndian(bytes, static_cast<std::uint16_t>(3));
  for (std::uint32_t i : {2u, 0u, 1u}) appendBigEndian(bytes, i);
  appendBigEndian(bytes, static_cast<std::uint8_t>(1));
  appendBigEndian(bytes, 0.5f);
  appendBigEndian(bytes, static_cast<std::uint8_t>(0));

  const PolygonSoup soup = readBytes(bytes);
  ASSERT_EQ(soup.size(), 3u);
  EXPECT_EQ(soup.positions[0], Vec3(1.5, -2.0, 0.25));
  EXPECT_EQ(soup.positions[2], Vec3(0.0, static_cast<double>(1e-3f), 7.0));
  ASSERT_TRUE(soup.hasNormals());
  EXPECT_EQ(soup.normals[2], Vec3(0, -1, 2));
  ASSERT_EQ(soup.attributes.size(), 1u);
  EXPECT_EQ(soup.attributes[0].name, "intensity");
  EXPECT_EQ(soup.attributes[0].type, ScalarType::UInt8);
  EXPECT_THAT(soup.attributes[0].values, ElementsAre(1, 11, 21));
  ASSERT_EQ(soup.polygonCount(), 1u);
  EXPECT_THAT(soup.polygon(0), ElementsAre(2, 0, 1));
}

TEST(PlyTest, ReadsLittleEndianWithCrLfHeaderAndTrailingBytes) {
  std::string bytes =
      "ply\r\nformat binary_little_endian 1.0\r\nelement vertex 1\r\n"
      "property double x\r\nproperty double y\r\nproperty double z\r\nend_header\r\n";
  for (double c : {0.1, -0.2, 1e300}) appendLittleEndian(bytes, c);
  bytes += "padding";
  const PolygonSoup soup = readBytes(bytes);
  ASSERT_EQ(soup.size(), 1u);
  EXPECT_EQ(soup.positions[0], Vec3(0.1, -0.2, 1e300));
}

TEST(PlyTest, ElementWithoutPropertiesAndHugeCountIsSkipped) {
  const PolygonSoup soup = readBytes(
      "ply\nformat ascii 1.0\nelement nothing 1000000000000000000\n"
      "element vertex 1\nproperty float x\nproperty float y\nproperty float z\nend_header\n"
      "1 2 3\n");
  EXPECT_EQ(soup.size(), 1u);
}

TEST(PlyTest, RejectsHeaderErrors) {
  EXPECT_THAT(errorOf(""), HasSubstr("cloud.ply: empty file"));
  EXPECT_THAT(errorOf("plx\nformat ascii 1.0\nend_header\n"),
              HasSubstr("cloud.ply:1: not a PLY file"));
  EXPECT_THAT(errorOf("ply\nformat binary_middle_endian 1.0\nend_header\n"),
              HasSubstr("cloud.ply:2: unknown format 'binary_middle_endian'"));
  EXPECT_THAT(errorOf("ply\nformat ascii 2.0\nelement vertex 1\nend_header\n"),
              HasSubstr("cloud.ply:2: unsupported PLY version '2.0' (only 1.0 exists)"));
  EXPECT_THAT(errorOf("ply\nformat ascii 1.0\nelement vertex 1\nproperty float128 x\nend_header\n"),
              HasSubstr("cloud.ply:4: unknown property type 'float128'"));
  EXPECT_THAT(
      errorOf("ply\nformat ascii 1.0\nelement vertex 1\nproperty list float int x\nend_header\n"),
      HasSubstr("cloud.ply:4: list count type 'float' is not integral"));
  EXPECT_THAT(errorOf("ply\nformat ascii 1.0\nelement vertex 1\n"),
              HasSubstr("cloud.ply:3: unexpected end of file in the header"));
  EXPECT_THAT(errorOf("ply\nelement vertex 1\nend_header\n"),
              HasSubstr("cloud.ply:3: end_header before any format"));
  EXPECT_THAT(errorOf("ply\nformat ascii 1.0\nelement vertex -1\nend_header\n"),
              HasSubstr("cloud.ply:3: bad element count '-1'"));
  EXPECT_THAT(errorOf("ply\nformat ascii 1.0\nproperty float x\nend_header\n"),
              HasSubstr("cloud.ply:3: property before any element"));
  EXPECT_THAT(errorOf("ply\nformat ascii 1.0\nbogus\nend_header\n"),
              HasSubstr("cloud.ply:3: unknown header keyword 'bogus'"));
  EXPECT_THAT(errorOf("ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float "
                      "x\nend_header\n"),
              HasSubstr("cloud.ply:5: a second property 'x'"));
  EXPECT_THAT(errorOf("ply\nformat ascii 1.0\nelement vertex 10000000000\nend_header\n"),
              HasSubstr("cloud.ply:3: too many vertices"));
}

TEST(PlyTest, RejectsMissingCoordinatesAndPartialNormals) {
  EXPECT_THAT(
      errorOf("ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float z\n"
              "end_header\n1 2\n"),
      HasSubstr("cloud.ply:3: the vertex element has no 'y' property"));
  EXPECT_THAT(
      errorOf("ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n"
              "property float z\nproperty float nx\nend_header\n1 2 3 4\n"),
      HasSubstr("cloud.ply:3: the vertex element has some but not all of nx, ny, nz"));
  EXPECT_THAT(errorOf("ply\nformat ascii 1.0\nelement face 1\nproperty list uchar int corners\n"
                      "end_header\n3 0 1 2\n"),
              HasSubstr("cloud.ply:3: the face element has no 'vertex_indices' list"));
  EXPECT_THAT(
      errorOf("ply\nformat ascii 1.0\nelement face 1\nproperty list uchar float vertex_indices\n"
              "end_header\n3 0 1 2\n"),
      HasSubstr("cloud.ply:3: face property 'vertex_indices' is not integral"));
}

const std::string kAsciiHead =
    "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n"
    "property float z\nelement face 2\nproperty list uchar int vertex_indices\nend_header\n";

TEST(PlyTest, RejectsTruncatedBinaryData) {
  PolygonSoup soup = randomSoup(3, 10, 4, true);
  addAttributes(soup, 4);
  const std::string bytes = write(soup, PlyEncoding::BinaryLittleEndian);
  const std::size_t header = bytes.find("end_header\n") + 11;
  const std::size_t vertexBytes = 6 * 8 + (1 + 1 + 2 + 2 + 4 + 4 + 4 + 8);
  EXPECT_THAT(errorOf(bytes.substr(0, header + 2 * vertexBytes + 5)),
              HasSubstr("cloud.ply: vertex 2: unexpected end of file"));
  EXPECT_THAT(errorOf(bytes.substr(0, header + 10 * vertexBytes + 1)),
              HasSubstr("cloud.ply: face 0: unexpected end of file"));
  EXPECT_THAT(errorOf(bytes.substr(0, bytes.size() - 1)),
              HasSubstr("cloud.ply: face 3: unexpected end of file"));
}

TEST(PlyTest, RejectsWrongElementCounts) {
  // Three vertices where four are declared: the first face line is read as vertex 3.
  EXPECT_THAT(errorOf(kAsciiHead + "0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n3 0 2 1\n"),
              HasSubstr("cloud.ply:13: vertex 3: too many values on the line"));
  EXPECT_THAT(errorOf(kAsciiHead + "0 0 0\n1 0 0\n0 1 0\n1 1 0\n3 0 1 2\n"),
              HasSubstr("cloud.ply:14: face 1: unexpected end of file"));
  EXPECT_THAT(errorOf(kAsciiHead + "0 0 0\n1 0 0\n0 1 0\n1 1 0\n3 0 1 2\n3 0 2 1\n3 1 2 3\n"),
              HasSubstr("cloud.ply:16: unexpected data after the last element"));
  const std::string cloud =
      "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\n"
      "property float y\nproperty float z\nend_header\n";
  EXPECT_THAT(errorOf(cloud + std::string(24, '\0')),
              HasSubstr("cloud.ply: vertex 2: unexpected end of file"));
}

TEST(PlyTest, RejectsTooFewAsciiValues) {
  EXPECT_THAT(errorOf(kAsciiHead + "0 0 0\n1 0\n0 1 0\n1 1 0\n3 0 1 2\n3 0 2 1\n"),
              HasSubstr("cloud.ply:11: vertex 1: too few values on the line (2)"));
  EXPECT_THAT(errorOf(kAsciiHead + "0 0 0\n1 0 0\n0 1 0\n1 1 0\n3 0 1\n3 0 2 1\n"),
              HasSubstr("cloud.ply:14: face 0: too few values"));
}

TEST(PlyTest, RejectsOutOfRangeFaceIndices) {
  EXPECT_THAT(errorOf(kAsciiHead + "0 0 0\n1 0 0\n0 1 0\n1 1 0\n3 0 1 2\n3 0 9 1\n"),
              HasSubstr("cloud.ply:15: face 1: vertex index 9 is out of range (4 vertices)"));
  EXPECT_THAT(errorOf(kAsciiHead + "0 0 0\n1 0 0\n0 1 0\n1 1 0\n3 0 1 2\n3 0 -1 1\n"),
              HasSubstr("cloud.ply:15: face 1: vertex index -1 is out of range"));
  EXPECT_THAT(errorOf(kAsciiHead + "0 0 0\n1 0 0\n0 1 0\n1 1 0\n3 0 1 2\n2 0 1\n"),
              HasSubstr("cloud.ply:15: face 1: polygon has 2 vertices"));
}

TEST(PlyTest, RejectsNanAndNonNumericValues) {
  EXPECT_THAT(errorOf(kAsciiHead + "0 0 0\nnan 0 0\n0 1 0\n1 1 0\n3 0 1 2\n3 0 2 1\n"),
              HasSubstr("cloud.ply:11: vertex 1: non-finite coordinate"));
  EXPECT_THAT(errorOf(kAsciiHead + "0 0 0\n1 0 0\n0 inf 0\n1 1 0\n3 0 1 2\n3 0 2 1\n"),
              HasSubstr("cloud.ply:12: vertex 2: non-finite coordinate"));
  EXPECT_THAT(errorOf(kAsciiHead + "0 0 0\n1 abc 0\n0 1 0\n1 1 0\n3 0 1 2\n3 0 2 1\n"),
              HasSubstr("cloud.ply:11: vertex 1: value 'abc' is not a number for type float"));
  EXPECT_THAT(errorOf(kAsciiHead + "0 0 0\n1 0 0\n0 1 0\n1 1 0\n3 0 1 2\n3 0 2 1.5\n"),
              HasSubstr("cloud.ply:15: face 1: value '1.5' is not an integer for type int"));
  EXPECT_THAT(errorOf(kAsciiHead + "0 0 0\n1 0 0\n0 1 0\n1 1 0\n3 0 1 2\n256 0 2 1\n"),
              HasSubstr("cloud.ply:15: face 1: value '256' is out of range for type uchar"));
  std::string binary =
      "ply\nformat binary_little_endian 1.0\nelement vertex 2\nproperty double x\n"
      "property double y\nproperty double z\nend_header\n";
  for (double c : {0.0, 0.0, 0.0, 1.0, std::numeric_limits<double>::quiet_NaN(), 0.0})
    appendLittleEndian(binary, c);
  EXPECT_THAT(errorOf(binary), HasSubstr("cloud.ply: vertex 1: non-finite coordinate"));
}

TEST(PlyTest, HugeDeclaredCountsFailWithoutHugeAllocations) {
  EXPECT_THAT(errorOf("ply\nformat binary_little_endian 1.0\nelement vertex 4000000000\n"
                      "property double x\nproperty double y\nproperty double z\nend_header\n" +
                      std::string(30, '\0')),
              HasSubstr("cloud.ply: vertex 1: unexpected end of file"));
  std::string bytes =
      "ply\nformat binary_little_endian 1.0\nelement face 1000000000000000000\n"
      "property list uint int vertex_indices\nend_header\n";
  appendLittleEndian(bytes, std::uint32_t{4000000000u});
  EXPECT_THAT(errorOf(bytes), HasSubstr("cloud.ply: face 0: unexpected end of file"));
  EXPECT_THAT(
      errorOf("ply\nformat ascii 1.0\nelement junk 1000000000000000000\nproperty list uint char v\n"
              "end_header\n4000000000 1 2\n"),
      HasSubstr("cloud.ply:6: junk 0: too few values"));
  std::string negative =
      "ply\nformat binary_little_endian 1.0\nelement face 1\nproperty list char int "
      "vertex_indices\n"
      "end_header\n\xff";
  EXPECT_THAT(errorOf(negative), HasSubstr("cloud.ply: face 0: negative list length -1"));
}

TEST(PlyTest, WriteRejectsBadAttributes) {
  PolygonSoup soup;
  soup.positions = {{0, 0, 0}, {1, 0, 0}};
  std::ostringstream out;
  soup.attributes = {{"has space", ScalarType::UInt8, {0, 0}}};
  EXPECT_THROW(writePly(soup, out), InvalidInput);
  soup.attributes = {{"", ScalarType::UInt8, {0, 0}}};
  EXPECT_THROW(writePly(soup, out), InvalidInput);
  soup.attributes = {{"nx", ScalarType::Float64, {0, 0}}};
  EXPECT_THROW(writePly(soup, out), InvalidInput);
  soup.attributes = {{"a", ScalarType::UInt8, {0, 0}}, {"a", ScalarType::UInt8, {0, 0}}};
  EXPECT_THROW(writePly(soup, out), InvalidInput);
  soup.attributes = {{"red", ScalarType::UInt8, {0, 256}}};
  EXPECT_THROW(writePly(soup, out), InvalidInput);
  soup.attributes = {{"id", ScalarType::Int32, {0.5, 1}}};
  EXPECT_THROW(writePly(soup, out), InvalidInput);
  soup.attributes = {{"c", ScalarType::Float32, {1e300, 1}}};
  EXPECT_THROW(writePly(soup, out), InvalidInput);
  soup.attributes = {{"short", ScalarType::Float32, {1}}};
  EXPECT_THROW(writePly(soup, out), InvalidInput);
}

TEST(PlyTest, WriteRejectsBadFaceAttributes) {
  PolygonSoup soup;
  soup.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
  soup.addPolygon({0, 1, 2});
  const auto messageOf = [&] {
    std::ostringstream out;
    return test::messageOf<InvalidInput>([&] { writePly(soup, out); });
  };
  soup.faceAttributes = {{"vertex_indices", ScalarType::UInt8, {0}}};
  EXPECT_THAT(messageOf(), HasSubstr("face attribute 0 'vertex_indices': the name is reserved"));
  soup.faceAttributes = {{"red", ScalarType::UInt8, {300}}};
  EXPECT_THAT(messageOf(), HasSubstr("face attribute 0 'red': face 0: value"));
  soup.faceAttributes = {{"red", ScalarType::UInt8, {1, 2}}};
  EXPECT_THAT(messageOf(), HasSubstr("face attribute 'red' has 2 values for 1 polygons"));
  // A vertex attribute may share a face attribute's name: they are properties of different
  // elements.
  soup.faceAttributes = {{"red", ScalarType::UInt8, {1}}};
  soup.attributes = {{"red", ScalarType::UInt8, {1, 2, 3}}};
  EXPECT_EQ(messageOf(), "");
}

}  // namespace
}  // namespace spacewarp
