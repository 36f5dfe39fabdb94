// End-to-end tests of `spacewarp inverse`: it undoes `deform` for rigs with a closed-form
// inverse and for rigs it solves iteratively, fails with exit 4 and no output where a point has
// no preimage, and refuses bad input in one line.

#include <algorithm>
#include <filesystem>
#include <random>
#include <string>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <spacewarp/core/io/mesh_io.h>
#include <spacewarp/core/primitives.h>
#include "apps/cli_test_util.h"
#include "test_util.h"

namespace fs = std::filesystem;
using namespace spacewarp;
using ::testing::HasSubstr;

namespace {

using test::CliResult;
using test::slurp;

class InverseCliTest : public test::CliFixture {
 protected:
  InverseCliTest() : CliFixture("spacewarp_inverse_") {}

  std::string path(const std::string& name) const { return (dir_ / name).string(); }

  // `spacewarp inverse --rig RIG INPUT -o OUTPUT [extra]` in the test's folder.
  CliResult inverse(const std::string& rig, const std::string& input, const std::string& output,
                    const std::string& extra = "") {
    return run("inverse --rig " + path(rig) + " " + path(input) + " -o " + path(output) +
               (extra.empty() ? "" : " " + extra));
  }

  // A box cage around [-1, 1]^3 whose top is swayed and lifted: a smooth, injective, nonlinear
  // mean-value warp inside it, which has no closed-form inverse.
  void writeSwayedCage() {
    const PolygonSoup cage = makeBoxSurface(Vec3(-1), Vec3(1), {1, 1, 1});
    PolygonSoup posed = cage;
    for (Vec3& p : posed.positions)
      if (p.z > 0.0) p += Vec3(0.3, -0.1, 0.2);
    writeSoup(cage, dir_ / "cage.obj");
    writeSoup(posed, dir_ / "pose.obj");
    write("mvc.json", R"({"method": "mvc", "cage": "cage.obj", "pose": "pose.obj"})");
  }
};

// A cloud with normals, and a box surface: deform, then inverse, gives both back (positions
// to the tolerance's scale, normals too), by the closed form for twist and compositions of
// analytic warps, iteratively for a cage rig; the summary says which.
TEST_F(InverseCliTest, UndoesDeformForClosedFormAndIterativeRigs) {
  write("twist.json",
        R"({"method": "twist", "origin": [0.1, 0, 0], "axis": [0, 0.2, 1], "rate": 0.8})");
  write("compose.json", R"({"method": "compose", "warps": [
          {"method": "twist", "origin": [0, 0, 0], "axis": [0, 0, 1], "rate": 0.5},
          {"method": "taper", "origin": [0, 0, -1], "axis": [0, 0, 1], "rate": 0.2}]})");
  writeSwayedCage();
  PolygonSoup cloud;
  static_cast<PointSet&>(cloud) = makeRandomPoints(Vec3(-0.8), Vec3(0.8), 300, 4);
  std::mt19937 rng(4);
  for (const Vec3& p : cloud.positions) {
    (void)p;
    cloud.normals.push_back(test::randomUnit(rng));
  }
  writeSoup(cloud, dir_ / "cloud.ply");
  writeSoup(makeBoxSurface(Vec3(-0.7), Vec3(0.7), {3, 3, 5}), dir_ / "bar.obj");

  for (const std::string rig : {"twist.json", "compose.json", "mvc.json"}) {
    for (const std::string input : {"cloud.ply", "bar.obj"}) {
      SCOPED_TRACE(rig + " " + input);
      const std::string ext = fs::path(input).extension().string();
      ASSERT_EQ(run("deform --rig " + path(rig) + " " + path(input) + " -o " + path("warped" + ext))
                    .exitCode,
                0);
      const CliResult r = inverse(rig, "warped" + ext, "back" + ext);
      ASSERT_EQ(r.exitCode, 0) << r.err;
      EXPECT_EQ(r.err, "");
      const PolygonSoup before = readSoup(dir_ / input);
      const PolygonSoup back = readSoup(dir_ / ("back" + ext));
      ASSERT_EQ(back.size(), before.size());
      EXPECT_EQ(back.faceIndices, before.faceIndices);
      const std::size_t n = before.size();
      // One line: the points, then how they were solved.
      EXPECT_THAT(r.out, HasSubstr("inverted " + std::to_string(n) + " points"));
      const bool closedForm = rig != "mvc.json";
      EXPECT_THAT(r.out, HasSubstr(closedForm ? std::to_string(n) + " by the closed form, 0 "
                                              : "0 by the closed form, " + std::to_string(n) +
                                                    " iterative"));
      EXPECT_THAT(r.out, HasSubstr("worst residual "));
      EXPECT_EQ(std::count(r.out.begin(), r.out.end(), '\n'), 1) << r.out;
      // PLY stores floats: the round trip is exact to float precision.
      const double tolerance = ext == ".ply" ? 1e-6 : 1e-9;
      for (std::size_t i = 0; i < n; ++i) {
        ASSERT_LT(glm::length(back.positions[i] - before.positions[i]), tolerance) << i;
        if (before.hasNormals()) {
          ASSERT_LT(glm::length(back.normals[i] - before.normals[i]), 1e-5) << i;
        }
      }
    }
  }
}

