// End-to-end tests of what every subcommand shares (--threads, --quiet) and of the .npy
// export of `spacewarp weights`.

#include <algorithm>
#include <bit>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>

#include <gtest/gtest.h>

#include <spacewarp/core/io/mesh_io.h>
#include <spacewarp/core/primitives.h>
#include "apps/cli_test_util.h"

namespace spacewarp {
namespace {

namespace fs = std::filesystem;
using test::CliResult;
using test::Npy;
using test::readNpy;

class CommandsTest : public test::CliFixture {
 protected:
  CommandsTest() : CliFixture("spacewarp_commands_") {}
};

TEST_F(CommandsTest, WeightsNpyHoldsTheSameNumbersAsCsv) {
  writeSoup(makeBoxSurface(Vec3(-1), Vec3(1), {1, 1, 1}), dir_ / "cage.obj");
  writeCloud(Vec3(-0.9), Vec3(0.9), 57, 3);
  for (const std::string method : {"mvc", "green"}) {
    const std::string base = "weights --method " + method + " --cage " +
                             (dir_ / "cage.obj").string() + " " + (dir_ / "cloud.ply").string() +
                             " -o ";
    ASSERT_EQ(run(base + (dir_ / "w.npy").string()).exitCode, 0);
    ASSERT_EQ(run(base + (dir_ / "w.csv").string()).exitCode, 0);
    // Extensions in upper case are the same formats (as deform takes OUT.PLY).
    ASSERT_EQ(run(base + (dir_ / "W.NPY").string()).exitCode, 0);
    EXPECT_EQ(test::slurp(dir_ / "W.NPY"), test::slurp(dir_ / "w.npy"));
    const Npy npy = readNpy(dir_ / "w.npy");
    EXPECT_EQ(npy.rows, 57u);
    EXPECT_EQ(npy.columns, method == "mvc" ? 8u : 8u + 12u);  // Green: one column per face
    std::istringstream csv(test::slurp(dir_ / "w.csv"));
    std::string line;
    std::getline(csv, line);  // header
    std::size_t k = 0;
    while (std::getline(csv, line)) {
      std::istringstream row(line);
      std::string cell;
      while (std::getline(row, cell, ','))
        ASSERT_EQ(std::stod(cell), npy.values.at(k++)) << method << " entry " << k;
    }
    EXPECT_EQ(k, npy.values.size());
  }
}

TEST_F(CommandsTest, WeightsRejectAnUnknownExtensionBeforeAnyWork) {
  writeSoup(makeBoxSurface(Vec3(-1), Vec3(1), {1, 1, 1}), dir_ / "cage.obj");
  writeCloud(Vec3(-0.9), Vec3(0.9), 5, 3);
  const CliResult r = run("weights --method mvc --cage " + (dir_ / "cage.obj").string() + " " +
                          (dir_ / "cloud.ply").string() + " -o " + (dir_ / "w.txt").string());
  EXPECT_EQ(r.exitCode, 3);
  EXPECT_NE(r.err.find("w.txt"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(dir_ / "w.txt"));
}

TEST_F(CommandsTest, ThreadCountDoesNotChangeTheOutput) {
  writeSoup(makeBoxSurface(Vec3(-1), Vec3(1), {1, 1, 1}), dir_ / "cage.obj");
  PolygonSoup pose = makeBoxSurface(Vec3(-1), Vec3(1), {1, 1, 1});
  for (Vec3& p : pose.positions) p += Vec3(0.3 * p.z * p.z, 0.0, 0.1 * p.x);
  writeSoup(pose, dir_ / "pose.obj");
  writeCloud(Vec3(-0.9), Vec3(0.9), 5000, 4);
  const std::string args = "deform --method green --cage " + (dir_ / "cage.obj").string() +
                           " --pose " + (dir_ / "pose.obj").string() + " " +
                           (dir_ / "cloud.ply").string() + " -o ";
  ASSERT_EQ(run("--threads 1 " + args + (dir_ / "one.ply").string()).exitCode, 0);
  ASSERT_EQ(run(args + (dir_ / "two.ply").string() + " --threads 2").exitCode, 0);
  EXPECT_EQ(test::slurp(dir_ / "one.ply"), test::slurp(dir_ / "two.ply"));
  EXPECT_EQ(run("--threads -1 info " + (dir_ / "cage.obj").string()).exitCode, 2);
}

// Every command speaks through the same CliContext, so one stands for all (the demo, which says
// the most, is too slow to run twice here under the sanitizers).
TEST_F(CommandsTest, QuietSilencesInformationalOutputOnly) {
  writeSoup(makeBoxSurface(Vec3(-1), Vec3(1), {2, 2, 2}), dir_ / "box.obj");
  const std::string deform =
      "deform --rig " +
      write("twist.json",
            R"({"method": "twist", "origin": [0, 0, 0], "axis": [0, 0, 1], "rate": 0.5})")
          .string() +
      " " + (dir_ / "box.obj").string() + " -o ";
  const CliResult loud = run(deform + (dir_ / "a.obj").string());
  ASSERT_EQ(loud.exitCode, 0) << loud.err;
  EXPECT_FALSE(loud.out.empty());
  const CliResult quiet = run("--quiet " + deform + (dir_ / "b.obj").string());
  ASSERT_EQ(quiet.exitCode, 0) << quiet.err;
  EXPECT_TRUE(quiet.out.empty()) << quiet.out;
  EXPECT_TRUE(fs::exists(dir_ / "b.obj"));
  // Errors still speak.
  const CliResult error = run("-q info " + (dir_ / "missing.obj").string());
  EXPECT_EQ(error.exitCode, 3);
  EXPECT_NE(error.err.find("missing.obj"), std::string::npos);
}

}  // namespace
}  // namespace spacewarp

namespace spacewarp {
namespace {

TEST_F(CommandsTest, EverySubcommandReportsAMissingFileWithExit3AndNoOutput) {
  writeSoup(makeBoxSurface(Vec3(-1), Vec3(1), {1, 1, 1}), dir_ / "cage.obj");
  writeCloud(Vec3(-0.9), Vec3(0.9), 5, 3);
  const std::string missing = (dir_ / "missing.obj").string();
  const std::string cage = (dir_ / "cage.obj").string();
  const std::string cloud = (dir_ / "cloud.ply").string();
  const std::string out = (dir_ / "out").string();
  const std::vector<std::string> commands = {
      "info " + missing,
      "deform --method mvc --cage " + missing + " --pose " + cage + " " + cloud + " -o " + out +
          ".ply",
      "deform --method mvc --cage " + cage + " --pose " + cage + " " + missing + " -o " + out +
          ".ply",
      "weights --method green --cage " + missing + " " + cloud + " -o " + out + ".csv",
      "weights --method green --cage " + cage + " " + missing + " -o " + out + ".npy",
      "weights --rig " + (dir_ / "missing.json").string() + " " + cloud + " -o " + out + ".csv",
      "compare --cage " + missing + " --slice z=0 -o " + out,
  };
  for (const std::string& command : commands) {
    const CliResult r = run(command);
    EXPECT_EQ(r.exitCode, 3) << command;
    EXPECT_NE(r.err.find("missing."), std::string::npos) << command << ": " << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    for (const char* suffix : {"", ".ply", ".csv", ".npy"})
      EXPECT_FALSE(fs::exists(out + suffix)) << command;
  }
}

TEST_F(CommandsTest, MalformedRigForWeightsExits3WithoutOutput) {
  writeCloud(Vec3(-0.9), Vec3(0.9), 5, 3);
  write("rig.json", R"({"method": "mvc", "cage": "cage.obj", "pose": )");
  const CliResult r = run("weights --rig " + (dir_ / "rig.json").string() + " " +
                          (dir_ / "cloud.ply").string() + " -o " + (dir_ / "w.npy").string());
  EXPECT_EQ(r.exitCode, 3);
  EXPECT_NE(r.err.find("rig.json"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(dir_ / "w.npy"));
}

TEST_F(CommandsTest, AnUnwritableOutputFolderIsAnIoError) {
  write("occupied", "a file where the demo wants a folder");
  const CliResult r = run("demo " + (dir_ / "occupied").string());
  EXPECT_EQ(r.exitCode, 3);
  EXPECT_NE(r.err.find("occupied"), std::string::npos) << r.err;
}

}  // namespace
}  // namespace spacewarp
