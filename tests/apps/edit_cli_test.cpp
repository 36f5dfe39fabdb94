// End-to-end tests of `spacewarp edit`: every method reproduces the motions it must (a common
// translation; a common rigid motion for the ARAP methods), the output keeps the input's faces,
// the posed cage of cage-arap reproduces the edit through `spacewarp deform`, and every kind of
// bad input exits with its code, one line, and no output file.

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <sstream>
#include <string>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <glm/gtc/matrix_transform.hpp>

#include <spacewarp/core/io/mesh_io.h>
#include <spacewarp/core/primitives.h>
#include "apps/cli_test_util.h"

namespace fs = std::filesystem;
using namespace spacewarp;
using ::testing::HasSubstr;

namespace {

using test::CliResult;
using test::jsonPoints;

const Vec3 kLo(-0.5, -0.5, -2.0), kHi(0.5, 0.5, 2.0);

// The box bar with every face's corners written as vertices of their own (as flat-shaded
// exports write them): 1,800 soup vertices that weld into 452.
PolygonSoup duplicatedBar() {
  const PolygonSoup box = makeBoxSurface(kLo, kHi, {5, 5, 20});
  PolygonSoup soup;
  for (std::size_t p = 0; p < box.polygonCount(); ++p) {
    std::vector<std::uint32_t> corners;
    for (const std::uint32_t v : box.polygon(p)) {
      corners.push_back(static_cast<std::uint32_t>(soup.positions.size()));
      soup.positions.push_back(box.positions[v]);
    }
    soup.addPolygon(corners);
  }
  return soup;
}

// Soup vertices on the plane z = `z` (a cap of the bar, every copy).
std::vector<std::uint32_t> capVertices(const PolygonSoup& soup, double z) {
  std::vector<std::uint32_t> out;
  for (std::size_t v = 0; v < soup.size(); ++v)
    if (std::abs(soup.positions[v].z - z) < 1e-12) out.push_back(static_cast<std::uint32_t>(v));
  return out;
}

std::string jsonIndices(const std::vector<std::uint32_t>& indices) {
  std::string s = "[";
  for (std::size_t k = 0; k < indices.size(); ++k)
    s += (k ? ", " : "") + std::to_string(indices[k]);
  return s + "]";
}

// A region moved by `m`, written row-major as the handles file takes it.
std::string matrixRegion(const std::vector<std::uint32_t>& vertices, const Mat4& m) {
  std::ostringstream s;
  s.precision(17);
  s << R"({"vertices": )" << jsonIndices(vertices) << R"(, "matrix": [)";
  for (int r = 0; r < 4; ++r) {
    s << (r ? ", " : "") << "[";
    for (int c = 0; c < 4; ++c) s << (c ? ", " : "") << m[c][r];
    s << "]";
  }
  s << "]}";
  return s.str();
}

std::string handlesFile(const std::vector<std::string>& regions) {
  std::string s = R"({"handles": [)";
  for (std::size_t k = 0; k < regions.size(); ++k) s += (k ? ", " : "") + regions[k];
  return s + "]}";
}

Vec3 applied(const Mat4& m, const Vec3& p) { return Vec3(m * glm::dvec4(p, 1.0)); }

// A rotation about an oblique axis through the bar's middle, and a shift.
Mat4 rigidMotion() {
  Mat4 m = glm::translate(Mat4(1.0), Vec3(0.3, -0.2, 0.5));
  return glm::rotate(m, 0.7, glm::normalize(Vec3(1.0, 2.0, 0.5)));
}

class EditCliTest : public test::CliFixture {
 protected:
  EditCliTest() : CliFixture("spacewarp_edit_cli_") {}

  void SetUp() override {
    CliFixture::SetUp();
    bar_ = duplicatedBar();
    writeSoup(bar_, dir_ / "bar.obj");
    size_ = glm::length(kHi - kLo);
    // A cage around the bar (a box, 20 vertices).
    writeSoup(makeBoxSurface(kLo - 0.2, kHi + 0.2, {1, 1, 4}), dir_ / "cage.obj");
  }

  // Both caps moved by `bottom` and `top`.
  void writeCapHandles(const Mat4& bottom, const Mat4& top) {
    write("handles.json", handlesFile({matrixRegion(capVertices(bar_, kLo.z), bottom),
                                       matrixRegion(capVertices(bar_, kHi.z), top)}));
  }