// An affine rig that flattens space onto z = 0: points on the plane have a preimage (the seed
// already maps onto them), points off it have none. Exit 4, one line naming the first such
// point with its coordinates and residual, and the output that was there is kept.
TEST_F(InverseCliTest, APointWithoutPreimageExits4AndWritesNothing) {
  write(
      "flatten.json",
      R"({"method": "affine", "matrix": [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 0, 0], [0, 0, 0, 1]]})");
  write("points.obj", "v 0.5 0.25 0\nv -1 2 0\nv 0.125 -0.5 0.75\nv 1 1 1\nv 3 0 0\n");
  const fs::path output = write("out.obj", "precious");
  const CliResult r = inverse("flatten.json", "points.obj", "out.obj");
  EXPECT_EQ(r.exitCode, 4) << r.err;
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  EXPECT_THAT(r.err, HasSubstr("spacewarp: numerical failure: " + path("points.obj")));
  EXPECT_THAT(r.err, HasSubstr("did not converge at 2 of 5 vertices"));
  EXPECT_THAT(r.err, HasSubstr("vertex 2 at (0.125, -0.5, 0.75)"));
  EXPECT_THAT(r.err, HasSubstr("residual 0.75 > tolerance"));
  EXPECT_EQ(r.out, "");
  EXPECT_EQ(slurp(output), "precious");
  for (const auto& entry : fs::directory_iterator(dir_))
    EXPECT_THAT(entry.path().filename().string(), ::testing::Not(HasSubstr(".tmp")));
}

// Bad input: a rig that cannot be read or names no known method, a point that is not finite.
// Exit 3 and one line naming the file at fault; no output.
TEST_F(InverseCliTest, BadInputExits3InOneLine) {
  write("twist.json", R"({"method": "twist", "origin": [0, 0, 0], "axis": [0, 0, 1], "rate": 1})");
  write("unknown.json", R"({"method": "warpdrive"})");
  write("points.obj", "v 0 0 0\nv 1 0 0\n");
  write("nan.off", "OFF\n3 1 0\n0 0 0\nnan 0 0\n0 1 0\n3 0 1 2\n");
  struct Case {
    std::string rig, input, culprit;
  };
  for (const Case& c : {Case{"unknown.json", "points.obj", "unknown.json"},
                        Case{"missing.json", "points.obj", "missing.json"},
                        Case{"twist.json", "nan.off", "nan.off"},
                        Case{"twist.json", "missing.obj", "missing.obj"}}) {
    SCOPED_TRACE(c.rig + " " + c.input);
    const CliResult r = inverse(c.rig, c.input, "out.obj");
    EXPECT_EQ(r.exitCode, 3) << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    EXPECT_THAT(r.err, HasSubstr(c.culprit));
    EXPECT_FALSE(fs::exists(dir_ / "out.obj"));
  }
}

// What the command line alone decides is a usage error (exit 2), before any file is read.
TEST_F(InverseCliTest, UsageErrorsExit2) {
  write("twist.json", R"({"method": "twist", "origin": [0, 0, 0], "axis": [0, 0, 1], "rate": 1})");
  write("points.obj", "v 0 0 0\nv 1 0 0\n");
  for (const std::string extra : {"--tolerance nan", "--tolerance -1e-9", "--tolerance 0",
                                  "--max-iterations 0", "--max-iterations x", "--ascii"}) {
    SCOPED_TRACE(extra);
    const CliResult r = inverse("twist.json", "points.obj", "out.obj", extra);
    EXPECT_EQ(r.exitCode, 2) << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  }
  const CliResult volume = inverse("twist.json", "grid.vdb", "out.vdb");
  EXPECT_EQ(volume.exitCode, 2) << volume.err;
  EXPECT_THAT(volume.err, HasSubstr("volume"));
  const CliResult noRig = run("inverse " + path("points.obj") + " -o " + path("out.obj"));
  EXPECT_EQ(noRig.exitCode, 2) << noRig.err;
  EXPECT_FALSE(fs::exists(dir_ / "out.obj"));
  EXPECT_THAT(run("--help").out, HasSubstr("inverse"));
}

// The same bytes with one thread as with every core, and nothing on stdout with -q. A smaller
// --max-iterations and looser --tolerance still invert a gentle warp (continuation or not).
TEST_F(InverseCliTest, ThreadsQuietAndSolverOptions) {
  writeSwayedCage();
  PolygonSoup cloud;
  static_cast<PointSet&>(cloud) = makeRandomPoints(Vec3(-0.6), Vec3(0.6), 2000, 5);
  writeSoup(cloud, dir_ / "cloud.ply");
  ASSERT_EQ(inverse("mvc.json", "cloud.ply", "many.ply").exitCode, 0);
  const CliResult one = inverse("mvc.json", "cloud.ply", "one.ply", "--threads 1 -q");
  ASSERT_EQ(one.exitCode, 0) << one.err;
  EXPECT_EQ(one.out, "");
  EXPECT_EQ(slurp(dir_ / "one.ply"), slurp(dir_ / "many.ply"));

  const CliResult loose =
      inverse("mvc.json", "cloud.ply", "loose.ply", "--tolerance 1e-6 --max-iterations 3");
  ASSERT_EQ(loose.exitCode, 0) << loose.err;
  ASSERT_EQ(
      run("deform --rig " + path("mvc.json") + " " + path("loose.ply") + " -o " + path("again.ply"))
          .exitCode,
      0);
  const PolygonSoup again = readSoup(dir_ / "again.ply");
  const double diagonal = boundingBox(cloud.positions).diagonal();
  for (std::size_t i = 0; i < cloud.size(); ++i)
    ASSERT_LT(glm::length(again.positions[i] - cloud.positions[i]), 2e-6 * diagonal) << i;
}

}  // namespace
