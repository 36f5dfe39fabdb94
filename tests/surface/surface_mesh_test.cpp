#include <spacewarp/surface/surface_mesh.h>

#include <gtest/gtest.h>

#include <spacewarp/core/errors.h>
#include <spacewarp/core/primitives.h>

#include "surface/surface_test_shapes.h"

namespace spacewarp {
namespace {

TEST(WeldSoup, WeldsPerPolygonCopiesIntoTheSharedMesh) {
  const PolygonSoup box = makeBoxSurface(Vec3(0.0), Vec3(2.0, 1.0, 1.0), {4, 2, 2});
  const SurfaceMesh shared = weldSoup(box);
  const PolygonSoup split = test::unshared(box);
  const SurfaceMesh welded = weldSoup(split);
  EXPECT_EQ(welded.vertexCount(), box.positions.size());
  EXPECT_EQ(welded.triangles.size(), 2 * box.polygonCount());
  EXPECT_TRUE(welded.report.isManifold());
  EXPECT_EQ(welded.report.boundaryEdges, 0u);
  EXPECT_EQ(welded.report.componentCount, 1u);
  EXPECT_TRUE(welded.report.droppedPolygons.empty());
  // Every soup corner maps to a mesh vertex at the same place.
  for (std::size_t v = 0; v < split.positions.size(); ++v)
    EXPECT_EQ(welded.positions[welded.soupToMesh[v]], split.positions[v]);
  EXPECT_EQ(shared.vertexCount(), welded.vertexCount());
}

TEST(WeldSoup, ToleranceIsRelativeToTheSizeAndWorksFarFromTheOrigin) {
  for (double offset : {0.0, 1e8}) {
    for (double size : {1e-6, 1.0, 1e6}) {
      PolygonSoup soup;
      const Vec3 o(offset);
      soup.positions = {o, o + Vec3(size, 0, 0), o + Vec3(0, size, 0),
                        // copies of vertex 1: 1e-12 of the size away (welded), 1e-6 (kept)
                        o + Vec3(size * (1 + 1e-12), 0, 0), o + Vec3(size * (1 + 1e-6), 0, 0),
                        o + Vec3(size, size, 0)};
      soup.addPolygon({0, 1, 2});
      soup.addPolygon({3, 5, 2});
      soup.addPolygon({4, 5, 2});
      const SurfaceMesh mesh = weldSoup(soup);
      SCOPED_TRACE("offset " + std::to_string(offset) + " size " + std::to_string(size));
      if (offset / size > 1e12) continue;  // the copies are not representable apart
      EXPECT_EQ(mesh.soupToMesh[3], mesh.soupToMesh[1]);
      EXPECT_NE(mesh.soupToMesh[4], mesh.soupToMesh[1]);
    }
  }
}

TEST(WeldSoup, ExactToleranceMergesOnlyEqualPositions) {
  PolygonSoup soup;
  soup.positions = {Vec3(0), Vec3(1, 0, 0), Vec3(0, 1, 0), Vec3(1, 0, 0), Vec3(1 + 1e-15, 0, 0)};
  soup.addPolygon({0, 1, 2});
  soup.addPolygon({0, 3, 2});
  soup.addPolygon({0, 4, 2});
  const SurfaceMesh mesh = weldSoup(soup, {.relativeTolerance = 0.0});
  EXPECT_EQ(mesh.soupToMesh[3], mesh.soupToMesh[1]);
  EXPECT_NE(mesh.soupToMesh[4], mesh.soupToMesh[1]);
}

TEST(WeldSoup, ReportsNonManifoldEdgesAndVertices) {
  PolygonSoup soup;
  // Three triangles on the edge 0-1; a bow-tie pair touching only at vertex 5.
  soup.positions = {Vec3(0, 0, 0),   Vec3(1, 0, 0), Vec3(0.5, 1, 0), Vec3(0.5, -1, 0),
                    Vec3(0.5, 0, 1), Vec3(5, 0, 0), Vec3(6, 1, 0),   Vec3(6, -1, 0),
                    Vec3(4, 1, 0),   Vec3(4, -1, 0)};
  soup.addPolygon({0, 1, 2});
  soup.addPolygon({1, 0, 3});
  soup.addPolygon({0, 1, 4});
  soup.addPolygon({5, 6, 7});
  soup.addPolygon({5, 8, 9});
  const SurfaceMesh mesh = weldSoup(soup);
  ASSERT_EQ(mesh.report.nonManifoldEdges.size(), 1u);
  EXPECT_EQ(mesh.report.nonManifoldEdges[0], (std::array<std::uint32_t, 2>{0, 1}));
  EXPECT_EQ(mesh.report.nonManifoldVertices, std::vector<std::uint32_t>{5});
  EXPECT_FALSE(mesh.report.isManifold());
  EXPECT_EQ(mesh.report.componentCount, 2u);
  EXPECT_EQ(mesh.report.boundaryEdges, 6u + 6u);
}

TEST(WeldSoup, DropsCollapsedPolygonsAndReportsIsolatedVertices) {
  PolygonSoup soup;
  soup.positions = {Vec3(0), Vec3(1, 0, 0), Vec3(0, 1, 0), Vec3(0, 1, 0), Vec3(7, 7, 7)};
  soup.addPolygon({0, 1, 2});
  soup.addPolygon({0, 2, 3});     // 2 and 3 weld: nothing is left
  soup.addPolygon({0, 1, 3, 2});  // a quad that keeps one triangle
  const SurfaceMesh mesh = weldSoup(soup);
  EXPECT_EQ(mesh.report.droppedPolygons, std::vector<std::uint32_t>{1});
  EXPECT_EQ(mesh.triangles.size(), 2u);
  EXPECT_EQ(mesh.triangleToPolygon, (std::vector<std::uint32_t>{0, 2}));
  EXPECT_EQ(mesh.report.isolatedVertices, std::vector<std::uint32_t>{mesh.soupToMesh[4]});
  EXPECT_TRUE(mesh.report.degenerateTriangles.empty());
}

TEST(WeldSoup, ReportsTrianglesWithoutArea) {
  PolygonSoup soup;
  soup.positions = {Vec3(0), Vec3(1, 0, 0), Vec3(0, 1, 0), Vec3(2, 0, 0), Vec3(3, 0, 0)};
  soup.addPolygon({0, 1, 2});
  soup.addPolygon({1, 3, 4});  // collinear corners: kept in the mesh, reported
  const SurfaceMesh mesh = weldSoup(soup);
  EXPECT_EQ(mesh.triangles.size(), 2u);
  EXPECT_EQ(mesh.report.degenerateTriangles, std::vector<std::uint32_t>{1});
  EXPECT_TRUE(mesh.report.droppedPolygons.empty());
}

TEST(WeldSoup, AnOpenSheetHasItsPerimeterAsBoundary) {
  PolygonSoup soup;
  const int n = 5;
  for (int j = 0; j <= n; ++j)
    for (int i = 0; i <= n; ++i) soup.positions.push_back(Vec3(i, j, 0));
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) {
      const auto v = static_cast<std::uint32_t>(j * (n + 1) + i);
      soup.addPolygon({v, v + 1, v + n + 2, v + n + 1});
    }
  const SurfaceMesh mesh = weldSoup(soup);
  EXPECT_EQ(mesh.report.boundaryEdges, 4u * n);
  EXPECT_TRUE(mesh.report.isManifold());
}

TEST(WeldSoup, RefusesSoupsWithoutPolygonsOrWithBadData) {
  PolygonSoup points;
  points.positions = {Vec3(0), Vec3(1)};
  EXPECT_THROW(weldSoup(points), InvalidInput);
  PolygonSoup nan;
  nan.positions = {Vec3(0), Vec3(1, 0, 0), Vec3(0, std::nan(""), 0)};
  nan.addPolygon({0, 1, 2});
  EXPECT_THROW(weldSoup(nan), InvalidInput);
  PolygonSoup ok;
  ok.positions = {Vec3(0), Vec3(1, 0, 0), Vec3(0, 1, 0)};
  ok.addPolygon({0, 1, 2});
  EXPECT_THROW(weldSoup(ok, {.relativeTolerance = -1.0}), InvalidInput);
  PolygonSoup huge = ok;  // its squared lengths would overflow
  huge.positions[1].x = 1e200;
  EXPECT_THROW(weldSoup(huge), InvalidInput);
}

TEST(WeldSoup, SoupPositionsFollowTheirMeshVertex) {
  const PolygonSoup split = test::unshared(makeBoxSurface(Vec3(0.0), Vec3(1.0), {1, 1, 1}));
  const SurfaceMesh mesh = weldSoup(split);
  std::vector<Vec3> moved = mesh.positions;
  for (Vec3& x : moved) x = 2.0 * x + Vec3(1, 2, 3);
  const auto soupPositions = mesh.toSoupPositions(moved);
  ASSERT_EQ(soupPositions.size(), split.positions.size());
  for (std::size_t v = 0; v < split.positions.size(); ++v)
    EXPECT_EQ(soupPositions[v], 2.0 * split.positions[v] + Vec3(1, 2, 3));
  EXPECT_THROW(mesh.toSoupPositions(std::span<const Vec3>(moved).first(3)), InvalidInput);
}

}  // namespace
}  // namespace spacewarp