  CliResult edit(const std::string& method, const std::string& extra = "") {
    const std::string cage =
        method == "cage-arap" ? " --cage " + (dir_ / "cage.obj").string() : std::string();
    return run("edit --method " + method + cage + " --handles " + (dir_ / "handles.json").string() +
               " " + (dir_ / "bar.obj").string() + " -o " + (dir_ / "out.obj").string() + " " +
               extra);
  }

  // The largest distance of the output's vertices from `expected` of the input's.
  template <class Expected>
  double maxError(const Expected& expected) {
    const PolygonSoup out = readSoup(dir_ / "out.obj");
    EXPECT_EQ(out.size(), bar_.size());
    double worst = 0.0;
    for (std::size_t v = 0; v < std::min(out.size(), bar_.size()); ++v)
      worst = std::max(worst, glm::length(out.positions[v] - expected(bar_.positions[v])));
    return worst;
  }

  // deformed.obj (the bar deformed by a posed cage or lattice) equals `edited` to 1e-6 of the
  // size, and the edit did something.
  void expectDeformedAsEdited(const PolygonSoup& edited) {
    const PolygonSoup deformed = readSoup(dir_ / "deformed.obj");
    ASSERT_EQ(deformed.size(), edited.size());
    double worst = 0.0, moved = 0.0;
    for (std::size_t v = 0; v < edited.size(); ++v) {
      worst = std::max(worst, glm::length(deformed.positions[v] - edited.positions[v]));
      moved = std::max(moved, glm::length(edited.positions[v] - bar_.positions[v]));
    }
    EXPECT_LE(worst, 1e-6 * size_);
    EXPECT_GT(moved, 0.1 * size_);
  }

  // A failed run: exit `code`, one line containing `message`, no output (nor temporary) left.
  void expectFailure(const CliResult& r, int code, const std::string& message) {
    EXPECT_EQ(r.exitCode, code) << r.err;
    EXPECT_THAT(r.err, HasSubstr(message));
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    EXPECT_FALSE(fs::exists(dir_ / "out.obj"));
    for (const auto& entry : fs::directory_iterator(dir_))
      EXPECT_THAT(entry.path().filename().string(), ::testing::Not(HasSubstr(".tmp")));
  }

