#include <spacewarp/coords/convex_cage.h>

#include <cmath>
#include <filesystem>
#include <numbers>
#include <random>
#include <string>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <spacewarp/coords/detail/convex_polyhedron.h>
#include <spacewarp/core/errors.h>
#include <spacewarp/core/primitives.h>
#include "convex_test_shapes.h"
#include "coords_test_shapes.h"
#include "test_util.h"

namespace spacewarp {
namespace {

using ::testing::HasSubstr;

std::string convexityError(const PolygonSoup& soup) {
  return test::messageOf<InvalidInput>([&] { checkConvexCage(Cage(soup, "c.obj"), "M"); });
}

TEST(ConvexCage, AcceptsConvexPolyhedraOfAnyFaces) {
  for (const PolygonSoup& soup :
       {test::tetrahedron(), test::convexBox(Vec3(-1.0), Vec3(1.0)), test::hexagonalPrism(),
        test::pentagonalPrism(), test::truncatedOctahedron(), test::randomSphereHull(30, 5),
        test::pinchedBox(1.5), test::icosphere(2)}) {
    EXPECT_EQ(convexityError(soup), "");
  }
}

// The hull helper and the merge agree on the faces: a triangulated box has six quads again, the
// truncated octahedron 6 squares and 8 hexagons, each corner in 3 faces.
TEST(ConvexCage, MergesCoplanarFacesIntoOnePolygon) {
  const Cage cube(test::triangulated(test::convexBox(Vec3(0.0), Vec3(1.0))));
  ASSERT_EQ(cube.faceCount(), 12u);
  const detail::ConvexPolyhedron box = detail::buildConvexPolyhedron(cube, "M", kDefaultPlanarity);
  ASSERT_EQ(box.faces.size(), 6u);
  for (const auto& face : box.faces) {
    EXPECT_EQ(face.loop.size(), 4u);
    EXPECT_NEAR(face.area, 1.0, 1e-15);
  }
  const detail::ConvexPolyhedron octa =
      detail::buildConvexPolyhedron(Cage(test::truncatedOctahedron()), "M", kDefaultPlanarity);
  ASSERT_EQ(octa.faces.size(), 14u);
  int squares = 0, hexagons = 0;
  for (const auto& face : octa.faces) {
    squares += face.loop.size() == 4;
    hexagons += face.loop.size() == 6;
  }
  EXPECT_EQ(squares, 6);
  EXPECT_EQ(hexagons, 8);
  for (std::size_t v = 0; v < octa.vertices.size(); ++v)
    EXPECT_EQ(octa.ringOffsets[v + 1] - octa.ringOffsets[v], 3u);
  // The rings run counter-clockwise seen from outside: det(n_1, n_2, n_3) > 0 at every corner.
  for (std::size_t v = 0; v < octa.vertices.size(); ++v) {
    const std::uint32_t* r = octa.ring.data() + octa.ringOffsets[v];
    EXPECT_GT(glm::dot(octa.faces[r[0]].normal,
                       glm::cross(octa.faces[r[1]].normal, octa.faces[r[2]].normal)),
              0.0);
  }
}

TEST(ConvexCage, NamesTheReflexEdgeOfTheLPrism) {
  // The inner corner of the L is the vertical edge from vertex 3 (bottom) to 9 (top).
  const std::string message = convexityError(test::lPrism());
  EXPECT_THAT(message, HasSubstr("M: c.obj: the cage is not convex"));
  EXPECT_THAT(message, HasSubstr("edge between vertices 3 and 9"));
  EXPECT_THAT(message, HasSubstr("reflex"));
  EXPECT_THAT(convexityError(test::pinchedBox(0.5)), HasSubstr("reflex"));
  EXPECT_THAT(convexityError(test::star()), HasSubstr("reflex"));
}

TEST(ConvexCage, NamesAVertexThatIsNotACorner) {
  // The top quad of a box split into four triangles around its centre (vertex 8).
  PolygonSoup soup = test::convexBox(Vec3(0.0), Vec3(1.0));
  PolygonSoup split;
  split.positions = soup.positions;
  split.positions.push_back(Vec3(0.5, 0.5, 1.0));
  for (std::size_t f = 0; f < soup.polygonCount(); ++f) {
    const auto face = soup.polygon(f);
    bool top = true;
    for (std::uint32_t v : face) top = top && soup.positions[v].z == 1.0;
    if (!top) {
      split.addPolygon(face);
      continue;
    }
    for (std::size_t j = 0; j < 4; ++j) split.addPolygon({face[j], face[(j + 1) % 4], 8});
  }
  EXPECT_THAT(convexityError(split),
              HasSubstr("vertex 8 is not a corner of the polyhedron: its faces lie in 1 plane"));
  // A box cut 2 × 1 × 1: the midpoints of four edges lie on two planes only.
  EXPECT_THAT(convexityError(makeBoxSurface(Vec3(0.0), Vec3(1.0), {2, 1, 1})),
              HasSubstr("planes (remove it"));
}

TEST(ConvexCage, NamesANonPlanarFace) {
  PolygonSoup soup = test::convexBox(Vec3(0.0), Vec3(1.0));
  std::size_t lifted = 0;
  while (soup.positions[lifted] != Vec3(1.0)) ++lifted;
  soup.positions[lifted].z += 0.01;
  const std::string message = convexityError(soup);
  EXPECT_THAT(message, HasSubstr("is not planar"));
  EXPECT_THAT(message, HasSubstr("cage diagonals from its best-fit plane, more than planarity"));
  EXPECT_THAT(message, testing::ContainsRegex("vertices ([0-9]+, )*" + std::to_string(lifted)));
}

// The tolerance is relative to the diagonal: the same convex cage passes at any scale and place.
TEST(ConvexCage, JudgesRelativeToTheDiagonal) {
  for (double scale : {1e-6, 1.0, 1e6}) {
    PolygonSoup soup = test::truncatedOctahedron();
    for (Vec3& p : soup.positions) p = p * scale + Vec3(1e3 * scale);
    EXPECT_EQ(convexityError(soup), "") << scale;
    PolygonSoup lPrism = test::lPrism();
    for (Vec3& p : lPrism.positions) p = p * scale + Vec3(1e3 * scale);
    EXPECT_THAT(convexityError(lPrism), HasSubstr("reflex")) << scale;
  }
}

// F3: the checks run in cage-relative coordinates. Dyadic scales and offsets keep the shapes
// exact, so any refusal would be the check's own round-off (world coordinates of 2^27 ≈ 1e8 made
// the Newell normal of a unit triangle noise and refused a tetrahedron).
TEST(ConvexCage, IsInvariantUnderTranslationAndScale) {
  for (double scale : {std::ldexp(1.0, -20), 1.0, std::ldexp(1.0, 20)}) {
    for (int exponent : {10, 27, 33, 40}) {  // offsets 1e3, 1.3e8, 8.6e9, 1.1e12 (× scale)
      const auto moved = [&](PolygonSoup soup) {
        for (Vec3& p : soup.positions) p = p * scale + Vec3(std::ldexp(scale, exponent));
        return soup;
      };
      const std::string where = std::to_string(scale) + " 2^" + std::to_string(exponent);
      EXPECT_EQ(convexityError(moved(test::tetrahedron())), "") << where;
      const Cage box(moved(test::triangulated(test::convexBox(Vec3(-1.0), Vec3(1.0)))));
      EXPECT_EQ(detail::buildConvexPolyhedron(box, "M", kDefaultPlanarity).faces.size(), 6u)
          << where;
      EXPECT_THAT(convexityError(moved(test::lPrism())), HasSubstr("edge between vertices 3 and 9"))
          << where;
    }
  }
}

namespace {

// The box [-1,1]² × [0,1] whose top is two quads meeting at a ridge x = 0 lowered by `dip`
// (raised where negative): the ridge turns inward by ~2 dip radians when dip > 0.
PolygonSoup roof(double dip) {
  PolygonSoup s;
  s.positions = {Vec3(-1, -1, 0),     Vec3(1, -1, 0),       Vec3(1, 1, 0),  Vec3(-1, 1, 0),
                 Vec3(-1, -1, 1),     Vec3(0, -1, 1 - dip), Vec3(1, -1, 1), Vec3(1, 1, 1),
                 Vec3(0, 1, 1 - dip), Vec3(-1, 1, 1)};
  for (std::vector<std::uint32_t> face : {std::vector<std::uint32_t>{0, 3, 2, 1},
                                          {4, 5, 8, 9},
                                          {5, 6, 7, 8},
                                          {0, 1, 6, 5, 4},
                                          {2, 3, 9, 8, 7},
                                          {3, 0, 4, 9},
                                          {1, 2, 7, 6}})
    s.addPolygon(face);
  return s;
}

}  // namespace

// F11 / F5: cages written by ordinary exporters (6 decimals, float32), rotated so that the
// rounding leaves faces non-planar by ~1e-7 diagonals, are accepted with the default planarity,
// as quads and as triangles (which merge back into the same polyhedron: one tolerance for both).
TEST(ConvexCage, AcceptsCagesRoundedByExporters) {
  const PolygonSoup shapes[] = {test::convexBox(Vec3(-1.0), Vec3(1.0)), test::hexagonalPrism(),
                                test::truncatedOctahedron()};
  for (unsigned seed = 1; seed <= 10; ++seed) {
    for (const PolygonSoup& shape : shapes) {
      for (const PolygonSoup& soup : {test::rotatedAndRounded(shape, seed, test::sixDecimals),
                                      test::rotatedAndRounded(shape, seed, test::float32)}) {
        const std::size_t faces =
            detail::buildConvexPolyhedron(Cage(soup), "M", kDefaultPlanarity).faces.size();
        EXPECT_EQ(faces, shape.polygonCount()) << seed;
        EXPECT_EQ(
            detail::buildConvexPolyhedron(Cage(test::triangulated(soup)), "M", kDefaultPlanarity)
                .faces.size(),
            faces)
            << seed;
      }
    }
  }
}

// An edge turning inward by 1e-3 radians is refused (as quads and as triangles), naming the
// edge; the same roof turned outward is accepted. A planarity of 0 refuses the rounded box.
TEST(ConvexCage, RefusesAReflexEdgeOfAMilliradian) {
  for (const PolygonSoup& soup : {roof(5e-4), test::triangulated(roof(5e-4))}) {
    const std::string message = convexityError(soup);
    EXPECT_THAT(message, HasSubstr("the edge between vertices 5 and 8"));
    EXPECT_THAT(message,
                HasSubstr("is reflex (turning inward by 0.0573 degrees, which lifts a corner"));
    EXPECT_THAT(message, HasSubstr("more than planarity = 1e-06"));
  }
  EXPECT_EQ(convexityError(roof(-5e-4)), "");
  EXPECT_EQ(convexityError(test::triangulated(roof(-5e-4))), "");
  const Cage rounded(
      test::rotatedAndRounded(test::convexBox(Vec3(-1.0), Vec3(1.0)), 1, test::float32));
  EXPECT_THAT(test::messageOf<InvalidInput>([&] { checkConvexCage(rounded, "M", 0.0); }),
              HasSubstr("more than planarity = 0"));
  EXPECT_THAT(test::messageOf<InvalidInput>([&] { checkConvexCage(rounded, "M", 0.1); }),
              HasSubstr("planarity must be in [0, 1e-2]"));
}

// F5: a triangulation folded back onto itself (a fan of the L prism's concave caps) says so, with
// a positive angle.
TEST(ConvexCage, SaysWhereATriangulationFoldsBack) {
  const std::string message = convexityError(test::triangulated(test::lPrism()));
  EXPECT_THAT(message, HasSubstr("the cage is not convex: the edge between vertices"));
  EXPECT_THAT(message, testing::Not(HasSubstr("by -")));
}

// The armadillo's cage (optional shared data) is far from convex: the message names one edge.
TEST(ConvexCage, RejectsTheArmadilloCageNamingAReflexEdge) {
  const auto path =
      std::filesystem::path(SPACEWARP_SHARED_DATA_DIR) / "ju2005-armadillo" / "bounding_mesh.obj";
  if (!std::filesystem::exists(path)) GTEST_SKIP() << "shared data not found: " << path;
  const std::string message = test::messageOf<InvalidInput>(
      [&] { checkConvexCage(Cage::fromFile(path), "WachspressCoordinates"); });
  EXPECT_THAT(message, HasSubstr("bounding_mesh.obj: the cage is not convex: the edge between "
                                 "vertices "));
  EXPECT_THAT(message, HasSubstr(") is reflex (turning inward by "));
}

// Discrete harmonic coordinates' check: convex, and every polytope face a triangle.
TEST(ConvexCage, SimplicialCheckNamesThePolygonFace) {
  auto error = [](const PolygonSoup& soup) {
    return test::messageOf<InvalidInput>(
        [&] { checkSimplicialConvexCage(Cage(soup, "c.obj"), "M"); });
  };
  for (const PolygonSoup& soup : {test::tetrahedron(), test::octahedron(), test::icosphere(2),
                                  test::randomSphereHull(30, 5)}) {
    EXPECT_EQ(error(soup), "");
  }
  const PolygonSoup box = test::convexBox(Vec3(0.0), Vec3(1.0));
  EXPECT_THAT(error(box), HasSubstr("M: c.obj: face 0 (vertices "));
  EXPECT_THAT(error(box), HasSubstr(") is a planar quad: discrete harmonic coordinates need"));
  EXPECT_THAT(error(test::triangulated(box)),
              HasSubstr("M: c.obj: the coplanar faces 0, 1 merge into a planar quad"));
  EXPECT_THAT(error(test::hexagonalPrism()), HasSubstr("is a planar hexagon"));
  EXPECT_THAT(error(test::pinchedBox(0.5)), HasSubstr("reflex"));  // convexity first
}

}  // namespace
}  // namespace spacewarp
