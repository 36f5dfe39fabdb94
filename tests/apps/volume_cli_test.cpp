// End-to-end tests of `spacewarp deform` on OpenVDB files: every rig method warps every grid
// of a file, keeping grid names and metadata; bad files exit 3 with a message naming them and
// leave no output behind.

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <string>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <openvdb/io/File.h>
#include <openvdb/openvdb.h>
#include <openvdb/points/PointConversion.h>
#include <openvdb/points/PointCount.h>
#include <openvdb/tools/LevelSetSphere.h>
#include <tbb/info.h>

#include <spacewarp/core/io/mesh_io.h>
#include <spacewarp/core/primitives.h>
#include <spacewarp/core/twist.h>
#include <spacewarp/volume/warp_volume.h>
#include "apps/cli_test_util.h"

namespace fs = std::filesystem;
using namespace spacewarp;
using ::testing::HasSubstr;

namespace {

using test::CliResult;

constexpr double kVoxel = 0.1;

class VolumeCliTest : public test::CliFixture {
 protected:
  VolumeCliTest() : CliFixture("spacewarp_volume_cli_") {}

  // A file with a level set sphere "surface" (metadata "author"), a fog volume "density" and
  // file metadata "scene".
  void writeInput() {
    openvdb::initialize();
    sphere_ = openvdb::tools::createLevelSetSphere<openvdb::FloatGrid>(
        0.6f, openvdb::Vec3f(0.1f, 0.0f, 0.05f), float(kVoxel), 3.0f);
    sphere_->setName("surface");
    sphere_->insertMeta("author", openvdb::StringMetadata("spacewarp tests"));
    fog_ = openvdb::FloatGrid::create(0.0f);
    fog_->setName("density");
    fog_->setGridClass(openvdb::GRID_FOG_VOLUME);
    fog_->setTransform(openvdb::math::Transform::createLinearTransform(kVoxel));
    for (int i = -4; i <= 4; ++i)
      for (int j = -4; j <= 4; ++j)
        for (int k = -4; k <= 4; ++k)
          fog_->tree().setValue(openvdb::Coord(i, j, k),
                                float(std::exp(-(i * i + j * j + k * k) / 9.0)));
    openvdb::MetaMap meta;
    meta.insertMeta("scene", openvdb::StringMetadata("unit test"));
    openvdb::io::File file((dir_ / "in.vdb").string());
    file.write({sphere_, fog_}, meta);
    file.close();
  }

  struct Output {
    openvdb::GridPtrVec grids;
    openvdb::MetaMap::Ptr meta;

    // The float grid called `name` (null if none); files do not keep the order of grids.
    openvdb::FloatGrid::Ptr grid(const std::string& name) const {
      for (const auto& g : grids)
        if (g->getName() == name) return openvdb::gridPtrCast<openvdb::FloatGrid>(g);
      return nullptr;
    }
  };
  Output readOutput() {
    openvdb::io::File file((dir_ / "out.vdb").string());
    file.open();
    Output out{*file.getGrids(), file.getMetadata()};
    file.close();
    return out;
  }

  CliResult deformVolume(const std::string& flags, const std::string& input = "in.vdb") {
    return run("deform " + flags + " " + (dir_ / input).string() + " -o " +
               (dir_ / "out.vdb").string());
  }

  void expectNoOutput() {
    EXPECT_FALSE(fs::exists(dir_ / "out.vdb"));
    for (const auto& entry : fs::directory_iterator(dir_))
      EXPECT_THAT(entry.path().filename().string(), ::testing::Not(HasSubstr(".tmp")));
  }

