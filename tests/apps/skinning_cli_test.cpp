// End-to-end tests of the "skinning" rig method of the spacewarp executable: deform agrees with
// the library for weights from a file (.csv, .npy) and from coordinates, in both modes, and bad
// rigs and weight files exit with code 3, a message naming the key, and no output.

#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <spacewarp/core/io/mesh_io.h>
#include <spacewarp/core/primitives.h>
#include <spacewarp/nonlinear/mls.h>
#include <spacewarp/nonlinear/shepard.h>
#include <spacewarp/nonlinear/skinning.h>
#include "apps/cli_test_util.h"

namespace fs = std::filesystem;
using namespace spacewarp;
using ::testing::HasSubstr;

namespace {

using ::spacewarp::test::BadRigTest;

class SkinningCliTest : public test::CliFixture {
 protected:
  SkinningCliTest() : test::CliFixture("spacewarp_skinning_cli_") {}

  // Writes dense weights (points × bones) as CSV with a header of column names.
  void writeCsv(const std::string& name, const std::vector<double>& rows, std::size_t bones) {
    std::ostringstream s;
    s.precision(17);
    for (std::size_t b = 0; b < bones; ++b) s << (b ? "," : "") << "v" << b;
    s << "\n";
    for (std::size_t i = 0; i < rows.size(); ++i) s << rows[i] << ((i + 1) % bones ? "," : "\n");
    write(name, s.str());
  }

  // Writes dense weights as NumPy .npy (float64, C order).
  void writeNpy(const std::string& name, const std::vector<double>& rows, std::size_t bones) {
    std::string header = "{'descr': '<f8', 'fortran_order': False, 'shape': (" +
                         std::to_string(rows.size() / bones) + ", " + std::to_string(bones) +
                         "), }";
    header.append(63 - (10 + header.size()) % 64, ' ');
    header += '\n';
    std::ofstream out(dir_ / name, std::ios::binary);
    out.write("\x93NUMPY\x01\x00", 8);
    const char length[2] = {char(header.size() & 0xff), char(header.size() >> 8)};
    out.write(length, 2);
    out << header;
    out.write(reinterpret_cast<const char*>(rows.data()),
              std::streamsize(rows.size() * sizeof(double)));
  }
};

// Three bones along x: the rest, a turn of 60° about x, a turn of 150° about x with a shift.
const std::string kBones =
    "[[[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]],"
    " [[1,0,0,0],[0,0.5,-0.8660254037844386,0],[0,0.8660254037844386,0.5,0],[0,0,0,1]],"
    " [[1,0,0,0.2],[0,-0.8660254037844386,-0.5,0],[0,0.5,-0.8660254037844386,0],[0,0,0,1]]]";

std::vector<Mat4> bones() {
  const double c = 0.8660254037844386;
  std::vector<Mat4> b(3, Mat4(1.0));
  b[1][1][1] = 0.5, b[1][2][1] = -c, b[1][1][2] = c, b[1][2][2] = 0.5;
  b[2][1][1] = -c, b[2][2][1] = -0.5, b[2][1][2] = 0.5, b[2][2][2] = -c, b[2][3][0] = 0.2;
  return b;
}

// Weights that blend the bones along x in [-1, 1].
std::vector<double> weightsOf(const std::vector<Vec3>& points) {
  std::vector<double> rows;
  for (const Vec3& p : points) {
    const double t = std::clamp((p.x + 1.0) / 2.0, 0.0, 1.0);
    rows.push_back((1 - t) * (1 - t));
    rows.push_back(2 * t * (1 - t));
    rows.push_back(t * t);
  }
  return rows;
}

TEST_F(SkinningCliTest, DeformWithAWeightsFileMatchesTheLibraryBitForBit) {
  const PolygonSoup model = writeCloud(Vec3(-1.0), Vec3(1.0), 400, 3);
  writeSoup(model, dir_ / "model.ply");
  const std::vector<double> rows = weightsOf(model.positions);
  writeCsv("weights.csv", rows, 3);
  writeNpy("weights.npy", rows, 3);
  // The model itself, and other points (nearest-vertex weights).
  const PolygonSoup other = writeCloud(Vec3(-1.2), Vec3(1.2), 300, 4);
  for (const char* file : {"weights.csv", "weights.npy"}) {
    for (const char* mode : {"lbs", "dqs"}) {
      write("rig.json", std::string(R"({"method": "skinning", "mode": ")") + mode +
                            R"(", "bones": )" + kBones + R"(, "weights": ")" + file +
                            R"(", "model": "model.ply"})");
      const SkinningWarp warp(bones(), model.positions, sparseSkinningWeights(rows, 3),
                              skinningModeFromName(mode));
      for (const PolygonSoup* input : {&model, &other}) {
        writeSoup(*input, dir_ / "cloud.ply");
        const test::CliResult r = deform("rig.json");
        ASSERT_EQ(r.exitCode, 0) << file << " " << mode << ": " << r.err;
        const PolygonSoup out = readSoup(dir_ / "out.ply");
        ASSERT_EQ(out.size(), input->size());
        for (std::size_t i = 0; i < out.size(); ++i)
          ASSERT_EQ(out.positions[i], warp.apply(input->positions[i])) << file << " " << mode;
      }
    }
  }
}

