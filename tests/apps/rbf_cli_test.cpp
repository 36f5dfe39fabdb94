// End-to-end tests of the "rbf" rig method of the spacewarp executable: deform and weights
// agree with the library, and bad rigs exit with the documented codes and messages.

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <spacewarp/core/io/mesh_io.h>
#include <spacewarp/core/primitives.h>
#include <spacewarp/rbf/rbf_coordinates.h>
#include <spacewarp/rbf/rbf_warp.h>
#include "apps/cli_test_util.h"

namespace fs = std::filesystem;
using namespace spacewarp;
using ::testing::HasSubstr;

namespace {

using ::spacewarp::test::BadRigTest;

// A fresh folder per test (see cli_test_util.h).
class RbfCliTest : public test::CliFixture {
 protected:
  RbfCliTest() : test::CliFixture("spacewarp_rbf_cli_") {}
};

using test::jsonPoints;

struct RbfSetup {
  std::vector<Vec3> centers, targets, fixed;
};

RbfSetup setup() {
  RbfSetup s;
  s.centers = makeRandomPoints(Vec3(-1.0), Vec3(1.0), 20, 5).positions;
  const std::vector<Vec3> offsets = makeRandomPoints(Vec3(-0.2), Vec3(0.2), 20, 6).positions;
  for (std::size_t i = 0; i < s.centers.size(); ++i) s.targets.push_back(s.centers[i] + offsets[i]);
  s.fixed = {Vec3(2.0, 2.0, 2.0), Vec3(-2.0, -2.0, 2.0)};
  return s;
}

TEST_F(RbfCliTest, DeformMatchesTheLibraryWarp) {
  const RbfSetup s = setup();
  PolygonSoup cloud;
  static_cast<PointSet&>(cloud) = makeRandomPoints(Vec3(-1.5), Vec3(1.5), 300, 9);
  writeSoup(cloud, dir_ / "cloud.ply");
  write("rbf.json", R"({"method": "rbf", "centers": )" + jsonPoints(s.centers) +
                        R"(, "targets": )" + jsonPoints(s.targets) + "}");
  write("smooth.json", R"({"method": "rbf", "kernel": "gaussian", "scale": 0.8, "smoothing": 0.01,
                           "centers": )" +
                           jsonPoints(s.centers) + R"(, "targets": )" + jsonPoints(s.targets) +
                           R"(, "fixed": )" + jsonPoints(s.fixed) + "}");
  RbfOptions smooth;
  smooth.kernel = RbfKernel::Gaussian;
  smooth.scale = 0.8;
  smooth.smoothing = 0.01;
  const RbfWarp plain(s.centers, s.targets);
  const RbfWarp smoothed(s.centers, s.targets, s.fixed, smooth);
  for (const auto& [rig, warp] :
       {std::pair<std::string, const RbfWarp*>{"rbf.json", &plain}, {"smooth.json", &smoothed}}) {
    const test::CliResult r =
        run("deform --rig " + (dir_ / rig).string() + " " + (dir_ / "cloud.ply").string() + " -o " +
            (dir_ / "out.ply").string());
    ASSERT_EQ(r.exitCode, 0) << rig << ": " << r.err;
    const PolygonSoup out = readSoup(dir_ / "out.ply");
    ASSERT_EQ(out.size(), cloud.size());
    for (std::size_t i = 0; i < cloud.size(); ++i)
      ASSERT_LE(glm::length(out.positions[i] - warp->apply(cloud.positions[i])), 1e-12)
          << rig << " point " << i;
  }
}

TEST_F(RbfCliTest, WeightsWriteTheRbfCoordinates) {
  const RbfSetup s = setup();
  PolygonSoup cloud;
  static_cast<PointSet&>(cloud) = makeRandomPoints(Vec3(-1.5), Vec3(1.5), 40, 10);
  writeSoup(cloud, dir_ / "cloud.ply");
  write("rbf.json", R"({"method": "rbf", "kernel": "triharmonic", "centers": )" +
                        jsonPoints(s.centers) + R"(, "targets": )" + jsonPoints(s.targets) + "}");
  const fs::path csv = dir_ / "w.csv";
  const test::CliResult r = run("weights --rig " + (dir_ / "rbf.json").string() + " " +
                                (dir_ / "cloud.ply").string() + " -o " + csv.string());
  ASSERT_EQ(r.exitCode, 0) << r.err;
  const RbfCoordinates coords(s.centers);
  std::vector<double> expected(coords.columnCount());
  std::ifstream in(csv);
  std::string line;
  std::getline(in, line);
  EXPECT_TRUE(line.starts_with("v0,v1,"));
  EXPECT_EQ(std::count(line.begin(), line.end(), ','), 19);
  std::size_t row = 0;
  while (std::getline(in, line)) {
    ASSERT_LT(row, cloud.size());
    coords.weights(cloud.positions[row], expected);
    std::stringstream cells(line);
    std::string cell;
    double sum = 0.0;
    for (std::size_t c = 0; std::getline(cells, cell, ','); ++c) {
      EXPECT_EQ(std::stod(cell), expected[c]) << "row " << row << " column " << c;
      sum += std::stod(cell);
    }
    EXPECT_NEAR(sum, 1.0, 1e-10) << "row " << row;
    ++row;
  }
  EXPECT_EQ(row, cloud.size());
}

