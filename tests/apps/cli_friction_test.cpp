// End-to-end tests of what a user meets first: which input and output files go together
// (checked before any work), options that do not apply to the input being usage errors,
// --version, --help and --threads, the summary line of `deform`, and `info` on rigs.

#include <sys/stat.h>

#include <algorithm>
#include <filesystem>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <spacewarp/core/io/mesh_io.h>
#include <spacewarp/core/primitives.h>
#include "apps/cli_test_util.h"

namespace spacewarp {
namespace {

namespace fs = std::filesystem;
using test::CliResult;
using ::testing::HasSubstr;

using ::spacewarp::test::kSanitized;

// Moves every point by (5, 0, 0).
constexpr const char* kShift =
    R"({"method": "affine", "matrix": [[1,0,0,5],[0,1,0,0],[0,0,1,0],[0,0,0,1]]})";

class CliFrictionTest : public test::CliFixture {
 protected:
  CliFrictionTest() : CliFixture("spacewarp_friction_") {}

  std::string path(const std::string& name) const { return (dir_ / name).string(); }

  // Fails the test unless `r` is one line on stderr with exit `code` containing every word.
  static void expectOneLineError(const CliResult& r, int code,
                                 const std::vector<std::string>& words) {
    EXPECT_EQ(r.exitCode, code) << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    for (const std::string& w : words) EXPECT_THAT(r.err, HasSubstr(w));
  }

