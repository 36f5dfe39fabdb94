#pragma once
// Shared helpers of the end-to-end tests of the spacewarp executable: a fixture with a fresh
// folder per test that runs the binary (SPACEWARP_CLI, defined by tests/CMakeLists.txt) with
// stdout and stderr captured, and small file helpers.

#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <span>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

#include <spacewarp/core/io/mesh_io.h>
#include <spacewarp/core/primitives.h>

namespace spacewarp::test {

/// Whether this is a sanitizer build: tests that run the CLI under `ulimit -v` skip there
/// (AddressSanitizer reserves terabytes of address space, so no such limit lets it start).
#ifdef SPACEWARP_SANITIZED
inline constexpr bool kSanitized = true;
#else
inline constexpr bool kSanitized = false;
#endif

/// What one run of the executable did.
struct CliResult {
  int exitCode = -1;  ///< -1 if it did not exit normally
  std::string out, err;
};

/// The whole content of a file ("" if it cannot be read).
inline std::string slurp(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

/// A fresh folder per test, temp/<prefix><pid>_<test name>, removed afterwards; run() runs
/// the executable with the given arguments from the shell, capturing stdout and stderr.
class CliFixture : public ::testing::Test {
 protected:
  explicit CliFixture(std::string prefix) : prefix_(std::move(prefix)) {}

  void SetUp() override {
    dir_ = std::filesystem::temp_directory_path() /
           (prefix_ + std::to_string(::getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    std::filesystem::remove_all(dir_);
    std::filesystem::create_directories(dir_);
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }

  /// `shellPrefix` runs before the executable in the same shell (e.g. "ulimit -v 1000000; ").
  CliResult run(const std::string& args, const std::string& shellPrefix = "") {
    const std::string cmd = shellPrefix + std::string(SPACEWARP_CLI) + " " + args + " >" +
                            (dir_ / "stdout.txt").string() + " 2>" + (dir_ / "stderr.txt").string();
    const int status = std::system(cmd.c_str());
    CliResult r;
    r.exitCode = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    r.out = slurp(dir_ / "stdout.txt");
    r.err = slurp(dir_ / "stderr.txt");
    std::filesystem::remove(dir_ / "stdout.txt");
    std::filesystem::remove(dir_ / "stderr.txt");
    return r;
  }

  /// n random points in the box [lo, hi) (deterministic for `seed`), written as cloud.ply.
  PolygonSoup writeCloud(const Vec3& lo, const Vec3& hi, std::size_t n, std::uint64_t seed) {
    PolygonSoup cloud;
    static_cast<PointSet&>(cloud) = makeRandomPoints(lo, hi, n, seed);
    writeSoup(cloud, dir_ / "cloud.ply");
    return cloud;
  }

  /// `spacewarp deform --rig dir_/rig dir_/cloud.ply -o dir_/out.ply`.
  CliResult deform(const std::string& rig) {
    return run("deform --rig " + (dir_ / rig).string() + " " + (dir_ / "cloud.ply").string() +
               " -o " + (dir_ / "out.ply").string());
  }

  /// Writes `content` to dir_/name and returns that path.
  std::filesystem::path write(const std::string& name, const std::string& content) {
    std::ofstream(dir_ / name, std::ios::binary) << content;
    return dir_ / name;
  }

  std::filesystem::path dir_;

 private:
  std::string prefix_;
};

/// The matrix in a .npy file (float64, C order) that `spacewarp weights` writes; fails the
/// calling test on a malformed header.
struct Npy {
  std::size_t rows = 0, columns = 0;
  std::vector<double> values;
};

inline Npy readNpy(const std::filesystem::path& path) {
  const std::string bytes = test::slurp(path);
  Npy npy;
  EXPECT_GE(bytes.size(), 10u);
  if (bytes.size() < 10) return npy;
  EXPECT_EQ(bytes.compare(0, 8, std::string("\x93NUMPY\x01\x00", 8)), 0);
  const std::size_t headerLength =
      static_cast<unsigned char>(bytes[8]) | static_cast<unsigned char>(bytes[9]) << 8;
  EXPECT_EQ((10 + headerLength) % 64, 0u) << "the data must start 64-byte aligned";
  const std::string header = bytes.substr(10, headerLength);
  const std::string prefix = "{'descr': '<f8', 'fortran_order': False, 'shape': (";
  EXPECT_EQ(header.compare(0, prefix.size(), prefix), 0) << header;
  EXPECT_EQ(header.back(), '\n');
  unsigned long rows = 0, columns = 0;
  int end = 0;
  const int read = std::sscanf(header.c_str() + std::min(prefix.size(), header.size()),
                               "%lu, %lu), }%n", &rows, &columns, &end);
  EXPECT_EQ(read, 2) << header;
  if (read != 2) return npy;
  EXPECT_EQ(header.find_first_not_of(' ', prefix.size() + end), header.size() - 1)
      << "only spaces pad the header: " << header;
  npy.rows = rows;
  npy.columns = columns;
  const std::size_t data = 10 + headerLength;
  EXPECT_EQ(bytes.size() - data, npy.rows * npy.columns * sizeof(double));
  npy.values.resize(npy.rows * npy.columns);
  std::memcpy(npy.values.data(), bytes.data() + data,
              std::min(bytes.size() - data, npy.values.size() * sizeof(double)));
  return npy;
}

/// Points as a JSON array of [x, y, z] with full double precision, for writing rigs.
inline std::string jsonPoints(std::span<const Vec3> points) {
  std::ostringstream s;
  s.precision(17);
  s << "[";
  for (std::size_t i = 0; i < points.size(); ++i)
    s << (i ? ", " : "") << "[" << points[i].x << ", " << points[i].y << ", " << points[i].z << "]";
  s << "]";
  return s.str();
}

/// A malformed rig and what `spacewarp deform` must do with it: exit with `exitCode` (3 for
/// bad input, 4 for a numerical failure), print one line naming the rig file and containing
/// `message`, and write no output. `spacewarp info` must refuse it the same way, unless only
/// the solve finds the fault (solveOnly). Every rig method's test file instantiates BadRigTest with
/// its own list; the test itself is in cli_test.cpp.
struct BadRig {
  BadRig(std::string name, std::string json, std::string message)
      : name(std::move(name)), json(std::move(json)), message(std::move(message)) {}
  BadRig(std::string name, std::string json, int exitCode, std::string message)
      : name(std::move(name)),
        json(std::move(json)),
        message(std::move(message)),
        exitCode(exitCode) {}

  /// This case marked as refused by the solve itself (a singular fit, a solver that gives up),
  /// which `spacewarp info`, checking without solving, cannot find.
  BadRig atSolve() const {
    BadRig marked = *this;
    marked.solveOnly = true;
    return marked;
  }

  std::string name;  ///< the test's name suffix
  std::string json;
  std::string message;
  int exitCode = 3;
  bool solveOnly = false;
};

class BadRigTest : public CliFixture, public ::testing::WithParamInterface<BadRig> {
 protected:
  BadRigTest() : CliFixture("spacewarp_bad_rig_") {}
};

/// Names each instantiated case after its BadRig::name.
inline std::string badRigName(const ::testing::TestParamInfo<BadRig>& info) {
  return info.param.name;
}

}  // namespace spacewarp::test
