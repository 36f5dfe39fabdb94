#include <spacewarp/surface/arap.h>

#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <spacewarp/core/errors.h>
#include <spacewarp/surface/cotan_laplacian.h>
#include <spacewarp/surface/laplacian_editing.h>

#include "surface/surface_test_shapes.h"

namespace spacewarp {
namespace {

bool nonIncreasing(const std::vector<double>& e) {
  for (std::size_t k = 1; k < e.size(); ++k)
    if (e[k] > e[k - 1]) return false;
  return true;
}

TEST(ArapEditor, ReproducesACommonTranslation) {
  const SurfaceMesh mesh = test::bar();
  const auto handles = test::bentBar(mesh).constrained;
  ArapEditor editor(mesh.positions, mesh.triangles, handles);
  const Vec3 t(5, 6, -7);
  const auto result =
      editor.solve(test::applied([&](const Vec3& x) { return x + t; }, mesh.positions, handles));
  for (std::size_t v = 0; v < result.positions.size(); ++v)
    ASSERT_LT(glm::length(result.positions[v] - (mesh.positions[v] + t)), 1e-12);
  EXPECT_TRUE(result.report.converged);
}

TEST(ArapEditor, ReproducesACommonRigidMotionExactlyFarFromTheOrigin) {
  for (ArapEnergy energy : {ArapEnergy::SpokesAndRims, ArapEnergy::Spokes})
    for (double offset : {0.0, 1e6}) {
      const SurfaceMesh mesh = test::bar();
      const auto handles = test::bentBar(mesh).constrained;
      std::vector<Vec3> moved = mesh.positions;
      for (Vec3& x : moved) x += Vec3(offset);
      ArapEditor editor(moved, mesh.triangles, handles, {.energy = energy});
      const test::Rigid motion{test::rotationAbout(Vec3(1, 2, 3), 2.0), Vec3(0.5, offset, 3)};
      const auto result = editor.solve(test::applied(motion, moved, handles));
      const double tolerance = 1e-12 * (4.0 + offset);
      for (std::size_t v = 0; v < moved.size(); ++v)
        ASSERT_LT(glm::length(result.positions[v] - motion(moved[v])), tolerance) << v;
      EXPECT_TRUE(result.report.startedRigid);
      EXPECT_TRUE(result.report.converged);
    }
}

// A 90° bend: ARAP keeps the edges' lengths within a few percent, Laplacian editing shrinks and
// shears them; ARAP's energy never rises and ends below the Laplacian solution's.
TEST(ArapEditor, BendsABarKeepingItsEdgesWhereLaplacianEditingShrinksThem) {
  // Thin (1/40 of its length), so that bending itself strains the faces by about 1%.
  const SurfaceMesh mesh = test::thinBar(0.1, 40);
  const test::BentBar bent = test::bentBar(mesh, 0.1);
  ArapEditor arap(mesh.positions, mesh.triangles, bent.constrained, {.maxIterations = 100});
  const ArapResult result = arap.solve(bent.targets);
  LinearEditor laplacian(mesh.positions, mesh.triangles, bent.constrained);
  const auto linear = laplacian.solve(bent.targets);

  EXPECT_FALSE(result.report.startedRigid);
  ASSERT_EQ(result.report.energies.size(), std::size_t(result.report.iterations) + 1);
  EXPECT_TRUE(nonIncreasing(result.report.energies));
  EXPECT_NEAR(result.report.energies.front(), arap.energy(linear), 1e-9 * arap.energy(linear));
  EXPECT_LT(result.report.energies.back(), 0.2 * arap.energy(linear));
  EXPECT_NEAR(result.report.energies.back(), arap.energy(result.positions),
              1e-12 * result.report.energies.front());
  const double arapChange = test::meanEdgeLengthChange(mesh, result.positions);
  const double linearChange = test::meanEdgeLengthChange(mesh, linear);
  EXPECT_LT(arapChange, 0.05);
  EXPECT_GT(linearChange, 2.0 * arapChange);
  RecordProperty("arap_mean_edge_change", std::to_string(arapChange));
  RecordProperty("arap_iterations", result.report.iterations);
  RecordProperty("laplacian_mean_edge_change", std::to_string(linearChange));
  // The handles are where they were sent.
  for (std::size_t k = 0; k < bent.constrained.size(); ++k)
    EXPECT_EQ(result.positions[bent.constrained[k]], bent.targets[k]);
}

// Obtuse triangles have negative cotangent weights: with spokes alone the energy can drop below
// zero by stretching single edges; with rims every triangle's terms are a Dirichlet energy.
TEST(ArapEditor, SpokesAndRimsEnergyStaysNonNegativeOnObtuseTriangles) {
  PolygonSoup soup;
  const int n = 8;
  for (int j = 0; j <= n; ++j)
    for (int i = 0; i <= n; ++i)
      soup.positions.push_back(Vec3(i + 0.45 * ((i * 7 + j * 3) % 5 - 2) * (i > 0 && i < n),
                                    j + 0.45 * ((i * 3 + j * 5) % 5 - 2) * (j > 0 && j < n), 0.0));
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) {
      const auto v = static_cast<std::uint32_t>(j * (n + 1) + i);
      soup.addPolygon({v, v + 1, v + n + 2});
      soup.addPolygon({v, v + n + 2, v + n + 1});
    }
  const SurfaceMesh mesh = weldSoup(soup);
  std::size_t negative = 0;
  const auto l = cotanLaplacian(mesh.positions, mesh.triangles);
  for (Eigen::Index c = 0; c < l.outerSize(); ++c)
    for (Eigen::SparseMatrix<double>::InnerIterator it(l, c); it; ++it)
      negative += it.row() != c && it.value() > 0.0;
  ASSERT_GT(negative, 0u);  // the mesh does have obtuse pairs
  const auto handles = test::verticesWhere(
      mesh.positions, [](const Vec3& x) { return x.x <= 0.0 || x.x >= double(n); });
  const auto targets =
      test::applied([](const Vec3& x) { return x.x > 1.0 ? Vec3(x.x - 4.0, x.y, 6.0) : x; },
                    mesh.positions, handles);
  ArapEditor editor(mesh.positions, mesh.triangles, handles, {.maxIterations = 200});
  const ArapResult r = editor.solve(targets);
  EXPECT_TRUE(nonIncreasing(r.report.energies));
  EXPECT_GE(r.report.energies.back(), 0.0);
  // Both energies keep the rest pose when every handle stays: the spokes energy has its negative
  // weights replaced, so the rest pose is its minimum too.
  for (ArapEnergy energy : {ArapEnergy::SpokesAndRims, ArapEnergy::Spokes}) {
    ArapEditor still(mesh.positions, mesh.triangles, handles,
                     {.energy = energy, .maxIterations = 2000, .relativeTolerance = 1e-14});
    std::vector<Vec3> shaken = mesh.positions;  // from a start off the rest pose
    for (std::size_t v = 0; v < shaken.size(); ++v) shaken[v].z += 0.05 * std::sin(3.0 * double(v));
    const ArapResult rest = still.solveFrom(
        shaken, test::applied([](const Vec3& x) { return x; }, mesh.positions, handles));
    EXPECT_LT(test::maxDistance(rest.positions, mesh.positions), 1e-4 * n)
        << (energy == ArapEnergy::Spokes ? "spokes" : "rims");
    EXPECT_TRUE(nonIncreasing(rest.report.energies));
  }
}

// Anderson acceleration reaches the plain iteration's fixed point in fewer iterations, with the
// energy still never rising.
TEST(ArapEditor, AccelerationConvergesFasterToTheSameSolution) {
  const SurfaceMesh mesh = test::thinBar(0.1, 40);
  const test::BentBar bent = test::bentBar(mesh, 0.1);
  auto run = [&](int window, int iterations, double tolerance) {
    ArapEditor editor(mesh.positions, mesh.triangles, bent.constrained,
                      {.maxIterations = iterations,
                       .relativeTolerance = tolerance,
                       .accelerationWindow = window});
    return editor.solve(bent.targets);
  };
  const ArapResult accelerated = run(5, 2000, 1e-10);
  const ArapResult plain = run(0, 20000, 1e-12);
  ASSERT_TRUE(accelerated.report.converged);
  EXPECT_TRUE(nonIncreasing(accelerated.report.energies));
  EXPECT_LT(accelerated.report.iterations, plain.report.iterations / 4);
  EXPECT_NEAR(accelerated.report.energies.back(), plain.report.energies.back(),
              1e-6 * plain.report.energies.back());
  EXPECT_LT(test::maxDistance(accelerated.positions, plain.positions), 1e-3 * 4.0);
  RecordProperty("accelerated_iterations", accelerated.report.iterations);
  RecordProperty("plain_iterations", plain.report.iterations);
}

TEST(ArapEditor, ContinuesFromAPreviousResultAndStopsOnTolerance) {
  const SurfaceMesh mesh = test::bar();
  const test::BentBar bent = test::bentBar(mesh);
  ArapEditor few(mesh.positions, mesh.triangles, bent.constrained,
                 {.maxIterations = 3, .relativeTolerance = 0.0});
  const ArapResult first = few.solve(bent.targets);
  EXPECT_EQ(first.report.iterations, 3);
  EXPECT_FALSE(first.report.converged);
  const ArapResult second = few.solveFrom(first.positions, bent.targets);
  EXPECT_NEAR(second.report.energies.front(), first.report.energies.back(),
              1e-12 * first.report.energies.back());
  EXPECT_LT(second.report.energies.back(), first.report.energies.back());
}

TEST(ArapEditor, GivesBitIdenticalResultsForAnyThreadCount) {
  const SurfaceMesh mesh = test::bar();
  const test::BentBar bent = test::bentBar(mesh);
  auto run = [&] {
    ArapEditor editor(mesh.positions, mesh.triangles, bent.constrained, {.maxIterations = 5});
    return editor.solve(bent.targets).positions;
  };
  const auto many = run();
  const tbb::global_control one(tbb::global_control::max_allowed_parallelism, 1);
  const auto single = run();
  for (std::size_t v = 0; v < many.size(); ++v) ASSERT_EQ(many[v], single[v]) << v;
}

TEST(ArapEditor, ReportsCancellation) {
  const SurfaceMesh mesh = test::bar();
  const test::BentBar bent = test::bentBar(mesh);
  ArapEditor editor(mesh.positions, mesh.triangles, bent.constrained,
                    {.maxIterations = 50, .relativeTolerance = 0.0});
  int calls = 0;
  const ProgressCallback stop = [&](std::string_view stage, double) {
    EXPECT_EQ(stage, "arap");
    return ++calls < 3;
  };
  EXPECT_THROW(editor.solve(bent.targets, stop), Cancelled);
}

// An open sheet with a flap on one of its edges (three triangles on that edge): reported by
// weldSoup, and still edited: a translation of the handles is reproduced, the energy never rises.
TEST(ArapEditor, EditsOpenAndNonManifoldMeshes) {
  PolygonSoup soup;
  const int n = 6;
  for (int j = 0; j <= n; ++j)
    for (int i = 0; i <= n; ++i) soup.positions.push_back(Vec3(i, j, 0) / double(n));
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) {
      const auto v = static_cast<std::uint32_t>(j * (n + 1) + i);
      soup.addPolygon({v, v + 1, v + n + 2, v + n + 1});
    }
  soup.positions.push_back(Vec3(0.5, 0.5, 0.5));
  soup.addPolygon({24, 25, static_cast<std::uint32_t>(soup.positions.size() - 1)});
  const SurfaceMesh mesh = weldSoup(soup);
  EXPECT_FALSE(mesh.report.isManifold());
  EXPECT_GT(mesh.report.boundaryEdges, 0u);
  const auto handles =
      test::verticesWhere(mesh.positions, [](const Vec3& x) { return x.x == 0.0 || x.x == 1.0; });
  ArapEditor editor(mesh.positions, mesh.triangles, handles);
  const Vec3 t(0.1, 0.2, 0.3);
  const auto moved =
      editor.solve(test::applied([&](const Vec3& x) { return x + t; }, mesh.positions, handles));
  for (std::size_t v = 0; v < mesh.vertexCount(); ++v)
    EXPECT_LT(glm::length(moved.positions[v] - (mesh.positions[v] + t)), 1e-12) << v;
  const auto bent = editor.solve(test::applied(
      [](const Vec3& x) { return x.x == 1.0 ? x + Vec3(0, 0, 0.5) : x; }, mesh.positions, handles));
  EXPECT_TRUE(nonIncreasing(bent.report.energies));
  for (const Vec3& x : bent.positions) EXPECT_TRUE(isFinite(x));
}

