// End-to-end tests of the "graph" rig method (embedded deformation graph): deform agrees with
// the library, the default grid of nodes moves handles to their targets, and bad rigs exit
// with the documented codes and messages.

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <sstream>
#include <string>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <spacewarp/core/io/mesh_io.h>
#include <spacewarp/core/primitives.h>
#include <spacewarp/nonlinear/deformation_graph.h>
#include "apps/cli_test_util.h"

using namespace spacewarp;
using ::testing::HasSubstr;

namespace {

using ::spacewarp::test::BadRigTest;
using ::spacewarp::test::jsonPoints;

class GraphCliTest : public test::CliFixture {
 protected:
  GraphCliTest() : test::CliFixture("spacewarp_graph_cli_") {}

  PolygonSoup writeCloud() {
    return CliFixture::writeCloud(Vec3(0.0), Vec3(2.0, 1.0, 1.0), 300, 3);
  }
};

const std::vector<Vec3> kHandles{Vec3(0.0), Vec3(0.0, 1.0, 1.0), Vec3(2.0, 0.0, 0.0),
                                 Vec3(2.0, 1.0, 1.0)};
const std::vector<Vec3> kTargets{Vec3(0.0), Vec3(0.0, 1.0, 1.0), Vec3(2.1, 0.4, 0.0),
                                 Vec3(2.0, 1.4, 1.2)};

TEST_F(GraphCliTest, ExplicitNodesMatchTheLibraryWarp) {
  const PolygonSoup cloud = writeCloud();
  const std::vector<Vec3> nodes =
      makeRandomPoints(Vec3(-0.2), Vec3(2.2, 1.2, 1.2), 60, 4).positions;
  write("graph.json", R"({"method": "graph", "k": 5, "nodes": )" + jsonPoints(nodes) +
                          R"(, "handles": )" + jsonPoints(kHandles) + R"(, "targets": )" +
                          jsonPoints(kTargets) + "}");
  const test::CliResult r = deform("graph.json");
  ASSERT_EQ(r.exitCode, 0) << r.err;
  DeformationGraphOptions options;
  options.k = 5;
  DeformationGraph graph(nodes, {}, options);
  graph.solve(kHandles, kTargets);
  const DeformationGraphWarp warp = graph.warp();
  const PolygonSoup out = readSoup(dir_ / "out.ply");
  ASSERT_EQ(out.size(), cloud.size());
  for (std::size_t i = 0; i < cloud.size(); ++i)
    ASSERT_LE(glm::length(out.positions[i] - warp.apply(cloud.positions[i])), 1e-12) << i;
}

// The constraints are soft (w_con E_con); a large constraint weight makes them nearly exact.
TEST_F(GraphCliTest, GridNodesMoveTheHandlesToTheirTargets) {
  PolygonSoup cloud;
  static_cast<PointSet&>(cloud).positions = kHandles;
  writeSoup(cloud, dir_ / "cloud.ply");
  write("graph.json",
        R"({"method": "graph", "spacing": 0.4, "constraintWeight": 10000, "handles": )" +
            jsonPoints(kHandles) + R"(, "targets": )" + jsonPoints(kTargets) + "}");
  const test::CliResult r = deform("graph.json");
  ASSERT_EQ(r.exitCode, 0) << r.err;
  const PolygonSoup out = readSoup(dir_ / "out.ply");
  ASSERT_EQ(out.size(), kHandles.size());
  for (std::size_t i = 0; i < kHandles.size(); ++i)
    EXPECT_LE(glm::length(out.positions[i] - kTargets[i]), 0.02) << i;
}

// Issue 12, item 4: a rigid motion of a dozen handles in the unit cube moves every point of
// the cube rigidly, at the spacings and k that left far points behind or unmoved, silently.
TEST_F(GraphCliTest, RigidMotionOfTheHandlesMovesTheWholeCloudRigidly) {
  const PolygonSoup cloud = CliFixture::writeCloud(Vec3(0.0), Vec3(1.0), 2000, 7);
  const std::vector<Vec3> handles(cloud.positions.begin(), cloud.positions.begin() + 12);
  const double c = std::cos(0.5), s = std::sin(0.5);
  const auto motion = [&](const Vec3& x) {
    return Vec3(c * x.x - s * x.y, s * x.x + c * x.y, x.z) + Vec3(0.3, -0.2, 0.1);
  };
  std::vector<Vec3> targets;
  for (const Vec3& h : handles) targets.push_back(motion(h));
  for (const char* params : {R"("spacing": 0.2)", R"("spacing": 0.3)", R"("spacing": 0.3, "k": 2)",
                             R"("spacing": 0.5)", R"("spacing": 0.3, "k": 8)"}) {
    write("graph.json", R"({"method": "graph", )" + std::string(params) + R"(, "handles": )" +
                            jsonPoints(handles) + R"(, "targets": )" + jsonPoints(targets) + "}");
    const test::CliResult r = deform("graph.json");
    ASSERT_EQ(r.exitCode, 0) << params << ": " << r.err;
    EXPECT_EQ(r.err, "") << params;
    const PolygonSoup out = readSoup(dir_ / "out.ply");
    ASSERT_EQ(out.size(), cloud.size());
    double worst = 0.0;
    for (std::size_t i = 0; i < cloud.size(); ++i)
      worst = std::max(worst, glm::length(out.positions[i] - motion(cloud.positions[i])));
    EXPECT_LE(worst, 1e-9) << params;
  }
}

// The solve's report reaches the user: one warning line each for a solve stopped by
// 'maxIterations' and for parts of the graph that no handle reaches, counted in the summary,
// also from a graph nested in a compose rig; the warp is still written and the exit code is 0.
TEST_F(GraphCliTest, WarnsAboutNonConvergenceAndUnreachedParts) {
  writeCloud();
  write("graph.json", R"({"method": "graph", "spacing": 0.4, "maxIterations": 1, "handles": )" +
                          jsonPoints(kHandles) + R"(, "targets": )" + jsonPoints(kTargets) + "}");
  test::CliResult r = deform("graph.json");
  ASSERT_EQ(r.exitCode, 0) << r.err;
  EXPECT_THAT(r.err, HasSubstr("graph.json: the deformation graph did not converge in 1 "));
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  EXPECT_THAT(r.out, HasSubstr(", 1 warning\n"));
  EXPECT_TRUE(std::filesystem::exists(dir_ / "out.ply"));

  write(
      "compose.json",
      R"({"method": "compose", "warps": [{"method": "twist", "origin": [0, 0, 0], "axis": [0, 0, 1], "rate": 0}, {"method": "graph", "spacing": 0.4, "maxIterations": 1, "handles": )" +
          jsonPoints(kHandles) + R"(, "targets": )" + jsonPoints(kTargets) + "}]}");
  r = deform("compose.json");
  ASSERT_EQ(r.exitCode, 0) << r.err;
  EXPECT_THAT(r.err, HasSubstr("compose.json: warps[1]: the deformation graph did not converge"));
  EXPECT_THAT(r.out, HasSubstr(", 1 warning\n"));

  // Two clusters of nodes 50 apart; the handles are all in the first.
  std::vector<Vec3> nodes = makeRandomPoints(Vec3(-0.2), Vec3(2.2, 1.2, 1.2), 40, 4).positions;
  for (const Vec3& g : makeRandomPoints(Vec3(50.0), Vec3(51.0), 10, 5).positions)
    nodes.push_back(g);
  write("graph.json", R"({"method": "graph", "nodes": )" + jsonPoints(nodes) + R"(, "handles": )" +
                          jsonPoints(kHandles) + R"(, "targets": )" + jsonPoints(kTargets) + "}");
  r = deform("graph.json");
  ASSERT_EQ(r.exitCode, 0) << r.err;
  EXPECT_THAT(r.err, HasSubstr("graph.json: 1 of 2 parts of the deformation graph (10 nodes) are "
                               "reached by no handle and stay in place"));
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  EXPECT_THAT(r.out, HasSubstr(", 1 warning\n"));
}

// 'maxIterations' and 'tolerance' reach the solve: the output is the library's warp solved
// with the same options, and each setting gives another warp.
TEST_F(GraphCliTest, MaxIterationsAndToleranceReachTheSolve) {
  const PolygonSoup cloud = writeCloud();
  const std::vector<Vec3> nodes =
      makeRandomPoints(Vec3(-0.2), Vec3(2.2, 1.2, 1.2), 60, 4).positions;
  struct Setting {
    const char* json;
    int maxIterations;
    double tolerance;
  };
  std::vector<PolygonSoup> outputs;
  for (const Setting& setting :
       {Setting{R"("maxIterations": 0)", 0, 1e-6}, Setting{R"("tolerance": 0.9)", 50, 0.9},
        Setting{R"("maxIterations": 500, "tolerance": 0)", 500, 0.0}}) {
    write("graph.json", R"({"method": "graph", )" + std::string(setting.json) + R"(, "nodes": )" +
                            jsonPoints(nodes) + R"(, "handles": )" + jsonPoints(kHandles) +
                            R"(, "targets": )" + jsonPoints(kTargets) + "}");
    const test::CliResult r = deform("graph.json");
    ASSERT_EQ(r.exitCode, 0) << setting.json << ": " << r.err;
    DeformationGraph graph(nodes, {}, DeformationGraphOptions{});
    DeformationGraphSolveOptions options;
    options.maxIterations = setting.maxIterations;
    options.tolerance = setting.tolerance;
    graph.solve(kHandles, kTargets, options);
    const DeformationGraphWarp warp = graph.warp();
    outputs.push_back(readSoup(dir_ / "out.ply"));
    ASSERT_EQ(outputs.back().size(), cloud.size());
    for (std::size_t i = 0; i < cloud.size(); ++i) {
      ASSERT_LE(glm::length(outputs.back().positions[i] - warp.apply(cloud.positions[i])), 1e-12)
          << setting.json << ", point " << i;
    }
  }
  for (std::size_t a = 0; a < outputs.size(); ++a)
    for (std::size_t b = a + 1; b < outputs.size(); ++b)
      EXPECT_NE(outputs[a].positions, outputs[b].positions) << a << " " << b;
}

// An input point whose squared distances to the nodes overflow is bad input (exit 3) naming
// the point, not a crash or a point moved by another point's neighbours.
TEST_F(GraphCliTest, InputPointsBeyondTheReachOfSquaredDistancesAreBadInput) {
  PolygonSoup cloud;
  static_cast<PointSet&>(cloud) = makeRandomPoints(Vec3(0.0), Vec3(1.0), 50, 1);
  cloud.positions[7] = Vec3(1e200, 3e199, -2e199);
  writeSoup(cloud, dir_ / "cloud.ply");
  write("graph.json", R"({"method": "graph", "spacing": 0.25, "handles": )" + jsonPoints(kHandles) +
                          R"(, "targets": )" + jsonPoints(kTargets) + "}");
  const test::CliResult r = deform("graph.json");
  EXPECT_EQ(r.exitCode, 3) << r.err;
  EXPECT_THAT(r.err, HasSubstr("point 7 "));
  EXPECT_FALSE(std::filesystem::exists(dir_ / "out.ply"));
}

// An energy that overflows is a numerical failure (exit 4), not a converged identity.
TEST_F(GraphCliTest, EnergyOverflowIsANumericalFailure) {
  writeCloud();
  std::vector<Vec3> targets = kTargets;
  targets[2] = Vec3(1e300, 0.0, 0.0);
  write("graph.json", R"({"method": "graph", "spacing": 0.4, "handles": )" + jsonPoints(kHandles) +
                          R"(, "targets": )" + jsonPoints(targets) + "}");
  const test::CliResult r = deform("graph.json");
  EXPECT_EQ(r.exitCode, 4) << r.err;
  EXPECT_THAT(r.err, HasSubstr("overflows"));
  EXPECT_FALSE(std::filesystem::exists(dir_ / "out.ply"));
}

INSTANTIATE_TEST_SUITE_P(
    GraphRigs, BadRigTest,
    ::testing::Values(
        test::BadRig{"MissingTargets",
                     R"({"method": "graph", "spacing": 0.5, "handles": [[0, 0, 0]]})",
                     "'targets' is missing"},
        test::BadRig{"MismatchedTargets",
                     R"({"method": "graph", "spacing": 0.5, "handles": [[0, 0, 0]],
                        "targets": [[0, 0, 0], [1, 1, 1]]})",
                     "'targets' must have as many points"},
        test::BadRig{"ZeroSpacing",
                     R"({"method": "graph", "spacing": 0, "handles": [[0, 0, 0]],
                        "targets": [[1, 0, 0]]})",
                     "'spacing' must be > 0"},
        test::BadRig{"HugeSpacing",
                     R"({"method": "graph", "spacing": 1e155, "handles": [[0, 0, 0]],
                        "targets": [[1, 0, 0]]})",
                     "'spacing' must be > 0 and at most 1e150"},
        test::BadRig{"FractionalK",
                     R"({"method": "graph", "spacing": 0.5, "k": 2.5, "handles": [[0, 0, 0]],
                        "targets": [[1, 0, 0]]})",
                     "'k' must be an integer"},
        test::BadRig{"KNotBelowNodeCount",
                     R"({"method": "graph", "k": 3, "nodes": [[0, 0, 0], [1, 0, 0], [0, 1, 0]],
                        "handles": [[0, 0, 0]], "targets": [[1, 0, 0]]})",
                     "'k' must be less than the number of nodes (3)"},
        test::BadRig{"NegativeWeight",
                     R"({"method": "graph", "spacing": 0.5, "rotationWeight": -1,
                        "handles": [[0, 0, 0]], "targets": [[1, 0, 0]]})",
                     "'rotationWeight' must be >= 0"},
        test::BadRig{"FractionalMaxIterations",
                     R"({"method": "graph", "spacing": 0.5, "maxIterations": 1.5,
                        "handles": [[0, 0, 0]], "targets": [[1, 0, 0]]})",
                     "'maxIterations' must be an integer in [0, 1000000]"},
        test::BadRig{"NegativeTolerance",
                     R"({"method": "graph", "spacing": 0.5, "tolerance": -1e-6,
                        "handles": [[0, 0, 0]], "targets": [[1, 0, 0]]})",
                     "'tolerance' must be >= 0"},
        test::BadRig{"UnknownKey",
                     R"({"method": "graph", "spacing": 0.5, "handle": [[0, 0, 0]],
                        "handles": [[0, 0, 0]], "targets": [[1, 0, 0]]})",
                     "'handle' is not a key of this method"},
        // Keys are checked before the solve: this one's energy overflows (exit 4).
        test::BadRig{"UnknownKeyBeforeTheSolve",
                     R"({"method": "graph", "spacing": 0.5, "tolerence": 0,
                        "handles": [[0, 0, 0], [1, 0, 0]], "targets": [[0, 0, 0], [1e300, 0, 0]]})",
                     "'tolerence' is not a key of this method"},
        test::BadRig{"SpacingWithNodes",
                     R"({"method": "graph", "spacing": 0.5, "nodes": [[0, 0, 0], [1, 0, 0]],
                        "k": 1, "handles": [[0, 0, 0]], "targets": [[1, 0, 0]]})",
                     "'spacing' is not read when 'nodes' is given"}),
    ::spacewarp::test::badRigName);

}  // namespace
