// End-to-end tests of the "mls" rig with "distance": "inside": deform agrees with the library on
// soups and point clouds, warps level sets, `info` describes it, and bad keys exit with 3,
// naming the rig file and key, and write nothing.

#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <spacewarp/core/io/mesh_io.h>
#include <spacewarp/core/primitives.h>
#include <spacewarp/nonlinear/mls.h>
#include <spacewarp/volume/inside_distance.h>
#include <spacewarp/volume/mesh_level_set.h>
#include <spacewarp/volume/read_vdb.h>
#include <spacewarp/volume/write_vdb.h>
#include "apps/cli_test_util.h"

namespace fs = std::filesystem;
using namespace spacewarp;
using ::testing::HasSubstr;

namespace {

class MlsInsideCliTest : public test::CliFixture {
 protected:
  MlsInsideCliTest() : test::CliFixture("spacewarp_mls_inside_cli_") {}

  // Two fingers (x = 0 and x = 4, y = 1..4) on a palm (y = 0), unit cells one thick: a U.
  PolygonSoup fingers() const {
    std::vector<glm::ivec3> cells;
    for (int x = 0; x <= 4; ++x) cells.emplace_back(x, 0, 0);
    for (int y = 1; y <= 4; ++y) {
      cells.emplace_back(0, y, 0);
      cells.emplace_back(4, y, 0);
    }
    return makeBlocksSurface(cells, Vec3(0.0), 1.0);
  }

  const std::vector<Vec3> handles_ = {
      {0.5, 4.5, 0.5}, {0.5, 0.5, 0.5}, {2.5, 0.5, 0.8}, {4.5, 0.5, 0.5}, {4.5, 4.5, 0.5}};
  std::vector<Vec3> targets() const {
    std::vector<Vec3> t = handles_;
    t[0].x += 1.5;
    return t;
  }

