// End-to-end tests of hostile rigs and inputs (issue 12, items 8-10): numbers out of range,
// duplicate keys, control characters in keys, a folder as the rig, nesting past the limits,
// solver failures caused by a key, and jobs too large for the memory the process may use. Each
// must exit 3 with one line on stderr naming the file and the key, and write nothing.

#include <algorithm>
#include <filesystem>
#include <string>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <spacewarp/core/io/mesh_io.h>
#include <spacewarp/core/primitives.h>
#include <spacewarp/rig/rig.h>
#include "apps/cli_test_util.h"
#include "test_util.h"

namespace fs = std::filesystem;
using namespace spacewarp;
using ::testing::HasSubstr;

namespace {

using ::spacewarp::test::kSanitized;

using ::spacewarp::test::BadRig;
using ::spacewarp::test::BadRigTest;

const std::string kTwist = R"("method": "twist", "origin": [0, 0, 0], "axis": [0, 0, 1])";

// A compose rig nested `depth` deep around a twist (`inner` ends its keys).
std::string nestedCompose(int depth, const std::string& inner = R"(, "rate": 1)") {
  std::string rig;
  for (int i = 0; i < depth; ++i) rig += R"({"method": "compose", "warps": [)";
  rig += "{" + kTwist + inner + "}";
  for (int i = 0; i < depth; ++i) rig += "]}";
  return rig;
}

INSTANTIATE_TEST_SUITE_P(
    HostileRigs, BadRigTest,
    ::testing::Values(
        BadRig{"NumberOutOfRange", "{" + kTwist + R"(, "rate": 1e999})",
               "'rate' is a number outside the range of double"},
        BadRig{"NumberOutOfRangeInAnArray",
               R"({"method": "twist", "origin": [0, -1e999, 0], "axis": [0, 0, 1], "rate": 1})",
               "'origin[1]' is a number outside the range of double"},
        BadRig{"DuplicateKey", "{" + kTwist + R"(, "rate": 1, "rate": 2})",
               "'rate' is given twice"},
        BadRig{"DuplicateKeyInANestedRig",
               R"({"method": "compose", "warps": [{)" + kTwist + R"(, "rate": 1}, {)" + kTwist +
                   R"(, "rate": 1, "rate": 1}]})",
               "'warps[1].rate' is given twice"},
        // The NUL is printed escaped, so the message is not cut short at it.
        BadRig{"NulInAKey", "{" + kTwist + R"(, "rate": 1, "\u0000after": 2})",
               R"('\u0000after' is not a key of this method)"},
        BadRig{"ComposeTooDeep", nestedCompose(70),
               "rig.json: warps[0].warps[0]...warps[0] (64 levels): 'warps' nests compose rigs "
               "deeper than 64 levels"},
        // A fault deep inside: the path is shortened, not "warps[0]: " 64 times.
        BadRig{"FaultDeepInACompose", nestedCompose(64, ""),
               "rig.json: warps[0].warps[0]...warps[0] (64 levels): 'rate' is missing"},
        BadRig{"FaultInAShallowCompose",
               R"({"method": "compose", "warps": [{"method": "compose", "warps": [{)" + kTwist +
                   R"(, "rate": 1}, {)" + kTwist + R"(}]}]})",
               "rig.json: warps[0].warps[1]: 'rate' is missing"},
        // A misspelt key is reported rather than the required key it leaves missing.
        BadRig{"MisspeltKeyBeforeTheMissingOne", "{" + kTwist + R"(, "rat": 1})",
               "'rat' is not a key of this method (the keys of twist: origin, axis, rate, "
               "limits)"},
        // The issue's case: 20,000 levels, refused while parsing, before any recursion.
        BadRig{"ComposeFarTooDeep", nestedCompose(20000),
               "nests arrays and objects deeper than 256 levels"},
        BadRig{"ArraysTooDeep",
               R"({"method": "twist", "rate": )" + std::string(20000, '[') +
                   std::string(20000, ']') + "}",
               "'rate[0][0]"},
        // Without smoothing the control points no constraint reaches are free: the key is named.
        BadRig{"FfdFitWithoutSmoothness",
               R"({"method": "ffd", "basis": "trilinear", "origin": [0, 0, 0], "size": [1, 1, 1],
                   "resolution": [3, 3, 3], "smoothness": 0,
                   "constraints": {"from": [[0.1, 0.1, 0.1]], "to": [[0.2, 0.1, 0.1]]}})",
               "'smoothness' is 0 and the fit is singular"}
            .atSolve(),
        BadRig{"FfdNegativeSmoothness",
               R"({"method": "ffd", "basis": "trilinear", "origin": [0, 0, 0], "size": [1, 1, 1],
                   "resolution": [3, 3, 3], "smoothness": -1,
                   "constraints": {"from": [[0.1, 0.1, 0.1]], "to": [[0.2, 0.1, 0.1]]}})",
               "'smoothness' must be finite and >= 0"}),
    test::badRigName);