// Shepard's weights need no affine reproduction: three bones, three handles, all weights kept
// (non-negative, so DQS blends without sign flips).
TEST_F(SkinningCliTest, IdwCoordinatesSkinWithAnyNumberOfBones) {
  const std::vector<Vec3> handles = {{-1, 0, 0}, {0, 0.3, 0.1}, {1, -0.2, 0.4}};
  const PolygonSoup cloud = writeCloud(Vec3(-1.0), Vec3(1.0), 300, 7);
  for (const char* mode : {"lbs", "dqs"}) {
    write("rig.json", std::string(R"({"method": "skinning", "mode": ")") + mode +
                          R"(", "bones": )" + kBones + R"(, "handles": )" +
                          test::jsonPoints(handles) + R"(, "coordinates": "idw"})");
    const SkinningWarp warp(bones(), std::make_shared<ShepardCoordinates>(handles),
                            {skinningModeFromName(mode), 0});
    const test::CliResult r = deform("rig.json");
    ASSERT_EQ(r.exitCode, 0) << mode << ": " << r.err;
    const PolygonSoup out = readSoup(dir_ / "out.ply");
    ASSERT_EQ(out.size(), cloud.size());
    for (std::size_t i = 0; i < out.size(); ++i)
      ASSERT_EQ(out.positions[i], warp.apply(cloud.positions[i])) << mode << " point " << i;
    // At a handle the point follows its bone exactly (Shepard interpolates).
    EXPECT_LE(glm::length(warp.apply(handles[1]) - Vec3(bones()[1] * glm::dvec4(handles[1], 1.0))),
              1e-12);
  }
}

TEST_F(SkinningCliTest, DeformWithWeightsFromCoordinatesMatchesTheLibrary) {
  const std::vector<Vec3> handles = {{-1, 0, 0}, {0, 0.3, 0.1}, {1, -0.2, 0.4}, {0.2, 1, -0.5}};
  const std::string handlesJson = test::jsonPoints(handles);
  const std::string fourBones =
      kBones.substr(0, kBones.size() - 1) + ", [[1,0,0,0],[0,1,0,0.1],[0,0,1,0],[0,0,0,1]]]";
  std::vector<Mat4> four = bones();
  four.push_back(Mat4(1.0));
  four[3][3][1] = 0.1;
  const PolygonSoup cloud = writeCloud(Vec3(-1.0), Vec3(1.0), 300, 5);
  // An OBJ soup too: the generic path of every soup format.
  writeSoup(cloud, dir_ / "cloud.obj");
  for (const char* mode : {"lbs", "dqs"}) {
    write("rig.json", std::string(R"({"method": "skinning", "mode": ")") + mode +
                          R"(", "influences": 3, "bones": )" + fourBones + R"(, "handles": )" +
                          handlesJson + R"(, "coordinates": "mls-affine"})");
    const SkinningWarp warp(four, std::make_shared<MlsAffineCoordinates>(handles),
                            {skinningModeFromName(mode), 3});
    const test::CliResult r = deform("rig.json");
    ASSERT_EQ(r.exitCode, 0) << mode << ": " << r.err;
    const PolygonSoup out = readSoup(dir_ / "out.ply");
    for (std::size_t i = 0; i < out.size(); ++i)
      ASSERT_EQ(out.positions[i], warp.apply(cloud.positions[i])) << mode << " point " << i;
    const test::CliResult obj =
        run("deform --rig " + (dir_ / "rig.json").string() + " " + (dir_ / "cloud.obj").string() +
            " -o " + (dir_ / "out.obj").string());
    ASSERT_EQ(obj.exitCode, 0) << obj.err;
    const PolygonSoup outObj = readSoup(dir_ / "out.obj");
    for (std::size_t i = 0; i < outObj.size(); ++i)
      ASSERT_LE(glm::length(outObj.positions[i] - warp.apply(cloud.positions[i])), 1e-12);
  }
  // The default coordinates are RBF's; `spacewarp info` describes the rig.
  write("rig.json",
        R"({"method": "skinning", "bones": )" + fourBones + R"(, "handles": )" + handlesJson + "}");
  ASSERT_EQ(deform("rig.json").exitCode, 0);
  const test::CliResult info = run("info " + (dir_ / "rig.json").string());
  EXPECT_EQ(info.exitCode, 0) << info.err;
  EXPECT_THAT(info.out, HasSubstr("skinning (linear blend)"));
  EXPECT_THAT(info.out, HasSubstr("rbf coordinates of 4 handles"));
  EXPECT_THAT(info.out, HasSubstr("0 per point (0: all)"));  // the handles' default
}

