// End-to-end tests of the spacewarp executable: results, exit codes, messages, and that a
// failure leaves no output file behind.

#include <sys/wait.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <sstream>
#include <string>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <spacewarp/core/io/mesh_io.h>
#include <spacewarp/core/primitives.h>
#include <spacewarp/core/twist.h>
#include "apps/cli_test_util.h"

namespace fs = std::filesystem;
using namespace spacewarp;
using ::testing::HasSubstr;
using ::testing::Not;

namespace {

using ::spacewarp::test::BadRig;
using ::spacewarp::test::BadRigTest;

using test::CliResult;
using test::slurp;

class CliTest : public test::CliFixture {
 protected:
  CliTest() : CliFixture("spacewarp_cli_") {}

  // Nothing but the inputs the test wrote may be in the folder after a failed run.
  void expectNoOutput(const fs::path& output) {
    EXPECT_FALSE(fs::exists(output)) << output;
    for (const auto& entry : fs::directory_iterator(dir_))
      EXPECT_THAT(entry.path().filename().string(), ::testing::Not(HasSubstr(".tmp")));
  }
};

TEST_F(CliTest, TwistRigMatchesTheClosedForm) {
  PolygonSoup bar = makeBoxSurface(Vec3(-0.5, -0.5, -1), Vec3(0.5, 0.5, 1), {2, 2, 4});
  writeSoup(bar, dir_ / "bar.ply");
  write("twist.json",
        R"({"method": "twist", "origin": [0, 0, 0], "axis": [0, 0, 2], "rate": 0.5})");
  const CliResult r = run("deform --rig " + (dir_ / "twist.json").string() + " " +
                          (dir_ / "bar.ply").string() + " -o " + (dir_ / "out.obj").string());
  ASSERT_EQ(r.exitCode, 0) << r.err;
  const PolygonSoup out = readSoup(dir_ / "out.obj");
  ASSERT_EQ(out.size(), bar.size());
  ASSERT_EQ(out.faceIndices, bar.faceIndices);
  for (std::size_t i = 0; i < bar.size(); ++i) {
    // Rotation about +z by 0.5 * z, written out by hand.
    const Vec3 p = bar.positions[i];
    const double a = 0.5 * p.z;
    const Vec3 expected(std::cos(a) * p.x - std::sin(a) * p.y,
                        std::sin(a) * p.x + std::cos(a) * p.y, p.z);
    EXPECT_NEAR(glm::length(out.positions[i] - expected), 0.0, 1e-14) << i;
  }
}

TEST_F(CliTest, AffineRigIsRowMajorOnColumnPoints) {
  PolygonSoup cloud;
  static_cast<PointSet&>(cloud) = makeRandomPoints(Vec3(-1), Vec3(1), 100, 3);
  writeSoup(cloud, dir_ / "cloud.ply");
  write(
      "affine.json",
      R"({"method": "affine", "matrix": [[0, -1, 0, 5], [1, 0, 0, 6], [0, 0, 2, 7], [0, 0, 0, 1]]})");
  const CliResult r = run("deform --rig " + (dir_ / "affine.json").string() + " " +
                          (dir_ / "cloud.ply").string() + " -o " + (dir_ / "out.ply").string());
  ASSERT_EQ(r.exitCode, 0) << r.err;
  const PolygonSoup out = readSoup(dir_ / "out.ply");
  ASSERT_EQ(out.size(), cloud.size());
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    const Vec3 p = cloud.positions[i];
    EXPECT_EQ(out.positions[i], Vec3(-p.y + 5, p.x + 6, 2 * p.z + 7)) << i;
  }
  // Per-point attributes are carried through.
  ASSERT_EQ(out.attributes.size(), 1u);
  EXPECT_EQ(out.attributes[0].values, cloud.attributes[0].values);
}

TEST_F(CliTest, InfoPrintsCountsAndBox) {
  writeSoup(makeBoxSurface(Vec3(0), Vec3(1, 2, 3), {1, 1, 1}), dir_ / "box.off");
  const CliResult r = run("info " + (dir_ / "box.off").string());
  ASSERT_EQ(r.exitCode, 0) << r.err;
  EXPECT_THAT(r.out, HasSubstr("vertices:   8"));
  EXPECT_THAT(r.out, HasSubstr("polygons:   6"));
  EXPECT_THAT(r.out, HasSubstr("bbox max:   1 2 3"));
}

