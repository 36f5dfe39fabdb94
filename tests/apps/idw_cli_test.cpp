// End-to-end tests of the "idw" rig method (Shepard weighting) of the spacewarp executable:
// deform agrees with the library on a soup and a point cloud, weights agree with the
// coordinates, points out of every handle's reach are refused, and bad rigs exit with the
// documented codes and messages.

#include <cstdlib>
#include <filesystem>
#include <sstream>
#include <string>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <spacewarp/core/io/mesh_io.h>
#include <spacewarp/core/primitives.h>
#include <spacewarp/nonlinear/shepard.h>
#include "apps/cli_test_util.h"

namespace fs = std::filesystem;
using namespace spacewarp;
using ::testing::HasSubstr;

namespace {

using ::spacewarp::test::BadRigTest;
using test::jsonPoints;

class IdwCliTest : public test::CliFixture {
 protected:
  IdwCliTest() : test::CliFixture("spacewarp_idw_cli_") {}

  void SetUp() override {
    test::CliFixture::SetUp();
    handles = makeRandomPoints(Vec3(-1.0), Vec3(1.0), 12, 5).positions;
    const std::vector<Vec3> offsets = makeRandomPoints(Vec3(-0.3), Vec3(0.3), 12, 6).positions;
    for (std::size_t i = 0; i < handles.size(); ++i) targets.push_back(handles[i] + offsets[i]);
  }

  std::vector<Vec3> handles, targets;
};

TEST_F(IdwCliTest, DeformMatchesTheLibraryOnASoupAndACloud) {
  const PolygonSoup cloud = writeCloud(Vec3(-1.5), Vec3(1.5), 300, 9);
  const PolygonSoup box = makeBoxSurface(Vec3(-0.8), Vec3(0.8), {4, 4, 4});
  writeSoup(box, dir_ / "box.obj");
  write("idw.json", R"({"method": "idw", "power": 3, "handles": )" + jsonPoints(handles) +
                        R"(, "targets": )" + jsonPoints(targets) + "}");
  ShepardOptions options;
  options.power = 3.0;
  const ShepardWarp warp(handles, targets, options);
  ASSERT_EQ(deform("idw.json").exitCode, 0);
  const PolygonSoup out = readSoup(dir_ / "out.ply");
  ASSERT_EQ(out.size(), cloud.size());
  for (std::size_t i = 0; i < cloud.size(); ++i)
    ASSERT_EQ(out.positions[i], warp.apply(cloud.positions[i])) << "point " << i;
  const test::CliResult r =
      run("deform --rig " + (dir_ / "idw.json").string() + " " + (dir_ / "box.obj").string() +
          " -o " + (dir_ / "box_out.obj").string());
  ASSERT_EQ(r.exitCode, 0) << r.err;
  const PolygonSoup boxOut = readSoup(dir_ / "box_out.obj");
  const PolygonSoup boxIn = readSoup(dir_ / "box.obj");
  ASSERT_EQ(boxOut.size(), boxIn.size());
  for (std::size_t i = 0; i < boxIn.size(); ++i)
    EXPECT_LE(glm::length(boxOut.positions[i] - warp.apply(boxIn.positions[i])), 1e-15)
        << "vertex " << i;
}

TEST_F(IdwCliTest, WeightsMatchTheCoordinates) {
  const PolygonSoup cloud = writeCloud(Vec3(-1.0), Vec3(1.0), 20, 3);
  write("idw.json", R"({"method": "idw", "handles": )" + jsonPoints(handles) + R"(, "targets": )" +
                        jsonPoints(targets) + "}");
  const test::CliResult r = run("weights --rig " + (dir_ / "idw.json").string() + " " +
                                (dir_ / "cloud.ply").string() + " -o " + (dir_ / "w.csv").string());
  ASSERT_EQ(r.exitCode, 0) << r.err;
  std::istringstream csv(test::slurp(dir_ / "w.csv"));
  std::string line;
  std::getline(csv, line);
  EXPECT_EQ(line.substr(0, 6), "v0,v1,");
  const ShepardCoordinates coords(handles);
  std::vector<double> row(handles.size());
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    ASSERT_TRUE(std::getline(csv, line)) << "row " << i;
    coords.weights(cloud.positions[i], row);
    std::istringstream cells(line);
    std::string cell;
    for (std::size_t c = 0; c < row.size(); ++c) {
      ASSERT_TRUE(std::getline(cells, cell, ','));
      EXPECT_EQ(std::strtod(cell.c_str(), nullptr), row[c]) << "row " << i << " column " << c;
    }
  }
}

