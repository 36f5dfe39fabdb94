#include <spacewarp/surface/cage_arap.h>

#include <filesystem>

#include <gtest/gtest.h>

#include <spacewarp/coords/cage.h>
#include <spacewarp/coords/green.h>
#include <spacewarp/coords/mean_value.h>
#include <spacewarp/core/errors.h>
#include <spacewarp/core/io/mesh_io.h>
#include <spacewarp/ffd/lattice_coordinates.h>
#include <spacewarp/surface/arap.h>
#include <spacewarp/surface/cotan_laplacian.h>

#include "surface/surface_test_shapes.h"

namespace spacewarp {
namespace {

// A box cage around the bar [0, 4] × [0, 1]², 4 × 1 × 1 cells of quads.
std::shared_ptr<const Cage> barCage() {
  PolygonSoup soup = makeBoxSurface(Vec3(-0.5), Vec3(4.5, 1.5, 1.5), {4, 1, 1});
  soup.normals.clear();
  return std::make_shared<const Cage>(soup);
}

std::shared_ptr<const Coordinates> barLattice() {
  LatticeOptions o;
  o.origin = Vec3(-0.5);
  o.extents = Vec3(5.0, 2.0, 2.0);
  o.resolution = {5, 2, 2};
  return std::make_shared<const LatticeCoordinates>(Lattice(o));
}

bool nonIncreasing(const std::vector<double>& e) {
  for (std::size_t k = 1; k < e.size(); ++k)
    if (e[k] > e[k - 1]) return false;
  return true;
}

std::vector<std::pair<std::string, std::shared_ptr<const Coordinates>>> allCoordinates() {
  return {{"mvc", std::make_shared<const MeanValueCoordinates>(barCage())},
          {"green", std::make_shared<const GreenCoordinates>(barCage())},
          {"lattice", barLattice()}};
}

TEST(CageArapEditor, ReproducesACommonTranslationWithEveryCoordinates) {
  const SurfaceMesh mesh = test::bar();
  const auto handles = test::bentBar(mesh).constrained;
  const Vec3 t(1, -2, 0.5);
  for (const auto& [name, coordinates] : allCoordinates()) {
    SCOPED_TRACE(name);
    CageArapEditor editor(mesh.positions, mesh.triangles, coordinates, handles);
    const auto result =
        editor.solve(test::applied([&](const Vec3& x) { return x + t; }, mesh.positions, handles));
    for (std::size_t v = 0; v < result.positions.size(); ++v)
      ASSERT_LT(glm::length(result.positions[v] - (mesh.positions[v] + t)), 1e-10) << v;
    EXPECT_TRUE(result.report.unreached.empty());
    EXPECT_LT(result.report.maxResidual, 1e-10);
  }
}

TEST(CageArapEditor, ReproducesACommonRigidMotion) {
  const SurfaceMesh mesh = test::bar();
  const auto handles = test::bentBar(mesh).constrained;
  const test::Rigid motion{test::rotationAbout(Vec3(-1, 2, 0.5), 1.3), Vec3(3, 0, -1)};
  for (const auto& [name, coordinates] : allCoordinates()) {
    if (name == "green") continue;  // its vertex block alone does not rotate the face normals
    SCOPED_TRACE(name);
    CageArapEditor editor(mesh.positions, mesh.triangles, coordinates, handles);
    const auto result = editor.solve(test::applied(motion, mesh.positions, handles));
    EXPECT_TRUE(result.report.startedRigid);
    for (std::size_t v = 0; v < result.positions.size(); ++v)
      ASSERT_LT(glm::length(result.positions[v] - motion(mesh.positions[v])), 1e-9) << v;
    const auto rest = coordinates->restControlPoints();
    for (std::size_t c = 0; c < rest.size(); ++c)
      EXPECT_LT(glm::length(result.controlPoints[c] - motion(rest[c])), 1e-9) << c;
  }
}

TEST(CageArapEditor, BendsABarWithEnergyNeverRising) {
  const SurfaceMesh mesh = test::bar();
  const test::BentBar bent = test::bentBar(mesh);
  const auto mvc = std::make_shared<const MeanValueCoordinates>(barCage());
  CageArapEditor editor(mesh.positions, mesh.triangles, mvc, bent.constrained,
                        {.maxIterations = 60});
  const CageArapResult result = editor.solve(bent.targets);
  ASSERT_GE(result.report.energies.size(), 2u);
  EXPECT_TRUE(nonIncreasing(result.report.energies));
  EXPECT_LT(result.report.energies.back(), result.report.energies.front());
  // The model is the binding of the posed cage.
  const auto warp = makeWarp(mvc, result.controlPoints);
  for (std::size_t v = 0; v < mesh.vertexCount(); v += 7)
    EXPECT_LT(glm::length(warp->apply(mesh.positions[v]) - result.positions[v]), 1e-9);
  // A 5-segment cage cannot bend the bar into a quarter circle exactly: some handle vertices are
  // left off their targets, and every one of them is reported.
  ASSERT_EQ(result.report.handleResiduals.size(), bent.constrained.size());
  std::size_t far = 0;
  for (double r : result.report.handleResiduals) far += r > 1e-3 * 4.25;
  EXPECT_EQ(result.report.unreached.size(), far);
  // Still a bend: the moved end went most of the way.
  const Vec3 tip = result.positions[bent.constrained.back()];
  EXPECT_LT(glm::length(tip - bent.targets.back()), 0.5);
}

TEST(CageArapEditor, WithOneClusterPerVertexHasTheSurfaceArapEnergy) {
  const SurfaceMesh mesh = test::bar(2.0, 3);
  const auto handles = test::verticesWhere(
      mesh.positions, [](const Vec3& x) { return x.x <= 1e-12 || x.x >= 2.0 - 1e-12; });
  const auto targets = test::applied(
      [](const Vec3& x) { return x.x > 1.0 ? x + Vec3(0, 0.4, 0.1) : x; }, mesh.positions, handles);
  PolygonSoup cageSoup = makeBoxSurface(Vec3(-0.5), Vec3(2.5, 1.5, 1.5), {2, 1, 1});
  cageSoup.normals.clear();
  const auto mvc =
      std::make_shared<const MeanValueCoordinates>(std::make_shared<const Cage>(cageSoup));
  CageArapEditor editor(
      mesh.positions, mesh.triangles, mvc, handles,
      {.rotationClusters = mesh.vertexCount(), .handleWeight = 1.0, .maxIterations = 5});
  EXPECT_EQ(editor.clusterCount(), mesh.vertexCount());
  const CageArapResult result = editor.solve(targets);
  // Its ARAP part equals ArapEditor's energy of the same positions (plus the handle term).
  ArapEditor surface(mesh.positions, mesh.triangles, handles);
  double handleTerm = 0.0;
  for (std::size_t k = 0; k < handles.size(); ++k) {
    const Vec3 d = result.positions[handles[k]] - targets[k];
    handleTerm += glm::dot(d, d);
  }
  // λ = handleWeight × Σ w over the energy's terms, per handle vertex: 1.5 trace(L) with rims
  // (every triangle's three edge weights, once for each of its vertices).
  const double lambda = 1.0 * 1.5 *
                        cotanLaplacian(mesh.positions, mesh.triangles).diagonal().sum() /
                        double(handles.size());
  EXPECT_NEAR(result.report.energies.back(), surface.energy(result.positions) + lambda * handleTerm,
              1e-9 * result.report.energies.front());
}

// The same edit carried far away gives the same shape, carried: the solve runs in the frame of
// the handles' mean displacement, so the expanded energy has no large terms to cancel.
TEST(CageArapEditor, IsTheSameEditWhenTheTargetsAreTranslatedFarAway) {
  const SurfaceMesh mesh = test::bar();
  const test::BentBar bent = test::bentBar(mesh);
  const auto mvc = std::make_shared<const MeanValueCoordinates>(barCage());
  CageArapEditor editor(mesh.positions, mesh.triangles, mvc, bent.constrained);
  const CageArapResult near = editor.solve(bent.targets);
  for (double distance : {1e4, 1e7}) {
    const Vec3 t(distance, -0.5 * distance, 0.0);
    std::vector<Vec3> far = bent.targets;
    for (Vec3& x : far) x += t;
    const CageArapResult away = editor.solve(far);
    double worst = 0.0;
    for (std::size_t v = 0; v < mesh.vertexCount(); ++v)
      worst = std::max(worst, glm::length(away.positions[v] - t - near.positions[v]));
    EXPECT_LT(worst, 1e-14 * distance + 1e-10) << distance;
    EXPECT_EQ(away.report.iterations, near.report.iterations) << distance;
  }
}

TEST(CageArapEditor, RefusesBadInput) {
  const SurfaceMesh mesh = test::bar(2.0, 2);
  const std::vector<std::uint32_t> handles = {0, 1, 2};
  const auto mvc = std::make_shared<const MeanValueCoordinates>(barCage());
  EXPECT_THROW(CageArapEditor(mesh.positions, mesh.triangles, nullptr, handles), InvalidInput);
  EXPECT_THROW(CageArapEditor(mesh.positions, mesh.triangles, mvc, handles, {.handleWeight = 0.0}),
               InvalidInput);
  EXPECT_THROW(CageArapEditor(mesh.positions, mesh.triangles, mvc, {}), InvalidInput);
  CageArapEditor editor(mesh.positions, mesh.triangles, mvc, handles);
  EXPECT_THROW(editor.solve(std::vector<Vec3>(2)), InvalidInput);
  EXPECT_THROW(editor.solve(std::vector<Vec3>{Vec3(0), Vec3(0), Vec3(NAN)}), InvalidInput);
  EXPECT_THROW(editor.solveFrom(std::vector<Vec3>(3), std::vector<Vec3>(3)), InvalidInput);
}

// The armadillo of Ju et al. 2005 in its bounding cage: drag the head, pin the feet.
TEST(CageArapEditor, MovesTheArmadillosHeadWithinItsCagesReach) {
  const std::filesystem::path dir = SPACEWARP_SHARED_DATA_DIR "/ju2005-armadillo";
  if (!std::filesystem::exists(dir / "armadilloman.obj")) GTEST_SKIP() << "no shared data";
  const SurfaceMesh mesh = weldSoup(readSoup(dir / "armadilloman.obj"));
  const auto cage = std::make_shared<const Cage>(Cage::fromFile(dir / "bounding_mesh.obj"));
  const auto mvc = std::make_shared<const MeanValueCoordinates>(cage);
  const BoundingBox box = boundingBox(mesh.positions);
  const double h = box.extent().y;
  const auto handles = test::verticesWhere(mesh.positions, [&](const Vec3& x) {
    return x.y <= box.min.y + 0.1 * h || x.y >= box.max.y - 0.1 * h;
  });
  const Vec3 shift(0.15 * h, 0.0, 0.0);
  const auto targets =
      test::applied([&](const Vec3& x) { return x.y > box.min.y + 0.5 * h ? x + shift : x; },
                    mesh.positions, handles);
  CageArapEditor editor(mesh.positions, mesh.triangles, mvc, handles);
  const CageArapResult result = editor.solve(targets);
  EXPECT_TRUE(nonIncreasing(result.report.energies));
  // Most of the way there, and what is not is reported.
  double mean = 0.0;
  for (double r : result.report.handleResiduals) mean += r / double(handles.size());
  EXPECT_LT(mean, 0.2 * glm::length(shift));
  for (std::size_t k = 0; k < handles.size(); ++k) {
    const bool listed = std::find(result.report.unreached.begin(), result.report.unreached.end(),
                                  handles[k]) != result.report.unreached.end();
    EXPECT_EQ(listed, result.report.handleResiduals[k] > 1e-3 * box.diagonal()) << k;
  }
}

}  // namespace
}  // namespace spacewarp
