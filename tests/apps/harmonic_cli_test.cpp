// End-to-end tests of the "harmonic" cage method of the spacewarp executable: deform and
// weights with --method harmonic and a harmonic rig, the coordinate cache, and bad caches and
// rigs exiting with the documented codes and no output. Only built with SPACEWARP_WITH_TETGEN.

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <spacewarp/coords/harmonic.h>
#include <spacewarp/core/coordinate_warp.h>
#include <spacewarp/core/io/mesh_io.h>
#include <spacewarp/core/primitives.h>
#include "apps/cli_test_util.h"

namespace fs = std::filesystem;
using namespace spacewarp;
using ::testing::HasSubstr;

namespace {

using ::spacewarp::test::BadRigTest;

class HarmonicCliTest : public test::CliFixture {
 protected:
  HarmonicCliTest() : test::CliFixture("spacewarp_harmonic_cli_") {}

  // A box cage [-1, 1]³ and a posed copy moved by an affine map, which harmonic coordinates
  // reproduce, plus a cloud inside the box.
  void SetUp() override {
    test::CliFixture::SetUp();
    const PolygonSoup cage = makeBoxSurface(Vec3(-1), Vec3(1), {1, 1, 1});
    PolygonSoup posed = cage;
    for (Vec3& p : posed.positions) p = affine(p);
    writeSoup(cage, dir_ / "cage.obj");
    writeSoup(posed, dir_ / "pose.obj");
    cloud_ = writeCloud(Vec3(-0.9), Vec3(0.9), 200, 11);
  }

  static Vec3 affine(const Vec3& p) {
    return Vec3(1.2 * p.x + 0.3 * p.y + 1.0, -0.2 * p.x + 0.9 * p.y, 1.1 * p.z + 0.2 * p.x - 2.0);
  }

  std::string cageFlags() const {
    return "--method harmonic --cage " + (dir_ / "cage.obj").string() + " --tets 2000";
  }

  test::CliResult deformWith(const std::string& flags) {
    return run("deform " + flags + " " + (dir_ / "cloud.ply").string() + " -o " +
               (dir_ / "out.ply").string());
  }

  void expectAffine(const std::string& what) {
    const PolygonSoup out = readSoup(dir_ / "out.ply");
    ASSERT_EQ(out.size(), cloud_.size()) << what;
    for (std::size_t i = 0; i < cloud_.size(); ++i) {
      ASSERT_LE(glm::length(out.positions[i] - affine(cloud_.positions[i])), 1e-9)
          << what << " point " << i;
    }
  }

