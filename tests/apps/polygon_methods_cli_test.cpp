// End-to-end tests of the polygon and convex cage methods (qmvc, qgc, wachspress,
// discrete-harmonic) in the CLI: deform by --method and by a rig gives the same bytes, weights
// are the library's bit for bit (rows summing to 1), compare's default set depends on the cage
// (wachspress only on a convex cage, discrete-harmonic only on a convex cage of triangles), and a
// concave cage with a convex method, or --outside with a method that has no outside policy, is
// refused with the right exit code.

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <spacewarp/coords/cage.h>
#include <spacewarp/core/io/mesh_io.h>
#include <spacewarp/core/primitives.h>
#include <spacewarp/rig/cage_rig.h>
#include "apps/cli_test_util.h"
#include "coords/convex_test_shapes.h"
#include "coords/coords_test_shapes.h"

namespace spacewarp {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using test::CliResult;
using ::testing::HasSubstr;

const char* const kNewMethods[] = {"qmvc", "qgc", "wachspress", "discrete-harmonic"};

bool needsConvex(const std::string& method) {
  return method == "wachspress" || method == "discrete-harmonic";
}

// The cage each method is tested on: discrete-harmonic takes convex cages of triangles only.
std::string cageFor(const std::string& method) {
  if (method == "discrete-harmonic") return "simplicial";
  return method == "wachspress" ? "convex" : "concave";
}

class PolygonMethodsTest : public test::CliFixture {
 protected:
  PolygonMethodsTest() : CliFixture("spacewarp_polygon_methods_") {}

  void SetUp() override {
    CliFixture::SetUp();
    // Convex: the cube of 6 quads. Concave: the box pinched at its waist, 10 quads. Simplicial:
    // the octahedron |x| + |y| + |z| <= 2, 8 triangles.
    writeCage("convex", makeBoxSurface(Vec3(-1.0), Vec3(1.0), {1, 1, 1}));
    writeCage("concave", test::pinchedBox(0.6));
    PolygonSoup octahedron = test::octahedron();
    for (Vec3& p : octahedron.positions) p *= 2.0;
    writeCage("simplicial", octahedron);
    writeCloud(Vec3(-0.55), Vec3(0.55), 400, 3);  // inside the three cages
  }

  // name.obj and its pose name_pose.obj (every vertex moved differently).
  void writeCage(const std::string& name, PolygonSoup soup) {
    writeSoup(soup, dir_ / (name + ".obj"));
    for (std::size_t i = 0; i < soup.size(); ++i) {
      const double t = static_cast<double>(i);
      soup.positions[i] += 0.15 * Vec3(std::sin(t), std::cos(2.0 * t), std::sin(3.0 * t));
    }
    writeSoup(soup, dir_ / (name + "_pose.obj"));
  }

  std::string cagePath(const std::string& name) const { return (dir_ / (name + ".obj")).string(); }

  CliResult deformByMethod(const std::string& method, const std::string& cage,
                           const std::string& output) {
    return run("deform --method " + method + " --cage " + cagePath(cage) + " --pose " +
               (dir_ / (cage + "_pose.obj")).string() + " " + (dir_ / "cloud.ply").string() +
               " -o " + (dir_ / output).string());
  }