  openvdb::FloatGrid::Ptr sphere_, fog_;
};

TEST_F(VolumeCliTest, TwistRigWarpsEveryGridKeepingNamesAndMetadata) {
  writeInput();
  // Add a point data grid to the file.
  const std::vector<openvdb::Vec3R> positions = {
      {0.1, 0.2, 0.3}, {-0.4, 0.0, 0.5}, {0.0, -0.3, 0.0}};
  {
    const auto xform = openvdb::math::Transform::createLinearTransform(kVoxel);
    auto points =
        openvdb::points::createPointDataGrid<openvdb::points::NullCodec,
                                             openvdb::points::PointDataGrid>(positions, *xform);
    points->setName("particles");
    openvdb::io::File file((dir_ / "in.vdb").string());
    file.write({sphere_, fog_, points});
    file.close();
  }
  write("twist.json",
        R"({"method": "twist", "origin": [0, 0, 0], "axis": [0, 1, 0], "rate": 0.8})");
  const CliResult r = deformVolume("--rig " + (dir_ / "twist.json").string());
  ASSERT_EQ(r.exitCode, 0) << r.err;
  EXPECT_THAT(r.out, HasSubstr("'surface'"));
  const Output out = readOutput();
  ASSERT_EQ(out.grids.size(), 3u);
  openvdb::points::PointDataGrid::Ptr particles;
  for (const auto& g : out.grids)
    if (g->getName() == "particles")
      particles = openvdb::gridPtrCast<openvdb::points::PointDataGrid>(g);
  ASSERT_TRUE(particles);
  EXPECT_EQ(openvdb::points::pointCount(particles->tree()), positions.size());
  TwistOptions tp;
  tp.axis = Vec3(0, 1, 0);
  tp.rate = 0.8;
  for (auto leaf = particles->tree().cbeginLeaf(); leaf; ++leaf) {
    openvdb::points::AttributeHandle<openvdb::Vec3f> handle(leaf->constAttributeArray("P"));
    for (auto idx = leaf->beginIndexOn(); idx; ++idx) {
      const openvdb::Vec3d w =
          particles->transform().indexToWorld(handle.get(*idx) + idx.getCoord().asVec3d());
      double nearest = 1e300;  // some input point must warp onto it
      for (const auto& p : positions)
        nearest = std::min(nearest, glm::length(TwistWarp(tp).apply(Vec3(p[0], p[1], p[2])) -
                                                Vec3(w[0], w[1], w[2])));
      EXPECT_LT(nearest, 1e-6);
    }
  }
  auto surface = out.grid("surface");
  auto density = out.grid("density");
  ASSERT_TRUE(surface && density);
  EXPECT_EQ(surface->getName(), "surface");
  EXPECT_EQ(surface->getGridClass(), openvdb::GRID_LEVEL_SET);
  EXPECT_EQ(surface->metaValue<std::string>("author"), "spacewarp tests");
  EXPECT_EQ(density->getName(), "density");
  EXPECT_EQ(density->getGridClass(), openvdb::GRID_FOG_VOLUME);

  // The same as the library's result.
  TwistOptions p;
  p.axis = Vec3(0, 1, 0);
  p.rate = 0.8;
  const TwistWarp twist(p);
  const auto expected = warpVolume(twist, *sphere_);
  EXPECT_EQ(surface->activeVoxelCount(), expected.grid->activeVoxelCount());
  auto acc = surface->getConstAccessor();
  for (auto it = expected.grid->cbeginValueOn(); it; ++it)
    ASSERT_EQ(acc.getValue(it.getCoord()), *it) << it.getCoord();
}

// A cage and a posed copy moved by a similarity (mean-value coordinates reproduce it exactly).
Vec3 similarity(const Vec3& p) { return Vec3(-1.5 * p.y + 0.2, 1.5 * p.x, 1.5 * p.z - 0.1); }

TEST_F(VolumeCliTest, CageRigWarpsTheLevelSetToTheSimilarSphere) {
  writeInput();
  const PolygonSoup cage = makeBoxSurface(Vec3(-1), Vec3(1), {1, 1, 1});
  PolygonSoup posed = cage;
  for (Vec3& q : posed.positions) q = similarity(q);
  writeSoup(cage, dir_ / "cage.obj");
  writeSoup(posed, dir_ / "pose.obj");
  write("mvc.json", R"({"method": "mvc", "cage": "cage.obj", "pose": "pose.obj"})");
  const CliResult r =
      deformVolume("--rig " + (dir_ / "mvc.json").string() + " --sampler triquadratic");
  ASSERT_EQ(r.exitCode, 0) << r.err;
  const Output out = readOutput();
  ASSERT_EQ(out.grids.size(), 2u);
  auto surface = out.grid("surface");
  ASSERT_TRUE(surface);
  EXPECT_EQ(surface->getName(), "surface");
  EXPECT_EQ(surface->metaValue<std::string>("author"), "spacewarp tests");
  const Vec3 center = similarity(Vec3(0.1, 0.0, 0.05));
  std::size_t near = 0;
  for (auto it = surface->cbeginValueOn(); it; ++it) {
    const openvdb::Vec3d w = surface->indexToWorld(it.getCoord());
    const double exact = glm::length(Vec3(w[0], w[1], w[2]) - center) - 0.9;
    if (std::abs(exact) > 1.5 * kVoxel) continue;
    EXPECT_NEAR(*it, exact, 0.5 * kVoxel) << it.getCoord();
    ++near;
  }
  EXPECT_GT(near, 500u);
}

TEST_F(VolumeCliTest, ConserveMassKeepsTheFogTotal) {
  writeInput();
  write("taper.json",
        R"({"method": "taper", "origin": [0, 0, 0], "axis": [0, 0, 1], "rate": -0.5})");
  const CliResult r = deformVolume("--rig " + (dir_ / "taper.json").string() + " --conserve-mass");
  ASSERT_EQ(r.exitCode, 0) << r.err;
  const Output out = readOutput();
  auto density = out.grid("density");
  ASSERT_TRUE(density);
  double before = 0.0, after = 0.0;
  for (auto it = fog_->cbeginValueOn(); it; ++it) before += *it;
  for (auto it = density->cbeginValueOn(); it; ++it) after += *it;
  EXPECT_NEAR(after / before, 1.0, 0.03);
}

// --conserve-mass on a file without a fog volume (a level set only) does nothing: a warning says
// so.
TEST_F(VolumeCliTest, ConserveMassWithoutAFogVolumeIsAWarning) {
  writeInput();
  openvdb::io::File((dir_ / "surface.vdb").string()).write({sphere_});
  write("taper.json",
        R"({"method": "taper", "origin": [0, 0, 0], "axis": [0, 0, 1], "rate": -0.5})");
  const std::string rig = "--rig " + (dir_ / "taper.json").string() + " --conserve-mass";
  const CliResult alone = deformVolume(rig, "surface.vdb");
  ASSERT_EQ(alone.exitCode, 0) << alone.err;
  EXPECT_THAT(alone.err, HasSubstr("surface.vdb: --conserve-mass: no grid is a fog volume"));
  const CliResult withFog = deformVolume(rig);
  ASSERT_EQ(withFog.exitCode, 0) << withFog.err;
  EXPECT_THAT(withFog.err, ::testing::Not(HasSubstr("no grid is a fog volume")));
}

// -q silences the informational lines (one per grid, the summary), before or after the
// subcommand, while warnings stay: here the unsupported grid's and --conserve-mass's.
TEST_F(VolumeCliTest, QuietPrintsNoInformationForAVolume) {
  writeInput();
  const std::vector<openvdb::Vec3R> positions = {{0.1, 0.2, 0.3}, {-0.4, 0.0, 0.5}};
  const auto xform = openvdb::math::Transform::createLinearTransform(kVoxel);
  auto points =
      openvdb::points::createPointDataGrid<openvdb::points::NullCodec,
                                           openvdb::points::PointDataGrid>(positions, *xform);
  points->setName("particles");
  auto flags = openvdb::BoolGrid::create(false);
  flags->setName("flags");
  flags->tree().setValue(openvdb::Coord(0, 0, 0), true);
  {
    openvdb::io::File file((dir_ / "in.vdb").string());
    file.write({sphere_, fog_, points, flags});
    file.close();
  }
  write("squeeze.json", R"({"method": "affine", "matrix": [[1, 0, 0, 0], [0, 1, 0, 0],
                                                           [0, 0, 1e-4, 0], [0, 0, 0, 1]]})");
  const std::string rig = "--rig " + (dir_ / "squeeze.json").string() + " --conserve-mass ";
  const CliResult loud = deformVolume(rig);
  ASSERT_EQ(loud.exitCode, 0) << loud.err;
  EXPECT_THAT(loud.out, HasSubstr("grid 'particles'"));
  const std::string files = (dir_ / "in.vdb").string() + " -o " + (dir_ / "out.vdb").string();
  for (const std::string& args : {"-q deform " + rig + files, "deform " + rig + "-q " + files,
                                  "deform --quiet " + rig + files}) {
    SCOPED_TRACE(args);
    const CliResult quiet = run(args);
    ASSERT_EQ(quiet.exitCode, 0) << quiet.err;
    EXPECT_EQ(quiet.out, "");
    EXPECT_EQ(quiet.err, loud.err) << "the same warnings";
    EXPECT_THAT(quiet.err, HasSubstr("'flags'"));
  }
}