class RigErrorsCliTest : public test::CliFixture {
 protected:
  RigErrorsCliTest() : test::CliFixture("spacewarp_rig_errors_cli_") {}

  void SetUp() override {
    test::CliFixture::SetUp();
    writeCloud(Vec3(0.0), Vec3(1.0), 20, 5);
  }

  // Runs spacewarp under `ulimit -v` (kB), a real limit that the memory estimate must see.
  // Tests that use it skip in sanitizer builds: AddressSanitizer reserves terabytes of address
  // space for its shadow memory, so an instrumented binary cannot start under such a limit.
  test::CliResult runLimited(const std::string& args, long kilobytes = 1500000) {
    return run(args, "ulimit -v " + std::to_string(kilobytes) + "; ");
  }

  // One line on stderr, exit 3, no output nor temporary file left behind.
  void expectRefused(const test::CliResult& r, const fs::path& output) {
    EXPECT_EQ(r.exitCode, 3) << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    EXPECT_FALSE(fs::exists(output));
    for (const auto& entry : fs::directory_iterator(dir_))
      EXPECT_THAT(entry.path().filename().string(), ::testing::Not(HasSubstr(".tmp")));
  }
};

// The deepest allowed nesting with a fault at its bottom: one short line.
TEST_F(RigErrorsCliTest, AFaultDeepInAComposeIsOneShortLine) {
  write("rig.json", nestedCompose(64, ""));
  const test::CliResult r = deform("rig.json");
  expectRefused(r, dir_ / "out.ply");
  EXPECT_LT(r.err.size(), (dir_ / "rig.json").string().size() + 120) << r.err;
  EXPECT_EQ(r.err.find("warps[0]: warps[0]"), std::string::npos) << r.err;
}

// info refuses what deform refuses (here a mistyped rate inside a compose rig, and a cage file
// that is missing), with the same line, and prints nothing on stdout, not even "file:".
TEST_F(RigErrorsCliTest, InfoRefusesWhatDeformRefusesAndPrintsNothing) {
  write("typed.json", R"({"method": "compose", "warps": [{"method": "twist", "origin": [0, 0, 0],
                          "axis": [0, 0, 1], "rate": "x"}]})");
  write("cage.json", R"({"method": "compose", "warps": [
                          {"method": "twist", "origin": [0, 0, 0], "axis": [0, 0, 1], "rate": 1},
                          {"method": "mvc", "cage": "missing.obj", "pose": "missing.obj"}]})");
  for (const std::string rig : {"typed.json", "cage.json"}) {
    SCOPED_TRACE(rig);
    const test::CliResult deformed = deform(rig);
    const test::CliResult info = run("info " + (dir_ / rig).string());
    EXPECT_EQ(deformed.exitCode, 3) << deformed.err;
    EXPECT_EQ(info.exitCode, 3) << info.err;
    EXPECT_EQ(info.err, deformed.err);
    EXPECT_EQ(info.out, "");
  }
}

TEST_F(RigErrorsCliTest, AFolderAsTheRigIsNamed) {
  fs::create_directories(dir_ / "rigs.json");
  const test::CliResult r = deform("rigs.json");
  expectRefused(r, dir_ / "out.ply");
  EXPECT_THAT(r.err, HasSubstr("rigs.json: is a directory"));
}

