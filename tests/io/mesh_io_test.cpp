#include "core/io/mesh_io.h"

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <random>
#include <set>
#include <string>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "core/errors.h"
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