// Far from the origin the edit is the same, to a few units in the last place of the
// coordinates: the solve runs relative to the model's centre.
TEST(ArapEditor, KeepsItsDigitsFarFromTheOrigin) {
  const SurfaceMesh mesh = test::thinBar(0.1, 40);
  const test::BentBar bent = test::bentBar(mesh, 0.1);
  const Vec3 offset(1e8, -3e8, 2e8);
  // The same mesh in both places: the far coordinates rounded, the near ones their exact
  // differences from the offset.
  std::vector<Vec3> far = mesh.positions, farTargets = bent.targets;
  for (Vec3& x : far) x += offset;
  for (Vec3& x : farTargets) x += offset;
  std::vector<Vec3> close = far, closeTargets = farTargets;
  for (Vec3& x : close) x -= offset;
  for (Vec3& x : closeTargets) x -= offset;
  const ArapOptions converge{
      .maxIterations = 50, .relativeTolerance = 0.0, .accelerationWindow = 0};
  ArapEditor near(close, mesh.triangles, bent.constrained, converge);
  ArapEditor away(far, mesh.triangles, bent.constrained, converge);
  const auto a = near.solve(closeTargets).positions;
  const auto b = away.solve(farTargets).positions;
  double worst = 0.0;
  for (std::size_t v = 0; v < a.size(); ++v) worst = std::max(worst, maxAbs(b[v] - offset - a[v]));
  EXPECT_LT(worst, 16 * std::numeric_limits<double>::epsilon() * 3e8);
}

TEST(ArapEditor, RefusesBadInput) {
  const SurfaceMesh mesh = test::bar(1.0, 1);
  const std::vector<std::uint32_t> handles = {0, 1};
  EXPECT_THROW(ArapEditor(mesh.positions, mesh.triangles, handles, {.maxIterations = -1}),
               InvalidInput);
  EXPECT_THROW(ArapEditor(mesh.positions, mesh.triangles, handles, {.relativeTolerance = NAN}),
               InvalidInput);
  EXPECT_THROW(ArapEditor(mesh.positions, mesh.triangles, handles, {.accelerationWindow = -1}),
               InvalidInput);
  ArapEditor editor(mesh.positions, mesh.triangles, handles);
  EXPECT_THROW(editor.solve(std::vector<Vec3>{Vec3(0), Vec3(INFINITY)}), InvalidInput);
  EXPECT_THROW(editor.solveFrom(std::vector<Vec3>(3), std::vector<Vec3>(2)), InvalidInput);
  EXPECT_THROW(editor.energy(std::vector<Vec3>(3)), InvalidInput);
}

}  // namespace
}  // namespace spacewarp