// A .npy's shape is checked from its header, against the file's size and against the model and
// bones, before its data is allocated or read; Fortran order is read transposed.
TEST_F(SkinningCliTest, NpyShapesAreCheckedBeforeReadingAndFortranOrderIsRead) {
  const PolygonSoup model = writeCloud(Vec3(-1.0), Vec3(1.0), 6, 6);
  writeSoup(model, dir_ / "model.ply");
  write("rig.json", R"({"method": "skinning", "bones": )" + kBones +
                        R"(, "weights": "w.npy", "model": "model.ply"})");
  const auto npy = [&](const std::string& shape, bool fortran, const std::vector<double>& data) {
    std::string header =
        "{'descr': '<f8', 'fortran_order': " + std::string(fortran ? "True" : "False") +
        ", 'shape': (" + shape + "), }";
    header.append(63 - (10 + header.size()) % 64, ' ');
    header += '\n';
    std::ofstream out(dir_ / "w.npy", std::ios::binary);
    out.write("\x93NUMPY\x01\x00", 8);
    const char length[2] = {char(header.size() & 0xff), char(header.size() >> 8)};
    out.write(length, 2);
    out << header;
    out.write(reinterpret_cast<const char*>(data.data()),
              std::streamsize(data.size() * sizeof(double)));
  };
  const auto expectRefused = [&](const std::string& message) {
    const test::CliResult r = deform("rig.json");
    EXPECT_EQ(r.exitCode, 3) << r.err;
    EXPECT_THAT(r.err, HasSubstr("rig.json: 'weights'"));
    EXPECT_THAT(r.err, HasSubstr(message));
    EXPECT_FALSE(fs::exists(dir_ / "out.ply"));
  };
  // Shapes far larger than the file: refused by the header (reading them would take terabytes).
  npy("4000000000000, 3", false, std::vector<double>(18, 0.5));
  expectRefused("the .npy shape (4000000000000, 3) is too large for the file");
  npy("6, 40000000", false, std::vector<double>(18, 0.5));
  expectRefused("is too large for the file");
  // A shape that fits its file but not the rig: named from the header.
  npy("6, 2", false, std::vector<double>(12, 0.5));
  expectRefused("has 2 columns, but there are 3 bones");
  npy("3, 3", false, std::vector<double>(9, 0.5));
  expectRefused("has 3 rows, but the model has 6 vertices");
  // Fortran order: the same weights, column-major, deform alike.
  const std::vector<double> rows = weightsOf(model.positions);
  std::vector<double> columns(rows.size());
  for (std::size_t i = 0; i < 6; ++i)
    for (std::size_t b = 0; b < 3; ++b) columns[b * 6 + i] = rows[i * 3 + b];
  writeSoup(model, dir_ / "cloud.ply");
  npy("6, 3", true, columns);
  ASSERT_EQ(deform("rig.json").exitCode, 0);
  const PolygonSoup fromFortran = readSoup(dir_ / "out.ply");
  npy("6, 3", false, rows);
  ASSERT_EQ(deform("rig.json").exitCode, 0);
  EXPECT_EQ(readSoup(dir_ / "out.ply").positions, fromFortran.positions);
}

