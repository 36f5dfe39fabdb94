#pragma once
// Procedural test cages: a tetrahedron, an L-shaped (concave) prism, a star-shaped polyhedron,
// a box with a pinched waist and an icosphere, each a closed, outward-oriented soup.

#include <algorithm>
#include <cmath>
#include <map>
#include <utility>
#include <vector>

#include <spacewarp/core/geometry.h>

namespace spacewarp::test {

inline PolygonSoup tetrahedron() {
  PolygonSoup s;
  s.positions = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0), Vec3(0, 0, 1)};
  s.addPolygon({0, 2, 1});
  s.addPolygon({0, 1, 3});
  s.addPolygon({0, 3, 2});
  s.addPolygon({1, 2, 3});
  return s;
}
inline double tetrahedronVolume() { return 1.0 / 6.0; }

/// An L-shaped prism of height 1 over the L made of the unit squares [0,2]x[0,1] and
/// [0,1]x[1,2]: concave, with two hexagonal caps (face 0 is the bottom cap).
inline PolygonSoup lPrism() {
  PolygonSoup s;
  const double xy[6][2] = {{0, 0}, {2, 0}, {2, 1}, {1, 1}, {1, 2}, {0, 2}};
  for (int z = 0; z < 2; ++z)
    for (const auto& p : xy) s.positions.push_back(Vec3(p[0], p[1], z));
  s.addPolygon({5, 4, 3, 2, 1, 0});    // bottom, facing -z
  s.addPolygon({6, 7, 8, 9, 10, 11});  // top, facing +z
  for (std::uint32_t i = 0; i < 6; ++i) {
    const std::uint32_t j = (i + 1) % 6;
    s.addPolygon({i, j, j + 6, i + 6});
  }
  return s;
}

/// A prism of height 1 over the planar concave ("dart") quad (0,0), (2,1), (0,2), (0.7,1), whose
/// reflex corner is vertex 3: a closed, outward cage whose caps' bilinear patches fold over the
/// notch. Face 0 is the bottom cap {3, 2, 1, 0}.
inline PolygonSoup dartPrism() {
  PolygonSoup s;
  const double xy[4][2] = {{0, 0}, {2, 1}, {0, 2}, {0.7, 1}};
  for (int z = 0; z < 2; ++z)
    for (const auto& p : xy) s.positions.push_back(Vec3(p[0], p[1], z));
  s.addPolygon({3, 2, 1, 0});
  s.addPolygon({4, 5, 6, 7});
  for (std::uint32_t i = 0; i < 4; ++i) {
    const std::uint32_t j = (i + 1) % 4;
    s.addPolygon({i, j, j + 4, i + 4});
  }
  return s;
}

/// A star-shaped (concave) polyhedron: an octahedron whose 8 face centers are pushed out into
/// spikes, 14 vertices and 24 triangles.
inline PolygonSoup star() {
  PolygonSoup s;
  s.positions = {Vec3(1, 0, 0),  Vec3(-1, 0, 0), Vec3(0, 1, 0),
                 Vec3(0, -1, 0), Vec3(0, 0, 1),  Vec3(0, 0, -1)};
  const std::uint32_t faces[8][3] = {{0, 2, 4}, {2, 1, 4}, {1, 3, 4}, {3, 0, 4},
                                     {2, 0, 5}, {1, 2, 5}, {3, 1, 5}, {0, 3, 5}};
  for (const auto& f : faces) {
    const Vec3 c = (s.positions[f[0]] + s.positions[f[1]] + s.positions[f[2]]) / 3.0;
    const auto tip = static_cast<std::uint32_t>(s.positions.size());
    s.positions.push_back(c * 3.0);
    s.addPolygon({f[0], f[1], tip});
    s.addPolygon({f[1], f[2], tip});
    s.addPolygon({f[2], f[0], tip});
  }
  return s;
}

/// The box [−1, 1]³ with its middle ring of vertices (z = 0) scaled by `waist` towards the z
/// axis: concave for waist < 1, 12 vertices, 10 quads (its slanted sides are planar trapezoids).
/// Vertices 0–3 are the bottom ring, 4–7 the waist, 8–11 the top.
inline PolygonSoup pinchedBox(double waist) {
  PolygonSoup s;
  const double ring[4][2] = {{-1, -1}, {1, -1}, {1, 1}, {-1, 1}};
  for (const double z : {-1.0, 0.0, 1.0}) {
    const double scale = z == 0.0 ? waist : 1.0;
    for (const auto& p : ring) s.positions.push_back(Vec3(scale * p[0], scale * p[1], z));
  }
  s.addPolygon({3, 2, 1, 0});
  s.addPolygon({8, 9, 10, 11});
  for (std::uint32_t r = 0; r < 2; ++r) {
    for (std::uint32_t i = 0; i < 4; ++i) {
      const std::uint32_t j = (i + 1) % 4;
      s.addPolygon({4 * r + i, 4 * r + j, 4 * r + 4 + j, 4 * r + 4 + i});
    }
  }
  return s;
}

/// An icosahedron subdivided `levels` times and projected onto the unit sphere.
inline PolygonSoup icosphere(int levels) {
  const double t = (1.0 + std::sqrt(5.0)) / 2.0;
  std::vector<Vec3> v = {{-1, t, 0},  {1, t, 0},  {-1, -t, 0}, {1, -t, 0}, {0, -1, t},  {0, 1, t},
                         {0, -1, -t}, {0, 1, -t}, {t, 0, -1},  {t, 0, 1},  {-t, 0, -1}, {-t, 0, 1}};
  std::vector<glm::u32vec3> f = {{0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11},
                                 {1, 5, 9},  {5, 11, 4}, {11, 10, 2}, {10, 7, 6}, {7, 1, 8},
                                 {3, 9, 4},  {3, 4, 2},  {3, 2, 6},   {3, 6, 8},  {3, 8, 9},
                                 {4, 9, 5},  {2, 4, 11}, {6, 2, 10},  {8, 6, 7},  {9, 8, 1}};
  for (int level = 0; level < levels; ++level) {
    std::map<std::pair<std::uint32_t, std::uint32_t>, std::uint32_t> mid;
    auto midpoint = [&](std::uint32_t a, std::uint32_t b) {
      const auto key = std::minmax(a, b);
      auto [it, inserted] = mid.try_emplace(key, static_cast<std::uint32_t>(v.size()));
      if (inserted) v.push_back((v[a] + v[b]) * 0.5);
      return it->second;
    };
    std::vector<glm::u32vec3> next;
    for (const auto& tri : f) {
      const std::uint32_t ab = midpoint(tri.x, tri.y), bc = midpoint(tri.y, tri.z),
                          ca = midpoint(tri.z, tri.x);
      next.insert(next.end(), {{tri.x, ab, ca}, {tri.y, bc, ab}, {tri.z, ca, bc}, {ab, bc, ca}});
    }
    f = std::move(next);
  }
  PolygonSoup s;
  for (const Vec3& p : v) s.positions.push_back(glm::normalize(p));
  for (const auto& tri : f) s.addPolygon({tri.x, tri.y, tri.z});
  return s;
}

}  // namespace spacewarp::test
