// End-to-end tests of the "kelvinlet" rig method of the spacewarp executable: deform agrees with
// the library for every brush and for composed brushes, and bad rigs exit with the documented
// codes and messages.

#include <filesystem>
#include <string>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <spacewarp/core/combinators.h>
#include <spacewarp/core/io/mesh_io.h>
#include <spacewarp/core/primitives.h>
#include <spacewarp/nonlinear/kelvinlet.h>
#include "apps/cli_test_util.h"

namespace fs = std::filesystem;
using namespace spacewarp;
using ::testing::HasSubstr;

namespace {

using ::spacewarp::test::BadRigTest;

class KelvinletCliTest : public test::CliFixture {
 protected:
  KelvinletCliTest() : test::CliFixture("spacewarp_kelvinlet_cli_") {}
};

KelvinletOptions base(KelvinletBrush brush) {
  KelvinletOptions o;
  o.brush = brush;
  o.center = Vec3(0.1, 0.2, -0.3);
  o.radius = 0.8;
  o.poisson = 0.3;
  return o;
}

TEST_F(KelvinletCliTest, DeformMatchesTheLibraryForEveryBrush) {
  const PolygonSoup cloud = writeCloud(Vec3(-1.5), Vec3(1.5), 300, 9);
  const std::string common = R"("center": [0.1, 0.2, -0.3], "radius": 0.8, "poisson": 0.3)";
  std::vector<std::pair<std::string, KelvinletOptions>> cases;
  KelvinletOptions g = base(KelvinletBrush::Grab);
  g.displacement = Vec3(0.4, -0.1, 0.2);
  g.steps = 3;
  g.falloff = KelvinletFalloff::Bi;
  cases.push_back(
      {R"("brush": "grab", "displacement": [0.4, -0.1, 0.2], "steps": 3, "falloff": "bi")", g});
  KelvinletOptions t = base(KelvinletBrush::Twist);
  t.axis = Vec3(0.0, 1.0, 1.0);
  t.angle = 0.7;
  t.falloff = KelvinletFalloff::Tri;
  cases.push_back({R"("brush": "twist", "axis": [0, 1, 1], "angle": 0.7, "falloff": "tri")", t});
  KelvinletOptions s = base(KelvinletBrush::Scale);
  s.factor = 1.5;
  cases.push_back({R"("brush": "scale", "factor": 1.5)", s});
  KelvinletOptions p = base(KelvinletBrush::Pinch);
  p.matrix = Mat3(0.0);
  p.matrix[0][0] = 0.2;
  p.matrix[1][1] = -0.2;
  p.matrix[1][0] = p.matrix[0][1] = 0.1;
  cases.push_back({R"("brush": "pinch", "matrix": [[0.2, 0.1, 0], [0.1, -0.2, 0], [0, 0, 0]])", p});
  for (const auto& [keys, options] : cases) {
    write("k.json", R"({"method": "kelvinlet", )" + common + ", " + keys + "}");
    const test::CliResult r = deform("k.json");
    ASSERT_EQ(r.exitCode, 0) << keys << ": " << r.err;
    const KelvinletWarp warp(options);
    const PolygonSoup out = readSoup(dir_ / "out.ply");
    ASSERT_EQ(out.size(), cloud.size());
    for (std::size_t i = 0; i < cloud.size(); ++i)
      ASSERT_EQ(out.positions[i], warp.apply(cloud.positions[i])) << keys << " point " << i;
  }
}

TEST_F(KelvinletCliTest, ComposedBrushesDeformASoup) {
  const PolygonSoup box = makeBoxSurface(Vec3(-0.5), Vec3(0.5), {3, 3, 3});
  writeSoup(box, dir_ / "box.obj");
  write("k.json", R"({"method": "compose", "warps": [
      {"method": "kelvinlet", "brush": "grab", "center": [0, 0, 0.5], "radius": 1,
       "displacement": [0.3, 0, 0]},
      {"method": "kelvinlet", "brush": "twist", "center": [0, 0, -0.5], "radius": 1,
       "axis": [0, 0, 1], "angle": 0.5}]})");
  const test::CliResult r = run("deform --rig " + (dir_ / "k.json").string() + " " +
                                (dir_ / "box.obj").string() + " -o " + (dir_ / "out.obj").string());
  ASSERT_EQ(r.exitCode, 0) << r.err;
  KelvinletOptions g;
  g.center = Vec3(0.0, 0.0, 0.5);
  g.displacement = Vec3(0.3, 0.0, 0.0);
  KelvinletOptions t;
  t.brush = KelvinletBrush::Twist;
  t.center = Vec3(0.0, 0.0, -0.5);
  t.angle = 0.5;
  const ComposedWarp both(std::make_shared<KelvinletWarp>(g), std::make_shared<KelvinletWarp>(t));
  const PolygonSoup in = readSoup(dir_ / "box.obj");
  const PolygonSoup out = readSoup(dir_ / "out.obj");
  ASSERT_EQ(out.size(), in.size());
  for (std::size_t i = 0; i < in.size(); ++i)
    EXPECT_LE(glm::length(out.positions[i] - both.apply(in.positions[i])), 1e-15) << i;
}