// Bad weight files: exit 3, the rig, key and file named, nothing written.
TEST_F(SkinningCliTest, BadWeightFilesAreRefusedByName) {
  const PolygonSoup model = writeCloud(Vec3(-1.0), Vec3(1.0), 5, 6);
  writeSoup(model, dir_ / "model.ply");
  const std::string rig = R"({"method": "skinning", "bones": )" + kBones +
                          R"(, "weights": "w.csv", "model": "model.ply"})";
  write("rig.json", rig);
  const auto expectRefused = [&](const std::string& csv, const std::string& message) {
    write("w.csv", csv);
    const test::CliResult r = deform("rig.json");
    EXPECT_EQ(r.exitCode, 3) << csv << "\n" << r.err;
    EXPECT_THAT(r.err, HasSubstr("rig.json: 'weights'")) << csv;
    EXPECT_THAT(r.err, HasSubstr(message)) << csv;
    EXPECT_FALSE(fs::exists(dir_ / "out.ply"));
  };
  expectRefused("1,0,0\n1,0,0\n1,0,0\n1,0,0\n", "has 4 rows, but the model has 5 vertices");
  expectRefused("1,0\n1,0\n1,0\n1,0\n1,0\n", "has 2 columns, but there are 3 bones");
  expectRefused("1,0,0\n1,0,0\nnan,0,0\n1,0,0\n1,0,0\n",
                "point 2 has a non-finite weight for bone 0");
  expectRefused("1,0,0\n1,0,0\n1,0,0\n0.5,-0.5,0\n1,0,0\n", "weights of point 3 sum to 0");
  expectRefused("1,0,0\n1,0,0\n1,x,0\n", "line 3 is not a row of numbers");
  expectRefused("1,0,0\n1,0\n", "line 2 has 2 values");
  fs::remove(dir_ / "w.csv");
  const test::CliResult missing = deform("rig.json");
  EXPECT_EQ(missing.exitCode, 3) << missing.err;
  EXPECT_THAT(missing.err, HasSubstr("w.csv: cannot open"));
}

const std::string kHandles = "[[0,0,0],[1,0,0],[0,1,0]]";

INSTANTIATE_TEST_SUITE_P(
    SkinningRigs, BadRigTest,
    ::testing::Values(
        test::BadRig{"UnknownMode",
                     R"({"method": "skinning", "mode": "slerp", "bones": )" + kBones +
                         R"(, "handles": )" + kHandles + "}",
                     3, "'mode' skinning mode 'slerp' is not one of: lbs, dqs"},
        test::BadRig{
            "NonRigidBoneForDqs",
            R"({"method": "skinning", "mode": "dqs", "bones": [[[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]],
                       [[2,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]], [[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]],
                       "handles": )" +
                kHandles + "}",
            3, "'bones[1]' dual-quaternion skinning needs a rigid bone"},
        test::BadRig{
            "ShortBone",
            R"({"method": "skinning", "bones": [[[1,0,0,0],[0,1,0,0],[0,0,1,0]]], "handles": [[0,0,0]]})",
            3, "'bones[0]' must be an array of 4 rows"},
        test::BadRig{
            "NonFiniteBoneEntry",
            R"({"method": "skinning", "bones": [[[1,0,0,0],[0,1,0,0],[0,0,1,"a"],[0,0,0,1]]], "handles": [[0,0,0]]})",
            3, "'bones[0][2]' must contain finite numbers only"},
        test::BadRig{
            "HandleCount",
            R"({"method": "skinning", "bones": )" + kBones + R"(, "handles": [[0,0,0],[1,0,0]]})",
            3, "'handles' must have one point per bone (3), not 2"},
        test::BadRig{"UnknownCoordinates",
                     R"({"method": "skinning", "bones": )" + kBones + R"(, "handles": )" +
                         kHandles + R"(, "coordinates": "harmonic"})",
                     3, "'coordinates' 'harmonic' is not one of: idw, mls-affine, rbf"},
        test::BadRig{
            "TooFewHandlesForTheCoordinates",
            R"({"method": "skinning", "bones": )" + kBones + R"(, "handles": )" + kHandles + "}", 3,
            "'handles' the rbf coordinates of the handles need at least 4 handles not "
            "in one plane (so at least 4 bones)"},
        test::BadRig{"NegativeInfluences",
                     R"({"method": "skinning", "influences": -1, "bones": )" + kBones +
                         R"(, "handles": )" + kHandles + "}",
                     3, "'influences' must be an integer >= 0"},
        test::BadRig{"WeightsWithoutModel",
                     R"({"method": "skinning", "bones": )" + kBones + R"(, "weights": "w.csv"})", 3,
                     "'model' is missing"},
        test::BadRig{"WeightsAndHandles",
                     R"({"method": "skinning", "bones": )" + kBones + R"(, "handles": )" +
                         kHandles + R"(, "weights": "w.csv", "model": "m.ply"})",
                     3, "'handles' is not read when 'weights' are given"}),
    ::spacewarp::test::badRigName);

}  // namespace
