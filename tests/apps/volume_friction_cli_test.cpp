// End-to-end tests of the volume side of `deform`'s file checks and summary, and of
// `spacewarp info` on .vdb files.

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <string>
#include <utility>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <openvdb/io/File.h>
#include <openvdb/openvdb.h>
#include <openvdb/tools/LevelSetSphere.h>

#include "apps/cli_test_util.h"

namespace spacewarp {
namespace {

namespace fs = std::filesystem;
using test::CliResult;
using ::testing::HasSubstr;

// 1234567 as "1,234,567".
std::string grouped(std::uint64_t n) {
  const std::string digits = std::to_string(n);
  std::string out;
  for (std::size_t i = 0; i < digits.size(); ++i) {
    // (Appended piece by piece: GCC 12 warns falsely about "literal" + std::string here.)
    if (i > 0 && (digits.size() - i) % 3 == 0) out += ',';
    out += digits[i];
  }
  return out;
}

constexpr float kVoxel = 0.125f;  // exact in binary, so printed exactly

class VolumeFrictionTest : public test::CliFixture {
 protected:
  VolumeFrictionTest() : CliFixture("spacewarp_volume_friction_") {}

  // in.vdb: a level set sphere "surface" (grid metadata "author"), a 5^3 fog block "density"
  // and file metadata "scene".
  void writeInput() {
    openvdb::initialize();
    sphere_ = openvdb::tools::createLevelSetSphere<openvdb::FloatGrid>(0.6f, openvdb::Vec3f(0.0f),
                                                                       kVoxel, 3.0f);
    sphere_->setName("surface");
    sphere_->insertMeta("author", openvdb::StringMetadata("spacewarp tests"));
    auto fog = openvdb::FloatGrid::create(0.0f);
    fog->setName("density");
    fog->setGridClass(openvdb::GRID_FOG_VOLUME);
    fog->setTransform(openvdb::math::Transform::createLinearTransform(kVoxel));
    for (int i = -2; i <= 2; ++i)
      for (int j = -2; j <= 2; ++j)
        for (int k = -2; k <= 2; ++k) fog->tree().setValue(openvdb::Coord(i, j, k), 1.0f);
    openvdb::MetaMap meta;
    meta.insertMeta("scene", openvdb::StringMetadata("unit test"));
    openvdb::io::File file((dir_ / "in.vdb").string());
    file.write({sphere_, fog}, meta);
    file.close();
  }

