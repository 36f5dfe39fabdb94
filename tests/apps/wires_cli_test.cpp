// End-to-end tests of the "wires" rig method of the spacewarp executable: deform agrees with the
// library on soups and point clouds, info describes the rig, and bad rigs exit with the
// documented codes and messages.

#include <filesystem>
#include <string>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <spacewarp/core/io/mesh_io.h>
#include <spacewarp/core/primitives.h>
#include <spacewarp/nonlinear/wires.h>
#include "apps/cli_test_util.h"

namespace fs = std::filesystem;
using namespace spacewarp;
using ::testing::HasSubstr;

namespace {

using ::spacewarp::test::BadRigTest;

class WiresCliTest : public test::CliFixture {
 protected:
  WiresCliTest() : test::CliFixture("spacewarp_wires_cli_") {}
};

using test::jsonPoints;

const std::vector<Vec3> kRest = {{-1, 0, 0}, {-0.3, 0.2, 0}, {0.4, 0.1, 0.1}, {1, -0.2, 0}};
const std::vector<Vec3> kDeformed = {{-1, 0, 0.1}, {-0.3, 0.5, 0}, {0.4, 0.4, 0.3}, {1, 0, 0}};
const std::vector<Vec3> kRest2 = {{0, -1, 0}, {0.1, 0, 0.2}, {0, 1, 0}};
const std::vector<Vec3> kDeformed2 = {{0, -1, 0}, {0.4, 0, 0.1}, {0, 1, 0}};

TEST_F(WiresCliTest, DeformMatchesTheLibraryOnSoupsAndClouds) {
  write("wires.json", R"({"method": "wires", "locality": 2, "wires": [
      {"rest": )" + jsonPoints(kRest) +
                          R"(, "deformed": )" + jsonPoints(kDeformed) +
                          R"(, "radius": 0.6, "innerRadius": 0.1, "scale": 1.2,
       "dropoff": "linear", "curve": "catmull-rom"},
      {"rest": )" + jsonPoints(kRest2) +
                          R"(, "deformed": )" + jsonPoints(kDeformed2) + R"(, "radius": 0.5}]})");
  Wire a;
  a.rest = kRest;
  a.deformed = kDeformed;
  a.radius = 0.6;
  a.innerRadius = 0.1;
  a.scale = 1.2;
  a.dropoff = WireDropoff::Linear;
  a.curve = WireCurve::CatmullRom;
  Wire b;
  b.rest = kRest2;
  b.deformed = kDeformed2;
  b.radius = 0.5;
  const WiresWarp warp({a, b}, WiresOptions{2.0});

  PolygonSoup cloud;
  static_cast<PointSet&>(cloud) = makeRandomPoints(Vec3(-1.2), Vec3(1.2), 500, 3);
  writeSoup(cloud, dir_ / "cloud.ply");
  writeSoup(makeBoxSurface(Vec3(-1.0, -0.3, -0.3), Vec3(1.0, 0.3, 0.3), {8, 3, 3}),
            dir_ / "bar.obj");
  for (const char* name : {"cloud.ply", "bar.obj"}) {
    const fs::path in = dir_ / name;
    const fs::path out = dir_ / ("out_" + std::string(name));
    const test::CliResult r = run("deform --rig " + (dir_ / "wires.json").string() + " " +
                                  in.string() + " -o " + out.string());
    ASSERT_EQ(r.exitCode, 0) << name << ": " << r.err;
    const PolygonSoup before = readSoup(in);
    const PolygonSoup after = readSoup(out);
    ASSERT_EQ(after.size(), before.size());
    std::size_t movedCount = 0;
    for (std::size_t i = 0; i < before.size(); ++i) {
      const Vec3 expected = warp.apply(before.positions[i]);
      movedCount += expected != before.positions[i];
      // The files store floats (PLY) or decimal text (OBJ).
      ASSERT_LE(glm::length(after.positions[i] - expected), 1e-6) << name << " point " << i;
    }
    EXPECT_GT(movedCount, before.size() / 10) << name;
  }

  const test::CliResult info = run("info " + (dir_ / "wires.json").string());
  ASSERT_EQ(info.exitCode, 0) << info.err;
  EXPECT_THAT(info.out, HasSubstr("wires (Singh & Fiume)"));
  EXPECT_THAT(info.out, HasSubstr("wires:      2"));
}

