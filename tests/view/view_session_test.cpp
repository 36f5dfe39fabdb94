#include "apps/view/view_session.h"

#include <cmath>
#include <numeric>

#include <gtest/gtest.h>

#include <spacewarp/coords/cage.h>
#include <spacewarp/core/errors.h>
#include <spacewarp/rig/cage_rig.h>

#include "coords/convex_test_shapes.h"
#include "view_test_util.h"

namespace spacewarp::test {
namespace {

using view::ViewSession;

class ViewSessionTest : public ViewFixture {};

// The heart of the viewer's contract: what the page shows is what the saved rig deforms to.
TEST_F(ViewSessionTest, EveryCageMethodGivesThePositionsOfTheRigItSaves) {
  ViewSession session = cageSession();
  const std::vector<Vec3> pose = sway(session.restControls());
  ASSERT_GE(session.methods().size(), 6u);
  for (const std::string& method : session.methods()) {
    SCOPED_TRACE(method);
    session.setMethod(method);
    session.setPose(pose);
    const auto paths = session.writeRig(dir_);
    ASSERT_EQ(paths.back(), dir_ / "model_rig.json");
    EXPECT_LT(relativeGap(session.positions(), deformedByRig(paths.back()), model_.positions),
              1e-12);
    // The pose really moved the model.
    EXPECT_GT(relativeGap(session.positions(), model_.positions, model_.positions), 1e-3);
  }
}

TEST_F(ViewSessionTest, TheRestPoseGivesTheRestModel) {
  ViewSession session = cageSession();
  for (const std::string& method : session.methods()) {
    SCOPED_TRACE(method);
    session.setMethod(method);
    session.setPose(session.restControls());
    EXPECT_LT(relativeGap(session.positions(), model_.positions, model_.positions), 1e-12);
  }
}

TEST_F(ViewSessionTest, SwitchingMethodKeepsThePose) {
  ViewSession session = cageSession("mvc");
  const std::vector<Vec3> pose = sway(session.restControls());
  session.setPose(pose);
  session.setMethod("green");
  ASSERT_EQ(session.method(), "green");
  EXPECT_TRUE(std::equal(pose.begin(), pose.end(), session.pose().begin()));
  ViewSession fresh = cageSession("green");
  fresh.setPose(pose);
  EXPECT_EQ(relativeGap(session.positions(), fresh.positions(), model_.positions), 0.0);
  // Back to mvc: its binding is cached (no bind time) and the pose is still the same.
  EXPECT_EQ(session.setMethod("mvc"), 0.0);
  EXPECT_TRUE(std::equal(pose.begin(), pose.end(), session.pose().begin()));
}

TEST_F(ViewSessionTest, WeightsAreTheCoordinatesColumnsAndSumToOne) {
  ViewSession session = cageSession();
  const auto cage = std::make_shared<const Cage>(Cage::fromFile(dir_ / "cage.obj"));
  const std::size_t m = session.restControls().size();
  for (const std::string method : {"mvc", "green", "harmonic", "rbf", "idw"}) {
    if (std::find(session.methods().begin(), session.methods().end(), method) ==
        session.methods().end())
      continue;  // harmonic without TetGen
    SCOPED_TRACE(method);
    session.setMethod(method);
    ASSERT_TRUE(session.hasWeights());
    std::shared_ptr<const Coordinates> reference;
    if (std::string(method) == "rbf" || std::string(method) == "idw") {
      reference = loadRig(session.writeRig(dir_).back()).coordinates;
    } else {
      CageMethodOptions options;
      options.harmonicTets = 3000;
      reference = cageCoordinates(method, cage, options);
    }
    ASSERT_TRUE(reference);
    std::vector<double> sum(model_.positions.size(), 0.0);
    std::vector<double> row(reference->columnCount());
    for (std::size_t c = 0; c < m; ++c) {
      const std::vector<double> w = session.weights(c);
      ASSERT_EQ(w.size(), model_.positions.size());
      for (std::size_t i = 0; i < w.size(); i += 7) {
        reference->weights(model_.positions[i], row);
        ASSERT_NEAR(w[i], row[c], 1e-12) << "vertex " << i << " control " << c;
      }
      for (std::size_t i = 0; i < w.size(); ++i) sum[i] += w[i];
    }
    for (std::size_t i = 0; i < sum.size(); ++i) ASSERT_NEAR(sum[i], 1.0, 1e-9) << i;
  }
  EXPECT_THROW(session.weights(m), InvalidInput);
  session.setMethod("mls");
  EXPECT_FALSE(session.hasWeights());
  EXPECT_THROW(session.weights(0), view::NotAvailable);
  EXPECT_THROW(session.slice(0, 2, 0.0, 8), view::NotAvailable);
}

TEST_F(ViewSessionTest, FoldsMarkAnInvertedPoseAndNoRigidPose) {
  ViewSession session = cageSession();
  for (const std::string& method : session.methods()) {
    SCOPED_TRACE(method);
    session.setMethod(method);
    session.setPose(rigid(session.restControls()));
    const std::vector<std::uint8_t> folds = session.folds();
    ASSERT_EQ(folds.size(), model_.positions.size());
    EXPECT_EQ(std::accumulate(folds.begin(), folds.end(), 0), 0);
  }
  // Methods that reproduce linear maps mirror the whole model with the cage.
  for (const std::string method : {"mvc", "harmonic", "rbf"}) {
    if (std::find(session.methods().begin(), session.methods().end(), method) ==
        session.methods().end())
      continue;
    SCOPED_TRACE(method);
    session.setMethod(method);
    session.setPose(mirror(session.restControls()));
    const std::vector<std::uint8_t> folds = session.folds();
    EXPECT_EQ(std::accumulate(folds.begin(), folds.end(), std::size_t(0)), folds.size());
  }
}

TEST_F(ViewSessionTest, SliceValuesAreTheCoordinatesAtTheSlicePoints) {
  ViewSession session = cageSession("mvc");
  const auto cage = std::make_shared<const Cage>(Cage::fromFile(dir_ / "cage.obj"));
  const auto mvc = cageCoordinates("mvc", cage);
  const int r = 9;
  for (int axis = 0; axis < 3; ++axis) {
    const ViewSession::Slice slice = session.slice(3, axis, 0.25, r);
    ASSERT_EQ(slice.values.size(), std::size_t(r * r));
    EXPECT_EQ(slice.origin[axis], 0.25);
    EXPECT_EQ(slice.u[axis], 0.0);
    EXPECT_EQ(slice.v[axis], 0.0);
    EXPECT_GT(glm::length(glm::cross(slice.u, slice.v)), 0.0);
    std::vector<double> row(mvc->columnCount());
    for (int b = 0; b < r; ++b)
      for (int a = 0; a < r; ++a) {
        const Vec3 x = slice.origin + slice.u * (a / double(r - 1)) + slice.v * (b / double(r - 1));
        mvc->weights(x, row);
        ASSERT_NEAR(slice.values[b * r + a], row[3], 1e-12) << axis << " " << a << " " << b;
      }
  }
  // Harmonic coordinates are undefined outside the cage: NaN there, numbers inside.
  if (std::ranges::count(session.methods(), "harmonic") > 0) {
    session.setMethod("harmonic");
    const ViewSession::Slice slice = session.slice(0, 2, 0.0, 16);
    const auto nan = std::ranges::count_if(slice.values, [](double v) { return std::isnan(v); });
    EXPECT_GT(nan, 0);
    EXPECT_LT(nan, 16 * 16);
  }
}

TEST_F(ViewSessionTest, RefusesBadPosesAndMethods) {
  ViewSession session = cageSession();
  std::vector<Vec3> pose(session.restControls().begin(), session.restControls().end());
  pose.pop_back();
  EXPECT_THROW(session.setPose(pose), InvalidInput);
  pose = sway(session.restControls());
  pose[2].y = std::nan("");
  EXPECT_THROW(session.setPose(pose), InvalidInput);
  EXPECT_THROW(session.setMethod("skinning"), InvalidInput);
  EXPECT_EQ(session.method(), "mvc");
  view::ViewSessionOptions options;
  options.method = "graph";  // not a cage method
  EXPECT_THROW(view::ViewSession::withCage(dir_ / "model.obj", dir_ / "cage.obj", options),
               InvalidInput);
  EXPECT_THROW(view::ViewSession::withCage(dir_ / "missing.obj", dir_ / "cage.obj"), IoError);
}

TEST_F(ViewSessionTest, SavesThePoseTheRigAndTheModel) {
  ViewSession session = cageSession("green");
  session.setPose(sway(session.restControls()));
  const std::filesystem::path pose = session.writePose(dir_);
  const PolygonSoup posedCage = readSoup(pose);
  EXPECT_EQ(posedCage.polygonCount(), readSoup(dir_ / "cage.obj").polygonCount());
  EXPECT_EQ(relativeGap(posedCage.positions, session.pose(), model_.positions), 0.0);
  const PolygonSoup deformed = readSoup(session.writeModel(dir_));
  EXPECT_EQ(deformed.polygonCount(), model_.polygonCount());
  EXPECT_EQ(relativeGap(deformed.positions, session.positions(), model_.positions), 0.0);
}

// A rig of each kind: the session starts at the rig's own pose (positions = the rig's deform),
// and a new pose saves as a rig that deforms to the new positions.
struct RigCase {
  std::string name, json;
  view::ControlKind kind;
  std::size_t controls;
};

class ViewSessionRigTest : public ViewFixture, public ::testing::WithParamInterface<RigCase> {};

TEST_P(ViewSessionRigTest, StartsAtTheRigsPoseAndSavesNewPosesAsRigs) {
  const RigCase& c = GetParam();
  const std::filesystem::path rig = write("input_rig.json", c.json);
  view::ViewSessionOptions options;
  options.harmonicTets = 3000;  // the cage rig's harmonic method, kept quick
  ViewSession session = ViewSession::withRig(dir_ / "model.obj", rig, options);
  EXPECT_EQ(session.controlKind(), c.kind);
  ASSERT_EQ(session.restControls().size(), c.controls);
  EXPECT_LT(relativeGap(session.positions(), deformedByRig(rig), model_.positions), 1e-12);
  for (const std::string& method : session.methods()) {
    SCOPED_TRACE(method);
    session.setMethod(method);
    if (c.controls > 0) session.setPose(sway(session.restControls(), 0.2));
    const auto paths = session.writeRig(dir_);
    EXPECT_LT(relativeGap(session.positions(), deformedByRig(paths.back()), model_.positions),
              1e-12);
  }
  if (c.kind == view::ControlKind::None) {
    EXPECT_THROW(session.writePose(dir_), view::NotAvailable);
  } else {
    EXPECT_EQ(readSoup(session.writePose(dir_)).positions.size(), c.controls);
  }
}

std::vector<RigCase> rigCases() {
  const std::vector<Vec3> corners = boxCorners();
  const std::string handles = jsonOf(corners), targets = jsonOf(sway(corners, 0.1));
  std::vector<Vec3> lattice;
  for (int k = 0; k < 3; ++k)
    for (int j = 0; j < 3; ++j)
      for (int i = 0; i < 3; ++i) lattice.emplace_back(-1 + i + 0.05 * k, -1 + j, -1.5 + 1.5 * k);
  return {
      {"cage", R"({"method": "green", "cage": "cage.obj", "pose": "cage.obj"})",
       view::ControlKind::Cage, 12},
      {"ffd",
       R"({"method": "ffd", "basis": "bernstein", "origin": [-1, -1, -1.5], "size": [2, 2, 3],
           "resolution": [3, 3, 3], "controlPoints": )" +
           jsonOf(lattice) + "}",
       view::ControlKind::Lattice, 27},
      {"rbf", R"({"method": "rbf", "centers": )" + handles + R"(, "targets": )" + targets + "}",
       view::ControlKind::Handles, 8},
      {"idw",
       R"({"method": "idw", "power": 3, "handles": )" + handles + R"(, "targets": )" + targets +
           "}",
       view::ControlKind::Handles, 8},
      {"mls",
       R"({"method": "mls", "mode": "similarity", "handles": )" + handles + R"(, "targets": )" +
           targets + "}",
       view::ControlKind::Handles, 8},
      {"graph",
       R"({"method": "graph", "spacing": 0.6, "handles": )" + handles + R"(, "targets": )" +
           targets + "}",
       view::ControlKind::Handles, 8},
      {"twist", R"({"method": "twist", "origin": [0, 0, 0], "axis": [0, 0, 1], "rate": 0.5})",
       view::ControlKind::None, 0},
  };
}

INSTANTIATE_TEST_SUITE_P(Kinds, ViewSessionRigTest, ::testing::ValuesIn(rigCases()),
                         [](const auto& info) { return info.param.name; });

// The cage methods offered are those that take the cage: wachspress only on a convex cage,
// discrete-harmonic only on a convex cage of triangles, each giving the positions of the rig it
// saves.
TEST_F(ViewSessionTest, CageMethodsAreThoseThatTakeTheCage) {
  const auto has = [](const ViewSession& session, const std::string& method) {
    return std::ranges::count(session.methods(), method) > 0;
  };
  PolygonSoup pinched = readSoup(dir_ / "cage.obj");  // its middle ring at z = 0
  for (Vec3& p : pinched.positions)
    if (p.z == 0.0) p.x *= 0.8, p.y *= 0.8;
  writeSoup(pinched, dir_ / "cage.obj");
  ViewSession concave = cageSession();
  for (const char* method : {"mvc", "green", "qmvc", "qgc"}) EXPECT_TRUE(has(concave, method));
  EXPECT_FALSE(has(concave, "wachspress"));
  EXPECT_FALSE(has(concave, "discrete-harmonic"));
  EXPECT_THROW(concave.setMethod("wachspress"), InvalidInput);

  const auto offersAndMatchesItsRig = [&](ViewSession& session, const char* method) {
    SCOPED_TRACE(method);
    ASSERT_TRUE(has(session, method));
    session.setMethod(method);
    session.setPose(sway(session.restControls()));
    EXPECT_LT(relativeGap(session.positions(), deformedByRig(session.writeRig(dir_).back()),
                          model_.positions),
              1e-12);
  };
  // A box: convex, but quads.
  writeSoup(makeBoxSurface(Vec3(-1, -1, -1.5), Vec3(1, 1, 1.5), glm::ivec3(1, 1, 1)),
            dir_ / "cage.obj");
  ViewSession box = cageSession();
  EXPECT_FALSE(has(box, "discrete-harmonic"));
  EXPECT_THROW(box.setMethod("discrete-harmonic"), InvalidInput);
  for (const char* method : {"wachspress", "qmvc", "qgc"}) offersAndMatchesItsRig(box, method);
  // The octahedron |x| + |y| + |z| <= 3 around the model: convex, triangles.
  PolygonSoup octahedron = test::octahedron();
  for (Vec3& p : octahedron.positions) p *= 3.0;
  writeSoup(octahedron, dir_ / "cage.obj");
  ViewSession simplicial = cageSession();
  for (const char* method : {"discrete-harmonic", "wachspress", "qmvc", "qgc"})
    offersAndMatchesItsRig(simplicial, method);
}

// The Armadillo of Ju et al. (2005) in its cage, posed by one of the paper's posed cages.
TEST(ViewSessionArmadillo, PosedCageGivesTheSavedRigsPositions) {
  const auto dir = std::filesystem::path(SPACEWARP_SHARED_DATA_DIR) / "ju2005-armadillo";
  if (!std::filesystem::exists(dir / "bounding_mesh.obj"))
    GTEST_SKIP() << "no shared data at " << dir;
  const auto out = std::filesystem::temp_directory_path() /
                   ("spacewarp_view_armadillo_" + std::to_string(::getpid()));
  std::filesystem::create_directories(out);
  ViewSession session = ViewSession::withCage(dir / "armadilloman.obj", dir / "bounding_mesh.obj");
  const Cage cage = Cage::fromFile(dir / "bounding_mesh.obj");
  const std::vector<Vec3> pose = cage.posedVerticesFromFile(dir / "deformed_bounding_mesh2.obj");
  const PolygonSoup model = readSoup(dir / "armadilloman.obj");
  for (const std::string method : {"mvc", "green"}) {
    SCOPED_TRACE(method);
    session.setMethod(method);
    session.setPose(pose);
    const Rig rig = loadRig(session.writeRig(out).back());
    std::vector<Vec3> expected(model.positions.size());
    rig.warp->applyBatch(model.positions, expected);
    EXPECT_LT(relativeGap(session.positions(), expected, model.positions), 1e-12);
  }
  std::filesystem::remove_all(out);
}

}  // namespace
}  // namespace spacewarp::test