// A warp that nearly collapses one axis (an affine squeeze by 1e-4 along z, or a taper whose
// cross-section shrinks to 1/100 inside the fog) makes |det J| tiny: the densities divided by
// it are far off the conserved total, and a counted one-line warning says so, naming the grid.
TEST_F(VolumeCliTest, ConserveMassWarnsOfANearCollapse) {
  writeInput();
  write("squeeze.json", R"({"method": "affine", "matrix": [[1, 0, 0, 0], [0, 1, 0, 0],
                                                           [0, 0, 1e-4, 0], [0, 0, 0, 1]]})");
  write("taper.json", R"({"method": "taper", "origin": [0, 0, 0.45], "axis": [0, 0, 1],
                           "rate": 1.16, "limits": [-0.85, 0]})");
  for (const std::string rig : {"squeeze.json", "taper.json"}) {
    SCOPED_TRACE(rig);
    const CliResult r = deformVolume("--rig " + (dir_ / rig).string() + " --conserve-mass");
    ASSERT_EQ(r.exitCode, 0) << r.err;
    const std::string start = "spacewarp: warning: " + (dir_ / "in.vdb").string() +
                              ": grid 'density': --conserve-mass: the warp changes volumes";
    const auto at = r.err.find(start);
    ASSERT_NE(at, std::string::npos) << r.err;
    const std::string line = r.err.substr(at, r.err.find('\n', at) - at);
    EXPECT_THAT(line, HasSubstr("(mass ")) << "one line";
    EXPECT_EQ(r.err.find("--conserve-mass", at + start.size()), std::string::npos) << r.err;
    EXPECT_THAT(r.out, HasSubstr("warning")) << "counted in the summary: " << r.out;
    EXPECT_THAT(r.err, ::testing::Not(HasSubstr("grid 'surface': --conserve-mass")))
        << "level sets are not divided";
  }
  // A moderate taper conserves the mass: no such warning.
  write("mild.json",
        R"({"method": "taper", "origin": [0, 0, 0], "axis": [0, 0, 1], "rate": -0.5})");
  const CliResult mild =
      deformVolume("--rig " + (dir_ / "mild.json").string() + " --conserve-mass");
  ASSERT_EQ(mild.exitCode, 0) << mild.err;
  EXPECT_THAT(mild.err, ::testing::Not(HasSubstr("--conserve-mass")));
  // Without --conserve-mass nothing is divided, nothing to warn of.
  const CliResult plain = deformVolume("--rig " + (dir_ / "squeeze.json").string());
  EXPECT_THAT(plain.err, ::testing::Not(HasSubstr("--conserve-mass")));
}

