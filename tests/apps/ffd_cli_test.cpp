// End-to-end tests of the "ffd" rig: posed lattices, direct manipulation, `spacewarp weights`
// through the rig, and the errors of malformed ffd rigs.

#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <spacewarp/core/io/mesh_io.h>
#include <spacewarp/core/primitives.h>
#include <spacewarp/ffd/lattice_coordinates.h>
#include <spacewarp/ffd/lattice_warp.h>
#include "apps/cli_test_util.h"

namespace fs = std::filesystem;
using namespace spacewarp;
using ::testing::HasSubstr;

namespace {

using ::spacewarp::test::BadRigTest;

using test::CliResult;

class FfdCliTest : public test::CliFixture {
 protected:
  FfdCliTest() : CliFixture("spacewarp_ffd_cli_") {}

  // A cloud of n points in [lo, hi)³ written as cloud.ply.
  PolygonSoup writeCloud(double lo, double hi, std::size_t n) {
    return CliFixture::writeCloud(Vec3(lo), Vec3(hi), n, 5);
  }
};

nlohmann::json toJson(std::span<const Vec3> points) {
  nlohmann::json a = nlohmann::json::array();
  for (const Vec3& p : points) a.push_back({p.x, p.y, p.z});
  return a;
}

LatticeOptions rotatedBox(LatticeBasis basis) {
  LatticeOptions p;
  p.origin = Vec3(-1.0, -1.5, -1.0);
  const double c = std::cos(0.3), s = std::sin(0.3);
  p.axes = {Vec3(c, s, 0.0), Vec3(-s, c, 0.0), Vec3(0.0, 0.0, 1.0)};
  p.extents = Vec3(2.5, 3.0, 2.0);
  p.resolution = {4, 5, 4};
  p.basis = basis;
  return p;
}

nlohmann::json rigOf(const LatticeOptions& p, const char* basis, std::span<const Vec3> posed) {
  return {{"method", "ffd"},
          {"basis", basis},
          {"origin", {p.origin.x, p.origin.y, p.origin.z}},
          {"size", {p.extents.x, p.extents.y, p.extents.z}},
          {"resolution", {p.resolution[0], p.resolution[1], p.resolution[2]}},
          {"axes", toJson(p.axes)},
          {"controlPoints", toJson(posed)}};
}

TEST_F(FfdCliTest, PosedLatticeRigsMatchTheLibrary) {
  const PolygonSoup cloud = writeCloud(-0.5, 0.5, 500);
  std::mt19937 rng(1);
  std::uniform_real_distribution<double> u(-0.2, 0.2);
  for (auto [basis, name] : {std::pair{LatticeBasis::Trilinear, "trilinear"},
                             std::pair{LatticeBasis::Bernstein, "bernstein"},
                             std::pair{LatticeBasis::BSpline, "bspline"}}) {
    const LatticeOptions params = rotatedBox(basis);
    const Lattice lattice(params);
    std::vector<Vec3> posed(lattice.restControlPoints().begin(), lattice.restControlPoints().end());
    for (Vec3& c : posed) {
      const double x = u(rng), y = u(rng), z = u(rng);
      c += Vec3(x, y, z);
    }
    write("ffd.json", rigOf(params, name, posed).dump());
    const CliResult r = deform("ffd.json");
    ASSERT_EQ(r.exitCode, 0) << r.err;
    const PolygonSoup out = readSoup(dir_ / "out.ply");
    ASSERT_EQ(out.size(), cloud.size());
    const LatticeWarp warp(lattice, posed);
    for (std::size_t i = 0; i < cloud.size(); ++i)
      EXPECT_LE(glm::length(out.positions[i] - warp.apply(cloud.positions[i])), 1e-12)
          << name << " point " << i;
  }
}

// "ends": "repeat" (Blender's B-spline lattice) reaches the library, and differs from the
// default near the faces.
TEST_F(FfdCliTest, RepeatEndsRigMatchesTheLibrary) {
  const PolygonSoup cloud = writeCloud(-0.5, 0.5, 500);
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-0.2, 0.2);
  LatticeOptions params = rotatedBox(LatticeBasis::BSpline);
  params.ends = LatticeEnds::Repeat;
  const Lattice lattice(params);
  std::vector<Vec3> posed;
  for (const Vec3& p : lattice.restControlPoints())
    posed.push_back(p + Vec3(u(rng), u(rng), u(rng)));
  nlohmann::json rig = rigOf(params, "bspline", posed);
  rig["ends"] = "repeat";
  write("ffd.json", rig.dump());
  const CliResult r = deform("ffd.json");
  ASSERT_EQ(r.exitCode, 0) << r.err;
  const PolygonSoup out = readSoup(dir_ / "out.ply");
  ASSERT_EQ(out.size(), cloud.size());
  const LatticeWarp repeat(lattice, posed);
  params.ends = LatticeEnds::Extrapolate;
  const LatticeWarp extrapolate(Lattice(params), posed);
  double differs = 0.0;
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    EXPECT_EQ(out.positions[i], repeat.apply(cloud.positions[i])) << i;
    differs =
        std::max(differs, glm::length(out.positions[i] - extrapolate.apply(cloud.positions[i])));
  }
  EXPECT_GT(differs, 1e-3);
}