const std::string kGrab = R"("method": "kelvinlet", "center": [0, 0, 0], "radius": 1)";

INSTANTIATE_TEST_SUITE_P(
    KelvinletRigs, BadRigTest,
    ::testing::Values(
        test::BadRig{"KelvinletUnknownBrush", "{" + kGrab + R"(, "brush": "smear"})", 3,
                     "'brush' Kelvinlet brush 'smear' is not one of: grab, twist, scale, pinch"},
        test::BadRig{"KelvinletMissingDisplacement", "{" + kGrab + R"(, "brush": "grab"})", 3,
                     "'displacement' is missing"},
        test::BadRig{"KelvinletZeroRadius",
                     R"({"method": "kelvinlet", "brush": "scale", "center": [0, 0, 0],
                        "radius": 0, "factor": 2})",
                     3, "'radius' must be > 0"},
        test::BadRig{
            "KelvinletPoisson",
            "{" + kGrab + R"(, "brush": "grab", "poisson": 0.7, "displacement": [1, 0, 0]})", 3,
            "'poisson' must be in [0, 0.5]"},
        test::BadRig{"KelvinletZeroAxis",
                     "{" + kGrab + R"(, "brush": "twist", "axis": [0, 0, 0], "angle": 1})", 3,
                     "'axis' must not be zero"},
        test::BadRig{"KelvinletNegativeFactor",
                     "{" + kGrab + R"(, "brush": "scale", "factor": -2})", 3,
                     "'factor' must be > 0"},
        test::BadRig{
            "KelvinletPinchNotTraceless",
            "{" + kGrab + R"(, "brush": "pinch", "matrix": [[1, 0, 0], [0, 1, 0], [0, 0, 1]]})", 3,
            "'matrix' must be traceless"},
        test::BadRig{
            "KelvinletPinchNotSymmetric",
            "{" + kGrab + R"(, "brush": "pinch", "matrix": [[0, 1, 0], [0, 0, 0], [0, 0, 0]]})", 3,
            "'matrix' must be symmetric"},
        test::BadRig{"KelvinletUnknownFalloff",
                     "{" + kGrab + R"(, "brush": "scale", "factor": 2, "falloff": "quad"})", 3,
                     "'falloff' Kelvinlet falloff 'quad' is not one of: single, bi, tri"},
        test::BadRig{"KelvinletFractionalSteps",
                     "{" + kGrab + R"(, "brush": "scale", "factor": 2, "steps": 1.5})", 3,
                     "'steps' must be a whole number in 1..10000"},
        test::BadRig{"KelvinletOtherBrushKey",
                     "{" + kGrab + R"(, "brush": "scale", "factor": 2, "angle": 1})", 3,
                     "'angle' has no effect with the other keys given"}),
    ::spacewarp::test::badRigName);

}  // namespace
