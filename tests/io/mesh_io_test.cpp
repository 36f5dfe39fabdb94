#include "core/io/mesh_io.h"

#include <filesystem>
#include <fstream>
#include <random>
#include <set>
#include <string>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "core/errors.h"

namespace spacewarp {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

/// A fresh directory under the system temp directory, removed with everything in it.
class TempDir {
 public:
  TempDir() {
    std::random_device device;
    path_ = fs::temp_directory_path() /
            ("spacewarp_mesh_io_test_" + std::to_string(device()) + "_" + std::to_string(device()));
    fs::create_directories(path_);
  }
  ~TempDir() {
    std::error_code ignored;
    fs::remove_all(path_, ignored);
  }
  const fs::path& path() const { return path_; }

 private:
  fs::path path_;
};

std::set<std::string> listDirectory(const fs::path& directory) {
  std::set<std::string> names;
  for (const auto& entry : fs::directory_iterator(directory))
    names.insert(entry.path().filename().string());
  return names;
}

void writeText(const fs::path& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary);
  out << text;
}

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

void expectSameSoup(const PolygonSoup& a, const PolygonSoup& b) {
  EXPECT_EQ(a.positions, b.positions);
  EXPECT_EQ(a.normals, b.normals);
  EXPECT_EQ(a.faceOffsets, b.faceOffsets);
  EXPECT_EQ(a.faceIndices, b.faceIndices);
}

/// The message of the IoError that reading `path` throws ("" if none).
std::string readError(const fs::path& path) {
  try {
    readSoup(path);
  } catch (const IoError& e) {
    return e.what();
  }
  return "";
}

TEST(MeshIoTest, FormatFromPathIsCaseInsensitive) {
  EXPECT_EQ(formatFromPath("a/b/model.obj"), FileFormat::Obj);
  EXPECT_EQ(formatFromPath("MODEL.OBJ"), FileFormat::Obj);
  EXPECT_EQ(formatFromPath("mesh.Off"), FileFormat::Off);
  EXPECT_EQ(formatFromPath("scan.tar.PLY"), FileFormat::Ply);
}

TEST(MeshIoTest, FormatFromPathRejectsUnknownExtensions) {
  try {
    formatFromPath("dir/model.stl");
    FAIL() << "no exception";
  } catch (const IoError& e) {
    EXPECT_THAT(e.what(), HasSubstr("dir/model.stl"));
    EXPECT_THAT(e.what(), HasSubstr("'.stl'"));
  }
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
  writeText(dir.path() / "model.stl", "solid\n");
  EXPECT_THAT(readError(dir.path() / "model.stl"), HasSubstr("model.stl"));
}

TEST(MeshIoTest, MalformedFilesNameTheFileAndLine) {
  TempDir dir;
  writeText(dir.path() / "bad.obj", "v 0 0 0\nv nan 1 2\n");
  EXPECT_THAT(readError(dir.path() / "bad.obj"),
              HasSubstr((dir.path() / "bad.obj").string() + ":2: vertex has a non-finite"));
  writeText(dir.path() / "bad.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n");
  EXPECT_THAT(readError(dir.path() / "bad.off"),
              HasSubstr((dir.path() / "bad.off").string() + ":6: face 0: vertex index 3"));
  writeText(dir.path() / "bad.ply",
            "ply\nformat binary_little_endian 1.0\nelement vertex 2\nproperty float x\n"
            "property float y\nproperty float z\nend_header\n" +
                std::string(20, '\0'));
  EXPECT_THAT(readError(dir.path() / "bad.ply"),
              HasSubstr((dir.path() / "bad.ply").string() + ": vertex 1: unexpected end of file"));
}

TEST(MeshIoTest, WriteToMissingDirectoryThrowsAndLeavesNothing) {
  TempDir dir;
  const fs::path path = dir.path() / "missing" / "out.ply";
  try {
    writeSoup(sampleSoup(false, true), path);
    FAIL() << "no exception";
  } catch (const IoError& e) {
    EXPECT_THAT(e.what(), HasSubstr(path.string()));
  }
  EXPECT_TRUE(listDirectory(dir.path()).empty());
}

TEST(MeshIoTest, WriteToUnwritableLocationThrowsAndLeavesNothing) {
  TempDir dir;
  writeText(dir.path() / "plain_file", "x");
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
