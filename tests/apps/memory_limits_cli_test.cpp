// End-to-end tests of the executable under memory limits (apps/out_of_memory.h and the memory
// estimates of compare, harmonic and RBF coordinates): every run ends promptly, either done or
// with exit 3 and one line, never a hang, an abort or a numerical failure; jobs too large are
// refused before any work, and normal ones still run.
//
// The runs under `ulimit -v` skip in sanitizer builds: AddressSanitizer reserves terabytes of
// address space for its shadow memory, so an instrumented binary cannot start under such a limit.

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <string>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <tbb/info.h>

#include <spacewarp/core/io/mesh_io.h>
#include <spacewarp/core/primitives.h>
#include "apps/cli_test_util.h"

namespace fs = std::filesystem;
using namespace spacewarp;
using ::testing::AnyOf;
using ::testing::HasSubstr;
using ::testing::StartsWith;

namespace {

using ::spacewarp::test::kSanitized;

class MemoryLimitsCliTest : public test::CliFixture {
 protected:
  MemoryLimitsCliTest() : test::CliFixture("spacewarp_memory_limits_cli_") {}

  void SetUp() override {
    test::CliFixture::SetUp();
    writeCloud(Vec3(-0.4), Vec3(0.4), 200, 5);
    write("twist.json", R"({"method": "twist", "origin": [0, 0, 0], "axis": [0, 0, 1],
                            "rate": 1})");
  }

  // Runs spacewarp under `ulimit -v` (kB) and `timeout` (a hang exits 124 instead of blocking
  // the suite), timing the run. With at most 2 worker threads: every thread's stack takes
  // address space, so the limits below would not hold on a machine with many cores.
  test::CliResult runLimited(const std::string& args, long kilobytes, int seconds = 120) {
    const auto start = std::chrono::steady_clock::now();
    const int threads = std::min(2, tbb::info::default_concurrency());
    test::CliResult r = run(
        "--threads " + std::to_string(threads) + " " + args,
        "ulimit -v " + std::to_string(kilobytes) + "; timeout " + std::to_string(seconds) + " ");
    seconds_ = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    return r;
  }

  // Done (exit 0), or out of memory in one line and exit 3; `what` names the run.
  static void expectDoneOrOneLine(const test::CliResult& r, const std::string& what) {
    EXPECT_THAT(r.exitCode, AnyOf(0, 3)) << what << ": " << r.err;
    if (r.exitCode == 3) {
      EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << what << ": " << r.err;
      EXPECT_THAT(r.err, StartsWith("spacewarp: error: ")) << what;
    }
  }

  // No output and no temporary left in the folder.
  void expectNoOutput(const std::string& output) {
    EXPECT_FALSE(fs::exists(dir_ / output));
    for (const auto& entry : fs::directory_iterator(dir_))
      EXPECT_THAT(entry.path().filename().string(), ::testing::Not(HasSubstr(".tmp")));
  }

  // A closed box surface of 6 n² + 2 vertices and 12 n² triangles.
  void writeBoxCage(const std::string& name, int n) {
    writeSoup(makeBoxSurface(Vec3(0.0), Vec3(1.0), {n, n, n}), dir_ / name);
  }

  double seconds_ = 0.0;
};

// OpenBLAS's worker thread, started when the library loads, retried its 128 MiB allocation
// forever, and the process hung at exit joining it: `--version` never ended under 250 MB; under
// 150 MB the threads log4cplus starts before main() could not be created and the process
// aborted. Now every limit ends promptly: done, or one line and exit 3.
TEST_F(MemoryLimitsCliTest, VersionEndsPromptlyUnderAnyAddressSpaceLimit) {
  if (kSanitized) GTEST_SKIP() << "an address-space limit cannot apply to a sanitizer build";
  for (const long limit : {150000L, 200000L, 250000L, 280000L, 300000L}) {
    const test::CliResult r = runLimited("--version", limit, 60);
    const std::string what = "--version under ulimit -v " + std::to_string(limit);
    expectDoneOrOneLine(r, what);
    if (r.exitCode == 3) {
      EXPECT_THAT(r.err, HasSubstr("out of memory while starting")) << what;
    }
    EXPECT_LT(seconds_, 30.0) << what;
  }
  const test::CliResult r = runLimited("--version", 300000, 60);
  EXPECT_EQ(r.exitCode, 0) << r.err;
  EXPECT_THAT(r.out, HasSubstr("spacewarp " SPACEWARP_VERSION));
}