  openvdb::FloatGrid::Ptr sphere_;
};

TEST_F(VolumeFrictionTest, InfoDescribesEveryGridAndTheMetadata) {
  writeInput();
  const CliResult r = run("info " + (dir_ / "in.vdb").string());
  ASSERT_EQ(r.exitCode, 0) << r.err;
  EXPECT_THAT(r.out, HasSubstr("grids:      2\n"));
  EXPECT_THAT(r.out, HasSubstr("scene = unit test"));
  EXPECT_THAT(r.out, HasSubstr("grid 'surface':\n  class:          level set\n"
                               "  value type:     float"));
  EXPECT_THAT(r.out, HasSubstr("author = spacewarp tests"));
  EXPECT_THAT(r.out, HasSubstr("  voxel size:     0.125 0.125 0.125\n"));
  EXPECT_THAT(r.out, HasSubstr("grid 'density':\n  class:          fog volume\n"));
  EXPECT_THAT(r.out, HasSubstr("  active voxels:  125\n"));
  // The fog block's voxels span [-2.5, 2.5] voxels: [-0.3125, 0.3125] in world units.
  EXPECT_THAT(r.out, HasSubstr("  active index box: [-2 -2 -2] .. [2 2 2]\n"
                               "  active world box: [-0.3125 -0.3125 -0.3125] .. "
                               "[0.3125 0.3125 0.3125]\n"));
  EXPECT_THAT(r.out, HasSubstr("  active voxels:  " + grouped(sphere_->activeVoxelCount()) + "\n"));
}

TEST_F(VolumeFrictionTest, AVolumeIsWrittenOnlyAsVdbBeforeAnyWork) {
  writeInput();
  write("twist.json", R"({"method": "twist", "origin": [0,0,0], "axis": [0,1,0], "rate": 0.8})");
  for (const std::string output : {"out.obj", "out.ply", "out.off"}) {
    const CliResult r = run("deform --rig " + (dir_ / "twist.json").string() + " " +
                            (dir_ / "in.vdb").string() + " -o " + (dir_ / output).string());
    EXPECT_EQ(r.exitCode, 2) << r.err;
    EXPECT_THAT(r.err, HasSubstr("in.vdb -> " + (dir_ / output).string()));
    EXPECT_FALSE(fs::exists(dir_ / output));
  }
}

TEST_F(VolumeFrictionTest, ABadVolumeIsReportedBeforeTheRigIsRead) {
  write("garbage.vdb", "not a vdb file");
  const CliResult r = run("deform --rig " + (dir_ / "missing.json").string() + " " +
                          (dir_ / "garbage.vdb").string() + " -o " + (dir_ / "out.vdb").string());
  EXPECT_EQ(r.exitCode, 3);
  EXPECT_THAT(r.err, HasSubstr("garbage.vdb"));
  EXPECT_THAT(r.err, ::testing::Not(HasSubstr("missing.json")));
  EXPECT_FALSE(fs::exists(dir_ / "out.vdb"));
}

TEST_F(VolumeFrictionTest, TruncatedFilesAreRefusedByInfoAndDeformNamingTheFile) {
  // io::File read a cut file as one whose grids were empty or partial, and both commands
  // succeeded. (Every cut is tried in tests/volume/read_vdb_test.cpp; these are the CLI's.)
  writeInput();
  write("twist.json", R"({"method": "twist", "origin": [0,0,0], "axis": [0,1,0], "rate": 0.8})");
  const std::string bytes = test::slurp(dir_ / "in.vdb");
  const std::string cut = (dir_ / "cut.vdb").string();
  const std::string out = (dir_ / "out.vdb").string();
  for (const std::size_t length :
       {std::size_t{0}, std::size_t{7}, std::size_t{100}, std::size_t{1000}, std::size_t{1040},
        bytes.size() / 3, bytes.size() / 2, bytes.size() - 1}) {
    SCOPED_TRACE("the first " + std::to_string(length) + " of " + std::to_string(bytes.size()) +
                 " bytes");
    fs::remove(cut);
    write("cut.vdb", bytes.substr(0, length));
    for (const std::string& args :
         {"info " + cut,
          "deform --rig " + (dir_ / "twist.json").string() + " " + cut + " -o " + out}) {
      const CliResult r = run(args);
      EXPECT_EQ(r.exitCode, 3) << args;
      EXPECT_THAT(r.err, ::testing::StartsWith("spacewarp: error: " + cut +
                                               ": truncated or corrupt OpenVDB file: "));
      EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
      EXPECT_EQ(r.out, "") << args;
      EXPECT_FALSE(fs::exists(out));
    }
  }
}

TEST_F(VolumeFrictionTest, OpenVdbWarningsAreOneLineWarningsNamingTheFile) {
  // OpenVDB printed these itself: its library's in colour on stdout (" WARN: ..." between
  // escape codes, in the middle of info's output), its headers' as "WARNING: ..." on stderr.
  writeInput();
  write("twist.json", R"({"method": "twist", "origin": [0,0,0], "axis": [0,1,0], "rate": 0.8})");
  const std::string bytes = test::slurp(dir_ / "in.vdb");

  // A newer file format version than this OpenVDB's (224): warned about by its library.
  std::string future = bytes;
  const std::uint32_t version = 225;
  std::memcpy(future.data() + 8, &version, sizeof version);
  write("future.vdb", future);
  // A tree that says it has two buffers: warned about by its headers. The level set's tree
  // starts with its buffer count (1), its background (3 voxels) and its tile count (0).
  std::string pattern(12, '\0');
  const std::int32_t one = 1;
  const float background = 3 * kVoxel;
  std::memcpy(pattern.data(), &one, 4);
  std::memcpy(pattern.data() + 4, &background, 4);
  const std::size_t at = bytes.find(pattern);
  ASSERT_NE(at, std::string::npos);
  ASSERT_EQ(at, bytes.rfind(pattern));
  std::string multi = bytes;
  multi[at] = 2;
  write("multi.vdb", multi);

  const std::string out = (dir_ / "out.vdb").string();
  for (const auto& [name, message] : std::vector<std::pair<std::string, std::string>>{
           {"future.vdb",
            "unsupported VDB file format (expected version 224 or earlier, got version 225)"},
           {"multi.vdb", "multi-buffer trees are no longer supported"}}) {
    SCOPED_TRACE(name);
    const std::string path = (dir_ / name).string();
    const std::string warning = "spacewarp: warning: " + path + ": " + message + "\n";
    CliResult r = run("info " + path);
    EXPECT_EQ(r.exitCode, 0) << r.err;
    EXPECT_EQ(r.err, warning);
    EXPECT_THAT(r.out, ::testing::StartsWith("file:       " + path + "\n"));
    EXPECT_EQ(r.out.find('\033'), std::string::npos) << r.out;
    // deform checks the header before the rig and reads the file after: warned about once.
    r = run("deform --rig " + (dir_ / "twist.json").string() + " " + path + " -o " + out);
    EXPECT_EQ(r.exitCode, 0) << r.err;
    EXPECT_EQ(r.err, warning);
    EXPECT_THAT(r.out, HasSubstr(", 1 warning\n"));
    EXPECT_EQ(r.out.find('\033'), std::string::npos) << r.out;
  }
}

TEST_F(VolumeFrictionTest, DeformSummarisesGridsVoxelsAndInverseFailures) {
  writeInput();
  write("twist.json", R"({"method": "twist", "origin": [0,0,0], "axis": [0,1,0], "rate": 0.8})");
  const std::string out = (dir_ / "out.vdb").string();
  const CliResult r = run("deform --rig " + (dir_ / "twist.json").string() + " " +
                          (dir_ / "in.vdb").string() + " -o " + out);
  ASSERT_EQ(r.exitCode, 0) << r.err;
  EXPECT_THAT(r.out, ::testing::ContainsRegex("deformed 2 grids \\([0-9,]+ active voxels, 0 "
                                              "inverse failures\\) in [0-9.e-]+ s -> " +
                                              out + "\n"));
  // The voxel count is the written grids' total.
  openvdb::io::File file(out);
  file.open();
  openvdb::Index64 total = 0;
  const openvdb::GridPtrVecPtr grids = file.getGrids();  // kept: the loop borrows from it
  for (const auto& grid : *grids) total += grid->activeVoxelCount();
  file.close();
  EXPECT_THAT(r.out, HasSubstr("deformed 2 grids (" + grouped(total) + " active voxels"));
}

}  // namespace
}  // namespace spacewarp
