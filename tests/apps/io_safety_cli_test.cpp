// End-to-end tests of what the spacewarp executable does when writing goes wrong. A write that
// fails (a full disk; here a file size limit, RLIMIT_FSIZE, which fails the write with EFBIG
// just as a full disk fails it with ENOSPC) is exit 3 with one line naming the file, the old
// output stays byte for byte and no temporary is left — for every kind of writer. A run
// interrupted by SIGINT, SIGTERM or SIGHUP while writing removes its temporaries, keeps the old
// output and ends with 128 + the signal's number — for every subcommand that writes.

#include <fcntl.h>
#include <signal.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <spacewarp/core/io/mesh_io.h>
#include <spacewarp/core/primitives.h>
#include "apps/cli_test_util.h"

#ifdef SPACEWARP_WITH_OPENVDB
#include <openvdb/io/File.h>
#include <openvdb/openvdb.h>
#include <openvdb/tools/LevelSetSphere.h>
#endif

extern char** environ;

namespace spacewarp {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

/// The file size limit of the failure tests: well below every output written under it, well
/// above the one line of error.
constexpr rlim_t kFileSizeLimit = 4096;

const std::string kOldOutput = "the previous run's output\n";

/// How a run ended: its exit code, or 128 + the signal that ended it (as a shell reports it).
struct Outcome {
  int status = -1;
  std::string err;
};

class IoSafetyCliTest : public test::CliFixture {
 protected:
  IoSafetyCliTest() : CliFixture("spacewarp_io_safety_") {}

  /// Starts `spacewarp -q args...` with stdout to /dev/null and stderr to a pipe (which the
  /// file size limit does not cover); with a file size limit of `limit` bytes if not 0, and
  /// block_fsync.so preloaded if `blockInSync` (blocking only the files whose path contains
  /// `blockName` if it is not empty).
  pid_t start(const std::vector<std::string>& args, rlim_t limit = 0, bool blockInSync = false,
              const std::string& blockName = "") {
    std::vector<std::string> arguments = {SPACEWARP_CLI, "-q"};
    arguments.insert(arguments.end(), args.begin(), args.end());
    std::vector<std::string> environment;
    for (char** e = environ; *e; ++e) {
      const std::string entry = *e;
      if (!entry.starts_with("LD_PRELOAD=") && !entry.starts_with("ASAN_OPTIONS=") &&
          !entry.starts_with("SPACEWARP_BLOCK_FSYNC_NAME="))
        environment.push_back(entry);
    }
    if (!blockName.empty()) environment.push_back("SPACEWARP_BLOCK_FSYNC_NAME=" + blockName);
    if (blockInSync) {
      environment.push_back(std::string("LD_PRELOAD=") + SPACEWARP_BLOCK_FSYNC);
      // A sanitizer build's runtime must otherwise come first in the library list.
      const char* asan = std::getenv("ASAN_OPTIONS");
      environment.push_back(std::string("ASAN_OPTIONS=") + (asan ? std::string(asan) + ":" : "") +
                            "verify_asan_link_order=0");
    }
    // Everything the child needs is prepared before fork: after it, only async-signal-safe
    // calls.
    std::vector<char*> argv, envp;
    for (std::string& a : arguments) argv.push_back(a.data());
    argv.push_back(nullptr);
    for (std::string& e : environment) envp.push_back(e.data());
    envp.push_back(nullptr);
    int err[2];
    EXPECT_EQ(::pipe2(err, O_CLOEXEC), 0);
    const pid_t pid = ::fork();
    if (pid == 0) {
      const int null = ::open("/dev/null", O_WRONLY);
      if (null < 0 || ::dup2(null, 1) < 0 || ::dup2(err[1], 2) < 0) ::_exit(126);
      if (limit != 0) {
        const rlimit fileSize{limit, limit};
        if (::setrlimit(RLIMIT_FSIZE, &fileSize) != 0) ::_exit(126);
      }
      ::execve(argv[0], argv.data(), envp.data());
      ::_exit(127);
    }
    EXPECT_GT(pid, 0) << "fork failed";
    ::close(err[1]);
    stderrOf_[pid] = err[0];
    return pid;
  }

  /// What the run has written to stderr so far (all of it once it has ended).
  std::string readStderr(pid_t pid) {
    std::string text;
    char buffer[4096];
    for (ssize_t n; (n = ::read(stderrOf_.at(pid), buffer, sizeof buffer)) > 0;)
      text.append(buffer, static_cast<std::size_t>(n));
    return text;
  }