// Binary or endless input as a rig fails at its first block, not after reading it all; a
// syntax error gives the position and reason without the JSON library's own labels.
TEST_F(RigErrorsCliTest, BinaryRigsAndSyntaxErrorsAreOneClearLine) {
  fs::create_symlink("/dev/zero", dir_ / "zero.json");
  test::CliResult r = deform("zero.json");
  expectRefused(r, dir_ / "out.ply");
  EXPECT_THAT(r.err, HasSubstr("zero.json: not a rig file: a NUL byte at byte offset 0"));
  write("broken.json", "{\"method\": \"twist\",\n \"rate\": }");
  r = deform("broken.json");
  expectRefused(r, dir_ / "out.ply");
  EXPECT_THAT(r.err, HasSubstr("broken.json: not valid JSON: line 2, column 10: "));
  EXPECT_THAT(r.err, ::testing::Not(HasSubstr("json.exception")));
}

TEST_F(RigErrorsCliTest, AGraphTooLargeForTheMemoryLimitIsRefusedNamingTheSpacing) {
  if (kSanitized) GTEST_SKIP() << "an address-space limit cannot apply to a sanitizer build";
  // 30³ grid nodes: about 4 GB by the estimate, which a larger machine would run, but more than
  // the 1.5 GB this run may use: refused at once, before any node is made.
  write("graph.json", R"({"method": "graph", "spacing": 0.08, "handles": [[0, 0, 0], [2, 2, 2]],
                          "targets": [[0, 0, 0], [2, 2, 2.5]]})");
  const test::CliResult r =
      runLimited("deform --rig " + (dir_ / "graph.json").string() + " " +
                 (dir_ / "cloud.ply").string() + " -o " + (dir_ / "out.ply").string());
  expectRefused(r, dir_ / "out.ply");
  EXPECT_THAT(r.err, HasSubstr("graph.json: 'spacing' (27000 graph nodes) needs about"));
  EXPECT_THAT(r.err, HasSubstr("GB of memory"));
}

TEST_F(RigErrorsCliTest, AnFfdFitTooLargeForTheMemoryLimitIsRefusedNamingTheResolution) {
  if (kSanitized) GTEST_SKIP() << "an address-space limit cannot apply to a sanitizer build";
  write("ffd.json", R"({"method": "ffd", "basis": "bspline", "origin": [0, 0, 0],
                        "size": [1, 1, 1], "resolution": [200, 200, 200],
                        "constraints": {"from": [[0.5, 0.5, 0.5]], "to": [[0.6, 0.5, 0.5]]}})");
  const test::CliResult r =
      runLimited("deform --rig " + (dir_ / "ffd.json").string() + " " +
                 (dir_ / "cloud.ply").string() + " -o " + (dir_ / "out.ply").string());
  expectRefused(r, dir_ / "out.ply");
  EXPECT_THAT(r.err, HasSubstr("ffd.json: fitControlPoints: the resolution 200 x 200 x 200"));
  EXPECT_THAT(r.err, HasSubstr("GB of memory"));
}

TEST_F(RigErrorsCliTest, TheSameJobsRunUnderTheLimitWhenSmall) {
  if (kSanitized) GTEST_SKIP() << "an address-space limit cannot apply to a sanitizer build";
  // The limit itself is not what fails: a small graph runs under it.
  write("graph.json", R"({"method": "graph", "spacing": 0.5, "handles": [[0, 0, 0], [1, 1, 1]],
                          "targets": [[0, 0, 0], [1, 1, 1.2]]})");
  const test::CliResult r =
      runLimited("deform --rig " + (dir_ / "graph.json").string() + " " +
                 (dir_ / "cloud.ply").string() + " -o " + (dir_ / "out.ply").string());
  EXPECT_EQ(r.exitCode, 0) << r.err;
  EXPECT_TRUE(fs::exists(dir_ / "out.ply"));
}