TEST_F(CliTest, UsageErrorsExitWith2) {
  EXPECT_EQ(run("").exitCode, 2);
  EXPECT_EQ(run("deform").exitCode, 2);
  const CliResult unknown = run("--threads 1 frobnicate");
  EXPECT_EQ(unknown.exitCode, 2);
  EXPECT_THAT(unknown.err, HasSubstr("unknown command 'frobnicate' (one of info, deform,"));
  EXPECT_EQ(run("deform --help").exitCode, 0);
}

TEST_P(BadRigTest, FailsWithItsCodeInOneLineAndWritesNothing) {
  PolygonSoup cloud;
  static_cast<PointSet&>(cloud) = makeRandomPoints(Vec3(0), Vec3(1), 10, 11);
  writeSoup(cloud, dir_ / "cloud.ply");
  write("rig.json", GetParam().json);
  const fs::path output = dir_ / "out.ply";
  const test::CliResult r = run("deform --rig " + (dir_ / "rig.json").string() + " " +
                                (dir_ / "cloud.ply").string() + " -o " + output.string());
  EXPECT_EQ(r.exitCode, GetParam().exitCode) << r.err;
  EXPECT_THAT(r.err, HasSubstr("rig.json"));
  EXPECT_THAT(r.err, HasSubstr(GetParam().message));
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;  // one line
  EXPECT_FALSE(fs::exists(output));
  for (const auto& entry : fs::directory_iterator(dir_))
    EXPECT_THAT(entry.path().filename().string(), ::testing::Not(HasSubstr(".tmp")));
}

// `spacewarp info` checks a rig with the same code as deform (checkRig): what deform refuses
// before its solve, info refuses with the same line and exit code, printing nothing on stdout.
TEST_P(BadRigTest, InfoRefusesItAsDeformDoes) {
  PolygonSoup cloud;
  static_cast<PointSet&>(cloud) = makeRandomPoints(Vec3(0), Vec3(1), 10, 11);
  writeSoup(cloud, dir_ / "cloud.ply");
  write("rig.json", GetParam().json);
  const test::CliResult deformed =
      run("deform --rig " + (dir_ / "rig.json").string() + " " + (dir_ / "cloud.ply").string() +
          " -o " + (dir_ / "out.ply").string());
  const test::CliResult info = run("info " + (dir_ / "rig.json").string());
  if (GetParam().solveOnly) {
    EXPECT_EQ(info.exitCode, 0) << info.err;
    return;
  }
  EXPECT_EQ(info.exitCode, deformed.exitCode) << info.err;
  EXPECT_EQ(info.err, deformed.err);
  EXPECT_EQ(info.out, "");
}

INSTANTIATE_TEST_SUITE_P(
    CoreRigs, BadRigTest,
    ::testing::Values(
        BadRig{"NotJson", R"({"method": "twist", )", "JSON"},
        BadRig{"MissingKey", R"({"method": "twist", "origin": [0,0,0], "axis": [0,0,1]})",
               "'rate' is missing"},
        BadRig{"UnknownKey",
               R"({"method": "twist", "origin": [0,0,0], "axis": [0,0,1], "rate": 1, "rat": 2})",
               "'rat'"},
        BadRig{"UnknownMethod", R"({"method": "warp9"})", "warp9"},
        BadRig{"ShortVector", R"({"method": "twist", "origin": [0,0], "axis": [0,0,1], "rate": 1})",
               "'origin'"},
        BadRig{"ZeroAxis", R"({"method": "twist", "origin": [0,0,0], "axis": [0,0,0], "rate": 1})",
               "axis"},
        BadRig{"ProjectiveMatrix",
               R"({"method": "affine", "matrix": [[1,0,0,0],[0,1,0,0],[0,0,1,0],[1,0,0,1]]})",
               "last row"},
        BadRig{
            "NestedError",
            R"({"method": "compose", "warps": [{"method": "taper", "origin": [0,0,0], "axis": [0,0,1]}]})",
            "warps[0]"}),
    ::spacewarp::test::badRigName);