// A 'curve' or 'dropoff' of the wrong JSON type used to print its place twice.
TEST_F(WiresCliTest, WrongTypeOfCurveNamesThePlaceOnce) {
  for (const char* key : {"curve", "dropoff"}) {
    write("rig.json", std::string(R"({"method": "wires", "wires": [{"rest": [[0,0,0],[0,0,1]],
        "deformed": [[0,0,0],[0,0,1]], "radius": 1, ")") +
                          key + R"(": 3}]})");
    const test::CliResult r = run("info " + (dir_ / "rig.json").string());
    EXPECT_EQ(r.exitCode, 3) << r.err;
    EXPECT_THAT(r.err, HasSubstr("wires[0]: '" + std::string(key) + "' must be a string"));
    EXPECT_EQ(r.err.find("rig.json"), r.err.rfind("rig.json")) << r.err;
  }
}

const std::string kLine = "[[0,0,0],[1,0,0],[2,1,0]]";
const std::string kLine2 = "[[0,0,0],[1,0,0.5],[2,1,0]]";

std::string wireRig(const std::string& wire, const std::string& top = "") {
  return R"({"method": "wires", )" + top + R"("wires": [{"rest": )" + kLine + R"(, "deformed": )" +
         kLine2 + R"(, "radius": 1})" + (wire.empty() ? "" : ", " + wire) + "]}";
}

INSTANTIATE_TEST_SUITE_P(
    WiresRigs, BadRigTest,
    ::testing::Values(
        test::BadRig{
            "ZeroRadius",
            wireRig(R"({"rest": )" + kLine + R"(, "deformed": )" + kLine + R"(, "radius": 0})"), 3,
            "rig.json: wires[1]: 'radius' must be > 0"},
        test::BadRig{"MissingRadius",
                     wireRig(R"({"rest": )" + kLine + R"(, "deformed": )" + kLine + "}"), 3,
                     "wires[1]: 'radius' is missing"},
        test::BadRig{"CountMismatch",
                     wireRig(R"({"rest": )" + kLine + R"(, "deformed": [[0,0,0],[1,1,1]],
                                 "radius": 1})"),
                     3, "wires[1]: 'deformed' must have as many points as 'rest' (3), not 2"},
        test::BadRig{"OnePoint",
                     wireRig(R"({"rest": [[0,0,0]], "deformed": [[0,0,0]], "radius": 1})"), 3,
                     "wires[1]: 'rest' must be an array of at least 2 [x, y, z] points"},
        test::BadRig{"RepeatedPoint",
                     wireRig(R"({"rest": [[0,0,0],[0,0,0],[1,0,0]], "deformed": )" + kLine +
                             R"(, "radius": 1})"),
                     3, "wire 1: rest[1] repeats rest[0]"},
        test::BadRig{"UnknownDropoff",
                     wireRig(R"({"rest": )" + kLine + R"(, "deformed": )" + kLine +
                             R"(, "radius": 1, "dropoff": "gauss"})"),
                     3, "wires[1]: 'dropoff' wire drop-off 'gauss' is not one of: smooth, linear"},
        test::BadRig{"UnknownCurve",
                     wireRig(R"({"rest": )" + kLine + R"(, "deformed": )" + kLine +
                             R"(, "radius": 1, "curve": "bezier"})"),
                     3, "wires[1]: 'curve' wire curve 'bezier' is not one of"},
        test::BadRig{"InnerRadiusTooLarge",
                     wireRig(R"({"rest": )" + kLine + R"(, "deformed": )" + kLine +
                             R"(, "radius": 1, "innerRadius": 1})"),
                     3, "wires[1]: 'innerRadius' must be >= 0 and < 'radius'"},
        test::BadRig{"NegativeScale",
                     wireRig(R"({"rest": )" + kLine + R"(, "deformed": )" + kLine +
                             R"(, "radius": 1, "scale": -1})"),
                     3, "wires[1]: 'scale' must be > 0"},
        test::BadRig{"UnknownWireKey",
                     wireRig(R"({"rest": )" + kLine + R"(, "deformed": )" + kLine +
                             R"(, "radius": 1, "raduis": 2})"),
                     3, "wires[1]: 'raduis' is not a key of a wire"},
        test::BadRig{"NegativeLocality", wireRig("", R"("locality": -1, )"), 3,
                     "'locality' must be >= 0"},
        test::BadRig{"WireNotAnObject", wireRig("[1, 2]"), 3,
                     "'wires' [1] must be a JSON object (a wire)"},
        test::BadRig{"NoWires", R"({"method": "wires", "wires": []})", 3,
                     "'wires' must be a non-empty array"},
        test::BadRig{"CatmullRomHairpin",
                     wireRig(R"({"rest": )" + kLine + R"(, "deformed": [[0,0,0],[1,0,0],[0,0,0]],
                                 "radius": 1, "curve": "catmull-rom"})"),
                     3, "wire 1: deformed[2] repeats deformed[0] (a hairpin"}),
    ::spacewarp::test::badRigName);

}  // namespace