TEST_F(IdwCliTest, PointsOutOfReachExitWith3AndWriteNothing) {
  writeCloud(Vec3(-3.0), Vec3(3.0), 200, 4);
  write("idw.json", R"({"method": "idw", "radius": 0.3, "handles": )" + jsonPoints(handles) +
                        R"(, "targets": )" + jsonPoints(targets) + "}");
  const test::CliResult r = deform("idw.json");
  EXPECT_EQ(r.exitCode, 3);
  EXPECT_THAT(r.err, HasSubstr("points are farther than the radius 0.3 from every handle"));
  EXPECT_FALSE(fs::exists(dir_ / "out.ply"));
  // weights names the points file as deform does.
  const test::CliResult w = run("weights --rig " + (dir_ / "idw.json").string() + " " +
                                (dir_ / "cloud.ply").string() + " -o " + (dir_ / "w.csv").string());
  EXPECT_EQ(w.exitCode, 3);
  EXPECT_THAT(w.err, HasSubstr("cloud.ply: ShepardCoordinates: "));
  EXPECT_FALSE(fs::exists(dir_ / "w.csv"));
  // With a radius that reaches every point the same rig works, and agrees with the library.
  const PolygonSoup near = writeCloud(Vec3(-0.5), Vec3(0.5), 100, 4);
  write("wide.json", R"({"method": "idw", "radius": 2.5, "handles": )" + jsonPoints(handles) +
                         R"(, "targets": )" + jsonPoints(targets) + "}");
  ASSERT_EQ(deform("wide.json").exitCode, 0);
  ShepardOptions options;
  options.radius = 2.5;
  const ShepardWarp warp(handles, targets, options);
  const PolygonSoup out = readSoup(dir_ / "out.ply");
  for (std::size_t i = 0; i < near.size(); ++i)
    ASSERT_EQ(out.positions[i], warp.apply(near.positions[i])) << "point " << i;
}

const std::string kThree = "[[0,0,0],[1,0,0],[0,1,0]]";

INSTANTIATE_TEST_SUITE_P(
    IdwRigs, BadRigTest,
    ::testing::Values(
        test::BadRig{"IdwMissingTargets", R"({"method": "idw", "handles": )" + kThree + "}", 3,
                     "'targets' is missing"},
        test::BadRig{"IdwSizeMismatch",
                     R"({"method": "idw", "handles": )" + kThree + R"(, "targets": [[0,0,0]]})", 3,
                     "'targets' must have as many points as 'handles' (3), not 1"},
        test::BadRig{"IdwZeroPower",
                     R"({"method": "idw", "power": 0, "handles": )" + kThree + R"(, "targets": )" +
                         kThree + "}",
                     3, "'power' must be > 0"},
        test::BadRig{"IdwNegativeRadius",
                     R"({"method": "idw", "radius": -1, "handles": )" + kThree +
                         R"(, "targets": )" + kThree + "}",
                     3, "'radius' must be > 0"},
        test::BadRig{"IdwNoHandles", R"({"method": "idw", "handles": [], "targets": []})", 3,
                     "'handles' must be an array of at least 1 [x, y, z] points"},
        test::BadRig{"IdwUnknownKey",
                     R"({"method": "idw", "alpha": 1, "handles": )" + kThree + R"(, "targets": )" +
                         kThree + "}",
                     3, "'alpha' is not a key of"},
        test::BadRig{
            "IdwCoincident",
            R"({"method": "idw", "handles": [[0,0,0],[1,0,0],[0,0,0]], "targets": )" + kThree + "}",
            3, "handles 0 and 2 coincide"}),
    ::spacewarp::test::badRigName);

}  // namespace