  CliResult compare(const std::string& cage, const std::string& args) {
    return run("compare --cage " + cagePath(cage) + " --slice z=0.1 --resolution 16 --samples 50 " +
               args + " -o " + (dir_ / "out").string());
  }
};

TEST_F(PolygonMethodsTest, DeformByMethodAndByRigWriteTheSameBytes) {
  for (const std::string method : kNewMethods) {
    const std::string cage = cageFor(method);
    const CliResult byMethod = deformByMethod(method, cage, "by_method.ply");
    ASSERT_EQ(byMethod.exitCode, 0) << method << ": " << byMethod.err;
    write("rig.json",
          json{{"method", method}, {"cage", cage + ".obj"}, {"pose", cage + "_pose.obj"}}.dump());
    const CliResult byRig =
        run("deform --rig " + (dir_ / "rig.json").string() + " " + (dir_ / "cloud.ply").string() +
            " -o " + (dir_ / "by_rig.ply").string());
    ASSERT_EQ(byRig.exitCode, 0) << method << ": " << byRig.err;
    const std::string a = test::slurp(dir_ / "by_method.ply");
    EXPECT_FALSE(a.empty()) << method;
    EXPECT_EQ(a, test::slurp(dir_ / "by_rig.ply")) << method;
    EXPECT_NE(a, test::slurp(dir_ / "cloud.ply")) << method << ": the pose moved nothing";
  }
}

// The weights CLI writes the library's rows bit for bit; the vertex columns of the methods
// with linear precision sum to 1 (qgc: its vertex columns too, at rest, reproduce the point with
// its face columns; only the partition of unity of the vertex columns is asserted).
TEST_F(PolygonMethodsTest, WeightsAreTheLibrarysAndRowsSumToOne) {
  const PointSet cloud = readSoup(dir_ / "cloud.ply");
  for (const std::string method : kNewMethods) {
    const std::string cage = cageFor(method);
    const CliResult r = run("weights --method " + method + " --cage " + cagePath(cage) + " " +
                            (dir_ / "cloud.ply").string() + " -o " + (dir_ / "w.npy").string());
    ASSERT_EQ(r.exitCode, 0) << method << ": " << r.err;
    const test::Npy npy = test::readNpy(dir_ / "w.npy");
    const auto rest = std::make_shared<const Cage>(Cage::fromFile(cagePath(cage)));
    const auto coordinates = cageCoordinates(method, rest);
    ASSERT_EQ(npy.rows, cloud.size()) << method;
    ASSERT_EQ(npy.columns, coordinates->columnCount()) << method;
    std::vector<double> rows(npy.rows * npy.columns);
    coordinates->weightsBatch(cloud.positions, rows);
    EXPECT_TRUE(std::equal(rows.begin(), rows.end(), npy.values.begin(),
                           [](double a, double b) { return std::memcmp(&a, &b, 8) == 0; }))
        << method << ": the CLI's weights differ from the library's";
    const std::size_t vertices = rest->vertexCount();
    for (std::size_t i = 0; i < npy.rows; ++i) {
      double sum = 0.0;
      for (std::size_t c = 0; c < vertices; ++c) sum += npy.values[i * npy.columns + c];
      ASSERT_NEAR(sum, 1.0, 1e-12) << method << " row " << i;
    }
  }
}

TEST_F(PolygonMethodsTest, CompareRunsEveryCageMethodOnAConvexCageOfTriangles) {
  const CliResult r = compare("simplicial", "--methods qmvc,qgc,wachspress,discrete-harmonic,mvc");
  ASSERT_EQ(r.exitCode, 0) << r.err;
  // The default set on the octahedron: every method, none left out (harmonic's tet mesh makes
  // it slow: its options keep it small).
  const CliResult all = compare("simplicial", "--tets 3000");
  ASSERT_EQ(all.exitCode, 0) << all.err;
  const json report = json::parse(test::slurp(dir_ / "out" / "report.json"));
  std::vector<std::string> names;
  for (const json& m : report["methods"]) names.push_back(m["name"].get<std::string>());
  for (const std::string& method : cageMethods())
    EXPECT_NE(std::find(names.begin(), names.end(), method), names.end()) << method;
  EXPECT_TRUE(report["leftOutMethods"].empty()) << report["leftOutMethods"].dump();
  EXPECT_TRUE(report["failedMethods"].empty()) << report["failedMethods"].dump();
}

TEST_F(PolygonMethodsTest, CompareLeavesTheConvexMethodsOutOfTheDefaultOnAConcaveCage) {
  const CliResult r = compare("concave", "--tets 3000");
  ASSERT_EQ(r.exitCode, 0) << r.err;
  const json report = json::parse(test::slurp(dir_ / "out" / "report.json"));
  std::vector<std::string> names, leftOut;
  for (const json& m : report["methods"]) names.push_back(m["name"].get<std::string>());
  for (const json& m : report["leftOutMethods"]) {
    leftOut.push_back(m["name"].get<std::string>());
    EXPECT_THAT(m["reason"].get<std::string>(), HasSubstr("edge"));
  }
  EXPECT_THAT(leftOut, ::testing::UnorderedElementsAre("wachspress", "discrete-harmonic"));
  for (const char* method : {"mvc", "green", "qmvc", "qgc"})
    EXPECT_NE(std::find(names.begin(), names.end(), method), names.end()) << method;
  for (const std::string& method : leftOut) {
    EXPECT_EQ(std::find(names.begin(), names.end(), method), names.end()) << method;
    // One line each says why.
    EXPECT_THAT(r.out, HasSubstr("leaving " + method + " out of the default methods"));
  }
}

// On the cube (convex, quads) the default set leaves discrete-harmonic out, with a note saying it
// needs triangle faces, and runs wachspress; asked for by name, it is bad input (3).
TEST_F(PolygonMethodsTest, CompareLeavesDiscreteHarmonicOutOfTheDefaultOnAConvexCageOfQuads) {
  const CliResult r = compare("convex", "--tets 3000");
  ASSERT_EQ(r.exitCode, 0) << r.err;
  const json report = json::parse(test::slurp(dir_ / "out" / "report.json"));
  std::vector<std::string> names;
  for (const json& m : report["methods"]) names.push_back(m["name"].get<std::string>());
  ASSERT_EQ(report["leftOutMethods"].size(), 1u) << report["leftOutMethods"].dump();
  const json& leftOut = report["leftOutMethods"][0];
  EXPECT_EQ(leftOut["name"], "discrete-harmonic");
  EXPECT_THAT(leftOut["reason"].get<std::string>(), HasSubstr("convex.obj"));
  EXPECT_THAT(leftOut["reason"].get<std::string>(), HasSubstr("triangle faces"));
  EXPECT_THAT(r.out, HasSubstr("leaving discrete-harmonic out of the default methods"));
  EXPECT_EQ(std::find(names.begin(), names.end(), "discrete-harmonic"), names.end());
  for (const char* method : {"wachspress", "mvc", "qmvc", "qgc"})
    EXPECT_NE(std::find(names.begin(), names.end(), method), names.end()) << method;
  fs::remove_all(dir_ / "out");
  const CliResult byName = compare("convex", "--methods wachspress,discrete-harmonic");
  EXPECT_EQ(byName.exitCode, 3) << byName.err;
  EXPECT_THAT(byName.err, HasSubstr("triangle faces"));
  EXPECT_FALSE(fs::exists(dir_ / "out"));
}

// Asked for by name, a convex method on a concave cage is bad input (3) naming the cage and an
// edge, and nothing is written: compare, deform and weights alike.
TEST_F(PolygonMethodsTest, AConvexMethodOnAConcaveCageExitsWith3NamingTheEdge) {
  const CliResult r = compare("concave", "--methods mvc,wachspress");
  EXPECT_EQ(r.exitCode, 3) << r.err;
  EXPECT_THAT(r.err, HasSubstr("concave.obj"));
  EXPECT_THAT(r.err, HasSubstr("edge"));
  EXPECT_FALSE(fs::exists(dir_ / "out"));
  const CliResult d = deformByMethod("discrete-harmonic", "concave", "out.ply");
  EXPECT_EQ(d.exitCode, 3) << d.err;
  EXPECT_THAT(d.err, HasSubstr("edge"));
  EXPECT_FALSE(fs::exists(dir_ / "out.ply"));
  const CliResult w = run("weights --method wachspress --cage " + cagePath("concave") + " " +
                          (dir_ / "cloud.ply").string() + " -o " + (dir_ / "w.csv").string());
  EXPECT_EQ(w.exitCode, 3) << w.err;
  EXPECT_FALSE(fs::exists(dir_ / "w.csv"));
}

TEST_F(PolygonMethodsTest, OutsideAppliesToTheMethodsWithAnOutsidePolicyOnly) {
  writeCloud(Vec3(-1.5), Vec3(1.5), 50, 4);  // some points outside the cube and the octahedron
  const auto deformOutside = [&](const std::string& method, const std::string& extra) {
    const std::string cage = needsConvex(method) ? cageFor(method) : "convex";
    return run("deform --method " + method + " --cage " + cagePath(cage) + " --pose " +
               (dir_ / (cage + "_pose.obj")).string() + " " + extra + " " +
               (dir_ / "cloud.ply").string() + " -o " + (dir_ / "out.ply").string());
  };
  for (const char* method : {"wachspress", "discrete-harmonic"}) {
    const CliResult refused = deformOutside(method, "");
    EXPECT_EQ(refused.exitCode, 3) << method << ": points outside refused";
    // The remedy as the CLI spells it, not as the C++ enum does.
    EXPECT_THAT(refused.err, HasSubstr("--outside nearest")) << method;
    const CliResult nearest = deformOutside(method, "--outside nearest");
    EXPECT_EQ(nearest.exitCode, 0) << method << ": " << nearest.err;
  }
  const CliResult qmvc = deformOutside("qmvc", "--outside nearest");
  EXPECT_EQ(qmvc.exitCode, 2);
  EXPECT_THAT(qmvc.err, HasSubstr("--outside applies to --method harmonic, wachspress or "
                                  "discrete-harmonic only, not to --method qmvc"));
}

// spacewarp info describes each new rig, with the outside policy of the convex ones.
TEST_F(PolygonMethodsTest, InfoDescribesTheNewRigs) {
  const std::pair<const char*, const char*> expected[] = {
      {"qmvc", "mean-value coordinates of polygon and quad faces"},
      {"qgc", "Green coordinates of triangle and quad faces"},
      {"wachspress", "Wachspress coordinates of a convex cage"},
      {"discrete-harmonic", "discrete harmonic coordinates of a convex cage of triangles"}};
  for (const auto& [method, what] : expected) {
    const std::string cage = cageFor(method);
    json rig = {{"method", method}, {"cage", cage + ".obj"}, {"pose", cage + "_pose.obj"}};
    if (needsConvex(method)) rig["outside"] = "nearest";
    const CliResult r = run("info " + write("rig.json", rig.dump()).string());
    ASSERT_EQ(r.exitCode, 0) << method << ": " << r.err;
    EXPECT_THAT(r.out, HasSubstr(std::string(method) + " (" + what + ")"));
    EXPECT_THAT(r.out, HasSubstr(cage + ".obj (" + std::to_string(readSoup(cagePath(cage)).size()) +
                                 " vertices"));
    if (needsConvex(method)) {
      EXPECT_THAT(r.out, HasSubstr("nearest")) << method;
    }
  }
}

}  // namespace
}  // namespace spacewarp
