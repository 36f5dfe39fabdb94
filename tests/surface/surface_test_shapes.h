#pragma once
// Meshes, handle sets and measurements shared by the surface tests.

#include <array>
#include <cmath>
#include <functional>
#include <vector>

#include <glm/gtc/matrix_transform.hpp>

#include <spacewarp/core/primitives.h>
#include <spacewarp/surface/surface_mesh.h>

namespace spacewarp::test {

/// The box [0, length] × [0, 1] × [0, 1] as a triangle mesh (every quad of makeBoxSurface
/// fanned), cells of about 1/divisions.
inline SurfaceMesh bar(double length = 4.0, int divisions = 4) {
  const int along = static_cast<int>(std::lround(length * divisions));
  return weldSoup(makeBoxSurface(Vec3(0.0), Vec3(length, 1.0, 1.0), {along, divisions, divisions}));
}

/// A thin bar [0, 4] × [0, width]², `along` cells long and 2 × 2 across.
inline SurfaceMesh thinBar(double width, int along) {
  return weldSoup(makeBoxSurface(Vec3(0.0), Vec3(4.0, width, width), {along, 2, 2}));
}

/// The soup with every polygon given its own copies of its vertices, as STL-like exports are.
inline PolygonSoup unshared(const PolygonSoup& soup) {
  PolygonSoup out;
  for (std::size_t p = 0; p < soup.polygonCount(); ++p) {
    std::vector<std::uint32_t> corners;
    for (std::uint32_t v : soup.polygon(p)) {
      corners.push_back(static_cast<std::uint32_t>(out.positions.size()));
      out.positions.push_back(soup.positions[v]);
    }
    out.addPolygon(corners);
  }
  return out;
}

/// The vertices satisfying `keep`, in increasing order.
inline std::vector<std::uint32_t> verticesWhere(std::span<const Vec3> positions,
                                                const std::function<bool(const Vec3&)>& keep) {
  std::vector<std::uint32_t> out;
  for (std::uint32_t v = 0; v < positions.size(); ++v)
    if (keep(positions[v])) out.push_back(v);
  return out;
}

/// A rigid motion x -> r x + t as a function.
struct Rigid {
  Mat3 r{1.0};
  Vec3 t{0.0};
  Vec3 operator()(const Vec3& x) const { return r * x + t; }
};

inline Mat3 rotationAbout(const Vec3& axis, double radians) {
  return Mat3(glm::rotate(glm::dmat4(1.0), radians, glm::normalize(axis)));
}

inline std::vector<Vec3> applied(const std::function<Vec3(const Vec3&)>& f,
                                 std::span<const Vec3> points,
                                 std::span<const std::uint32_t> only) {
  std::vector<Vec3> out;
  for (std::uint32_t v : only) out.push_back(f(points[v]));
  return out;
}

/// Largest distance between corresponding points.
inline double maxDistance(std::span<const Vec3> a, std::span<const Vec3> b) {
  double d = 0.0;
  for (std::size_t i = 0; i < a.size(); ++i) d = std::max(d, glm::length(a[i] - b[i]));
  return d;
}

/// Mean of |l' − l| / l over the mesh's edges (each triangle side once per triangle).
inline double meanEdgeLengthChange(const SurfaceMesh& mesh, std::span<const Vec3> deformed) {
  double sum = 0.0;
  std::size_t count = 0;
  for (const auto& t : mesh.triangles)
    for (int c = 0; c < 3; ++c) {
      const std::uint32_t a = t[c], b = t[(c + 1) % 3];
      const double l = glm::length(mesh.positions[a] - mesh.positions[b]);
      sum += std::abs(glm::length(deformed[a] - deformed[b]) - l) / l;
      ++count;
    }
  return sum / double(count);
}

/// The handles of a bar [0, 4] × [0, width]² bent by 90°: the end x <= 0.25 pinned, the end x
/// >= 3.75 turned by 90° about z and carried to where a quarter circle of the free length ends.
struct BentBar {
  std::vector<std::uint32_t> constrained;
  std::vector<Vec3> targets;
};
inline BentBar bentBar(const SurfaceMesh& mesh, double width = 1.0) {
  BentBar b;
  const double radius = 3.5 * 2.0 / M_PI;
  const Vec3 end(0.25 + radius, 0.5 * width + radius, 0.0);
  for (std::uint32_t v = 0; v < mesh.vertexCount(); ++v) {
    const Vec3& x = mesh.positions[v];
    if (x.x <= 0.25 + 1e-12) {
      b.constrained.push_back(v);
      b.targets.push_back(x);
    } else if (x.x >= 3.75 - 1e-12) {
      const Vec3 d = x - Vec3(3.75, 0.5 * width, 0.0);
      b.constrained.push_back(v);
      b.targets.push_back(end + Vec3(-d.y, d.x, d.z));
    }
  }
  return b;
}

}  // namespace spacewarp::test
