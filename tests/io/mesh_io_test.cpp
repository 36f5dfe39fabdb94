#include <spacewarp/core/io/mesh_io.h>

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <random>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <spacewarp/core/errors.h>
#include <spacewarp/core/io/detail/text_format.h>
#include <spacewarp/core/io/obj.h>
#include <spacewarp/core/io/off.h>
#include <spacewarp/core/io/ply.h>
#include "endless_input.h"
#include "io_test_util.h"

namespace spacewarp {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

using test::expectSameSoup;
using test::listDirectory;
using test::TempDir;
using test::writeFile;

PolygonSoup sampleSoup(bool withNormals, bool withFaces) {
  std::mt19937_64 rng(42);
  std::uniform_real_distribution<double> coordinate(-10.0, 10.0);
  PolygonSoup soup;
  for (int v = 0; v < 40; ++v) {
    soup.positions.emplace_back(coordinate(rng), coordinate(rng), coordinate(rng));
    if (withNormals)
      soup.normals.push_back(glm::normalize(Vec3(coordinate(rng), coordinate(rng), 1.0)));
  }
  if (withFaces) {
    for (std::uint32_t p = 0; p < 30; ++p) {
      const std::uint32_t size = 3 + p % 5;
      std::vector<std::uint32_t> polygon;
      for (std::uint32_t k = 0; k < size; ++k) polygon.push_back((p * 7 + k * 3) % 40);
      soup.addPolygon(polygon);
    }
  }
  return soup;
}

/// The message of the IoError that reading `path` throws ("" if none).
std::string readError(const fs::path& path) {
  return test::messageOf<IoError>([&] { readSoup(path); });
}

TEST(MeshIoTest, FormatFromPathIsCaseInsensitive) {
  EXPECT_EQ(formatFromPath("a/b/model.obj"), FileFormat::Obj);
  EXPECT_EQ(formatFromPath("MODEL.OBJ"), FileFormat::Obj);
  EXPECT_EQ(formatFromPath("mesh.Off"), FileFormat::Off);
  EXPECT_EQ(formatFromPath("scan.tar.PLY"), FileFormat::Ply);
}

TEST(MeshIoTest, FormatFromPathRejectsUnknownExtensions) {
  const std::string message = test::messageOf<IoError>([] { formatFromPath("dir/model.stl"); });
  EXPECT_THAT(message, HasSubstr("dir/model.stl"));
  EXPECT_THAT(message, HasSubstr("'.stl'"));
  EXPECT_THROW(formatFromPath("noextension"), IoError);
  EXPECT_THROW(formatFromPath("model.obj.bak"), IoError);
}

TEST(MeshIoTest, RoundTripEveryFormat) {
  TempDir dir;
  for (const char* file : {"soup.obj", "soup.off", "soup.ply", "SOUP.PLY"}) {
    for (bool withNormals : {false, true}) {
      for (bool withFaces : {false, true}) {
        SCOPED_TRACE(std::string(file) + (withNormals ? " normals" : "") +
                     (withFaces ? " faces" : ""));
        const PolygonSoup soup = sampleSoup(withNormals, withFaces);
        writeSoup(soup, dir.path() / file);
        expectSameSoup(readSoup(dir.path() / file), soup);
      }
    }
  }
  EXPECT_EQ(listDirectory(dir.path()).size(), 4u);
}

TEST(MeshIoTest, PlyEncodingOption) {
  TempDir dir;
  PolygonSoup soup = sampleSoup(true, true);
  soup.attributes.push_back({"label", ScalarType::Int16, std::vector<double>(soup.size(), -7.0)});
  for (PlyEncoding encoding :
       {PlyEncoding::Ascii, PlyEncoding::BinaryLittleEndian, PlyEncoding::BinaryBigEndian}) {
    const fs::path path = dir.path() / "soup.ply";
    writeSoup(soup, path, WriteOptions{encoding});
    std::ifstream in(path, std::ios::binary);
    std::string magic;
    std::string format;
    std::getline(in, magic);
    std::getline(in, format);
    EXPECT_EQ(format, encoding == PlyEncoding::Ascii ? "format ascii 1.0"
                      : encoding == PlyEncoding::BinaryLittleEndian
                          ? "format binary_little_endian 1.0"
                          : "format binary_big_endian 1.0");
    const PolygonSoup back = readSoup(path);
    expectSameSoup(back, soup);
    ASSERT_EQ(back.attributes.size(), 1u);
    EXPECT_EQ(back.attributes[0].values, soup.attributes[0].values);
  }
}

TEST(MeshIoTest, MissingFileThrowsCannotOpen) {
  TempDir dir;
  const fs::path path = dir.path() / "missing.obj";
  const std::string message = readError(path);
  EXPECT_THAT(message, HasSubstr("cannot open"));
  EXPECT_THAT(message, HasSubstr(path.string()));
}

// The ASCII PLY header of one vertex: its values follow on line 8.
const std::string kAsciiPlyHeader =
    "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n"
    "property float z\nend_header\n";

TEST(MeshIoTest, BinaryFilesAreRefusedAtTheirFirstNulNamingFileLineAndOffset) {
  TempDir dir;
  std::mt19937_64 rng(3);
  std::string random(100000, ' ');
  for (char& c : random) c = static_cast<char>(rng());
  for (const std::string extension : {"obj", "off", "ply"}) {
    SCOPED_TRACE(extension);
    const fs::path zeros = dir.path() / ("zeros." + extension);
    writeFile(zeros, std::string(1 << 20, '\0'));
    EXPECT_EQ(readError(zeros),
              zeros.string() + ":1: unexpected NUL byte (byte offset 0): not a text file");
    // Random bytes; for PLY as the values of an ASCII file, where they fail as a value.
    const fs::path noise = dir.path() / ("noise." + extension);
    writeFile(noise, (extension == "ply" ? kAsciiPlyHeader : "") + random);
    EXPECT_THAT(readError(noise), ::testing::StartsWith(noise.string() + ":"));
  }
  // A NUL after valid lines is found on its line, at its offset.
  const fs::path late = dir.path() / "late.ply";
  writeFile(late, kAsciiPlyHeader + "1 2 3\n" + std::string("\0", 1));
  EXPECT_EQ(readError(late), late.string() + ":9: unexpected NUL byte (byte offset " +
                                 std::to_string(kAsciiPlyHeader.size() + 6) + "): not a text file");
}

// Every text reader on input that never ends (as /dev/zero or a FIFO fed forever): NULs fail
// within the first block read, a line that never ends at the line length limit; neither is
// read on into memory. (The readers used to take the whole input before looking at it.)
TEST(MeshIoTest, EndlessInputIsRefusedAfterABoundedRead) {
  using Reader = PolygonSoup (*)(std::istream&, const std::string&);
  const std::pair<Reader, std::string> readers[] = {
      {readObj, ""}, {readOff, ""}, {readPly, ""}, {readPly, kAsciiPlyHeader}};
  for (const auto& [read, prefix] : readers) {
    SCOPED_TRACE(prefix.empty() ? "from the first byte" : "after an ASCII PLY header");
    test::EndlessInput zeros(prefix, '\0');
    std::istream zeroStream(&zeros);
    EXPECT_THAT(test::messageOf<IoError>([&] { read(zeroStream, "endless"); }),
                HasSubstr("unexpected NUL byte (byte offset " + std::to_string(prefix.size()) +
                          "): not a text file"));
    EXPECT_LE(zeros.served(), prefix.size() + test::EndlessInput::kBlockBound);

    test::EndlessInput letters(prefix, '7');
    std::istream letterStream(&letters);
    EXPECT_THAT(test::messageOf<IoError>([&] { read(letterStream, "endless"); }),
                HasSubstr("line too long"));
    EXPECT_LE(letters.served(),
              prefix.size() + detail::kMaxTextLine + test::EndlessInput::kBlockBound);
  }
}

TEST(MeshIoTest, DirectoryThrowsIoError) {
  TempDir dir;
  fs::create_directory(dir.path() / "folder.ply");
  EXPECT_THAT(readError(dir.path() / "folder.ply"), HasSubstr("folder.ply"));
}

TEST(MeshIoTest, UnknownExtensionOnReadNamesTheFile) {
  TempDir dir;
  writeFile(dir.path() / "model.stl", "solid\n");
  EXPECT_THAT(readError(dir.path() / "model.stl"), HasSubstr("model.stl"));
}

TEST(MeshIoTest, MalformedFilesNameTheFileAndLine) {
  TempDir dir;
  writeFile(dir.path() / "bad.obj", "v 0 0 0\nv nan 1 2\n");
  EXPECT_THAT(readError(dir.path() / "bad.obj"),
              HasSubstr((dir.path() / "bad.obj").string() + ":2: vertex has a non-finite"));
  writeFile(dir.path() / "bad.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n");
  EXPECT_THAT(readError(dir.path() / "bad.off"),
              HasSubstr((dir.path() / "bad.off").string() + ":6: face 0: vertex index 3"));
  writeFile(dir.path() / "bad.ply",
            "ply\nformat binary_little_endian 1.0\nelement vertex 2\nproperty float x\n"
            "property float y\nproperty float z\nend_header\n" +
                std::string(20, '\0'));
  EXPECT_THAT(readError(dir.path() / "bad.ply"),
              HasSubstr((dir.path() / "bad.ply").string() + ": vertex 1: unexpected end of file"));
}

TEST(MeshIoTest, InputsWithoutVerticesAreErrorsNamingTheFile) {
  TempDir dir;
  const std::pair<const char*, const char*> files[] = {
      {"empty.obj", ""},
      {"comments.obj", "# nothing here\ng group\n"},
      {"empty.off", ""},
      {"zero.off", "OFF\n0 0 0\n"},
      {"empty.ply", ""},
      {"zero.ply",
       "ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\n"
       "property float y\nproperty float z\nend_header\n"},
      {"novertex.ply", "ply\nformat ascii 1.0\nend_header\n"}};
  for (const auto& [name, text] : files) {
    SCOPED_TRACE(name);
    writeFile(dir.path() / name, text);
    EXPECT_THAT(readError(dir.path() / name), HasSubstr((dir.path() / name).string() + ": "));
  }
  EXPECT_THAT(readError(dir.path() / "empty.obj"), HasSubstr("empty.obj: no vertices"));
  EXPECT_THAT(readError(dir.path() / "zero.ply"), HasSubstr("zero.ply: no vertices"));
}

TEST(MeshIoTest, AttributesSurviveFilesInTheirFormats) {
  TempDir dir;
  PolygonSoup soup = sampleSoup(false, true);
  soup.texcoords.values = {{0.25, 0.5, 0}, {1, 0, 0}};
  soup.cornerNormals.values = {{0, 0, 1}, {0, 1, 0}};
  for (std::size_t c = 0; c < soup.faceIndices.size(); ++c) {
    soup.texcoords.indices.push_back(static_cast<std::uint32_t>(c % 2));
    // No normals on the first triangle, so they cannot read back as per-vertex normals.
    soup.cornerNormals.indices.push_back(c < 3 ? CornerAttribute::kNone
                                               : static_cast<std::uint32_t>(c % 3 == 0));
  }
  writeSoup(soup, dir.path() / "a.obj");
  const PolygonSoup obj = readSoup(dir.path() / "a.obj");
  expectSameSoup(obj, soup);
  EXPECT_EQ(obj.texcoords.values, soup.texcoords.values);
  EXPECT_EQ(obj.texcoords.indices, soup.texcoords.indices);
  EXPECT_EQ(obj.cornerNormals.values, soup.cornerNormals.values);
  EXPECT_EQ(obj.cornerNormals.indices, soup.cornerNormals.indices);

  PolygonSoup colours = sampleSoup(true, true);
  colours.attributes = {{"red", ScalarType::UInt8, std::vector<double>(colours.size(), 7)}};
  colours.faceAttributes = {
      {"material_index", ScalarType::Int32, std::vector<double>(colours.polygonCount(), -2)}};
  writeSoup(colours, dir.path() / "a.ply");
  const PolygonSoup ply = readSoup(dir.path() / "a.ply");
  expectSameSoup(ply, colours);
  ASSERT_EQ(ply.attributes.size(), 1u);
  EXPECT_EQ(ply.attributes[0].values, colours.attributes[0].values);
  ASSERT_EQ(ply.faceAttributes.size(), 1u);
  EXPECT_EQ(ply.faceAttributes[0].name, "material_index");
  EXPECT_EQ(ply.faceAttributes[0].type, ScalarType::Int32);
  EXPECT_EQ(ply.faceAttributes[0].values, colours.faceAttributes[0].values);
}

TEST(MeshIoTest, UnstoredContentNamesWhatAFormatDrops) {
  PolygonSoup soup = sampleSoup(false, true);
  EXPECT_TRUE(unstoredContent(soup, FileFormat::Off).empty()) << "positions and faces fit all";
  soup.attributes = {{"red", ScalarType::UInt8, std::vector<double>(soup.size(), 1)},
                     {"green", ScalarType::UInt8, std::vector<double>(soup.size(), 2)}};
  soup.faceAttributes = {
      {"material_index", ScalarType::Int32, std::vector<double>(soup.polygonCount(), 0)}};
  soup.texcoords.values = {{0, 0, 0}};
  soup.texcoords.indices.assign(soup.faceIndices.size(), 0);
  soup.objStatements = {{0, "usemtl red"}};
  using ::testing::ElementsAre;
  EXPECT_THAT(unstoredContent(soup, FileFormat::Obj),
              ElementsAre("vertex attributes red, green", "face attributes material_index"));
  EXPECT_THAT(unstoredContent(soup, FileFormat::Ply),
              ElementsAre("texture coordinates", "OBJ groups and materials"));
  EXPECT_EQ(unstoredContent(soup, FileFormat::Off).size(), 4u);
  // With blue too, OFF stores the colours; the rest is still lost.
  soup.attributes.push_back({"blue", ScalarType::UInt8, std::vector<double>(soup.size(), 3)});
  soup.attributes.push_back({"confidence", ScalarType::Float32, std::vector<double>(soup.size())});
  EXPECT_THAT(unstoredContent(soup, FileFormat::Off),
              ElementsAre("vertex attributes confidence", "face attributes material_index",
                          "texture coordinates", "OBJ groups and materials"));
  soup.texcoords = {};
  soup.cornerNormals.values = {{0, 0, 1}};
  soup.cornerNormals.indices.assign(soup.faceIndices.size(), 0);
  EXPECT_THAT(unstoredContent(soup, FileFormat::Ply),
              ElementsAre("per-corner normals", "OBJ groups and materials"));
}

TEST(MeshIoTest, WriteToMissingDirectoryThrowsAndLeavesNothing) {
  TempDir dir;
  const fs::path path = dir.path() / "missing" / "out.ply";
  EXPECT_THAT(test::messageOf<IoError>([&] { writeSoup(sampleSoup(false, true), path); }),
              HasSubstr(path.string()));
  EXPECT_TRUE(listDirectory(dir.path()).empty());
}

TEST(MeshIoTest, WriteToUnwritableLocationThrowsAndLeavesNothing) {
  TempDir dir;
  writeFile(dir.path() / "plain_file", "x");
  EXPECT_THROW(writeSoup(sampleSoup(false, true), dir.path() / "plain_file" / "out.obj"), IoError);
  EXPECT_EQ(listDirectory(dir.path()), std::set<std::string>{"plain_file"});
}

TEST(MeshIoTest, WriteWithUnknownExtensionThrowsAndLeavesNothing) {
  TempDir dir;
  EXPECT_THROW(writeSoup(sampleSoup(false, true), dir.path() / "out.stl"), IoError);
  EXPECT_TRUE(listDirectory(dir.path()).empty());
}

TEST(MeshIoTest, InvalidSoupThrowsAndKeepsTheOldFile) {
  TempDir dir;
  const fs::path path = dir.path() / "out.off";
  const PolygonSoup good = sampleSoup(false, true);
  writeSoup(good, path);
  PolygonSoup bad = good;
  bad.addPolygon({0, 1, 4000});
  EXPECT_THROW(writeSoup(bad, path), InvalidInput);
  expectSameSoup(readSoup(path), good);
  EXPECT_EQ(listDirectory(dir.path()), std::set<std::string>{"out.off"});
}

}  // namespace
}  // namespace spacewarp