// Every rig method the tool has warps a volume file.
struct RigCase {
  std::string name, json;
};

void PrintTo(const RigCase& c, std::ostream* os) { *os << c.name; }

class VolumeRigTest : public VolumeCliTest, public ::testing::WithParamInterface<RigCase> {};

TEST_P(VolumeRigTest, WarpsEveryGrid) {
  writeInput();
  const PolygonSoup cage = makeBoxSurface(Vec3(-1), Vec3(1), {1, 1, 1});
  PolygonSoup posed = cage;
  for (Vec3& q : posed.positions) q = q * 1.1 + Vec3(0.05 * q.z, 0.0, 0.0);
  writeSoup(cage, dir_ / "cage.obj");
  writeSoup(posed, dir_ / "pose.obj");
  write("rig.json", GetParam().json);
  const CliResult r = deformVolume("--rig " + (dir_ / "rig.json").string());
  ASSERT_EQ(r.exitCode, 0) << r.err;
  EXPECT_THAT(r.err, ::testing::Not(HasSubstr("did not converge")));
  const Output out = readOutput();
  ASSERT_EQ(out.grids.size(), 2u);
  const auto surface = out.grid("surface");
  const auto density = out.grid("density");
  ASSERT_TRUE(surface && density);
  EXPECT_EQ(surface->getGridClass(), openvdb::GRID_LEVEL_SET);
  EXPECT_GT(surface->activeVoxelCount(), sphere_->activeVoxelCount() / 2);
  EXPECT_GT(density->activeVoxelCount(), fog_->activeVoxelCount() / 2);
}