  Outcome finish(pid_t pid) {
    int status = 0;
    Outcome outcome;
    if (::waitpid(pid, &status, 0) == pid) {
      if (WIFEXITED(status)) outcome.status = WEXITSTATUS(status);
      if (WIFSIGNALED(status)) outcome.status = 128 + WTERMSIG(status);
    }
    outcome.err = readStderr(pid);
    ::close(stderrOf_.at(pid));
    stderrOf_.erase(pid);
    return outcome;
  }

  /// Every file of `folder` (not recursive) by name, with its content.
  static std::map<std::string, std::string> folderContent(const fs::path& folder) {
    std::map<std::string, std::string> content;
    for (const auto& entry : fs::directory_iterator(folder))
      content[entry.path().filename().string()] =
          entry.is_regular_file() ? test::slurp(entry.path()) : "(not a file)";
    return content;
  }

  /// Every temporary (.<name>.<hex>.tmp: a file, or a folder of compare) under the test's
  /// folder.
  std::vector<fs::path> temporaries() const {
    std::vector<fs::path> found;
    for (const auto& entry : fs::recursive_directory_iterator(dir_)) {
      const std::string name = entry.path().filename().string();
      if (name.starts_with('.') && name.ends_with(".tmp")) found.push_back(entry.path());
    }
    return found;
  }

  /// Runs `args` under the file size limit, with `output` already there (the previous run's
  /// output; a marker if there is none), and checks the clean failure. Then runs `args`
  /// without the limit, which must succeed and replace `output`: so the limit is what failed
  /// the first run.
  void expectCleanWriteFailure(const std::vector<std::string>& args, const fs::path& output) {
    if (!fs::exists(output)) write(output.lexically_relative(dir_).string(), kOldOutput);
    const std::string old = test::slurp(output);

    const Outcome limited = finish(start(args, kFileSizeLimit));
    EXPECT_EQ(limited.status, 3) << limited.err;
    EXPECT_EQ(std::count(limited.err.begin(), limited.err.end(), '\n'), 1) << limited.err;
    EXPECT_THAT(limited.err, HasSubstr(output.string()));
    EXPECT_THAT(limited.err, HasSubstr(std::strerror(EFBIG)));
    EXPECT_EQ(test::slurp(output), old) << output;
    EXPECT_THAT(temporaries(), ::testing::IsEmpty());

    const Outcome unlimited = finish(start(args));
    ASSERT_EQ(unlimited.status, 0) << unlimited.err;
    EXPECT_NE(test::slurp(output), old) << output;
    EXPECT_GT(fs::file_size(output), kFileSizeLimit) << output;
  }

  /// Starts `args`, blocked in its write phase by block_fsync.so, waits until the temporary
  /// of `output` exists, sends `signal`, and checks that the run ends with 128 + signal, with
  /// no temporary left and the old output untouched.
  void expectCleanInterruption(const std::vector<std::string>& args, const fs::path& output,
                               int signal, bool blockInSync = true) {
    if (!fs::exists(output)) write(output.lexically_relative(dir_).string(), kOldOutput);
    const std::string old = test::slurp(output);
    const pid_t pid = start(args, 0, blockInSync);
    const std::string prefix = "." + output.filename().string() + ".";
    bool seen = false;
    for (auto deadline = std::chrono::steady_clock::now() + std::chrono::minutes(5);
         !seen && std::chrono::steady_clock::now() < deadline;) {
      for (const fs::path& t : temporaries())
        seen = seen || t.filename().string().starts_with(prefix);
      if (!seen) {
        int status = 0;
        if (::waitpid(pid, &status, WNOHANG) == pid) {
          ADD_FAILURE() << "the run ended before writing " << output << " (status " << status
                        << "): " << readStderr(pid);
          return;
        }
        std::this_thread::sleep_for(std::chrono::milliseconds(1));
      }
    }
    EXPECT_TRUE(seen) << "no temporary of " << output << " appeared";
    ::kill(pid, signal);
    const Outcome outcome = finish(pid);
    EXPECT_EQ(outcome.status, 128 + signal) << outcome.err;
    EXPECT_THAT(temporaries(), ::testing::IsEmpty());
    EXPECT_EQ(test::slurp(output), old) << output;
  }

