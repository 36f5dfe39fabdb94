#include <spacewarp/core/primitives.h>

#include <array>
#include <map>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

#include <spacewarp/core/errors.h>

namespace spacewarp {
namespace {

// The enclosed volume by the divergence theorem (fan triangles; exact for planar quads).
double signedVolume(const PolygonSoup& soup) {
  double volume = 0.0;
  for (std::size_t f = 0; f < soup.polygonCount(); ++f) {
    const auto p = soup.polygon(f);
    for (std::size_t k = 1; k + 1 < p.size(); ++k) {
      volume += glm::dot(soup.positions[p[0]],
                         glm::cross(soup.positions[p[k]], soup.positions[p[k + 1]])) /
                6.0;
    }
  }
  return volume;
}

TEST(MakeBlocksSurface, AnLIsClosedOutwardAndHasNoInnerFaces) {
  const std::vector<glm::ivec3> cells = {{0, 0, 0}, {1, 0, 0}, {2, 0, 0}, {0, 1, 0}, {0, 1, 0}};
  const double size = 0.5;
  const PolygonSoup soup = makeBlocksSurface(cells, Vec3(1.0, -2.0, 3.0), size);
  soup.validate();
  // 4 distinct cells: 24 faces less 2 per shared face (3 shared).
  EXPECT_EQ(soup.polygonCount(), 4u * 6u - 2u * 3u);
  // Every directed edge appears once and its reverse once: closed and consistently oriented.
  std::map<std::pair<std::uint32_t, std::uint32_t>, int> edges;
  for (std::size_t f = 0; f < soup.polygonCount(); ++f) {
    const auto p = soup.polygon(f);
    for (std::size_t k = 0; k < p.size(); ++k) ++edges[{p[k], p[(k + 1) % p.size()]}];
  }
  for (const auto& [edge, count] : edges) {
    EXPECT_EQ(count, 1);
    EXPECT_EQ(edges.count({edge.second, edge.first}), 1u);
  }
  EXPECT_NEAR(signedVolume(soup), 4.0 * size * size * size, 1e-12);  // outward: positive
  EXPECT_THROW(makeBlocksSurface({}, Vec3(0.0), 1.0), InvalidInput);
  EXPECT_THROW(makeBlocksSurface(cells, Vec3(0.0), 0.0), InvalidInput);
}

}  // namespace
}  // namespace spacewarp