struct BadFile {
  const char* name;
  const char* file;
  const char* content;
};

class CliBadFileTest : public CliTest, public ::testing::WithParamInterface<BadFile> {};

TEST_P(CliBadFileTest, ExitsWith3NamesTheFileAndWritesNothing) {
  write("rig.json", R"({"method": "twist", "origin": [0,0,0], "axis": [0,0,1], "rate": 1})");
  const fs::path input =
      GetParam().content ? write(GetParam().file, GetParam().content) : dir_ / GetParam().file;
  const fs::path output = dir_ / "out.ply";
  const CliResult r = run("deform --rig " + (dir_ / "rig.json").string() + " " + input.string() +
                          " -o " + output.string());
  EXPECT_EQ(r.exitCode, 3) << r.err;
  EXPECT_THAT(r.err, HasSubstr(GetParam().file));
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  expectNoOutput(output);
}

INSTANTIATE_TEST_SUITE_P(
    Files, CliBadFileTest,
    ::testing::Values(
        BadFile{"TruncatedBinaryPly", "trunc.ply",
                "ply\nformat binary_little_endian 1.0\nelement vertex 2\nproperty float x\n"
                "property float y\nproperty float z\nend_header\n\x01\x02\x03"},
        BadFile{"WrongCountPly", "count.ply",
                "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                "property float z\nend_header\n0 0 0\n1 1 1\n"},
        BadFile{"OutOfRangeObj", "range.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n"},
        BadFile{"NanOff", "nan.off", "OFF\n3 1 0\n0 0 0\nnan 0 0\n0 1 0\n3 0 1 2\n"},
        BadFile{"Missing", "missing.obj", nullptr},
        BadFile{"UnknownExtension", "model.stl", "solid x\n"}),
    [](const auto& info) { return std::string(info.param.name); });

TEST_F(CliTest, BadInputDoesNotReplaceAnExistingOutput) {
  write("rig.json", R"({"method": "twist", "origin": [0,0,0], "axis": [0,0,1], "rate": 1})");
  write("bad.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n");
  const fs::path output = write("out.obj", "precious");
  const CliResult r = run("deform --rig " + (dir_ / "rig.json").string() + " " +
                          (dir_ / "bad.obj").string() + " -o " + output.string());
  EXPECT_EQ(r.exitCode, 3);
  EXPECT_EQ(slurp(output), "precious");
}

TEST_F(CliTest, DemoWritesEveryResult) {
  const CliResult r = run("demo " + (dir_ / "demo").string());
  ASSERT_EQ(r.exitCode, 0) << r.err;
  const PolygonSoup bar = readSoup(dir_ / "demo" / "bar.obj");
  const PolygonSoup cloud = readSoup(dir_ / "demo" / "cloud.ply");
  for (const std::string method : {"twist", "bend", "taper", "mvc", "green", "qmvc", "qgc",
                                   "wachspress", "discrete-harmonic", "ffd", "rbf", "mls", "graph",
                                   "wires", "idw", "kelvinlet", "skinning-lbs", "skinning-dqs"}) {
    const PolygonSoup deformedBar = readSoup(dir_ / "demo" / ("bar_" + method + ".obj"));
    const PolygonSoup deformedCloud = readSoup(dir_ / "demo" / ("cloud_" + method + ".ply"));
    EXPECT_EQ(deformedBar.size(), bar.size()) << method;
    EXPECT_EQ(deformedBar.faceIndices, bar.faceIndices) << method;
    EXPECT_EQ(deformedCloud.size(), cloud.size()) << method;
    EXPECT_NE(deformedBar.positions, bar.positions) << method << " moved nothing";
    EXPECT_NE(r.out.find("bar_" + method + ".obj"), std::string::npos) << method;
    // Builds with OpenVDB also warp the bar's level set (its content is tested in
    // volume_cli_test.cpp).
    if (fs::exists(dir_ / "demo" / "bar.vdb")) {
      EXPECT_GT(fs::file_size(dir_ / "demo" / ("bar_" + method + ".vdb")), 0u) << method;
    }
  }
  // wachspress runs on the unpinched box, discrete-harmonic (triangle faces only) on the
  // bipyramid, the others on the pinched cage.
  const std::pair<const char*, const char*> cageOf[] = {
      {"wachspress", "convex_cage.obj"},
      {"discrete-harmonic", "simplicial_cage.obj"},
      {"qmvc", "cage.obj"},
      {"qgc", "cage.obj"}};
  for (const auto& [method, cage] : cageOf) {
    const nlohmann::json rig =
        nlohmann::json::parse(slurp(dir_ / "demo" / (std::string(method) + ".json")));
    EXPECT_EQ(rig["cage"], cage) << method;
  }
  // Builds with OpenVDB also run MLS with distances inside the bar, and on the fingers.
  if (fs::exists(dir_ / "demo" / "bar.vdb")) {
    EXPECT_EQ(readSoup(dir_ / "demo" / "bar_mls-inside.obj").size(), bar.size());
    EXPECT_GT(fs::file_size(dir_ / "demo" / "bar_mls-inside.vdb"), 0u);
    const PolygonSoup fingers = readSoup(dir_ / "demo" / "fingers.obj");
    for (const char* rig : {"mls-fingers", "mls-fingers-inside"})
      EXPECT_EQ(readSoup(dir_ / "demo" / ("fingers_" + std::string(rig) + ".obj")).size(),
                fingers.size());
  }
  // The bar twisted by 170° between two bones: by LBS the middle collapses towards the axis (to
  // cos 85° of its girth: the candy wrapper), by DQS it keeps its girth.
  const auto middleGirth = [&](const std::string& file) {
    const PolygonSoup skinned = readSoup(dir_ / "demo" / file);
    double girth = 0.0;
    for (std::size_t i = 0; i < bar.size(); ++i)
      if (std::abs(bar.positions[i].z) < 1e-9)
        girth = std::max(girth, std::hypot(skinned.positions[i].x, skinned.positions[i].y));
    return girth;
  };
  const double girth = middleGirth("bar.obj");
  EXPECT_NEAR(girth, std::sqrt(0.5), 1e-12);
  EXPECT_NEAR(middleGirth("bar_skinning-lbs.obj") / girth,
              std::cos(85.0 * std::numbers::pi / 180.0), 1e-9);
  EXPECT_NEAR(middleGirth("bar_skinning-dqs.obj") / girth, 1.0, 1e-9);
  const nlohmann::json report =
      nlohmann::json::parse(slurp(dir_ / "demo" / "compare" / "report.json"));
  EXPECT_GE(report["methods"].size(), 4u);
  EXPECT_TRUE(fs::exists(dir_ / "demo" / "compare" / "compare.png"));
  EXPECT_NE(r.out.find("report.md"), std::string::npos) << "the demo says where to look";
}

}  // namespace