INSTANTIATE_TEST_SUITE_P(
    AllRigs, VolumeRigTest,
    ::testing::Values(
        RigCase{"twist", R"({"method": "twist", "origin": [0,0,0], "axis": [0,0,1], "rate": 1})"},
        RigCase{"bend", R"({"method": "bend", "origin": [0,0,0], "axis": [0,0,1],
                            "direction": [1,0,0], "rate": 0.5})"},
        RigCase{"taper", R"({"method": "taper", "origin": [0,0,0], "axis": [0,0,1], "rate": 0.3})"},
        RigCase{"affine", R"({"method": "affine",
                              "matrix": [[0,-1,0,0.2],[1,0,0,0],[0,0,1.2,0],[0,0,0,1]]})"},
        RigCase{"mvc", R"({"method": "mvc", "cage": "cage.obj", "pose": "pose.obj"})"},
        RigCase{"green", R"({"method": "green", "cage": "cage.obj", "pose": "pose.obj"})"},
        RigCase{"ffd", R"({"method": "ffd", "basis": "trilinear", "origin": [-1,-1,-1],
                           "size": [2,2,2], "resolution": [2,2,2],
                           "controlPoints": [[-1,-1,-1],[1,-1,-1],[-1,1,-1],[1,1,-1],
                                             [-1.2,-1,1],[1.2,-1,1],[-1.2,1,1],[1.2,1,1]]})"},
        RigCase{"rbf", R"({"method": "rbf", "centers": [[0,0,0],[1,0,0],[0,1,0],[0,0,1]],
                           "targets": [[0,0,0],[1.1,0,0],[0,1,0.1],[0,0,1]]})"},
        RigCase{"mls", R"({"method": "mls", "handles": [[0,0,0],[1,0,0],[0,1,0],[0,0,1]],
                           "targets": [[0,0,0],[1,0.1,0],[-0.1,1,0],[0,0,1]]})"},
        RigCase{"graph", R"({"method": "graph", "handles": [[-1,0,0],[1,0,0]],
                             "targets": [[-1,0,0],[1,0.2,0]], "spacing": 0.5})"}),
    [](const ::testing::TestParamInfo<RigCase>& info) { return info.param.name; });

TEST_F(VolumeCliTest, BadFilesExitThreeNamingTheFileWithNoOutput) {
  write("twist.json", R"({"method": "twist", "origin": [0, 0, 0], "axis": [0, 0, 1], "rate": 1})");
  const std::string rig = "--rig " + (dir_ / "twist.json").string();

  CliResult r = deformVolume(rig, "missing.vdb");
  EXPECT_EQ(r.exitCode, 3);
  EXPECT_THAT(r.err, HasSubstr("missing.vdb"));
  expectNoOutput();

  write("text.vdb", "this is not a volume\n");
  r = deformVolume(rig, "text.vdb");
  EXPECT_EQ(r.exitCode, 3);
  EXPECT_THAT(r.err, HasSubstr("text.vdb"));
  expectNoOutput();

  openvdb::initialize();
  auto mask = openvdb::BoolGrid::create(false);
  mask->setName("occupancy");
  mask->tree().setValue(openvdb::Coord(0), true);
  openvdb::io::File file((dir_ / "mask.vdb").string());
  file.write({mask});
  file.close();
  r = deformVolume(rig, "mask.vdb");
  EXPECT_EQ(r.exitCode, 3);
  EXPECT_THAT(r.err, HasSubstr("mask.vdb"));
  EXPECT_THAT(r.err, HasSubstr("no supported grid"));
  expectNoOutput();
}

TEST_F(VolumeCliTest, VectorGridsAreRotatedUnlessKept) {
  // A uniform velocity field (VecType left at OpenVDB's default) under a quarter turn about z.
  openvdb::initialize();
  auto velocity = openvdb::Vec3SGrid::create(openvdb::Vec3s(0.0f));
  velocity->setName("velocity");
  velocity->setTransform(openvdb::math::Transform::createLinearTransform(kVoxel));
  for (int i = -4; i <= 4; ++i)
    for (int j = -4; j <= 4; ++j)
      for (int k = -4; k <= 4; ++k)
        velocity->tree().setValue(openvdb::Coord(i, j, k), openvdb::Vec3s(1.0f, 0.0f, 0.0f));
  {
    openvdb::io::File file((dir_ / "in.vdb").string());
    file.write({velocity});
    file.close();
  }
  write("turn.json",
        R"({"method": "affine", "matrix": [[0,-1,0,0],[1,0,0,0],[0,0,1,0],[0,0,0,1]]})");
  for (const std::string mode : {"", "keep"}) {
    const CliResult r = deformVolume("--rig " + (dir_ / "turn.json").string() +
                                     (mode.empty() ? "" : " --vectors " + mode));
    ASSERT_EQ(r.exitCode, 0) << r.err;
    EXPECT_THAT(r.out, HasSubstr(mode.empty() ? "vectors J v" : "vectors unchanged"));
    openvdb::io::File file((dir_ / "out.vdb").string());
    file.open();
    const auto out = openvdb::gridPtrCast<openvdb::Vec3SGrid>(file.readGrid("velocity"));
    file.close();
    ASSERT_TRUE(out);
    // The center voxel's preimage is the center: its stencil is inside the field.
    const openvdb::Vec3s v = out->tree().getValue(openvdb::Coord(0, 0, 0));
    const openvdb::Vec3s expected =
        mode.empty() ? openvdb::Vec3s(0, 1, 0) : openvdb::Vec3s(1, 0, 0);
    EXPECT_NEAR((v - expected).length(), 0.0, 1e-6) << v;
  }
  const CliResult bad =
      deformVolume("--rig " + (dir_ / "turn.json").string() + " --vectors sideways");
  EXPECT_EQ(bad.exitCode, 2);
}