TEST_F(FfdCliTest, AffinePoseMovesPointsAffinely) {
  const PolygonSoup cloud = writeCloud(-0.5, 0.5, 200);
  const LatticeOptions params = rotatedBox(LatticeBasis::BSpline);
  const Lattice lattice(params);
  std::vector<Vec3> posed;
  for (const Vec3& p : lattice.restControlPoints())
    posed.push_back(Vec3(2 * p.x, p.y - p.z, p.z) + 1.0);
  write("ffd.json", rigOf(params, "bspline", posed).dump());
  const CliResult r = deform("ffd.json");
  ASSERT_EQ(r.exitCode, 0) << r.err;
  const PolygonSoup out = readSoup(dir_ / "out.ply");
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    const Vec3 p = cloud.positions[i];
    EXPECT_LE(glm::length(out.positions[i] - (Vec3(2 * p.x, p.y - p.z, p.z) + 1.0)), 1e-12) << i;
  }
}

TEST_F(FfdCliTest, ConstraintsRigMovesTheConstrainedPoints) {
  const PolygonSoup cloud = writeCloud(0.1, 0.9, 100);
  // Translate everything by (0.1, 0.2, -0.1): met exactly through any smoothness.
  nlohmann::json from = nlohmann::json::array(), to = nlohmann::json::array();
  std::mt19937 rng(2);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (int k = 0; k < 200; ++k) {
    const Vec3 p(u(rng), u(rng), u(rng));
    from.push_back({p.x, p.y, p.z});
    to.push_back({p.x + 0.1, p.y + 0.2, p.z - 0.1});
  }
  const nlohmann::json rig = {{"method", "ffd"},
                              {"basis", "trilinear"},
                              {"origin", {0, 0, 0}},
                              {"size", {1, 1, 1}},
                              {"resolution", {3, 3, 3}},
                              {"outside", "clamp"},
                              {"constraints", {{"from", from}, {"to", to}}},
                              {"smoothness", 0.01}};
  write("ffd.json", rig.dump());
  const CliResult r = deform("ffd.json");
  ASSERT_EQ(r.exitCode, 0) << r.err;
  const PolygonSoup out = readSoup(dir_ / "out.ply");
  for (std::size_t i = 0; i < cloud.size(); ++i)
    EXPECT_LE(glm::length(out.positions[i] - (cloud.positions[i] + Vec3(0.1, 0.2, -0.1))), 1e-9);
}

TEST_F(FfdCliTest, WeightsThroughTheRigAreTheLatticeCoordinates) {
  const PolygonSoup cloud = writeCloud(-0.5, 0.5, 40);
  const LatticeOptions params = rotatedBox(LatticeBasis::BSpline);
  const Lattice lattice(params);
  write("ffd.json", rigOf(params, "bspline", lattice.restControlPoints()).dump());
  const CliResult r = run("weights --rig " + (dir_ / "ffd.json").string() + " " +
                          (dir_ / "cloud.ply").string() + " -o " + (dir_ / "w.csv").string());
  ASSERT_EQ(r.exitCode, 0) << r.err;
  std::ifstream in(dir_ / "w.csv");
  std::string header;
  std::getline(in, header);
  EXPECT_EQ(std::count(header.begin(), header.end(), ',') + 1,
            static_cast<long>(lattice.controlPointCount()));
  EXPECT_TRUE(header.starts_with("v0,v1,"));
  const LatticeCoordinates coords(lattice);
  std::vector<double> expected(coords.columnCount());
  std::string line;
  std::size_t rows = 0;
  while (std::getline(in, line)) {
    ASSERT_LT(rows, cloud.size());
    coords.weights(cloud.positions[rows], expected);
    std::stringstream s(line);
    std::string cell;
    double sum = 0.0;
    for (std::size_t c = 0; std::getline(s, cell, ','); ++c) {
      EXPECT_EQ(std::stod(cell), expected[c]) << "row " << rows << " column " << c;
      sum += std::stod(cell);
    }
    EXPECT_NEAR(sum, 1.0, 1e-13);
    ++rows;
  }
  EXPECT_EQ(rows, cloud.size());
}