const std::string kTet = "[[0,0,0],[1,0,0],[0,1,0],[0,0,1],[1,1,1]]";
const std::string kPlane = "[[0,0,0],[1,0,0],[0,1,0],[1,1,0],[2,1,0]]";

INSTANTIATE_TEST_SUITE_P(
    RbfRigs, BadRigTest,
    ::testing::Values(
        test::BadRig{"UnknownKernel",
                     R"({"method": "rbf", "kernel": "cubic", "centers": )" + kTet +
                         R"(, "targets": )" + kTet + "}",
                     3, "'kernel' unknown RBF kernel 'cubic'"},
        test::BadRig{"MissingTargets", R"({"method": "rbf", "centers": )" + kTet + "}", 3,
                     "'targets' is missing"},
        test::BadRig{"SizeMismatch",
                     R"({"method": "rbf", "centers": )" + kTet + R"(, "targets": [[0,0,0]]})", 3,
                     "as many points as 'centers'"},
        test::BadRig{
            "ScaleOnTriharmonic",
            R"({"method": "rbf", "scale": 2, "centers": )" + kTet + R"(, "targets": )" + kTet + "}",
            3, "'scale' applies to the gaussian"},
        test::BadRig{"NegativeSmoothing",
                     R"({"method": "rbf", "smoothing": -1, "centers": )" + kTet +
                         R"(, "targets": )" + kTet + "}",
                     3, "'smoothing' must be >= 0"},
        test::BadRig{
            "Coplanar",
            R"({"method": "rbf", "centers": )" + kPlane + R"(, "targets": )" + kPlane + "}", 3,
            "4 affinely independent centers"},
        test::BadRig{"Conflict",
                     R"({"method": "rbf", "centers": [[0,0,0],[1,0,0],[0,1,0],[0,0,1],[0,0,0]],
                      "targets": [[0,0,0],[1,0,0],[0,1,0],[0,0,1],[1,0,0]]})",
                     3, "center 0 and center 4 coincide"},
        test::BadRig{"Singular",
                     R"({"method": "rbf", "kernel": "gaussian", "scale": 1e6, "centers": )" + kTet +
                         R"(, "targets": )" + kTet + "}",
                     4, "singular"}
            .atSolve(),
        // Kernel scales whose kernel values under- or overflow are refused naming the key,
        // rather than giving non-finite points blamed on the input.
        test::BadRig{"GaussianScaleBeyondDouble",
                     R"({"method": "rbf", "kernel": "gaussian", "scale": 1e-200, "centers": )" +
                         kTet + R"(, "targets": )" + kTet + "}",
                     3, "'scale' 1e-200 is outside [1e-150, 1e150]"},
        test::BadRig{"GaussianScaleTooSmallForTheCenters",
                     R"({"method": "rbf", "kernel": "gaussian", "scale": 1e-50, "centers": )" +
                         kTet + R"(, "targets": )" + kTet + "}",
                     3, "'scale' 1e-50 is too small for centers 1 apart (the closest two)"},
        test::BadRig{"ScaleTooLargeForTheCenters",
                     R"({"method": "rbf", "kernel": "inverse-multiquadric", "scale": 1e12,
                        "centers": )" +
                         kTet + R"(, "targets": )" + kTet + "}",
                     3, "'scale' 1e+12 is too large for centers spanning 1.73"},
        test::BadRig{"WendlandRadiusBeyondDouble",
                     R"({"method": "rbf", "kernel": "wendland", "radius": 1e-300, "centers": )" +
                         kTet + R"(, "targets": )" + kTet + "}",
                     3, "'radius' must be within [1e-150, 1e150]"}),
    ::spacewarp::test::badRigName);

}  // namespace