// Running out of memory while warping a volume (no estimate guards it) ends in one line and
// exit 3 at every limit: a std::bad_alloc thrown while grids were being destroyed (OpenVDB's
// Tree::clear() allocates) used to abort the process (exit 134, "terminate called after
// throwing an instance of 'std::bad_alloc'"), and the 128 MiB buffer of OpenBLAS's worker
// thread made that happen under 300 MB already.
TEST_F(VolumeCliTest, RunningOutOfMemoryIsOneLineAndExit3AtAnyLimit) {
#ifdef SPACEWARP_SANITIZED
  GTEST_SKIP() << "an address-space limit cannot apply to a sanitizer build";
#endif
  openvdb::initialize();
  openvdb::FloatGrid::Ptr sphere = openvdb::tools::createLevelSetSphere<openvdb::FloatGrid>(
      1.0f, openvdb::Vec3f(0.0f), 0.02f, 3.0f);
  sphere->setName("surface");
  {
    openvdb::io::File file((dir_ / "in.vdb").string());
    file.write({sphere});
    file.close();
  }
  write(
      "ffd.json", R"({"method": "ffd", "basis": "bernstein", "origin": [-1.2, -1.2, -1.2],
                        "size": [2.4, 2.4, 2.4], "resolution": [3, 3, 3],
                        "controlPoints": [)" +
                      [] {
                        std::string points;
                        for (int k = 0; k < 3; ++k)
                          for (int j = 0; j < 3; ++j)
                            for (int i = 0; i < 3; ++i) {
                              const double x = -1.2 + 1.2 * i, y = -1.2 + 1.2 * j,
                                           z = -1.2 + 1.2 * k;
                              points += std::string(points.empty() ? "" : ", ") + "[" +
                                        std::to_string(x + 0.2 * z) + ", " + std::to_string(y) +
                                        ", " + std::to_string(z) + "]";
                            }
                        return points;
                      }() +
                      "]}");
  // At most 2 worker threads: each one's stack takes address space.
  const std::string threads =
      "--threads " + std::to_string(std::min(2, tbb::info::default_concurrency())) + " ";
  for (const long limit : {160000L, 180000L, 200000L, 250000L, 300000L, 400000L}) {
    const std::string what = "ulimit -v " + std::to_string(limit);
    const CliResult r = run(threads + "deform --rig " + (dir_ / "ffd.json").string() + " " +
                                (dir_ / "in.vdb").string() + " -o " + (dir_ / "out.vdb").string(),
                            what + "; timeout 120 ");
    EXPECT_TRUE(r.exitCode == 0 || r.exitCode == 3)
        << what << ": exit " << r.exitCode << ": " << r.err;
    if (r.exitCode == 3) {
      EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << what << ": " << r.err;
      EXPECT_THAT(r.err, HasSubstr("out of memory while ")) << what;
      expectNoOutput();
    }
    fs::remove(dir_ / "out.vdb");
  }
  // And with room enough it is done.
  const CliResult r = run(threads + "deform --rig " + (dir_ / "ffd.json").string() + " " +
                              (dir_ / "in.vdb").string() + " -o " + (dir_ / "out.vdb").string(),
                          "ulimit -v 1500000; timeout 120 ");
  EXPECT_EQ(r.exitCode, 0) << r.err;
}

TEST_F(VolumeCliTest, UnknownSamplerIsAUsageError) {
  writeInput();
  write("twist.json", R"({"method": "twist", "origin": [0, 0, 0], "axis": [0, 0, 1], "rate": 1})");
  const CliResult r = deformVolume("--rig " + (dir_ / "twist.json").string() + " --sampler cubic");
  EXPECT_EQ(r.exitCode, 2);
  expectNoOutput();
}

}  // namespace