  PolygonSoup cloud_;
};

TEST_F(HarmonicCliTest, DeformReproducesAnAffinePose) {
  const test::CliResult r = deformWith(cageFlags() + " --pose " + (dir_ / "pose.obj").string());
  ASSERT_EQ(r.exitCode, 0) << r.err;
  expectAffine("--method harmonic");
  write("harmonic.json",
        R"({"method": "harmonic", "cage": "cage.obj", "pose": "pose.obj", "tets": 2000})");
  fs::remove(dir_ / "out.ply");
  ASSERT_EQ(deform("harmonic.json").exitCode, 0);
  expectAffine("harmonic rig");
}

TEST_F(HarmonicCliTest, WeightsCsvHasOneColumnPerCageVertex) {
  const fs::path csv = dir_ / "w.csv";
  const test::CliResult r =
      run("weights " + cageFlags() + " " + (dir_ / "cloud.ply").string() + " -o " + csv.string());
  ASSERT_EQ(r.exitCode, 0) << r.err;
  std::ifstream in(csv);
  std::string header, line;
  std::getline(in, header);
  EXPECT_EQ(std::count(header.begin(), header.end(), ',') + 1, 8);
  EXPECT_TRUE(header.starts_with("v0,v1,"));
  std::size_t rows = 0;
  while (std::getline(in, line)) {
    std::stringstream s(line);
    std::string cell;
    double sum = 0.0;
    while (std::getline(s, cell, ',')) {
      const double w = std::stod(cell);
      EXPECT_GE(w, -1e-12);
      sum += w;
    }
    EXPECT_NEAR(sum, 1.0, 1e-10) << "row " << rows;
    ++rows;
  }
  EXPECT_EQ(rows, cloud_.size());
}

TEST_F(HarmonicCliTest, CacheIsWrittenThenReused) {
  const fs::path cache = dir_ / "box.swh";
  const std::string flags = cageFlags() + " --pose " + (dir_ / "pose.obj").string() +
                            " --harmonic-cache " + cache.string();
  ASSERT_EQ(deformWith(flags).exitCode, 0);
  ASSERT_TRUE(fs::exists(cache));
  const std::string first = test::slurp(dir_ / "out.ply");
  const auto written = fs::last_write_time(cache);
  fs::remove(dir_ / "out.ply");
  ASSERT_EQ(deformWith(flags).exitCode, 0);
  EXPECT_EQ(test::slurp(dir_ / "out.ply"), first);
  EXPECT_EQ(fs::last_write_time(cache), written);  // loaded, not rewritten
  // Another resolution: solved again and the cache replaced.
  const auto before = HarmonicCoordinates::readFileInfo(cache);
  std::string other = flags;
  other.replace(other.find("--tets 2000"), 11, "--tets 3000");
  ASSERT_EQ(deformWith(other).exitCode, 0);
  const auto after = HarmonicCoordinates::readFileInfo(cache);
  EXPECT_LT(after.maxTetVolume, before.maxTetVolume);
  EXPECT_EQ(after.cageHash, before.cageHash);
}

TEST_F(HarmonicCliTest, BadCacheExitsWithCode3AndNoOutput) {
  const fs::path cache = dir_ / "box.swh";
  const std::string flags = cageFlags() + " --pose " + (dir_ / "pose.obj").string() +
                            " --harmonic-cache " + cache.string();
  ASSERT_EQ(deformWith(flags).exitCode, 0);
  std::string bytes = test::slurp(cache);
  fs::remove(dir_ / "out.ply");
  // A flipped byte in the coordinate values.
  bytes[bytes.size() - 20] = static_cast<char>(bytes[bytes.size() - 20] ^ 1);
  std::ofstream(cache, std::ios::binary | std::ios::trunc) << bytes;
  test::CliResult r = deformWith(flags);
  EXPECT_EQ(r.exitCode, 3);
  EXPECT_THAT(r.err, HasSubstr(cache.string()));
  EXPECT_THAT(r.err, HasSubstr("checksum"));
  EXPECT_FALSE(fs::exists(dir_ / "out.ply"));
  // Not a coordinate file at all: an error too (and the file is left alone).
  write("box.swh", "not a cache");
  r = deformWith(flags);
  EXPECT_EQ(r.exitCode, 3);
  EXPECT_THAT(r.err, HasSubstr("not a harmonic coordinate file"));
  EXPECT_FALSE(fs::exists(dir_ / "out.ply"));
  EXPECT_EQ(test::slurp(cache), "not a cache");
  r = run("weights " + cageFlags() + " --harmonic-cache " + cache.string() + " " +
          (dir_ / "cloud.ply").string() + " -o " + (dir_ / "w.csv").string());
  EXPECT_EQ(r.exitCode, 3);
  EXPECT_FALSE(fs::exists(dir_ / "w.csv"));
}

TEST_F(HarmonicCliTest, PointsOutsideTheCage) {
  writeCloud(Vec3(-2), Vec3(2), 50, 3);
  const std::string flags = cageFlags() + " --pose " + (dir_ / "pose.obj").string();
  const test::CliResult r = deformWith(flags);
  EXPECT_EQ(r.exitCode, 3);
  EXPECT_THAT(r.err, HasSubstr("points are outside the cage"));
  EXPECT_FALSE(fs::exists(dir_ / "out.ply"));
  EXPECT_EQ(deformWith(flags + " --outside nearest").exitCode, 0);
}

// --precision p is --tets 200000 · 4^(p − 5): the same solve, bit for bit, for whole and
// fractional levels; both at once, an out-of-range level or another method are usage errors.
TEST_F(HarmonicCliTest, PrecisionIsATetBudget) {
  const std::string cage = "--method harmonic --cage " + (dir_ / "cage.obj").string() + " --pose " +
                           (dir_ / "pose.obj").string();
  ASSERT_EQ(deformWith(cage + " --precision 2").exitCode, 0);
  expectAffine("--precision 2");
  const std::string byPrecision = test::slurp(dir_ / "out.ply");
  ASSERT_EQ(deformWith(cage + " --tets 3125").exitCode, 0);
  EXPECT_EQ(test::slurp(dir_ / "out.ply"), byPrecision);
  ASSERT_EQ(deformWith(cage + " --precision 2.5").exitCode, 0);  // 200000 / 32 tets
  const std::string byFraction = test::slurp(dir_ / "out.ply");
  EXPECT_NE(byFraction, byPrecision);
  ASSERT_EQ(deformWith(cage + " --tets 6250").exitCode, 0);
  EXPECT_EQ(test::slurp(dir_ / "out.ply"), byFraction);
  fs::remove(dir_ / "out.ply");
  for (const char* bad :
       {" --precision 2 --tets 3125", " --precision 0", " --precision 8", " --precision 7.5",
        " --precision nan", " --precision 5x", " --precision 0x5", " --precision inf"}) {
    const test::CliResult r = deformWith(cage + bad);
    EXPECT_EQ(r.exitCode, 2) << bad;
    EXPECT_THAT(r.err, HasSubstr("--precision")) << bad;
    EXPECT_FALSE(fs::exists(dir_ / "out.ply")) << bad;
  }
  // Not numbers are called so (once "5x" was "not in range" and "0x5" was read as 5).
  for (const char* word : {"nan", "5x", "0x5"}) {
    const test::CliResult r = deformWith(cage + " --precision " + word);
    EXPECT_THAT(r.err, HasSubstr("'" + std::string(word) + "' is not a number")) << word;
  }
  const test::CliResult r =
      deformWith("--method mvc --cage " + (dir_ / "cage.obj").string() + " --pose " +
                 (dir_ / "pose.obj").string() + " --precision 2");
  EXPECT_EQ(r.exitCode, 2);
  EXPECT_THAT(r.err, HasSubstr("--precision applies to --method harmonic only"));
}

TEST_F(HarmonicCliTest, RigPrecisionKey) {
  write("rig.json",
        R"({"method": "harmonic", "cage": "cage.obj", "pose": "pose.obj", "precision": 1})");
  ASSERT_EQ(deform("rig.json").exitCode, 0);
  expectAffine("precision 1");
  write("rig.json",
        R"({"method": "harmonic", "cage": "cage.obj", "pose": "pose.obj", "precision": 1.5})");
  ASSERT_EQ(deform("rig.json").exitCode, 0);
  expectAffine("precision 1.5");
}

INSTANTIATE_TEST_SUITE_P(
    HarmonicRigs, BadRigTest,
    ::testing::Values(
        test::BadRig{"HarmonicMissingPose", R"({"method": "harmonic", "cage": "cage.obj"})", 3,
                     "'pose' is missing"},
        test::BadRig{"HarmonicBadTets",
                     R"({"method": "harmonic", "cage": "c.obj", "pose": "p.obj", "tets": 0.5})", 3,
                     "'tets' must be a whole number"},
        test::BadRig{"HarmonicBadOutside",
                     R"({"method": "harmonic", "cage": "c.obj", "pose": "p.obj", )"
                     R"("outside": "clamp"})",
                     3, "'outside' must be"},
        test::BadRig{"HarmonicPrecisionZero",
                     R"({"method": "harmonic", "cage": "c.obj", "pose": "p.obj", "precision": 0})",
                     3, "'precision' must be a number in [1, 7]"},
        test::BadRig{"HarmonicPrecisionAboveSeven",
                     R"({"method": "harmonic", "cage": "c.obj", "pose": "p.obj", )"
                     R"("precision": 7.5})",
                     3, "'precision' must be a number in [1, 7]"},
        test::BadRig{"HarmonicPrecisionAndTets",
                     R"({"method": "harmonic", "cage": "c.obj", "pose": "p.obj", )"
                     R"("precision": 2, "tets": 3000})",
                     3, "'precision' cannot be given with \"tets\" (give one of them)"},
        test::BadRig{"HarmonicPrecsionMistyped",
                     R"({"method": "harmonic", "cage": "c.obj", "pose": "p.obj", )"
                     R"("precison": 2})",
                     3, "precison"}),
    test::badRigName);

}  // namespace