  // The rig with extra keys (`extra` starts with ", ").
  fs::path rig(const std::string& extra, const std::vector<Vec3>* handles = nullptr) {
    return write("rig.json", R"({"method": "mls", "distance": "inside", "handles": )" +
                                 test::jsonPoints(handles ? *handles : handles_) +
                                 R"(, "targets": )" + test::jsonPoints(targets()) + extra + "}");
  }
};

TEST_F(MlsInsideCliTest, DeformMatchesTheLibraryOnSoupsAndClouds) {
  const PolygonSoup model = fingers();
  writeSoup(model, dir_ / "fingers.obj");
  rig(R"(, "model": "fingers.obj", "voxelSize": 0.05)");
  MlsOptions options;
  options.distances =
      std::make_shared<InsideDistances>(model, handles_, InsideDistanceOptions{0.05});
  const MlsWarp warp(handles_, targets(), options);

  const test::CliResult soup =
      run("deform --rig " + (dir_ / "rig.json").string() + " " + (dir_ / "fingers.obj").string() +
          " -o " + (dir_ / "out.obj").string());
  ASSERT_EQ(soup.exitCode, 0) << soup.err;
  const PolygonSoup out = readSoup(dir_ / "out.obj");
  ASSERT_EQ(out.size(), model.size());
  for (std::size_t i = 0; i < model.size(); ++i)
    ASSERT_LE(glm::length(out.positions[i] - warp.apply(model.positions[i])), 1e-12) << i;

  const PolygonSoup cloud = writeCloud(Vec3(-0.5), Vec3(5.5, 5.5, 1.5), 400, 3);
  const test::CliResult points = deform("rig.json");
  ASSERT_EQ(points.exitCode, 0) << points.err;
  const PolygonSoup warped = readSoup(dir_ / "out.ply");
  for (std::size_t i = 0; i < cloud.size(); ++i)
    ASSERT_EQ(warped.positions[i], warp.apply(cloud.positions[i])) << i;  // PLY keeps doubles

  const test::CliResult info = run("info " + (dir_ / "rig.json").string());
  ASSERT_EQ(info.exitCode, 0) << info.err;
  EXPECT_THAT(info.out, HasSubstr("inside the model fingers.obj, on voxels of 0.05"));
}

TEST_F(MlsInsideCliTest, DeformsALevelSet) {
  const PolygonSoup model = fingers();
  writeSoup(model, dir_ / "fingers.obj");
  openvdb::FloatGrid::Ptr grid = meshLevelSet(model, 0.1);
  grid->setName("surface");
  writeVdbFile(dir_ / "fingers.vdb", {grid}, openvdb::MetaMap());
  rig(R"(, "model": "fingers.obj", "voxelSize": 0.05)");
  const test::CliResult r =
      run("deform --rig " + (dir_ / "rig.json").string() + " " + (dir_ / "fingers.vdb").string() +
          " -o " + (dir_ / "out.vdb").string());
  ASSERT_EQ(r.exitCode, 0) << r.err;
  const VdbFile out = readVdbFile(dir_ / "out.vdb");
  ASSERT_EQ(out.grids.size(), 1u);
  EXPECT_GT(out.grids[0]->activeVoxelCount(), 1000u);
}

TEST_F(MlsInsideCliTest, BadKeysExitWith3AndWriteNothing) {
  writeSoup(fingers(), dir_ / "fingers.obj");
  PolygonSoup open = fingers();  // one face short
  open.faceIndices.resize(open.faceOffsets[open.faceOffsets.size() - 2]);
  open.faceOffsets.pop_back();
  writeSoup(open, dir_ / "open.obj");
  writeCloud(Vec3(0.0), Vec3(1.0), 10, 1);
  const std::vector<Vec3> outside = {
      {0.5, 4.5, 0.5}, {2.5, 3.0, 0.5}, {2.5, 0.5, 0.8}, {4.5, 0.5, 0.5}, {4.5, 4.5, 0.5}};
  struct Case {
    std::string extra;
    const std::vector<Vec3>* handles;
    std::string message;
  };
  const Case cases[] = {
      {R"(, "model": "fingers.obj", "distance": "geodesic")", nullptr, ""},  // duplicate key
      {"", nullptr, "'model' is missing"},
      {R"(, "model": "missing.obj")", nullptr, "missing.obj"},
      {R"(, "model": "fingers.obj", "voxelSize": -1)", nullptr, "'voxelSize' must be > 0"},
      {R"(, "model": "fingers.obj")", &outside,
       "'handles' " + (dir_ / "fingers.obj").string() +
           ": InsideDistances: handle 1 (2.5, 3, 0.5) is outside the model"},
      {R"(, "model": "fingers.obj", "voxelSize": 1e-5)", nullptr, "rig.json: 'voxelSize' 1e-05 ("},
      {R"(, "model": "fingers.obj", "voxelSize": 1e-300)", nullptr,
       "'voxelSize' 1e-300 (5e+300 x 5e+300 x 1e+300 voxels, 5 handles) needs far more memory"},
      {R"(, "model": "open.obj")", nullptr,
       "'model' " + (dir_ / "open.obj").string() + ": InsideDistances: the model is not closed"},
      {R"(, "model": ".")", nullptr, "is a directory"},
  };
  for (const Case& c : cases) {
    rig(c.extra, c.handles);
    const test::CliResult r = deform("rig.json");
    EXPECT_EQ(r.exitCode, 3) << c.extra << ": " << r.err;
    EXPECT_THAT(r.err, HasSubstr("rig.json")) << c.extra;
    EXPECT_THAT(r.err, HasSubstr(c.message)) << c.extra;
    EXPECT_FALSE(fs::exists(dir_ / "out.ply")) << c.extra;
  }
  // A wrong name, and a model with Euclidean distances.
  write("rig.json", R"({"method": "mls", "distance": "geodesic", "handles": )" +
                        test::jsonPoints(handles_) + R"(, "targets": )" +
                        test::jsonPoints(targets()) + "}");
  test::CliResult r = deform("rig.json");
  EXPECT_EQ(r.exitCode, 3);
  EXPECT_THAT(r.err, HasSubstr("'distance' must be \"euclidean\" or \"inside\", not \"geodesic\""));
  write("rig.json", R"({"method": "mls", "model": "fingers.obj", "handles": )" +
                        test::jsonPoints(handles_) + R"(, "targets": )" +
                        test::jsonPoints(targets()) + "}");
  r = deform("rig.json");
  EXPECT_EQ(r.exitCode, 3);
  EXPECT_THAT(r.err, HasSubstr("'model'"));
  EXPECT_FALSE(fs::exists(dir_ / "out.ply"));
}

}  // namespace