TEST_F(RigErrorsCliTest, ComposeRigsNestAsDeepAsTheLimitSays) {
  write("deep.json", nestedCompose(kMaxComposeDepth));
  const test::CliResult ok =
      run("deform --rig " + (dir_ / "deep.json").string() + " " + (dir_ / "cloud.ply").string() +
          " -o " + (dir_ / "out.ply").string());
  EXPECT_EQ(ok.exitCode, 0) << ok.err;
  write("deeper.json", nestedCompose(kMaxComposeDepth + 1));
  const test::CliResult refused =
      run("deform --rig " + (dir_ / "deeper.json").string() + " " + (dir_ / "cloud.ply").string() +
          " -o " + (dir_ / "out2.ply").string());
  EXPECT_EQ(refused.exitCode, 3) << refused.err;
  EXPECT_FALSE(fs::exists(dir_ / "out2.ply"));
}

TEST_F(RigErrorsCliTest, AnRbfSystemTooLargeForTheMemoryLimitIsRefusedNamingTheCenters) {
  if (kSanitized) GTEST_SKIP() << "an address-space limit cannot apply to a sanitizer build";
  // 20,000 RBF centers: a dense 20,000² matrix (3.5 GB) and the BLAS buffers of the threads,
  // which used to fail under the limit as a bare "out of memory"; now refused before the
  // system is formed.
  std::vector<Vec3> centers = makeRandomPoints(Vec3(0.0), Vec3(1.0), 20000, 7).positions;
  write("rbf.json", R"({"method": "rbf", "centers": )" + test::jsonPoints(centers) +
                        R"(, "targets": )" + test::jsonPoints(centers) + "}");
  const test::CliResult r =
      runLimited("deform --rig " + (dir_ / "rbf.json").string() + " " +
                 (dir_ / "cloud.ply").string() + " -o " + (dir_ / "out.ply").string());
  expectRefused(r, dir_ / "out.ply");
  EXPECT_THAT(r.err, HasSubstr("rbf.json: 'centers' (20000 centers) needs about "));
  EXPECT_THAT(r.err, HasSubstr(" GB of memory, more than the "));
}

#ifdef SPACEWARP_HAVE_HARMONIC
TEST_F(RigErrorsCliTest, ASelfIntersectingCageIsNamedByItsFile) {
  // A box whose corner (1, 1, 1) is pushed through its bottom face: TetGen refuses it.
  PolygonSoup cage = makeBoxSurface(Vec3(0.0), Vec3(1.0), {1, 1, 1});
  for (Vec3& p : cage.positions)
    if (p == Vec3(1.0)) p = Vec3(0.2, 0.2, -0.5);
  writeSoup(cage, dir_ / "crossed.obj");
  const test::CliResult r =
      run("weights --method harmonic --cage " + (dir_ / "crossed.obj").string() + " " +
          (dir_ / "cloud.ply").string() + " -o " + (dir_ / "w.csv").string());
  expectRefused(r, dir_ / "w.csv");
  EXPECT_THAT(r.err, HasSubstr("crossed.obj: "));
  EXPECT_THAT(r.err, HasSubstr("intersects itself"));
}
#endif

// The solves a rig runs report their progress to the callback given to rigFromJson, also
// from inside a compose rig.
TEST(RigProgress, SolvesReportToTheCallerThroughNestedRigs) {
  const std::string graph =
      R"({"method": "graph", "spacing": 0.5, "handles": [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]],
          "targets": [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1.3]]})";
  const std::string ffd =
      R"({"method": "ffd", "basis": "trilinear", "origin": [0, 0, 0], "size": [1, 1, 1],
          "resolution": [3, 3, 3],
          "constraints": {"from": [[0.1, 0.1, 0.1]], "to": [[0.2, 0.1, 0.1]]}})";
  const std::string rbf =
      R"({"method": "rbf", "centers": [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 1]],
          "targets": [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 1.2]]})";
  for (const auto& [rig, stage] : {std::pair{graph, "solve graph"}, std::pair{ffd, "fit lattice"},
                                   std::pair{rbf, "fit rbf"}}) {
    test::ProgressLog progress(stage);
    const std::string composed = R"({"method": "compose", "warps": [)" + rig + "]}";
    rigFromJson(parseRigJson(composed, "rig.json"), ".", "rig.json", progress.callback());
    progress.expectFromZeroToOne();
  }
}

}  // namespace
