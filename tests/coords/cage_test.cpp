#include <spacewarp/coords/cage.h>

#include <algorithm>
#include <string>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <spacewarp/core/errors.h>
#include <spacewarp/core/primitives.h>
#include "coords_test_shapes.h"

namespace spacewarp {
namespace {

using ::testing::HasSubstr;

// Runs `make` and expects InvalidInput whose message contains `message`.
template <typename F>
void expectInvalid(F make, const std::string& message) {
  try {
    make();
    ADD_FAILURE() << "no exception; expected: " << message;
  } catch (const InvalidInput& e) {
    EXPECT_THAT(e.what(), HasSubstr(message));
  }
}

TEST(Cage, QuadBoxIsTriangulatedAndOutward) {
  const PolygonSoup box = makeBoxSurface(Vec3(0), Vec3(1, 2, 3), {1, 1, 1});
  const Cage cage(box, "box");
  EXPECT_EQ(cage.vertexCount(), 8u);
  EXPECT_EQ(cage.triangleCount(), 12u);
  EXPECT_EQ(cage.reorientedCount(), 0u);
  EXPECT_NEAR(cage.volume(), 6.0, 1e-12);
  for (std::size_t t = 0; t < cage.triangleCount(); ++t) {
    // Outward: the normal points away from the center.
    const Triangle& tri = cage.triangles()[t];
    const Vec3 centroid =
        (cage.vertices()[tri.x] + cage.vertices()[tri.y] + cage.vertices()[tri.z]) / 3.0;
    EXPECT_GT(glm::dot(cage.normal(t), centroid - Vec3(0.5, 1, 1.5)), 0.0) << t;
    EXPECT_EQ(cage.triangleSource()[t], t / 2) << "quads are cut into two triangles in order";
  }
}

TEST(Cage, InwardAndMixedOrientationIsRepaired) {
  PolygonSoup box = test::tetrahedron();
  // Flip every face (inward), then flip one back (inconsistent).
  for (std::size_t f = 0; f < box.polygonCount(); ++f)
    std::swap(box.faceIndices[box.faceOffsets[f] + 1], box.faceIndices[box.faceOffsets[f] + 2]);
  std::swap(box.faceIndices[1], box.faceIndices[2]);
  const Cage cage(box, "tet");
  EXPECT_GT(cage.volume(), 0.0);
  EXPECT_EQ(cage.reorientedCount(), 3u);
  EXPECT_NEAR(cage.volume(), test::tetrahedronVolume(), 1e-14);
}

// The faces stay the input polygons, outward: every face's Newell normal points away from the
// box's center, a reversed face keeps its first vertex, and its triangles come from it.
TEST(Cage, KeepsItsPolygonsOrientedOutward) {
  PolygonSoup box = makeBoxSurface(Vec3(0), Vec3(1, 2, 3), {2, 1, 1});
  const std::vector<std::uint32_t> first(box.faceIndices.begin(), box.faceIndices.begin() + 4);
  std::reverse(box.faceIndices.begin() + 1, box.faceIndices.begin() + 4);  // face 0 inward
  const Cage cage(box, "box");
  ASSERT_EQ(cage.faceCount(), box.polygonCount());
  EXPECT_EQ(cage.maxFaceSize(), 4u);
  EXPECT_EQ(cage.reorientedCount(), 1u) << "one quad reversed, counted once, not per triangle";
  const auto face0 = cage.face(0);
  EXPECT_EQ(std::vector<std::uint32_t>(face0.begin(), face0.end()), first);
  for (std::size_t f = 0; f < cage.faceCount(); ++f) {
    const auto face = cage.face(f);
    ASSERT_EQ(face.size(), 4u);
    Vec3 normal(0.0), centroid(0.0);
    for (std::size_t k = 0; k < 4; ++k) {
      const Vec3 a = cage.vertices()[face[k]], b = cage.vertices()[face[(k + 1) % 4]];
      normal += glm::cross(a, b);
      centroid += a / 4.0;
    }
    EXPECT_GT(glm::dot(normal, centroid - Vec3(0.5, 1, 1.5)), 0.0) << f;
  }
  const PolygonSoup tet = test::tetrahedron();
  EXPECT_EQ(Cage(tet, "tet").maxFaceSize(), 3u);
}

TEST(Cage, ConcavePolygonIsEarClipped) {
  const PolygonSoup prism = test::lPrism();
  const Cage cage(prism, "L");
  // Two L-shaped hexagons (4 triangles each) and six side quads (2 each).
  EXPECT_EQ(cage.triangleCount(), 4u * 2 + 6u * 2);
  EXPECT_NEAR(cage.volume(), 3.0, 1e-12);  // three unit squares, unit height
  double area = 0.0;
  for (std::size_t t = 0; t < cage.triangleCount(); ++t)
    if (cage.triangleSource()[t] == 0) area += cage.area(t);
  EXPECT_NEAR(area, 3.0, 1e-12) << "the triangulation covers the L exactly";
}

TEST(Cage, RejectsOpenBoundaryNamingTheEdge) {
  PolygonSoup box = makeBoxSurface(Vec3(0), Vec3(1), {1, 1, 1});
  PolygonSoup open;
  static_cast<PointSet&>(open) = box;
  for (std::size_t f = 1; f < box.polygonCount(); ++f) open.addPolygon(box.polygon(f));
  expectInvalid([&] { Cage c(open, "open.obj"); }, "open boundary at edge (");
  expectInvalid([&] { Cage c(open, "open.obj"); }, "open.obj");
}

TEST(Cage, RejectsNonManifoldEdge) {
  PolygonSoup soup = test::tetrahedron();
  soup.positions.push_back(Vec3(1, 1, -1));
  soup.addPolygon({0, 1, 4});  // a fin on edge (0, 1)
  soup.addPolygon({1, 0, 4});
  expectInvalid([&] { Cage c(soup); }, "non-manifold edge (0, 1)");
}

TEST(Cage, RejectsDoubleCoveredSurface) {
  PolygonSoup soup = test::tetrahedron();
  PolygonSoup twice;
  static_cast<PointSet&>(twice) = soup;
  for (std::size_t f = 0; f < soup.polygonCount(); ++f) twice.addPolygon(soup.polygon(f));
  for (std::size_t f = 0; f < soup.polygonCount(); ++f) twice.addPolygon(soup.polygon(f));
  expectInvalid([&] { Cage c(twice); }, "non-manifold edge");
}

TEST(Cage, RejectsNonOrientableSurface) {
  // The six-vertex triangulation of the real projective plane (the hemi-icosahedron): closed,
  // every edge shared by exactly two triangles, and non-orientable (Euler characteristic 1).
  PolygonSoup rp2;
  rp2.positions = {Vec3(1, 0, 0),     Vec3(0, 1, 0),    Vec3(0, 0, 1),
                   Vec3(-1, -1, 0.3), Vec3(0.5, -1, 1), Vec3(-0.7, 0.4, -1)};
  const std::uint32_t faces[10][3] = {{0, 1, 2}, {0, 2, 3}, {0, 3, 4}, {0, 4, 5}, {0, 5, 1},
                                      {1, 2, 4}, {2, 3, 5}, {3, 4, 1}, {4, 5, 2}, {5, 1, 3}};
  for (const auto& f : faces) rp2.addPolygon({f[0], f[1], f[2]});
  expectInvalid([&] { Cage c(rp2, "rp2.off"); }, "not orientable");
  expectInvalid([&] { Cage c(rp2, "rp2.off"); }, "rp2.off");
}

TEST(Cage, RejectsDegenerateInput) {
  PolygonSoup tiny;
  tiny.positions = {Vec3(0), Vec3(1, 0, 0), Vec3(0, 1, 0)};
  tiny.addPolygon({0, 1, 2});
  expectInvalid([&] { Cage c(tiny); }, "at least 4 vertices");

  PolygonSoup nan = test::tetrahedron();
  nan.positions[2].y = std::nan("");
  expectInvalid([&] { Cage c(nan); }, "vertex 2 has a non-finite coordinate");

  PolygonSoup flat = test::tetrahedron();
  flat.positions[3] = flat.positions[0];  // collapses faces onto an edge
  expectInvalid([&] { Cage c(flat); }, "zero area");

  PolygonSoup unused = test::tetrahedron();
  unused.positions.push_back(Vec3(5));
  expectInvalid([&] { Cage c(unused); }, "vertex 4 is not used by any face");
}

TEST(Cage, PosedCageCountsMustMatch) {
  const Cage cage(test::tetrahedron(), "rest.obj");
  PolygonSoup posed = test::tetrahedron();
  posed.positions.pop_back();
  expectInvalid([&] { cage.posedVertices(posed, "posed.obj"); }, "has 3 vertices");

  PolygonSoup fewerFaces = test::tetrahedron();
  fewerFaces.faceOffsets.pop_back();
  fewerFaces.faceIndices.resize(fewerFaces.faceOffsets.back());
  expectInvalid([&] { cage.posedVertices(fewerFaces, "posed.obj"); }, "has 3 faces");

  PolygonSoup points;  // a bare point list is accepted: vertex order is what matters
  points.positions = test::tetrahedron().positions;
  EXPECT_EQ(cage.posedVertices(points, "points.ply").size(), 4u);
}

}  // namespace
}  // namespace spacewarp