  std::string path(const std::string& name) const { return (dir_ / name).string(); }

  void writeTwistRig() {
    write("twist.json",
          R"({"method": "twist", "origin": [0, 0, 0], "axis": [0, 0, 1], "rate": 0.5})");
  }

  void writeCubeCage(const std::string& name, double half) {
    writeSoup(makeBoxSurface(Vec3(-half), Vec3(half), {1, 1, 1}), dir_ / name);
  }

 private:
  std::map<pid_t, int> stderrOf_;  ///< the read end of each running child's stderr pipe
};

// ---- Every writer fails cleanly ----------------------------------------------------------

TEST_F(IoSafetyCliTest, SoupWritersFailCleanly) {
  writeSoup(makeBoxSurface(Vec3(-1), Vec3(1), {8, 8, 8}), dir_ / "box.obj");
  writeTwistRig();
  for (const std::string output : {"out.obj", "out.off", "out.ply"}) {
    SCOPED_TRACE(output);
    expectCleanWriteFailure(
        {"deform", "--rig", path("twist.json"), path("box.obj"), "-o", path(output)},
        dir_ / output);
  }
  SCOPED_TRACE("ascii ply");
  expectCleanWriteFailure(
      {"deform", "--ascii", "--rig", path("twist.json"), path("box.obj"), "-o", path("ascii.ply")},
      dir_ / "ascii.ply");
}

// spacewarp edit writes its mesh through the same writer, after its solve.
TEST_F(IoSafetyCliTest, EditWriterFailsCleanly) {
  writeSoup(makeBoxSurface(Vec3(-1), Vec3(1), {8, 8, 8}), dir_ / "box.obj");
  write("handles.json", R"({"handles": [{"vertices": [0], "targets": [[-1, -1, -1.5]]}]})");
  expectCleanWriteFailure({"edit", "--method", "laplacian", "--handles", path("handles.json"),
                           path("box.obj"), "-o", path("out.obj")},
                          dir_ / "out.obj");
}

TEST_F(IoSafetyCliTest, PointCloudWritersFailCleanly) {
  writeCloud(Vec3(-1), Vec3(1), 1000, 3);
  writeTwistRig();
  for (const bool ascii : {false, true}) {
    SCOPED_TRACE(ascii ? "ascii" : "binary");
    std::vector<std::string> args = {"deform",          "--rig", path("twist.json"),
                                     path("cloud.ply"), "-o",    path("out.ply")};
    if (ascii) args.insert(args.begin() + 1, "--ascii");
    fs::remove(dir_ / "out.ply");
    expectCleanWriteFailure(args, dir_ / "out.ply");
  }
  SCOPED_TRACE("obj");
  expectCleanWriteFailure(
      {"deform", "--rig", path("twist.json"), path("cloud.ply"), "-o", path("out.obj")},
      dir_ / "out.obj");
}

// A full disk (here the file size limit) during a streamed deform: exit 3 naming the output,
// no partial file, whether it fails in the first chunk or a later one.
TEST_F(IoSafetyCliTest, StreamedDeformWriterFailsCleanly) {
  writeCloud(Vec3(-1), Vec3(1), 1000, 3);
  writeTwistRig();
  for (const std::string chunk : {"1", "100", "1000"}) {
    SCOPED_TRACE(chunk);
    fs::remove(dir_ / "out.ply");
    expectCleanWriteFailure({"deform", "--chunk-points", chunk, "--rig", path("twist.json"),
                             path("cloud.ply"), "-o", path("out.ply")},
                            dir_ / "out.ply");
  }
}

TEST_F(IoSafetyCliTest, WeightsWritersFailCleanly) {
  writeCubeCage("cage.obj", 1.0);
  writeCloud(Vec3(-0.9), Vec3(0.9), 1000, 5);
  for (const std::string output : {"weights.csv", "weights.npy"}) {
    SCOPED_TRACE(output);
    expectCleanWriteFailure({"weights", "--method", "mvc", "--cage", path("cage.obj"),
                             path("cloud.ply"), "-o", path(output)},
                            dir_ / output);
  }
}

// compare writes a folder of several files, as a whole. For each of its files, a limit of 3/4
// of the file's size fails the run at the first file above it (3/4 rather than just below: the
// reports' timings change their size a little from run to run), so that the images and the
// JSON report are in turn the file that fails. The failing runs draw another slice than the
// folder's previous run, so every file they write before the failure differs from the old one:
// the whole folder must still be as it was, with no file added and no temporary left.
TEST_F(IoSafetyCliTest, CompareWritersFailCleanly) {
  writeCubeCage("cage.obj", 1.0);
  const auto compare = [&](const std::string& slice, const std::string& output) {
    return std::vector<std::string>{"compare",   "--cage", path("cage.obj"), "--methods", "mvc,ffd",
                                    "--slice",   slice,    "--resolution",   "8",         "-o",
                                    path(output)};
  };
  ASSERT_EQ(finish(start(compare("z=0.2", "out"))).status, 0);
  const std::map<std::string, std::string> old = folderContent(dir_ / "out");
  ASSERT_THAT(old, ::testing::SizeIs(6)) << "mvc, ffd, compare, colour_bar .png, 2 reports";
  // The new run's files, written elsewhere: their sizes set the limits.
  ASSERT_EQ(finish(start(compare("z=-0.3", "probe"))).status, 0);
  const std::map<std::string, std::string> next = folderContent(dir_ / "probe");
  ASSERT_THAT(next, ::testing::SizeIs(6));
  EXPECT_NE(next.at("mvc.png"), old.at("mvc.png")) << "the runs must write other images";

  std::set<std::string> failed;
  for (const auto& [name, content] : next) {
    SCOPED_TRACE(name);
    const std::uintmax_t limit = content.size() * 3 / 4;
    const Outcome limited = finish(start(compare("z=-0.3", "out"), limit));
    ASSERT_EQ(limited.status, 3) << limited.err;
    EXPECT_EQ(std::count(limited.err.begin(), limited.err.end(), '\n'), 1) << limited.err;
    EXPECT_THAT(limited.err, HasSubstr(std::strerror(EFBIG)));
    // The file named (by its name in the output folder) is one above the limit.
    std::string culprit;
    for (const auto& [other, ignored] : next)
      if (limited.err.find((dir_ / "out" / other).string() + "'") != std::string::npos)
        culprit = other;
    ASSERT_FALSE(culprit.empty()) << limited.err;
    EXPECT_GT(next.at(culprit).size(), limit) << culprit;
    EXPECT_EQ(folderContent(dir_ / "out"), old) << "failed at " << culprit;
    EXPECT_THAT(temporaries(), ::testing::IsEmpty());
    failed.insert(culprit);
  }
  EXPECT_TRUE(failed.contains("report.json"));
  EXPECT_TRUE(failed.contains("mvc.png"));

  // Without the limit the new run replaces the whole folder.
  ASSERT_EQ(finish(start(compare("z=-0.3", "out"))).status, 0);
  std::map<std::string, std::string> replaced = folderContent(dir_ / "out");
  ASSERT_THAT(replaced, ::testing::SizeIs(6));
  for (const std::string name : {"mvc.png", "ffd.png", "compare.png"})
    EXPECT_EQ(replaced.at(name), next.at(name)) << name;
  EXPECT_THAT(temporaries(), ::testing::IsEmpty());
}

// Since the folder is replaced as a whole, anything in it that compare did not write (a folder
// in the place of report.md, a file of the user's) is refused, named, and kept.
TEST_F(IoSafetyCliTest, CompareKeepsAFolderWithFilesItDidNotWrite) {
  writeCubeCage("cage.obj", 1.0);
  const std::vector<std::string> args = {"compare", "--cage",  path("cage.obj"), "--methods",
                                         "mvc",     "--slice", "z=0.2",          "--resolution",
                                         "8",       "-o",      path("out")};
  ASSERT_EQ(finish(start(args)).status, 0);
  for (const std::string intruder : {"report.md/keep", "notes.txt"}) {
    SCOPED_TRACE(intruder);
    ASSERT_EQ(finish(start(args)).status, 0);
    fs::remove(dir_ / "out" / "report.md");
    fs::create_directories((dir_ / "out" / intruder).parent_path());
    write("out/" + intruder, "the user's");
    const std::map<std::string, std::string> before = folderContent(dir_ / "out");
    const Outcome refused = finish(start(args));
    EXPECT_EQ(refused.status, 3) << refused.err;
    EXPECT_EQ(std::count(refused.err.begin(), refused.err.end(), '\n'), 1) << refused.err;
    const std::string named = fs::path(intruder).begin()->string();
    EXPECT_THAT(refused.err, HasSubstr((dir_ / "out" / named).string() + ": not an output of"));
    EXPECT_EQ(folderContent(dir_ / "out"), before);
    EXPECT_EQ(test::slurp(dir_ / "out" / intruder), "the user's");
    EXPECT_THAT(temporaries(), ::testing::IsEmpty());
    fs::remove_all(dir_ / "out" / named);
  }
}

#ifdef SPACEWARP_WITH_OPENVDB
// A level set sphere, written with OpenVDB's own writer.
void writeSphereVdb(const fs::path& path, float voxel) {
  openvdb::initialize();
  auto sphere = openvdb::tools::createLevelSetSphere<openvdb::FloatGrid>(1.0f, openvdb::Vec3f(0.0f),
                                                                         voxel, 3.0f);
  sphere->setName("surface");
  openvdb::io::File file(path.string());
  file.write({sphere});
  file.close();
}

TEST_F(IoSafetyCliTest, VolumeWriterFailsCleanly) {
  writeSphereVdb(dir_ / "in.vdb", 0.05f);
  writeTwistRig();
  expectCleanWriteFailure(
      {"deform", "--rig", path("twist.json"), path("in.vdb"), "-o", path("out.vdb")},
      dir_ / "out.vdb");
  // What replaced it is a complete file that OpenVDB reads.
  openvdb::io::File file(path("out.vdb"));
  file.open();
  EXPECT_EQ(file.getGrids()->size(), 1u);
  EXPECT_TRUE(file.hasGrid("surface"));
  file.close();
}
#endif

#ifdef SPACEWARP_HAVE_HARMONIC
// The cache holds another cage's solution: it is solved again and the new cache's write fails.
TEST_F(IoSafetyCliTest, HarmonicCacheWriterFailsCleanly) {
  writeCubeCage("small.obj", 1.0);
  writeCubeCage("large.obj", 1.5);
  writeCloud(Vec3(-0.9), Vec3(0.9), 50, 7);
  auto weights = [&](const std::string& cage) {
    return std::vector<std::string>{
        "weights",         "--method",        "harmonic", "--cage",
        path(cage),        "--tets",          "2000",     "--harmonic-cache",
        path("cache.bin"), path("cloud.ply"), "-o",       path("weights.csv")};
  };
  ASSERT_EQ(finish(start(weights("small.obj"))).status, 0);
  expectCleanWriteFailure(weights("large.obj"), dir_ / "cache.bin");
}
#endif

// ---- Interrupted runs ---------------------------------------------------------------------

TEST_F(IoSafetyCliTest, InterruptedDeformRemovesItsTemporary) {
  writeCloud(Vec3(-1), Vec3(1), 1000, 3);
  writeTwistRig();
  for (const int signal : {SIGINT, SIGTERM, SIGHUP}) {
    SCOPED_TRACE(signal);
    expectCleanInterruption(
        {"deform", "--rig", path("twist.json"), path("cloud.ply"), "-o", path("out.obj")},
        dir_ / "out.obj", signal);
  }
}

// No help from block_fsync.so: a large output, interrupted somewhere in its writing.
TEST_F(IoSafetyCliTest, InterruptedLargeDeformRemovesItsTemporary) {
  writeCloud(Vec3(-1), Vec3(1), 1000000, 3);
  writeTwistRig();
  expectCleanInterruption(
      {"deform", "--rig", path("twist.json"), path("cloud.ply"), "-o", path("out.obj")},
      dir_ / "out.obj", SIGINT, /*blockInSync=*/false);
}

// A streamed deform (--chunk-points) writes its chunks into the temporary as they are warped:
// a signal mid-stream (no block_fsync.so: 1M points in chunks of 1000 take a while) or in the
// final sync still leaves no output and no temporary.
TEST_F(IoSafetyCliTest, InterruptedStreamedDeformRemovesItsTemporary) {
  writeCloud(Vec3(-1), Vec3(1), 1000000, 3);
  writeTwistRig();
  const std::vector<std::string> args = {"deform", "--chunk-points",   "1000",
                                         "--rig",  path("twist.json"), path("cloud.ply"),
                                         "-o",     path("out.ply")};
  for (const int signal : {SIGINT, SIGTERM}) {
    SCOPED_TRACE(signal);
    expectCleanInterruption(args, dir_ / "out.ply", signal, /*blockInSync=*/false);
    expectCleanInterruption(args, dir_ / "out.ply", signal, /*blockInSync=*/true);
  }
}

TEST_F(IoSafetyCliTest, InterruptedWeightsRemovesItsTemporary) {
  writeCubeCage("cage.obj", 1.0);
  writeCloud(Vec3(-0.9), Vec3(0.9), 1000, 5);
  expectCleanInterruption({"weights", "--method", "mvc", "--cage", path("cage.obj"),
                           path("cloud.ply"), "-o", path("weights.npy")},
                          dir_ / "weights.npy", SIGTERM);
}

TEST_F(IoSafetyCliTest, InterruptedCompareRemovesItsTemporary) {
  writeCubeCage("cage.obj", 1.0);
  fs::create_directories(dir_ / "out");
  expectCleanInterruption({"compare", "--cage", path("cage.obj"), "--methods", "mvc", "--slice",
                           "z=0.2", "--resolution", "32", "-o", path("out")},
                          dir_ / "out" / "mvc.png", SIGINT);
}

// Interrupted at its last file, when the images and report.json are complete in its
// temporary folder: the previous folder (another slice) stays whole, and no temporary is left.
TEST_F(IoSafetyCliTest, InterruptedCompareKeepsTheWholeOldFolder) {
  writeCubeCage("cage.obj", 1.0);
  const auto compare = [&](const std::string& slice) {
    return std::vector<std::string>{"compare",  "--cage", path("cage.obj"), "--methods", "mvc,ffd",
                                    "--slice",  slice,    "--resolution",   "16",        "-o",
                                    path("out")};
  };
  ASSERT_EQ(finish(start(compare("z=0.2"))).status, 0);
  const std::map<std::string, std::string> old = folderContent(dir_ / "out");
  for (const int signal : {SIGINT, SIGTERM}) {
    SCOPED_TRACE(signal);
    const pid_t pid = start(compare("z=-0.3"), 0, /*blockInSync=*/true, "report.md");
    bool seen = false;
    for (auto deadline = std::chrono::steady_clock::now() + std::chrono::minutes(5);
         !seen && std::chrono::steady_clock::now() < deadline;) {
      for (const fs::path& t : temporaries())
        seen = seen || t.filename().string().starts_with(".report.md.");
      if (seen) break;
      int status = 0;
      ASSERT_NE(::waitpid(pid, &status, WNOHANG), pid)
          << "the run ended before writing report.md: " << readStderr(pid);
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
    ASSERT_TRUE(seen) << "report.md's temporary did not appear";
    ::kill(pid, signal);
    const Outcome outcome = finish(pid);
    EXPECT_EQ(outcome.status, 128 + signal) << outcome.err;
    EXPECT_THAT(temporaries(), ::testing::IsEmpty());
    EXPECT_EQ(folderContent(dir_ / "out"), old);
  }
}

#ifdef SPACEWARP_WITH_OPENVDB
TEST_F(IoSafetyCliTest, InterruptedVolumeDeformRemovesItsTemporary) {
  writeSphereVdb(dir_ / "in.vdb", 0.1f);
  writeTwistRig();
  expectCleanInterruption(
      {"deform", "--rig", path("twist.json"), path("in.vdb"), "-o", path("out.vdb")},
      dir_ / "out.vdb", SIGTERM);
}
#endif

// A replaced output keeps its permissions.
TEST_F(IoSafetyCliTest, ReplacedOutputKeepsItsPermissions) {
  writeCloud(Vec3(-1), Vec3(1), 100, 3);
  writeTwistRig();
  write("out.ply", kOldOutput);
  ASSERT_EQ(::chmod((dir_ / "out.ply").c_str(), 0640), 0);
  const Outcome r = finish(
      start({"deform", "--rig", path("twist.json"), path("cloud.ply"), "-o", path("out.ply")}));
  ASSERT_EQ(r.status, 0) << r.err;
  struct stat status {};
  ASSERT_EQ(::stat((dir_ / "out.ply").c_str(), &status), 0);
  EXPECT_EQ(status.st_mode & 07777, 0640u);
  EXPECT_EQ(readSoup(dir_ / "out.ply").size(), 100u);
}

}  // namespace
}  // namespace spacewarp
