#include <spacewarp/surface/laplacian_editing.h>

#include <gtest/gtest.h>

#include <spacewarp/core/errors.h>

#include "surface/surface_test_shapes.h"

namespace spacewarp {
namespace {

constexpr LinearEditMethod kMethods[] = {LinearEditMethod::Laplacian,
                                         LinearEditMethod::BiLaplacian};

TEST(LinearEditor, ReproducesACommonTranslationOfAllHandles) {
  const SurfaceMesh mesh = test::bar();
  const auto handles = test::bentBar(mesh).constrained;
  for (const Vec3 t : {Vec3(0.3, -1.7, 2.5), Vec3(1e6, -2e6, 3e6)})
    for (LinearEditMethod method : kMethods) {
      LinearEditor editor(mesh.positions, mesh.triangles, handles, {method});
      const auto targets =
          test::applied([&](const Vec3& x) { return x + t; }, mesh.positions, handles);
      const auto out = editor.solve(targets);
      for (std::size_t v = 0; v < out.size(); ++v)
        ASSERT_EQ(out[v], mesh.positions[v] + t) << "vertex " << v;  // exactly: no solve rounding
    }
}

TEST(LinearEditor, IsLinearInTheTargets) {
  const SurfaceMesh mesh = test::bar();
  const test::BentBar bent = test::bentBar(mesh);
  for (LinearEditMethod method : kMethods) {
    LinearEditor editor(mesh.positions, mesh.triangles, bent.constrained, {method});
    const auto rest =
        test::applied([](const Vec3& x) { return x; }, mesh.positions, bent.constrained);
    const auto a = editor.solve(bent.targets);
    const auto b = editor.solve(rest);
    std::vector<Vec3> mid(rest.size());
    for (std::size_t k = 0; k < mid.size(); ++k) mid[k] = 0.25 * bent.targets[k] + 0.75 * rest[k];
    const auto c = editor.solve(mid);  // a back-substitution with the kept factor
    for (std::size_t v = 0; v < c.size(); ++v)
      ASSERT_LT(glm::length(c[v] - (0.25 * a[v] + 0.75 * b[v])), 1e-11);
    EXPECT_LT(test::maxDistance(b, mesh.positions), 1e-12);  // rest targets: rest mesh
  }
}

// The seeds' "limitations of linear methods": a rotated handle shears the free region and
// shrinks it, because the differential coordinates are not rotated with it.
TEST(LinearEditor, CannotFollowARotation) {
  const SurfaceMesh mesh = test::bar();
  const test::BentBar bent = test::bentBar(mesh);
  for (LinearEditMethod method : kMethods) {
    LinearEditor editor(mesh.positions, mesh.triangles, bent.constrained, {method});
    const auto out = editor.solve(bent.targets);
    EXPECT_GT(test::meanEdgeLengthChange(mesh, out), 0.08);
  }
}

TEST(LinearEditor, BiLaplacianIsSmootherThanLaplacianAtTheHandles) {
  const SurfaceMesh mesh = test::bar();
  const auto handles = test::verticesWhere(
      mesh.positions, [](const Vec3& x) { return x.x <= 0.25 + 1e-12 || x.x >= 3.75 - 1e-12; });
  const auto targets = test::applied(
      [](const Vec3& x) { return x.x > 2.0 ? x + Vec3(0, 1, 0) : x; }, mesh.positions, handles);
  LinearEditor membrane(mesh.positions, mesh.triangles, handles, {LinearEditMethod::Laplacian});
  LinearEditor shell(mesh.positions, mesh.triangles, handles, {LinearEditMethod::BiLaplacian});
  const auto a = membrane.solve(targets);
  const auto b = shell.solve(targets);
  // The lift of the bar's axis just beside the moved end: the membrane's displacement has a
  // kink there (linear profile), the shell's leaves the handle flat (C1).
  auto liftAt = [&](const std::vector<Vec3>& out, double x) {
    double lift = 0.0;
    int count = 0;
    for (std::uint32_t v = 0; v < mesh.vertexCount(); ++v)
      if (std::abs(mesh.positions[v].x - x) < 1e-9 && mesh.positions[v].z == 0.0) {
        lift += out[v].y - mesh.positions[v].y;
        ++count;
      }
    return lift / count;
  };
  const double slopeMembrane = (liftAt(a, 3.75) - liftAt(a, 3.5)) / 0.25;
  const double slopeShell = (liftAt(b, 3.75) - liftAt(b, 3.5)) / 0.25;
  EXPECT_GT(slopeMembrane, 0.2);
  EXPECT_LT(slopeShell, 0.5 * slopeMembrane);
}

TEST(LinearEditor, HoldsComponentsWithoutHandlesAtRest) {
  PolygonSoup two = makeBoxSurface(Vec3(0.0), Vec3(1.0), {2, 2, 2});
  const PolygonSoup other = makeBoxSurface(Vec3(3.0), Vec3(4.0), {1, 1, 1});
  const auto base = static_cast<std::uint32_t>(two.positions.size());
  two.positions.insert(two.positions.end(), other.positions.begin(), other.positions.end());
  for (std::size_t p = 0; p < other.polygonCount(); ++p) {
    std::vector<std::uint32_t> corners;
    for (std::uint32_t v : other.polygon(p)) corners.push_back(v + base);
    two.addPolygon(corners);
  }
  two.normals.clear();
  const SurfaceMesh mesh = weldSoup(two);
  const std::vector<std::uint32_t> handles = {0};
  LinearEditor editor(mesh.positions, mesh.triangles, handles);
  EXPECT_EQ(editor.heldVertices().size(), other.positions.size());
  const auto out = editor.solve(std::vector<Vec3>{Vec3(-1, 0, 0)});
  for (std::uint32_t v : editor.heldVertices()) EXPECT_EQ(out[v], mesh.positions[v]);
  EXPECT_LT(glm::length(out[1] - (mesh.positions[1] + Vec3(-1, 0, 0))), 1e-12);
}

TEST(LinearEditor, RefusesBadInput) {
  const SurfaceMesh mesh = test::bar(1.0, 1);
  const std::vector<std::uint32_t> none;
  EXPECT_THROW(LinearEditor(mesh.positions, mesh.triangles, none), InvalidInput);
  const std::vector<std::uint32_t> outOfRange = {0, 9999};
  EXPECT_THROW(LinearEditor(mesh.positions, mesh.triangles, outOfRange), InvalidInput);
  const std::vector<std::uint32_t> twice = {1, 1};
  EXPECT_THROW(LinearEditor(mesh.positions, mesh.triangles, twice), InvalidInput);
  const std::vector<std::uint32_t> ok = {0, 1};
  LinearEditor editor(mesh.positions, mesh.triangles, ok);
  EXPECT_THROW(editor.solve(std::vector<Vec3>{Vec3(0)}), InvalidInput);
  EXPECT_THROW(editor.solve(std::vector<Vec3>{Vec3(0), Vec3(NAN)}), InvalidInput);
  std::vector<Vec3> nan = mesh.positions;
  nan[3].x = NAN;
  EXPECT_THROW(LinearEditor(nan, mesh.triangles, ok), InvalidInput);
  const std::vector<std::array<std::uint32_t, 3>> noTriangles;
  EXPECT_THROW(LinearEditor(mesh.positions, noTriangles, ok), InvalidInput);
  const std::vector<Vec3> flat(mesh.positions.size(), Vec3(1.0));  // every triangle degenerate
  EXPECT_THROW(LinearEditor(flat, mesh.triangles, ok), InvalidInput);
}

}  // namespace
}  // namespace spacewarp