  PolygonSoup bar_;
  double size_ = 0.0;
};

TEST_F(EditCliTest, EveryMethodReproducesACommonTranslation) {
  const Mat4 shift = glm::translate(Mat4(1.0), Vec3(0.4, -0.3, 1.1));
  writeCapHandles(shift, shift);
  for (const std::string method : {"laplacian", "bilaplacian", "arap", "cage-arap"}) {
    const CliResult r = edit(method);
    ASSERT_EQ(r.exitCode, 0) << method << ": " << r.err;
    EXPECT_EQ(r.err.find("warning"), std::string::npos) << method << ": " << r.err;
    EXPECT_LE(maxError([&](const Vec3& p) { return applied(shift, p); }), 1e-9 * size_) << method;
  }
}

TEST_F(EditCliTest, ArapMethodsReproduceACommonRigidMotion) {
  const Mat4 motion = rigidMotion();
  writeCapHandles(motion, motion);
  for (const std::string method : {"arap", "cage-arap"}) {
    const CliResult r = edit(method);
    ASSERT_EQ(r.exitCode, 0) << method << ": " << r.err;
    EXPECT_LE(maxError([&](const Vec3& p) { return applied(motion, p); }), 1e-9 * size_) << method;
  }
  // The linear methods cannot: the rotated caps shear the bar between them.
  ASSERT_EQ(edit("laplacian").exitCode, 0);
  EXPECT_GT(maxError([&](const Vec3& p) { return applied(motion, p); }), 1e-3 * size_);
}

// The report of the ARAP solve, and its warning (exit 0, output written) when it stops early.
TEST_F(EditCliTest, ArapReportsItsSolveAndWarnsWhenItDoesNotConverge) {
  writeCapHandles(Mat4(1.0), glm::rotate(Mat4(1.0), 0.8, Vec3(1.0, 0.0, 0.0)));
  CliResult r = edit("arap", "--iterations 500");
  ASSERT_EQ(r.exitCode, 0) << r.err;
  EXPECT_THAT(r.err, HasSubstr("spacewarp: arap: "));
  EXPECT_THAT(r.err, HasSubstr("converged"));
  EXPECT_EQ(r.err.find("warning"), std::string::npos) << r.err;
  EXPECT_THAT(r.out, HasSubstr("edited 452 vertices (900 triangles, 72 handle vertices) by arap"));
  r = edit("arap", "--iterations 1");
  ASSERT_EQ(r.exitCode, 0) << r.err;
  EXPECT_THAT(r.err, HasSubstr("warning: arap did not converge in 1 iteration"));
  EXPECT_TRUE(fs::exists(dir_ / "out.obj"));
  // --tolerance 0 asks for every iteration: no warning then.
  r = edit("arap", "--iterations 2 --tolerance 0");
  ASSERT_EQ(r.exitCode, 0) << r.err;
  EXPECT_THAT(r.err, HasSubstr("arap: 2 iterations"));
  EXPECT_EQ(r.err.find("warning"), std::string::npos) << r.err;
}

TEST_F(EditCliTest, BiLaplacianDiffersFromLaplacian) {
  const Mat4 lift = glm::translate(Mat4(1.0), Vec3(0.8, 0.0, 0.0));
  writeCapHandles(Mat4(1.0), lift);
  ASSERT_EQ(edit("laplacian").exitCode, 0);
  const PolygonSoup laplacian = readSoup(dir_ / "out.obj");
  ASSERT_EQ(edit("bilaplacian").exitCode, 0);
  const PolygonSoup bilaplacian = readSoup(dir_ / "out.obj");
  ASSERT_EQ(laplacian.size(), bilaplacian.size());
  double difference = 0.0;
  for (std::size_t v = 0; v < laplacian.size(); ++v)
    difference =
        std::max(difference, glm::length(laplacian.positions[v] - bilaplacian.positions[v]));
  EXPECT_GT(difference, 1e-3 * size_);
  // Both hold the handles exactly.
  for (const std::uint32_t v : capVertices(bar_, kHi.z)) {
    EXPECT_LE(glm::length(laplacian.positions[v] - applied(lift, bar_.positions[v])), 1e-9 * size_);
    EXPECT_LE(glm::length(bilaplacian.positions[v] - applied(lift, bar_.positions[v])),
              1e-9 * size_);
  }
}

TEST_F(EditCliTest, OutputKeepsTheFacesAndTheirOrder) {
  writeCapHandles(Mat4(1.0), glm::translate(Mat4(1.0), Vec3(0.5, 0.0, 0.0)));
  ASSERT_EQ(edit("arap").exitCode, 0);
  const PolygonSoup out = readSoup(dir_ / "out.obj");
  EXPECT_EQ(out.size(), bar_.size());
  EXPECT_EQ(out.faceOffsets, bar_.faceOffsets);
  EXPECT_EQ(out.faceIndices, bar_.faceIndices);
}

// Vertex and face attributes (PLY) come through the edit untouched.
TEST_F(EditCliTest, OutputKeepsTheAttributes) {
  PolygonSoup bar = bar_;
  ScalarAttribute label{"label", ScalarType::UInt8, {}};
  for (std::size_t v = 0; v < bar.size(); ++v) label.values.push_back(double(v % 7));
  ScalarAttribute material{"material_index", ScalarType::Int32, {}};
  for (std::size_t p = 0; p < bar.polygonCount(); ++p) material.values.push_back(double(p % 3));
  bar.attributes.push_back(label);
  bar.faceAttributes.push_back(material);
  writeSoup(bar, dir_ / "bar.ply");
  writeCapHandles(Mat4(1.0), glm::translate(Mat4(1.0), Vec3(0.5, 0.0, 0.0)));
  const CliResult r =
      run("edit --method bilaplacian --handles " + (dir_ / "handles.json").string() + " " +
          (dir_ / "bar.ply").string() + " -o " + (dir_ / "out.ply").string());
  ASSERT_EQ(r.exitCode, 0) << r.err;
  const PolygonSoup out = readSoup(dir_ / "out.ply");
  ASSERT_EQ(out.attributes.size(), 1u);
  EXPECT_EQ(out.attributes[0].name, "label");
  EXPECT_EQ(out.attributes[0].values, label.values);
  ASSERT_EQ(out.faceAttributes.size(), 1u);
  EXPECT_EQ(out.faceAttributes[0].values, material.values);
  EXPECT_EQ(out.faceIndices, bar.faceIndices);
}

// Normals: per-vertex ones are recomputed on the edited surface (so under a rigid motion they
// turn with it), per-corner ones turn with their face.
TEST_F(EditCliTest, NormalsTurnWithARigidMotion) {
  const Mat4 motion = rigidMotion();
  const Mat3 rotation(motion);
  // The shared-vertex box with flat corner normals (a vertex has one per face).
  PolygonSoup box = makeBoxSurface(kLo, kHi, {2, 2, 6});
  const std::vector<Vec3> vertexNormals = box.normals;
  box.normals.clear();
  for (std::size_t p = 0; p < box.polygonCount(); ++p) {
    const auto c = box.polygon(p);
    box.cornerNormals.values.push_back(glm::normalize(glm::cross(
        box.positions[c[1]] - box.positions[c[0]], box.positions[c[2]] - box.positions[c[0]])));
    for (std::size_t k = 0; k < c.size(); ++k)
      box.cornerNormals.indices.push_back(static_cast<std::uint32_t>(p));
  }
  writeSoup(box, dir_ / "bar.obj");
  bar_ = box;
  writeCapHandles(motion, motion);
  ASSERT_EQ(edit("arap").exitCode, 0);
  PolygonSoup out = readSoup(dir_ / "out.obj");
  ASSERT_EQ(out.cornerNormals.indices, box.cornerNormals.indices);
  for (std::size_t k = 0; k < box.cornerNormals.values.size(); ++k)
    EXPECT_LE(glm::length(out.cornerNormals.values[k] - rotation * box.cornerNormals.values[k]),
              1e-9)
        << k;

  // Per-vertex normals: the box's own (area-weighted at shared vertices, outward).
  box.cornerNormals = {};
  box.normals = vertexNormals;
  writeSoup(box, dir_ / "bar.obj");
  ASSERT_EQ(edit("arap").exitCode, 0);
  out = readSoup(dir_ / "out.obj");
  ASSERT_EQ(out.normals.size(), box.size());
  // makeBoxSurface averages the face normals; the edit weighs them by area: compare sides and
  // the rotation of what the edit computes at rest (an identity edit).
  const PolygonSoup moved = out;
  writeCapHandles(Mat4(1.0), Mat4(1.0));
  ASSERT_EQ(edit("arap").exitCode, 0);
  const PolygonSoup rest = readSoup(dir_ / "out.obj");
  for (std::size_t v = 0; v < box.size(); ++v) {
    EXPECT_GT(glm::dot(rest.normals[v], vertexNormals[v]), 0.5) << v;
    EXPECT_LE(glm::length(moved.normals[v] - rotation * rest.normals[v]), 1e-9) << v;
  }
}

// The posed cage of cage-arap, given to deform with the rest cage, moves the model where the
// edit put it: the route for point clouds and volumes.
TEST_F(EditCliTest, CageOutReproducesTheEditThroughDeform) {
  Mat4 top = glm::translate(Mat4(1.0), Vec3(0.6, 0.0, 0.2));
  top = glm::rotate(top, 0.4, Vec3(0.0, 1.0, 0.0));
  writeCapHandles(Mat4(1.0), top);
  const CliResult r = edit("cage-arap", "--cage-out " + (dir_ / "posed.obj").string());
  ASSERT_EQ(r.exitCode, 0) << r.err;
  EXPECT_THAT(r.err, HasSubstr("cage-arap: "));
  EXPECT_THAT(r.err, HasSubstr("rotation cluster"));
  const PolygonSoup edited = readSoup(dir_ / "out.obj");
  const PolygonSoup posed = readSoup(dir_ / "posed.obj");
  const PolygonSoup rest = readSoup(dir_ / "cage.obj");
  EXPECT_EQ(posed.faceIndices, rest.faceIndices);
  const CliResult d = run("deform --method mvc --cage " + (dir_ / "cage.obj").string() +
                          " --pose " + (dir_ / "posed.obj").string() + " " +
                          (dir_ / "bar.obj").string() + " -o " + (dir_ / "deformed.obj").string());
  ASSERT_EQ(d.exitCode, 0) << d.err;
  expectDeformedAsEdited(edited);
}

// A Bernstein lattice around the bar instead of a cage: a common translation is reproduced, and
// the posed ffd rig of --lattice-out carries the edit through `spacewarp deform --rig`.
TEST_F(EditCliTest, LatticeControlsTheSubspaceAndItsPoseReproducesTheEdit) {
  const Vec3 lo = kLo - 0.25, size = kHi - kLo + 0.5;
  std::vector<Vec3> rest;
  for (int k = 0; k < 5; ++k)
    for (int j = 0; j < 3; ++j)
      for (int i = 0; i < 3; ++i) rest.push_back(lo + size * Vec3(i / 2.0, j / 2.0, k / 4.0));
  const auto vec3 = [](const Vec3& v) {
    const std::string one = jsonPoints(std::vector<Vec3>{v});  // "[[x, y, z]]"
    return one.substr(1, one.size() - 2);
  };
  write("ffd.json", R"({"method": "ffd", "basis": "bernstein", "origin": )" + vec3(lo) +
                        R"(, "size": )" + vec3(size) +
                        R"(, "resolution": [3, 3, 5], "controlPoints": )" + jsonPoints(rest) + "}");
  const auto latticeEdit = [&](const std::string& extra) {
    return run("edit --method cage-arap --lattice " + (dir_ / "ffd.json").string() + " --handles " +
               (dir_ / "handles.json").string() + " " + (dir_ / "bar.obj").string() + " -o " +
               (dir_ / "out.obj").string() + " " + extra);
  };
  const Mat4 shift = glm::translate(Mat4(1.0), Vec3(0.4, -0.3, 1.1));
  writeCapHandles(shift, shift);
  CliResult r = latticeEdit("");
  ASSERT_EQ(r.exitCode, 0) << r.err;
  EXPECT_THAT(r.err, HasSubstr("the lattice's 45 control points"));
  EXPECT_LE(maxError([&](const Vec3& p) { return applied(shift, p); }), 1e-9 * size_);

  writeCapHandles(Mat4(1.0), glm::translate(Mat4(1.0), Vec3(0.6, 0.0, 0.2)));
  r = latticeEdit("--lattice-out " + (dir_ / "posed.json").string());
  ASSERT_EQ(r.exitCode, 0) << r.err;
  const PolygonSoup edited = readSoup(dir_ / "out.obj");
  const CliResult d = run("deform --rig " + (dir_ / "posed.json").string() + " " +
                          (dir_ / "bar.obj").string() + " -o " + (dir_ / "deformed.obj").string());
  ASSERT_EQ(d.exitCode, 0) << d.err;
  expectDeformedAsEdited(edited);
  // --lattice replaces --cage and its options.
  fs::remove(dir_ / "out.obj");
  expectFailure(latticeEdit("--cage " + (dir_ / "cage.obj").string()), 2, "--lattice and --cage");
  expectFailure(latticeEdit("--coordinates green"), 2, "--coordinates applies to --cage");
}

// Green coordinates' face-normal terms stay at rest in the edit, so their posed cage alone does
// not carry it: said in a warning, the outputs still written.
TEST_F(EditCliTest, CageOutWithGreenCoordinatesWarnsThatDeformDiffers) {
  writeCapHandles(Mat4(1.0), glm::translate(Mat4(1.0), Vec3(0.5, 0.0, 0.0)));
  const CliResult r =
      edit("cage-arap", "--coordinates green --cage-out " + (dir_ / "posed.obj").string());
  ASSERT_EQ(r.exitCode, 0) << r.err;
  EXPECT_THAT(r.err, HasSubstr("green coordinates of 20 cage vertices"));
  EXPECT_THAT(r.err, HasSubstr("does not reproduce the edit exactly"));
  EXPECT_TRUE(fs::exists(dir_ / "out.obj"));
  EXPECT_TRUE(fs::exists(dir_ / "posed.obj"));
}

// A part of the model that no handle reaches stays where it is, with a warning.
TEST_F(EditCliTest, UnreachedPartsStayWithAWarning) {
  PolygonSoup two = bar_;
  const std::size_t n = two.size();
  for (std::size_t v = 0; v < n; ++v) two.positions.push_back(bar_.positions[v] + Vec3(3.0, 0, 0));
  for (std::size_t p = 0; p < bar_.polygonCount(); ++p) {
    std::vector<std::uint32_t> corners;
    for (const std::uint32_t v : bar_.polygon(p))
      corners.push_back(static_cast<std::uint32_t>(v + n));
    two.addPolygon(corners);
  }
  writeSoup(two, dir_ / "bar.obj");
  const Mat4 shift = glm::translate(Mat4(1.0), Vec3(0.0, 0.0, 0.5));
  writeCapHandles(shift, shift);  // the first bar's caps only
  for (const std::string method : {"laplacian", "arap"}) {
    const CliResult r = edit(method);
    ASSERT_EQ(r.exitCode, 0) << r.err;
    EXPECT_THAT(r.err, HasSubstr("452 vertices in 1 part of the surface that no handle reaches"));
    const PolygonSoup out = readSoup(dir_ / "out.obj");
    for (std::size_t v = n; v < two.size(); ++v) ASSERT_EQ(out.positions[v], two.positions[v]) << v;
  }
}

// What the surface methods should know about a model is a warning each, not an error; a bad
// handles file on such a model is still one line.
TEST_F(EditCliTest, MeshTroubleIsWarnedNotFatal) {
  // Three triangles on the edge 0-1, a face collapsed by welding, two points in no face, a
  // face without area (collinear corners; vertex 9 only on it).
  write("bar.obj",
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nv 0 -1 0\nv 5 5 5\nv 1 1 1\nv 0 1 0\n"
        "v 2 0 0\nv 3 0 0\nf 1 2 3\nf 1 2 4\nf 1 2 5\nf 3 8 1\nf 2 9 10\n");
  write("handles.json", R"({"handles": [{"vertices": [0, 1, 3], "targets": [[0, 0, 0], )"
                        R"([1, 0, 0], [0, 0, 1.2]]}]})");
  CliResult r = edit("laplacian");
  ASSERT_EQ(r.exitCode, 0) << r.err;
  EXPECT_THAT(r.err, HasSubstr("1 non-manifold edge (more than two faces), the first between "
                               "vertices 0 and 1"));
  EXPECT_THAT(r.err, HasSubstr("1 face collapsed by welding (the first: face 3)"));
  EXPECT_THAT(r.err, HasSubstr("1 triangle without area (the first: of face 4)"));
  EXPECT_THAT(r.err, HasSubstr("2 isolated vertices; vertices 5, 6"));
  EXPECT_EQ(readSoup(dir_ / "out.obj").polygonCount(), 5u);
  fs::remove(dir_ / "out.obj");
  write("handles.json", R"({"handles": [{"vertices": [0, 1, 30], "targets": []}]})");
  expectFailure(edit("laplacian"), 3, "handles[0].vertices[2]: 30 is out of range");
}

// --- errors --------------------------------------------------------------------------------

// Outputs that collide: -o over the cage file still gets a posed cage built from the cage as it
// was read; -o and --cage-out naming one file is a usage error; a missing output folder is
// found before the work.
TEST_F(EditCliTest, OutputsThatCollideOrCannotBeWrittenAreCaughtFirst) {
  writeCapHandles(Mat4(1.0), glm::translate(Mat4(1.0), Vec3(0.3, 0.0, 0.0)));
  const PolygonSoup cage = readSoup(dir_ / "cage.obj");
  fs::copy_file(dir_ / "cage.obj", dir_ / "cage_copy.obj");
  CliResult r =
      run("edit --method cage-arap --cage " + (dir_ / "cage_copy.obj").string() + " --handles " +
          (dir_ / "handles.json").string() + " " + (dir_ / "bar.obj").string() + " -o " +
          (dir_ / "cage_copy.obj").string() + " --cage-out " + (dir_ / "posed.obj").string());
  ASSERT_EQ(r.exitCode, 0) << r.err;
  EXPECT_EQ(readSoup(dir_ / "posed.obj").size(), cage.size());
  EXPECT_EQ(readSoup(dir_ / "cage_copy.obj").size(), bar_.size());
  expectFailure(edit("cage-arap", "--cage-out " + (dir_ / "." / "out.obj").string()), 2,
                "-o and --cage-out name the same file");
  r = run("edit --method arap --handles " + (dir_ / "handles.json").string() + " " +
          (dir_ / "bar.obj").string() + " -o " + (dir_ / "missing" / "out.obj").string());
  EXPECT_EQ(r.exitCode, 3) << r.err;
  EXPECT_THAT(r.err, HasSubstr("does not exist"));
  EXPECT_THAT(r.err, Not(HasSubstr("arap:")));  // refused before the solve
}

// Endless or binary input as the handles file is refused at its first block, as rigs are.
TEST_F(EditCliTest, EndlessHandlesInputIsRefusedAtOnce) {
  const CliResult r = run("edit --method arap --handles /dev/zero " + (dir_ / "bar.obj").string() +
                          " -o " + (dir_ / "out.obj").string());
  expectFailure(r, 3, "/dev/zero: not a handles file: a NUL byte at byte offset 0");
}

struct BadHandles {
  std::string name, json, message;
  friend void PrintTo(const BadHandles& b, std::ostream* out) { *out << b.json; }
};

class BadHandlesTest : public EditCliTest, public ::testing::WithParamInterface<BadHandles> {};

TEST_P(BadHandlesTest, ExitsThreeWithOneLineAndNoOutput) {
  write("handles.json", GetParam().json);
  const CliResult r = edit("arap");
  expectFailure(r, 3, "handles.json: " + GetParam().message);
}

const std::string kIdentity = "[[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]";

INSTANTIATE_TEST_SUITE_P(
    Edit, BadHandlesTest,
    ::testing::Values(
        BadHandles{"MalformedJson", R"({"handles": [{"vertices": [0], )", "not valid JSON"},
        BadHandles{"NotAnObject", R"([1, 2])", "must be a JSON object"},
        BadHandles{"MissingHandles", R"({"regions": []})", "regions: is not a key here"},
        BadHandles{"NoHandles", R"({"handles": []})", "handles: must be a non-empty array"},
        BadHandles{"MissingVertices", R"({"handles": [{"matrix": )" + kIdentity + "}]}",
                   "handles[0].vertices: is missing"},
        BadHandles{"MissingMatrixAndTargets", R"({"handles": [{"vertices": [0]}]})",
                   "handles[0]: needs 'matrix'"},
        BadHandles{
            "UnknownKey",
            R"({"handles": [{"vertices": [0], "matrix": )" + kIdentity + R"(, "weight": 2}]})",
            "handles[0].weight: is not a key here"},
        BadHandles{"IndexOutOfRange",
                   R"({"handles": [{"vertices": [0], "matrix": )" + kIdentity +
                       R"(}, {"vertices": [1, 2, 1800], "matrix": )" + kIdentity + "}]}",
                   "handles[1].vertices[2]: 1800 is out of range (the model has 1800 vertices"},
        BadHandles{"NegativeIndex",
                   R"({"handles": [{"vertices": [-1], "matrix": )" + kIdentity + "}]}",
                   "handles[0].vertices[0]: must be a vertex index"},
        BadHandles{"FractionalIndex",
                   R"({"handles": [{"vertices": [1.5], "matrix": )" + kIdentity + "}]}",
                   "handles[0].vertices[0]: must be a vertex index"},
        BadHandles{"BothMatrixAndTargets",
                   R"({"handles": [{"vertices": [0], "matrix": )" + kIdentity +
                       R"(, "targets": [[0, 0, 0]]}]})",
                   "handles[0]: has both 'matrix' and 'targets'"},
        BadHandles{"TargetCountMismatch",
                   R"({"handles": [{"vertices": [0, 1], "targets": [[0, 0, 0]]}]})",
                   "handles[0].targets: has 1 points but 'vertices' has 2"},
        BadHandles{"NonAffineMatrix",
                   R"({"handles": [{"vertices": [0], "matrix": [[1, 0, 0, 0], [0, 1, 0, 0], )"
                   R"([0, 0, 1, 0], [0, 0, 0.5, 1]]}]})",
                   "handles[0].matrix[3]: must be [0, 0, 0, 1]"},
        BadHandles{"ShortMatrixRow",
                   R"({"handles": [{"vertices": [0], "matrix": [[1, 0, 0], [0, 1, 0, 0], )"
                   R"([0, 0, 1, 0], [0, 0, 0, 1]]}]})",
                   "handles[0].matrix[0]: must be an array of 4 numbers"},
        // JSON has no NaN: Python's json.dump writes it anyway, and 1e999 overflows.
        BadHandles{"NanTarget", R"({"handles": [{"vertices": [0], "targets": [[0, NaN, 0]]}]})",
                   "not valid JSON"},
        BadHandles{"HugeTarget", R"({"handles": [{"vertices": [0], "targets": [[0, 1e999, 0]]}]})",
                   "'handles[0].targets[0][1]' is a number outside the range of double"},
        BadHandles{"StringTarget", R"({"handles": [{"vertices": [0], "targets": [[0, "1", 0]]}]})",
                   "handles[0].targets[0]: must contain finite numbers only"},
        BadHandles{"ConflictingTargets",
                   R"({"handles": [{"vertices": [5], "targets": [[0, 0, 0]]}, )"
                   R"({"vertices": [5], "targets": [[1, 0, 0]]}]})",
                   "conflicting targets: handles[0] and handles[1] move vertex 5"},
        BadHandles{"DuplicateKey", R"({"handles": [], "handles": []})",
                   "'handles' is given twice"}),
    [](const ::testing::TestParamInfo<BadHandles>& info) { return info.param.name; });

// Two copies of one point (welded into one mesh vertex) sent to different places.
TEST_F(EditCliTest, ConflictingTargetsOfWeldedCopiesAreAnError) {
  // Soup vertices 0 and the other copies of its position.
  std::vector<std::uint32_t> copies;
  for (std::size_t v = 0; v < bar_.size(); ++v)
    if (bar_.positions[v] == bar_.positions[0]) copies.push_back(static_cast<std::uint32_t>(v));
  ASSERT_GE(copies.size(), 2u);
  const std::vector<Vec3> a{Vec3(0.0)}, b{Vec3(1.0)};
  write("handles.json", handlesFile({R"({"vertices": [)" + std::to_string(copies[0]) +
                                         R"(], "targets": )" + jsonPoints(a) + "}",
                                     R"({"vertices": [)" + std::to_string(copies[1]) +
                                         R"(], "targets": )" + jsonPoints(b) + "}"}));
  expectFailure(edit("laplacian"), 3, "welded into one");
}

TEST_F(EditCliTest, ModelWithoutTrianglesIsBadInput) {
  writeCapHandles(Mat4(1.0), Mat4(1.0));
  // A point cloud: no face at all.
  writeCloud(kLo, kHi, 2000, 3);
  CliResult r = run("edit --method arap --handles " + (dir_ / "handles.json").string() + " " +
                    (dir_ / "cloud.ply").string() + " -o " + (dir_ / "out.obj").string());
  expectFailure(r, 3, "cloud.ply");
  // Faces, but each collapses when its copies of one point are welded.
  write("flat.obj", "v 0 0 0\nv 0 0 0\nv 1 0 0\nv 1 0 0\nf 1 2 3\nf 2 3 4\n");
  write("handles.json", R"({"handles": [{"vertices": [0], "targets": [[0, 0, 0]]}]})");
  r = run("edit --method laplacian --handles " + (dir_ / "handles.json").string() + " " +
          (dir_ / "flat.obj").string() + " -o " + (dir_ / "out.obj").string());
  expectFailure(r, 3, "flat.obj: has no triangle");
}

TEST_F(EditCliTest, OptionsThatDoNotApplyAreUsageErrors) {
  writeCapHandles(Mat4(1.0), Mat4(1.0));
  expectFailure(edit("rigid"), 2, "--method");
  expectFailure(edit("arap", "--cage " + (dir_ / "cage.obj").string()), 2,
                "--cage applies to --method cage-arap only, not to --method arap");
  expectFailure(edit("laplacian", "--iterations 5"), 2,
                "--iterations applies to --method arap and cage-arap only");
  expectFailure(edit("arap", "--clusters 10"), 2, "--clusters applies to --method cage-arap only");
  expectFailure(edit("arap", "--cage-out " + (dir_ / "posed.obj").string()), 2, "--cage-out");
  // cage-arap without its cage.
  const CliResult r = run("edit --method cage-arap --handles " + (dir_ / "handles.json").string() +
                          " " + (dir_ / "bar.obj").string() + " -o " + (dir_ / "out.obj").string());
  expectFailure(r, 2, "--cage");
  expectFailure(edit("cage-arap", "--handle-weight nan"), 2, "--handle-weight");
}

}  // namespace