namespace {

// A cage and a posed copy moved by a known similarity (which both mean-value and Green
// coordinates reproduce exactly), as files.
struct CageFiles {
  fs::path rest, pose;
};

Vec3 similarity(const Vec3& p) { return Vec3(-1.5 * p.y + 1.0, 1.5 * p.x, 1.5 * p.z - 2.0); }

CageFiles writeBoxCage(const fs::path& dir) {
  const PolygonSoup cage = makeBoxSurface(Vec3(-1), Vec3(1), {1, 1, 1});
  PolygonSoup posed = cage;
  for (Vec3& p : posed.positions) p = similarity(p);
  writeSoup(cage, dir / "cage.obj");
  writeSoup(posed, dir / "pose.obj");
  return {dir / "cage.obj", dir / "pose.obj"};
}

TEST_F(CliTest, CageMethodsReproduceASimilarityPose) {
  const CageFiles cage = writeBoxCage(dir_);
  PolygonSoup cloud;
  static_cast<PointSet&>(cloud) = makeRandomPoints(Vec3(-0.9), Vec3(0.9), 200, 11);
  writeSoup(cloud, dir_ / "cloud.ply");
  write("mvc.json", R"({"method": "mvc", "cage": "cage.obj", "pose": "pose.obj"})");
  for (const std::string how : {"--method mvc", "--method green", "--rig mvc.json"}) {
    const std::string flags = how.starts_with("--rig") ? "--rig " + (dir_ / "mvc.json").string()
                                                       : how + " --cage " + cage.rest.string() +
                                                             " --pose " + cage.pose.string();
    const CliResult r = run("deform " + flags + " " + (dir_ / "cloud.ply").string() + " -o " +
                            (dir_ / "out.ply").string());
    ASSERT_EQ(r.exitCode, 0) << how << ": " << r.err;
    const PolygonSoup out = readSoup(dir_ / "out.ply");
    ASSERT_EQ(out.size(), cloud.size());
    for (std::size_t i = 0; i < cloud.size(); ++i) {
      ASSERT_LE(glm::length(out.positions[i] - similarity(cloud.positions[i])), 1e-11)
          << how << " point " << i;
    }
  }
}

TEST_F(CliTest, WeightsCsvHasHeaderAndOneRowPerPoint) {
  const CageFiles cage = writeBoxCage(dir_);
  PolygonSoup cloud;
  static_cast<PointSet&>(cloud) = makeRandomPoints(Vec3(-0.9), Vec3(0.9), 50, 12);
  writeSoup(cloud, dir_ / "cloud.ply");
  for (const std::string method : {"mvc", "green"}) {
    const fs::path csv = dir_ / (method + ".csv");
    const CliResult r = run("weights --method " + method + " --cage " + cage.rest.string() + " " +
                            (dir_ / "cloud.ply").string() + " -o " + csv.string());
    ASSERT_EQ(r.exitCode, 0) << r.err;
    std::ifstream in(csv);
    std::string header;
    std::getline(in, header);
    const std::size_t columns = method == "mvc" ? 8 : 8 + 12;
    EXPECT_EQ(std::count(header.begin(), header.end(), ',') + 1, static_cast<long>(columns));
    EXPECT_TRUE(header.starts_with("v0,v1,"));
    EXPECT_EQ(header.find("f0") != std::string::npos, method == "green");
    std::string line;
    std::size_t rows = 0;
    while (std::getline(in, line)) {
      std::stringstream s(line);
      std::string cell;
      double vertexSum = 0.0;
      for (std::size_t c = 0; std::getline(s, cell, ','); ++c)
        if (c < 8) vertexSum += std::stod(cell);
      EXPECT_NEAR(vertexSum, 1.0, 1e-12) << method << " row " << rows;
      ++rows;
    }
    EXPECT_EQ(rows, cloud.size());
  }
}

// Points too far for a method's weights are refused with exit 3 naming the point (MVC once gave
// weights 11% off at 1e9 diagonals, Green NaN rows from ~1e110 with exit 0); a bad
// SPACEWARP_SIMD is a usage error naming the variable, not the input file.
TEST_F(CliTest, WeightsRefuseFarPointsAndABadSimdVariable) {
  const CageFiles cage = writeBoxCage(dir_);
  PolygonSoup cloud;
  cloud.positions = {Vec3(0.1), Vec3(1e9, 0, 0)};
  writeSoup(cloud, dir_ / "mvc.ply");
  cloud.positions = {Vec3(0.1), Vec3(1e300, 0, 0)};
  writeSoup(cloud, dir_ / "green.ply");
  for (const std::string method : {"mvc", "green"}) {
    const std::string args = "weights --method " + method + " --cage " + cage.rest.string() + " " +
                             (dir_ / (method + ".ply")).string() + " -o " +
                             (dir_ / "w.csv").string();
    const CliResult r = run(args);
    EXPECT_EQ(r.exitCode, 3) << method << ": " << r.err;
    EXPECT_THAT(r.err, HasSubstr(method == "mvc" ? "(1000000000, 0, 0)"
                                                 : "(1.0000000000000001e+300, 0, 0)"))
        << method;
    EXPECT_FALSE(fs::exists(dir_ / "w.csv")) << method;
    const CliResult env = run(args, "SPACEWARP_SIMD=garbage ");
    EXPECT_EQ(env.exitCode, 2) << env.err;
    EXPECT_THAT(env.err, HasSubstr("spacewarp: error: SPACEWARP_SIMD=garbage: not a SIMD path "
                                   "(baseline, x86-64-v3, x86-64-v4)"));
    EXPECT_THAT(env.err, Not(HasSubstr(".ply")));
  }
}

TEST_F(CliTest, WeightsThroughARigMatchTheCageShortcut) {
  const CageFiles cage = writeBoxCage(dir_);
  PolygonSoup cloud;
  static_cast<PointSet&>(cloud) = makeRandomPoints(Vec3(-2), Vec3(2), 30, 13);
  writeSoup(cloud, dir_ / "cloud.ply");
  write("green.json", R"({"method": "green", "cage": "cage.obj", "pose": "pose.obj"})");
  write("twist.json", R"({"method": "twist", "origin": [0,0,0], "axis": [0,0,1], "rate": 1})");
  const std::string points = (dir_ / "cloud.ply").string();
  ASSERT_EQ(run("weights --rig " + (dir_ / "green.json").string() + " " + points + " -o " +
                (dir_ / "rig.csv").string())
                .exitCode,
            0);
  ASSERT_EQ(run("weights --method green --cage " + cage.rest.string() + " " + points + " -o " +
                (dir_ / "shortcut.csv").string())
                .exitCode,
            0);
  EXPECT_EQ(slurp(dir_ / "rig.csv"), slurp(dir_ / "shortcut.csv"));
  const CliResult twist = run("weights --rig " + (dir_ / "twist.json").string() + " " + points +
                              " -o " + (dir_ / "twist.csv").string());
  EXPECT_EQ(twist.exitCode, 3);
  EXPECT_THAT(twist.err, HasSubstr("no coordinates"));
  expectNoOutput(dir_ / "twist.csv");
}

TEST_F(CliTest, InvalidCagesExitWith3) {
  const CageFiles cage = writeBoxCage(dir_);
  write("open.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\n");
  write("short.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\n");
  writeSoup(makeBoxSurface(Vec3(0), Vec3(1), {1, 1, 1}), dir_ / "cloud.ply");
  const fs::path output = dir_ / "out.ply";
  const CliResult open = run("deform --method mvc --cage " + (dir_ / "open.obj").string() +
                             " --pose " + (dir_ / "open.obj").string() + " " +
                             (dir_ / "cloud.ply").string() + " -o " + output.string());
  EXPECT_EQ(open.exitCode, 3);
  EXPECT_THAT(open.err, HasSubstr("open.obj"));
  EXPECT_THAT(open.err, HasSubstr("open boundary at edge"));
  const CliResult mismatch = run("deform --method green --cage " + cage.rest.string() + " --pose " +
                                 (dir_ / "short.obj").string() + " " +
                                 (dir_ / "cloud.ply").string() + " -o " + output.string());
  EXPECT_EQ(mismatch.exitCode, 3);
  EXPECT_THAT(mismatch.err, HasSubstr("4 vertices"));
  expectNoOutput(output);
  EXPECT_EQ(run("deform --method harmonica --cage a --pose b in.obj -o out.obj").exitCode, 2);
  EXPECT_EQ(run("deform --method mvc in.obj -o out.obj").exitCode, 2);  // --cage missing
}

TEST_F(CliTest, InputsWithoutVerticesAreBadInputNamingTheFile) {
  write("affine.json",
        R"({"method": "affine", "matrix": [[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]})");
  for (const char* name : {"empty.obj", "empty.off", "empty.ply", "zero.off"}) {
    SCOPED_TRACE(name);
    write(name, std::string(name) == "zero.off" ? "OFF\n0 0 0\n" : "");
    const fs::path output = dir_ / (std::string("out_") + name);
    const CliResult r = run("deform --rig " + (dir_ / "affine.json").string() + " " +
                            (dir_ / name).string() + " -o " + output.string());
    EXPECT_EQ(r.exitCode, 3) << r.err;
    EXPECT_THAT(r.err, HasSubstr((dir_ / name).string()));
    expectNoOutput(output);
  }
}

TEST_F(CliTest, SingularAffineRigWarnsThatNormalsAreUndefined) {
  PolygonSoup cloud;
  static_cast<PointSet&>(cloud) = makeRandomPoints(Vec3(-1), Vec3(1), 50, 4);
  cloud.normals.assign(cloud.size(), Vec3(0, 0, 1));
  writeSoup(cloud, dir_ / "cloud.ply");
  write("flatten.json",
        R"({"method": "affine", "matrix": [[1,0,0,0],[0,1,0,0],[0,0,0,0],[0,0,0,1]]})");
  write("move.json",
        R"({"method": "affine", "matrix": [[0,-1,0,1],[1,0,0,2],[0,0,1,3],[0,0,0,1]]})");
  const CliResult flat = run("deform --rig " + (dir_ / "flatten.json").string() + " " +
                             (dir_ / "cloud.ply").string() + " -o " + (dir_ / "flat.ply").string());
  ASSERT_EQ(flat.exitCode, 0) << flat.err;
  EXPECT_THAT(flat.err, HasSubstr("warning: " + (dir_ / "cloud.ply").string() +
                                  ": the warp is singular at 50 of 50 vertices; their normals "
                                  "are undefined"));
  EXPECT_EQ(std::count(flat.err.begin(), flat.err.end(), '\n'), 1) << flat.err;
  const CliResult rigid =
      run("deform --rig " + (dir_ / "move.json").string() + " " + (dir_ / "cloud.ply").string() +
          " -o " + (dir_ / "moved.ply").string());
  ASSERT_EQ(rigid.exitCode, 0) << rigid.err;
  EXPECT_THAT(rigid.err, ::testing::Not(HasSubstr("warning")));
}

TEST_F(CliTest, TexturedObjKeepsItsTextureCoordinatesAndCornerNormals) {
  // A flat-shaded textured quad pair: the shared vertices have two normals each.
  write("quads.obj",
        "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 1 0 -1\nv 1 1 -1\n"
        "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvn 0 0 1\nvn 1 0 0\n"
        "f 1/1/1 2/2/1 3/3/1 4/4/1\nf 2/1/2 5/2/2 6/3/2 3/4/2\n");
  write("move.json",
        R"({"method": "affine", "matrix": [[0,-1,0,1],[1,0,0,2],[0,0,1,3],[0,0,0,1]]})");
  const CliResult r = run("deform --rig " + (dir_ / "move.json").string() + " " +
                          (dir_ / "quads.obj").string() + " -o " + (dir_ / "out.obj").string());
  ASSERT_EQ(r.exitCode, 0) << r.err;
  const PolygonSoup in = readSoup(dir_ / "quads.obj");
  const PolygonSoup out = readSoup(dir_ / "out.obj");
  EXPECT_EQ(out.faceIndices, in.faceIndices);
  EXPECT_EQ(out.texcoords.values, in.texcoords.values);
  EXPECT_EQ(out.texcoords.indices, in.texcoords.indices);
  EXPECT_EQ(out.cornerNormals.indices, in.cornerNormals.indices);
  // A quarter turn about z: (0, 0, 1) stays, (1, 0, 0) becomes (0, 1, 0).
  ASSERT_EQ(out.cornerNormals.values.size(), 2u);
  EXPECT_LT(glm::length(out.cornerNormals.values[0] - Vec3(0, 0, 1)), 1e-15);
  EXPECT_LT(glm::length(out.cornerNormals.values[1] - Vec3(0, 1, 0)), 1e-15);
  EXPECT_EQ(out.positions[4], Vec3(1, 3, 2));
  EXPECT_EQ(r.err, "") << "nothing dropped, nothing to warn about";

  // To PLY the per-corner data cannot go: one warning line says so.
  const CliResult ply = run("deform --rig " + (dir_ / "move.json").string() + " " +
                            (dir_ / "quads.obj").string() + " -o " + (dir_ / "out.ply").string());
  ASSERT_EQ(ply.exitCode, 0) << ply.err;
  EXPECT_EQ(ply.err, "spacewarp: warning: " + (dir_ / "out.ply").string() +
                         ": the format cannot store the input's texture coordinates; per-corner "
                         "normals; they are not written\n");
}

}  // namespace