#define SW_BOX R"("method": "ffd", "origin": [0,0,0], "size": [1,1,1], )"
#define SW_CORNERS \
  R"("controlPoints": [[0,0,0],[1,0,0],[0,1,0],[1,1,0],[0,0,1],[1,0,1],[0,1,1],[1,1,1]])"

INSTANTIATE_TEST_SUITE_P(
    FfdRigs, BadRigTest,
    ::testing::Values(
        test::BadRig{"UnknownBasis",
                     "{" SW_BOX R"("basis": "nurbs", "resolution": [2,2,2], )" SW_CORNERS "}",
                     "'basis' 'nurbs' is not one of"},
        test::BadRig{"BSplineNeeds4",
                     "{" SW_BOX R"("basis": "bspline", "resolution": [2,2,2], )" SW_CORNERS "}",
                     "the cubic B-spline basis needs at least 4"},
        test::BadRig{"WrongControlCount",
                     "{" SW_BOX R"("basis": "trilinear", "resolution": [2,2,3], )" SW_CORNERS "}",
                     "'controlPoints' has 8 points, the resolution 2 x 2 x 3 needs 12"},
        test::BadRig{"FractionalResolution",
                     "{" SW_BOX R"("basis": "trilinear", "resolution": [2,2.5,2], )" SW_CORNERS "}",
                     "'resolution' must contain integers"},
        test::BadRig{
            "ZeroSize",
            R"({"method": "ffd", "origin": [0,0,0], "size": [1,0,1], "basis": "trilinear", "resolution": [2,2,2], )" SW_CORNERS
            "}",
            "extent 1"},
        test::BadRig{
            "SkewAxes",
            "{" SW_BOX
            R"("basis": "trilinear", "resolution": [2,2,2], "axes": [[1,0,0],[1,1,0],[0,0,1]], )" SW_CORNERS
            "}",
            "not orthogonal"},
        test::BadRig{
            "UnknownOutside",
            "{" SW_BOX
            R"("basis": "trilinear", "resolution": [2,2,2], "outside": "wrap", )" SW_CORNERS "}",
            "'outside' 'wrap'"},
        test::BadRig{
            "UnknownEnds",
            "{" SW_BOX
            R"("basis": "bspline", "resolution": [4,4,4], "ends": "mirror", "controlPoints": []})",
            "'ends' 'mirror' is not one of: extrapolate, repeat"},
        test::BadRig{"EndsOfATrilinearLattice",
                     "{" SW_BOX
                     R"("basis": "trilinear", "resolution": [2,2,2], "ends": "repeat", )" SW_CORNERS
                     "}",
                     "'ends' applies to the bspline basis only"},
        test::BadRig{"NoControls", "{" SW_BOX R"("basis": "trilinear", "resolution": [2,2,2]})",
                     "'controlPoints' is missing"},
        test::BadRig{
            "BothControlsAndConstraints",
            "{" SW_BOX
            R"("basis": "trilinear", "resolution": [2,2,2], "constraints": {"from": [[0.5,0.5,0.5]], "to": [[0.5,0.5,0.6]]}, )" SW_CORNERS
            "}",
            "'constraints' cannot be combined"},
        test::BadRig{
            "ConstraintSizes",
            "{" SW_BOX
            R"("basis": "trilinear", "resolution": [2,2,2], "constraints": {"from": [[0.5,0.5,0.5]], "to": [[0,0,0],[1,1,1]]}})",
            "constraints: 'to' must have as many points as 'from' (1), not 2"},
        test::BadRig{
            "ConstraintTypo",
            "{" SW_BOX
            R"("basis": "trilinear", "resolution": [2,2,2], "constraints": {"from": [[0.5,0.5,0.5]], "to": [[0,0,0]], "too": 1}})",
            "constraints: 'too' is not a key"},
        test::BadRig{"SmoothnessWithControls",
                     "{" SW_BOX
                     R"("basis": "trilinear", "resolution": [2,2,2], "smoothness": 1, )" SW_CORNERS
                     "}",
                     "'smoothness' has no effect with the other keys given"}),
    [](const auto& info) { return std::string(info.param.name); });

#undef SW_BOX
#undef SW_CORNERS

}  // namespace
