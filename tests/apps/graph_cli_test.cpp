// End-to-end tests of the "graph" rig method (embedded deformation graph): deform agrees with
// the library, the default grid of nodes moves handles to their targets, and bad rigs exit
// with the documented codes and messages.

#include <filesystem>
#include <sstream>
#include <string>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "apps/cli_test_util.h"
#include "core/io/mesh_io.h"
#include "core/primitives.h"
#include "nonlinear/deformation_graph.h"

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
        test::BadRig{"UnknownKey",
                     R"({"method": "graph", "spacing": 0.5, "handle": [[0, 0, 0]],
                        "handles": [[0, 0, 0]], "targets": [[1, 0, 0]]})",
                     "'handle' is not a key of this method"}),
    ::spacewarp::test::badRigName);

}  // namespace
