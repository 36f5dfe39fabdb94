#include <spacewarp/surface/surface_mesh.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <numeric>
#include <string>
#include <unordered_map>

#include <spacewarp/core/errors.h>
#include <spacewarp/surface/detail/edit_problem.h>

namespace spacewarp {

namespace {

struct CellKey {
  std::int64_t x, y, z;
  bool operator==(const CellKey&) const = default;
};
struct CellHash {
  std::size_t operator()(const CellKey& k) const {
    std::size_t h = std::hash<std::int64_t>()(k.x);
    h = h * 1000003u ^ std::hash<std::int64_t>()(k.y);
    return h * 1000003u ^ std::hash<std::int64_t>()(k.z);
  }
};

// Mesh vertex of every soup vertex: each joins the first earlier mesh vertex within `tolerance`
// (cells of that size, the 27 around it searched), so the result does not depend on anything
// but the vertex order. Cells are counted from the box's corner, so far-away coordinates do
// not overflow them.
std::vector<std::uint32_t> weldVertices(std::span<const Vec3> points, double tolerance,
                                        std::vector<Vec3>& welded) {
  std::vector<std::uint32_t> map(points.size());
  const BoundingBox box = boundingBox(points);
  const bool exact = !(tolerance > 0.0);
  const double cell = exact ? 1.0 : tolerance;
  auto keyOf = [&](const Vec3& p) {
    if (exact) {
      return CellKey{std::bit_cast<std::int64_t>(p.x + 0.0), std::bit_cast<std::int64_t>(p.y + 0.0),
                     std::bit_cast<std::int64_t>(p.z + 0.0)};
    }
    const Vec3 c = glm::floor((p - box.min) / cell);
    return CellKey{std::int64_t(c.x), std::int64_t(c.y), std::int64_t(c.z)};
  };
  std::unordered_map<CellKey, std::vector<std::uint32_t>, CellHash> cells;
  cells.reserve(points.size());
  const double tol2 = tolerance * tolerance;
  for (std::size_t v = 0; v < points.size(); ++v) {
    const CellKey key = keyOf(points[v]);
    std::uint32_t found = std::uint32_t(-1);
    if (exact) {
      if (auto it = cells.find(key); it != cells.end()) found = it->second.front();
    } else {
      for (std::int64_t dx = -1; dx <= 1; ++dx)
        for (std::int64_t dy = -1; dy <= 1; ++dy)
          for (std::int64_t dz = -1; dz <= 1; ++dz) {
            auto it = cells.find({key.x + dx, key.y + dy, key.z + dz});
            if (it == cells.end()) continue;
            for (std::uint32_t m : it->second) {
              const Vec3 d = welded[m] - points[v];
              if (glm::dot(d, d) <= tol2 && m < found) found = m;
            }
          }
    }
    if (found == std::uint32_t(-1)) {
      found = static_cast<std::uint32_t>(welded.size());
      welded.push_back(points[v]);
      cells[key].push_back(found);
    }
    map[v] = found;
  }
  return map;
}

// Edges with their triangle counts, and the vertices whose incident triangles fall into more
// than one fan (connected through shared edges around the vertex).
void reportEdgesAndFans(SurfaceMesh& mesh) {
  struct HalfEdge {
    std::uint32_t a, b, triangle;
  };
  std::vector<HalfEdge> edges;
  edges.reserve(mesh.triangles.size() * 3);
  for (std::uint32_t t = 0; t < mesh.triangles.size(); ++t)
    for (int c = 0; c < 3; ++c) {
      std::uint32_t a = mesh.triangles[t][c], b = mesh.triangles[t][(c + 1) % 3];
      if (a > b) std::swap(a, b);
      edges.push_back({a, b, t});
    }
  std::sort(edges.begin(), edges.end(), [](const HalfEdge& l, const HalfEdge& r) {
    return std::tie(l.a, l.b, l.triangle) < std::tie(r.a, r.b, r.triangle);
  });
  MeshReport& report = mesh.report;
  for (std::size_t i = 0; i < edges.size();) {
    std::size_t j = i;
    while (j < edges.size() && edges[j].a == edges[i].a && edges[j].b == edges[i].b) ++j;
    if (j - i == 1) ++report.boundaryEdges;
    if (j - i > 2) report.nonManifoldEdges.push_back({edges[i].a, edges[i].b});
    i = j;
  }

  // Fans: per vertex, union its triangles that share an edge at the vertex.
  const std::size_t n = mesh.positions.size();
  std::vector<std::uint32_t> offsets(n + 1, 0);
  for (const auto& t : mesh.triangles)
    for (std::uint32_t v : t) ++offsets[v + 1];
  std::partial_sum(offsets.begin(), offsets.end(), offsets.begin());
  std::vector<std::uint32_t> incident(offsets.back());
  std::vector<std::uint32_t> fill(offsets.begin(), offsets.end() - 1);
  for (std::uint32_t t = 0; t < mesh.triangles.size(); ++t)
    for (std::uint32_t v : mesh.triangles[t]) incident[fill[v]++] = t;
  std::vector<std::uint32_t> parent;
  std::vector<std::pair<std::uint32_t, std::uint32_t>> spokes;  // (other vertex, local index)
  for (std::uint32_t v = 0; v < n; ++v) {
    const std::uint32_t begin = offsets[v], count = offsets[v + 1] - begin;
    if (count < 2) continue;
    parent.resize(count);
    std::iota(parent.begin(), parent.end(), 0u);
    auto find = [&](std::uint32_t x) {
      while (parent[x] != x) x = parent[x] = parent[parent[x]];
      return x;
    };
    spokes.clear();
    for (std::uint32_t k = 0; k < count; ++k)
      for (std::uint32_t w : mesh.triangles[incident[begin + k]])
        if (w != v) spokes.push_back({w, k});
    std::sort(spokes.begin(), spokes.end());
    for (std::size_t s = 1; s < spokes.size(); ++s)
      if (spokes[s].first == spokes[s - 1].first)
        parent[find(spokes[s].second)] = find(spokes[s - 1].second);
    std::uint32_t roots = 0;
    for (std::uint32_t k = 0; k < count; ++k) roots += find(k) == k;
    if (roots > 1) report.nonManifoldVertices.push_back(v);
  }
}

}  // namespace

std::vector<Vec3> SurfaceMesh::toSoupPositions(std::span<const Vec3> meshPositions) const {
  if (meshPositions.size() != positions.size()) {
    throw InvalidInput("SurfaceMesh::toSoupPositions: " + std::to_string(meshPositions.size()) +
                       " positions for a mesh of " + std::to_string(positions.size()) +
                       " vertices");
  }
  std::vector<Vec3> out(soupToMesh.size());
  for (std::size_t v = 0; v < out.size(); ++v) out[v] = meshPositions[soupToMesh[v]];
  return out;
}

SurfaceMesh weldSoup(const PolygonSoup& soup, const WeldOptions& options) {
  soup.validate();
  if (soup.polygonCount() == 0) throw InvalidInput("weldSoup: the soup has no polygon");
  if (!(options.relativeTolerance >= 0.0) || !std::isfinite(options.relativeTolerance)) {
    throw InvalidInput("weldSoup: relativeTolerance must be finite and >= 0");
  }
  detail::checkSurfaceScale(soup.positions, "weldSoup");
  SurfaceMesh mesh;
  const double tolerance = options.relativeTolerance * boundingBox(soup.positions).diagonal();
  mesh.soupToMesh = weldVertices(soup.positions, tolerance, mesh.positions);
  for (std::uint32_t p = 0; p < soup.polygonCount(); ++p) {
    const auto corners = soup.polygon(p);
    std::size_t kept = 0;
    for (std::size_t c = 1; c + 1 < corners.size(); ++c) {
      const std::array<std::uint32_t, 3> t{mesh.soupToMesh[corners[0]], mesh.soupToMesh[corners[c]],
                                           mesh.soupToMesh[corners[c + 1]]};
      if (t[0] == t[1] || t[1] == t[2] || t[0] == t[2]) continue;
      mesh.triangles.push_back(t);
      mesh.triangleToPolygon.push_back(p);
      ++kept;
    }
    if (kept == 0) mesh.report.droppedPolygons.push_back(p);
  }
  reportEdgesAndFans(mesh);
  for (std::uint32_t t = 0; t < mesh.triangles.size(); ++t) {
    const auto& tri = mesh.triangles[t];
    if (detail::isDegenerateTriangle(mesh.positions[tri[0]], mesh.positions[tri[1]],
                                     mesh.positions[tri[2]]))
      mesh.report.degenerateTriangles.push_back(t);
  }
  mesh.vertexComponent =
      detail::vertexComponents(mesh.positions, mesh.triangles, mesh.report.componentCount);
  std::vector<bool> used(mesh.positions.size(), false);
  for (const auto& t : mesh.triangles)
    for (std::uint32_t v : t) used[v] = true;
  for (std::uint32_t v = 0; v < used.size(); ++v)
    if (!used[v]) mesh.report.isolatedVertices.push_back(v);
  return mesh;
}

PolygonSoup toSoup(const SurfaceMesh& mesh) {
  PolygonSoup soup;
  soup.positions = mesh.positions;
  for (const auto& t : mesh.triangles) soup.addPolygon({t[0], t[1], t[2]});
  return soup;
}

}  // namespace spacewarp