TEST_F(MemoryLimitsCliTest, ASmallDeformRunsAndEndsPromptlyUnderAnAddressSpaceLimit) {
  if (kSanitized) GTEST_SKIP() << "an address-space limit cannot apply to a sanitizer build";
  for (const long limit : {250000L, 300000L}) {
    const test::CliResult r =
        runLimited("deform --rig " + (dir_ / "twist.json").string() + " " +
                       (dir_ / "cloud.ply").string() + " -o " + (dir_ / "out.ply").string(),
                   limit, 60);
    EXPECT_EQ(r.exitCode, 0) << "ulimit -v " << limit << ": " << r.err;
    EXPECT_TRUE(fs::exists(dir_ / "out.ply"));
    EXPECT_LT(seconds_, 30.0) << "ulimit -v " << limit;
    fs::remove(dir_ / "out.ply");
  }
}

// OpenBLAS maps a 128 MiB work buffer on a thread's first factorisation and retries forever
// when that fails: a graph rig's solve hung under these limits. The first sparse Cholesky on a
// thread now checks that the buffer fits.
TEST_F(MemoryLimitsCliTest, ASparseSolveNeverHangsUnderALimit) {
  if (kSanitized) GTEST_SKIP() << "an address-space limit cannot apply to a sanitizer build";
  write("graph.json", R"({"method": "graph", "spacing": 0.5, "handles": [[0, 0, 0], [1, 1, 1]],
                          "targets": [[0, 0, 0], [1, 1, 1.2]]})");
  for (const long limit : {250000L, 300000L, 350000L}) {
    const std::string what = "ulimit -v " + std::to_string(limit);
    const test::CliResult r =
        runLimited("deform --rig " + (dir_ / "graph.json").string() + " " +
                       (dir_ / "cloud.ply").string() + " -o " + (dir_ / "out.ply").string(),
                   limit, 60);
    expectDoneOrOneLine(r, what);
    if (r.exitCode == 3) {
      EXPECT_THAT(r.err, HasSubstr("BLAS work buffer")) << what;
      expectNoOutput("out.ply");
    }
    EXPECT_LT(seconds_, 30.0) << what;
    fs::remove(dir_ / "out.ply");
  }
}

// The property kit formed the weights of all its points at once: for a 1,178-vertex box cage's
// Green coordinates (3,530 columns) its 9,408 face samples alone took 266 MB, and under this
// limit every method failed (exit 4). It now works in blocks of 32 MB.
TEST_F(MemoryLimitsCliTest, CompareOfALargeCageRunsInBoundedMemory) {
  if (kSanitized) GTEST_SKIP() << "an address-space limit cannot apply to a sanitizer build";
  writeBoxCage("box.obj", 14);
  const test::CliResult r = runLimited("compare --cage " + (dir_ / "box.obj").string() +
                                           " --methods green,mvc --slice z=0.5 --resolution 32 "
                                           "--samples 200 -o " +
                                           (dir_ / "out").string(),
                                       400000, 300);
  EXPECT_EQ(r.exitCode, 0) << r.err;
  EXPECT_TRUE(fs::exists(dir_ / "out" / "report.json"));
}