  // Only the inputs the test wrote are in the folder: no output, no temporary.
  void expectOnly(const std::vector<std::string>& names) const {
    std::vector<std::string> found;
    for (const auto& entry : fs::directory_iterator(dir_))
      found.push_back(entry.path().filename().string());
    EXPECT_THAT(found, ::testing::UnorderedElementsAreArray(names));
  }
};

TEST_F(CliFrictionTest, GeometryConvertsBetweenEveryFormatKeepingPointsAndFaces) {
  const PolygonSoup box = makeBoxSurface(Vec3(-1), Vec3(1), {2, 1, 1});
  const PolygonSoup cloud = writeCloud(Vec3(-1), Vec3(1), 40, 7);
  write("shift.json", kShift);
  for (const std::string from : {"obj", "off", "ply"}) {
    writeSoup(box, dir_ / ("box." + from));
    for (const std::string to : {"obj", "off", "ply"}) {
      for (const auto& [input, original] :
           {std::pair{"box." + from, &box}, std::pair{std::string("cloud.ply"), &cloud}}) {
        const std::string output = path("out." + to);
        const CliResult r =
            run("deform --rig " + path("shift.json") + " " + path(input) + " -o " + output);
        ASSERT_EQ(r.exitCode, 0) << input << " -> " << output << ": " << r.err;
        const PolygonSoup out = readSoup(output);
        ASSERT_EQ(out.size(), original->size()) << input << " -> " << output;
        EXPECT_EQ(out.faceIndices, original->faceIndices) << input << " -> " << output;
        EXPECT_EQ(out.faceOffsets, original->faceOffsets) << input << " -> " << output;
        for (std::size_t i = 0; i < out.size(); ++i)
          ASSERT_EQ(out.positions[i], original->positions[i] + Vec3(5, 0, 0)) << input << " " << i;
      }
    }
  }
}

TEST_F(CliFrictionTest, VolumeAndGeometryDoNotMixAndNothingIsDoneFirst) {
  writeCloud(Vec3(-1), Vec3(1), 10, 1);
  write("in.vdb", "not read: the command line alone is wrong");
  // The rig does not exist: reading it would be an exit-3 error naming it, so these failures
  // show that nothing was read or solved before the usage error.
  const std::string rig = "deform --rig " + path("missing.json") + " ";
  for (const auto& [input, output] :
       std::vector<std::pair<std::string, std::string>>{{"in.vdb", "out.obj"},
                                                        {"in.vdb", "out.ply"},
                                                        {"in.vdb", "out.OFF"},
                                                        {"cloud.ply", "out.vdb"},
                                                        {"cloud.ply", "out.VDB"}}) {
    const CliResult r = run(rig + path(input) + " -o " + path(output));
    expectOneLineError(r, 2, {path(input), path(output)});
    EXPECT_THAT(r.err, ::testing::Not(HasSubstr("missing.json")));
  }
  expectOnly({"cloud.ply", "in.vdb"});
}

TEST_F(CliFrictionTest, UnknownExtensionsExit3NamingTheFileBeforeAnyWork) {
  writeCloud(Vec3(-1), Vec3(1), 10, 1);
  write("model.stl", "solid x\n");
  const std::string rig = "deform --rig " + path("missing.json") + " ";
  for (const auto& [input, output, culprit] :
       std::vector<std::tuple<std::string, std::string, std::string>>{
           {"model.stl", "out.ply", "model.stl"},
           {"cloud.ply", "out.stl", "out.stl"},
           {"cloud.ply", "out", "out"}}) {
    const CliResult r = run(rig + path(input) + " -o " + path(output));
    expectOneLineError(r, 3, {path(culprit), ".vdb"});
    EXPECT_THAT(r.err, ::testing::Not(HasSubstr("missing.json")));
  }
  expectOnly({"cloud.ply", "model.stl"});
}

TEST_F(CliFrictionTest, BinaryAndEndlessInputsAreRefusedEarly) {
  // The text readers used to read their whole input before looking at it: /dev/zero or a FIFO
  // fed forever grew until memory ran out. Each run here has a minute and (unless sanitizers,
  // which reserve terabytes of address space, are on) 1.5 GB of address space.
  const std::string limits = kSanitized ? "timeout 60 " : "ulimit -v 1500000; timeout 60 ";
  write("twist.json", R"({"method": "twist", "origin": [0,0,0], "axis": [0,0,1], "rate": 1})");
  const std::string deform = "deform --rig " + path("twist.json") + " ";
  for (const std::string extension : {"obj", "off", "ply"}) {
    SCOPED_TRACE(extension);
    const std::string zeros = path("zeros." + extension);
    write("zeros." + extension, std::string(1 << 22, '\0'));
    CliResult r = run(deform + zeros + " -o " + path("out.obj"), limits);
    expectOneLineError(r, 3, {zeros + ":1: unexpected NUL byte (byte offset 0): not a text file"});

    const std::string device = path("device." + extension);
    fs::create_symlink("/dev/zero", device);
    r = run(deform + device + " -o " + path("out.obj"), limits);
    expectOneLineError(r, 3, {device + ":1: unexpected NUL byte (byte offset 0)"});

    // A FIFO fed one endless line (its writer ends with the reader, or after a minute).
    const std::string fifo = path("fifo." + extension);
    ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
    r = run(deform + fifo + " -o " + path("out.obj"),
            "timeout 60 sh -c \"tr '\\\\0' 7 < /dev/zero > " + fifo + "\" 2>/dev/null & " + limits);
    expectOneLineError(r, 3, {fifo + ":1: line too long"});
  }
  // /dev/zero itself has no extension to say what it holds.
  expectOneLineError(run(deform + "/dev/zero -o " + path("out.obj"), limits), 3,
                     {"/dev/zero: no file extension"});
  EXPECT_FALSE(fs::exists(dir_ / "out.obj"));
}

TEST_F(CliFrictionTest, OutputMayBeTheInputItself) {
  const PolygonSoup cloud = writeCloud(Vec3(-1), Vec3(1), 25, 2);
  write("shift.json", kShift);
  const CliResult r = run("deform --rig " + path("shift.json") + " " + path("cloud.ply") + " -o " +
                          path("cloud.ply"));
  ASSERT_EQ(r.exitCode, 0) << r.err;
  const PolygonSoup out = readSoup(dir_ / "cloud.ply");
  ASSERT_EQ(out.size(), cloud.size());
  for (std::size_t i = 0; i < out.size(); ++i)
    EXPECT_EQ(out.positions[i], cloud.positions[i] + Vec3(5, 0, 0));
  expectOnly({"cloud.ply", "shift.json"});
}

// A command with an option that does not apply, and the option it must name.
struct Misfit {
  const char* name;
  const char* args;  // {dir} stands for the test's folder
  const char* option;
};

class MisfitOptionTest : public CliFrictionTest, public ::testing::WithParamInterface<Misfit> {};

TEST_P(MisfitOptionTest, IsAUsageErrorNamingTheOption) {
  writeSoup(makeBoxSurface(Vec3(-1), Vec3(1), {1, 1, 1}), dir_ / "cage.obj");
  writeCloud(Vec3(-0.5), Vec3(0.5), 10, 1);
  write("shift.json", kShift);
  write("in.vdb", "never read");
  std::string args = GetParam().args;
  for (std::size_t at; (at = args.find("{dir}")) != std::string::npos;)
    args.replace(at, 5, dir_.string());
  const CliResult r = run(args);
  expectOneLineError(r, 2, {GetParam().option});
  expectOnly({"cage.obj", "cloud.ply", "shift.json", "in.vdb"});
}

// The harmonic options exist only in builds with TetGen.
std::vector<Misfit> misfits() {
  return {
      Misfit{"AsciiWithObjOutput",
             "deform --rig {dir}/shift.json {dir}/cloud.ply -o {dir}/o.obj --ascii", "--ascii"},
      Misfit{"AsciiWithVdbOutput",
             "deform --rig {dir}/shift.json {dir}/in.vdb -o {dir}/o.vdb --ascii", "--ascii"},
      Misfit{"SamplerWithACloud",
             "deform --rig {dir}/shift.json {dir}/cloud.ply -o {dir}/o.ply --sampler triquadratic",
             "--sampler"},
      Misfit{"ConserveMassWithACloud",
             "deform --rig {dir}/shift.json {dir}/cloud.ply -o {dir}/o.ply --conserve-mass",
             "--conserve-mass"},
#ifdef SPACEWARP_HAVE_HARMONIC
      Misfit{"TetsWithMvc",
             "deform --method mvc --cage {dir}/cage.obj --pose {dir}/cage.obj {dir}/cloud.ply -o "
             "{dir}/o.ply --tets 1000",
             "--tets"},
      Misfit{"OutsideWithARig",
             "deform --rig {dir}/shift.json {dir}/cloud.ply -o {dir}/o.ply --outside nearest",
             "--outside"},
      Misfit{"CacheWithGreenWeights",
             "weights --method green --cage {dir}/cage.obj {dir}/cloud.ply -o {dir}/w.csv "
             "--harmonic-cache {dir}/h.bin",
             "--harmonic-cache"},
#endif
  };
}

INSTANTIATE_TEST_SUITE_P(Options, MisfitOptionTest, ::testing::ValuesIn(misfits()),
                         [](const auto& info) { return std::string(info.param.name); });

TEST_F(CliFrictionTest, AsciiAppliesToPlyOutput) {
  writeCloud(Vec3(-1), Vec3(1), 10, 1);
  write("shift.json", kShift);
  const CliResult r = run("deform --rig " + path("shift.json") + " " + path("cloud.ply") + " -o " +
                          path("o.ply") + " --ascii");
  ASSERT_EQ(r.exitCode, 0) << r.err;
  EXPECT_THAT(test::slurp(dir_ / "o.ply"), HasSubstr("format ascii 1.0"));
}

TEST_F(CliFrictionTest, VersionPrintsTheProjectVersion) {
  const CliResult r = run("--version");
  EXPECT_EQ(r.exitCode, 0) << r.err;
  EXPECT_EQ(r.out, std::string("spacewarp ") + SPACEWARP_VERSION + "\n");
}

TEST_F(CliFrictionTest, EverySubcommandsHelpListsTheGlobalOptions) {
  for (const std::string command : {"info", "deform", "weights", "compare", "demo"}) {
    const CliResult r = run(command + " --help");
    EXPECT_EQ(r.exitCode, 0) << command;
    EXPECT_THAT(r.out, HasSubstr("--threads")) << command;
    EXPECT_THAT(r.out, HasSubstr("--quiet")) << command;
  }
}

TEST_F(CliFrictionTest, ThreadsOutOfRangeNamesTheRange) {
  writeSoup(makeBoxSurface(Vec3(-1), Vec3(1), {1, 1, 1}), dir_ / "box.obj");
  for (const std::string args :
       {"--threads -1 info ", "info --threads 1.5 ", "info --threads x "}) {
    const CliResult r = run(args + path("box.obj"));
    expectOneLineError(r, 2, {"--threads", "0 (every core) or 1.."});
  }
  // More threads than can run: a warning, and the work is done.
  const CliResult many = run("--threads 100000 info " + path("box.obj"));
  EXPECT_EQ(many.exitCode, 0) << many.err;
  EXPECT_THAT(many.err, HasSubstr("warning: --threads 100000"));
  EXPECT_THAT(many.out, HasSubstr("vertices:   8"));
}

// What the input holds but spacewarp does not keep is one counted warning naming it; the
// output is still written.
TEST_F(CliFrictionTest, WhatTheInputLosesIsOneWarning) {
  write("shift.json", kShift);
  write("lines.obj", "v 0 0 0 1 0 0\nv 1 0 0 0 1 0\nv 0 1 0 0 0 1\nf 1 2 3\nl 1 2\np 3\n");
  const CliResult r =
      run("deform --rig " + path("shift.json") + " " + path("lines.obj") + " -o " + path("o.obj"));
  ASSERT_EQ(r.exitCode, 0) << r.err;
  EXPECT_EQ(r.err, "spacewarp: warning: " + path("lines.obj") +
                       ": spacewarp does not keep the input's vertex colours; line elements (l); "
                       "point elements (p); they are not in the output\n");
  EXPECT_THAT(r.out, HasSubstr(", 1 warning\n"));
  EXPECT_TRUE(fs::exists(dir_ / "o.obj"));
}

TEST_F(CliFrictionTest, DeformEndsWithASummaryUnlessQuiet) {
  writeSoup(makeBoxSurface(Vec3(-1), Vec3(1), {1, 1, 1}), dir_ / "box.obj");
  writeCloud(Vec3(-1), Vec3(1), 1234, 1);
  write("shift.json", kShift);
  const std::string rig = "deform --rig " + path("shift.json") + " ";
  const CliResult soup = run(rig + path("box.obj") + " -o " + path("o.obj"));
  ASSERT_EQ(soup.exitCode, 0) << soup.err;
  EXPECT_THAT(soup.out,
              ::testing::MatchesRegex("deformed 8 points \\(6 faces\\) in [0-9.e-]+ s -> " +
                                      path("o.obj") + "\n"));
  const CliResult cloud = run(rig + path("cloud.ply") + " -o " + path("o.ply"));
  EXPECT_THAT(cloud.out, HasSubstr("deformed 1,234 points in "));
  const CliResult warned =
      run("--threads 100000 " + rig + path("cloud.ply") + " -o " + path("o.ply"));
  EXPECT_THAT(warned.out, HasSubstr("-> " + path("o.ply") + ", 1 warning\n"));
  const CliResult quiet = run(rig + path("cloud.ply") + " -o " + path("q.ply") + " -q");
  ASSERT_EQ(quiet.exitCode, 0) << quiet.err;
  EXPECT_EQ(quiet.out, "");
  EXPECT_TRUE(fs::exists(dir_ / "q.ply"));
}

TEST_F(CliFrictionTest, InfoChecksARigWithoutSolvingIt) {
  writeSoup(makeBoxSurface(Vec3(-1), Vec3(1), {2, 1, 1}), dir_ / "cage.obj");
  write("cage.json", R"({"method": "mvc", "cage": "cage.obj", "pose": "cage.obj"})");
  const CliResult cage = run("info " + path("cage.json"));
  ASSERT_EQ(cage.exitCode, 0) << cage.err;
  EXPECT_THAT(cage.out, HasSubstr("method:     mvc (mean-value coordinates)"));
  EXPECT_THAT(cage.out, HasSubstr("cage:       cage.obj (12 vertices, 10 faces)"));
  EXPECT_THAT(cage.out, HasSubstr("does:"));

  write("ffd.json", R"({"method": "ffd", "basis": "bspline", "origin": [0,0,0], "size": [1,1,1],
                        "resolution": [4, 5, 6],
                        "constraints": {"from": [[0.5, 0.5, 0.5]], "to": [[0.6, 0.5, 0.5]]}})");
  EXPECT_THAT(run("info " + path("ffd.json")).out, HasSubstr("[4,5,6] = 120 control points"));