// RBF coordinates with one handle per vertex of a 9,602-vertex cage need five dense 9,602²
// arrays (3.7 GB): refused before any work, naming the method, with nothing written.
TEST_F(MemoryLimitsCliTest, CompareRefusesAMethodTooLargeForTheLimitBeforeAnyWork) {
  if (kSanitized) GTEST_SKIP() << "an address-space limit cannot apply to a sanitizer build";
  writeBoxCage("box.obj", 40);
  const test::CliResult r =
      runLimited("compare --cage " + (dir_ / "box.obj").string() +
                     " --methods mvc,rbf --slice z=0.5 -o " + (dir_ / "out").string(),
                 1500000);
  EXPECT_EQ(r.exitCode, 3) << r.err;
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  EXPECT_THAT(r.err,
              HasSubstr("box.obj: comparing method 'rbf' on this 9602-vertex cage needs about "));
  EXPECT_THAT(r.err, HasSubstr("GB of memory, more than the"));
  EXPECT_LT(seconds_, 20.0);  // before the mean-value panel was drawn
  expectNoOutput("out");
}

#ifdef SPACEWARP_HAVE_HARMONIC
// A billion tets: refused at once (no limit needed: terabytes), not after TetGen has filled the
// memory, by every command that makes harmonic coordinates.
TEST_F(MemoryLimitsCliTest, AnAbsurdTetCountIsRefusedBeforeMeshing) {
  writeBoxCage("cage.obj", 1);
  write("pose.obj", test::slurp(dir_ / "cage.obj"));
  write("harmonic.json", R"({"method": "harmonic", "cage": "cage.obj", "pose": "pose.obj",
                             "tets": 1e9})");
  const std::string cage = (dir_ / "cage.obj").string(), cloud = (dir_ / "cloud.ply").string();
  const std::vector<std::string> commands = {
      "deform --method harmonic --tets 1000000000 --cage " + cage + " --pose " +
          (dir_ / "pose.obj").string() + " " + cloud + " -o " + (dir_ / "out.ply").string(),
      "deform --rig " + (dir_ / "harmonic.json").string() + " " + cloud + " -o " +
          (dir_ / "out.ply").string(),
      "weights --method harmonic --tets 1000000000 --cage " + cage + " " + cloud + " -o " +
          (dir_ / "w.csv").string(),
      "compare --cage " + cage + " --methods harmonic --tets 1000000000 --slice z=0.5 -o " +
          (dir_ / "out").string()};
  for (const std::string& command : commands) {
    const auto start = std::chrono::steady_clock::now();
    const test::CliResult r = run(command, "timeout 120 ");
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    EXPECT_EQ(r.exitCode, 3) << command << ": " << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << command << ": " << r.err;
    EXPECT_THAT(r.err, HasSubstr("1000000")) << command;
    EXPECT_THAT(r.err, HasSubstr("TB of memory, more than the")) << command;
    EXPECT_LT(seconds, 20.0) << command;
  }
  expectNoOutput("out.ply");
  expectNoOutput("w.csv");
  expectNoOutput("out");
}

// The estimates do not refuse normal work: the default mesh (200,000 tets) under 1 GB.
TEST_F(MemoryLimitsCliTest, AHarmonicDeformAtTheDefaultResolutionRunsUnderALimit) {
  if (kSanitized) GTEST_SKIP() << "an address-space limit cannot apply to a sanitizer build";
  writeBoxCage("cage.obj", 2);
  write("pose.obj", test::slurp(dir_ / "cage.obj"));
  writeCloud(Vec3(0.1), Vec3(0.9), 200, 5);  // inside the cage
  const test::CliResult r =
      runLimited("deform --method harmonic --cage " + (dir_ / "cage.obj").string() + " --pose " +
                     (dir_ / "pose.obj").string() + " " + (dir_ / "cloud.ply").string() + " -o " +
                     (dir_ / "out.ply").string(),
                 1000000);
  EXPECT_EQ(r.exitCode, 0) << r.err;
  EXPECT_TRUE(fs::exists(dir_ / "out.ply"));
}
#endif

}  // namespace