  // A graph is checked but not solved: no "did not converge" warning of its solve (which
  // deform gives: no iteration allowed).
  write("graph.json", R"({"method": "compose", "warps": [)" + std::string(kShift) +
                          R"(, {"method": "graph", "spacing": 0.5, "maxIterations": 0,
                              "handles": [[0,0,0],[1,1,1]], "targets": [[0,0,0],[1,1,1.5]]}]})");
  const CliResult compose = run("info " + path("graph.json"));
  ASSERT_EQ(compose.exitCode, 0) << compose.err;
  EXPECT_EQ(compose.err, "");
  EXPECT_THAT(compose.out, HasSubstr("applies the 2 warps below in order"));
  EXPECT_THAT(compose.out, HasSubstr("warps[1]:\n  method:     graph"));
  EXPECT_THAT(compose.out, HasSubstr("  handles:    2, moved to as many targets"));
  EXPECT_THAT(
      run("deform --rig " + path("graph.json") + " " + path("cage.obj") + " -o " + path("o.obj"))
          .err,
      HasSubstr("did not converge"));

  // What deform refuses before solving, info refuses too: here a graph too fine to build.
  write("fine.json", R"({"method": "graph", "spacing": 1e-6, "handles": [[0,0,0],[1,1,1]],
                         "targets": [[0,0,0],[1,1,1]]})");
  expectOneLineError(run("info " + path("fine.json")), 3,
                     {path("fine.json"), "'spacing' gives more than 2,000,000 grid nodes"});

  write("bad.json", R"({"method": "warp9"})");
  expectOneLineError(run("info " + path("bad.json")), 3, {path("bad.json"), "warp9"});
}

}  // namespace
}  // namespace spacewarp
