#pragma once
// A triangle mesh made from any polygon soup: coincident vertices welded, polygons fanned into
// triangles, and what the surface methods need to know about it (boundaries, non-manifold
// parts, connected components) reported rather than assumed.

#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include <spacewarp/core/geometry.h>
#include <spacewarp/core/math.h>

namespace spacewarp {

/// How weldSoup() merges vertices.
struct WeldOptions {
  /// Vertices closer than this fraction of the soup's bounding-box diagonal become one mesh
  /// vertex (default 1e-9: only copies of the same point, as OBJ and STL exports of a mesh
  /// write them). 0 merges exactly equal positions only.
  double relativeTolerance = 1e-9;
};

/// What weldSoup() found about the surface. Indices are mesh vertices and triangles.
struct MeshReport {
  /// Edges with one triangle: the mesh has holes or is an open sheet (fine for every method).
  std::size_t boundaryEdges = 0;
  /// Edges shared by more than two triangles, as vertex pairs (smaller index first).
  std::vector<std::array<std::uint32_t, 2>> nonManifoldEdges;
  /// Vertices whose triangles do not form one fan (two cones touching at a point).
  std::vector<std::uint32_t> nonManifoldVertices;
  /// Polygons of the soup that welding collapsed (every triangle of their fan had two corners
  /// welded into one vertex): they are not in the mesh. Soup polygon indices.
  std::vector<std::uint32_t> droppedPolygons;
  /// Mesh triangles without area (twice the area at most 1e-12 of the longest edge squared:
  /// collinear corners). They are in the mesh but take no part in the surface energies, so a
  /// vertex on such triangles only follows nothing.
  std::vector<std::uint32_t> degenerateTriangles;
  /// Mesh vertices that no triangle uses (points of the soup outside any polygon).
  std::vector<std::uint32_t> isolatedVertices;
  /// Connected components of the triangles (isolated vertices not counted).
  std::size_t componentCount = 0;

  /// Whether every edge has at most two triangles and every vertex one fan.
  bool isManifold() const { return nonManifoldEdges.empty() && nonManifoldVertices.empty(); }
};

/// A triangle mesh with the weld map back to the soup it came from.
struct SurfaceMesh {
  std::vector<Vec3> positions;  ///< Mesh vertices, world units.
  std::vector<std::array<std::uint32_t, 3>> triangles;
  /// For each soup vertex, its mesh vertex (soup.positions.size() entries).
  std::vector<std::uint32_t> soupToMesh;
  /// For each triangle, the soup polygon it was cut from.
  std::vector<std::uint32_t> triangleToPolygon;
  /// Component of each mesh vertex, 0 .. report.componentCount - 1; isolated vertices get
  /// report.componentCount and up, one each.
  std::vector<std::uint32_t> vertexComponent;
  MeshReport report;

  std::size_t vertexCount() const { return positions.size(); }

  /// The soup's vertices moved as the mesh vertices they were welded into: out[v] =
  /// meshPositions[soupToMesh[v]] (soupToMesh.size() entries).
  std::vector<Vec3> toSoupPositions(std::span<const Vec3> meshPositions) const;
};

/// Welds the soup's coincident vertices, fans every polygon into triangles (polygon p with
/// corners c0..ck gives (c0, ci, ci+1)) and reports boundaries, non-manifold edges and
/// vertices, dropped polygons and components. Never throws for a bad surface: it reports it.
/// Throws InvalidInput if the soup fails validate() or has no polygon.
SurfaceMesh weldSoup(const PolygonSoup& soup, const WeldOptions& options = {});

/// A soup of the mesh's triangles (no attributes), e.g. to write it.
PolygonSoup toSoup(const SurfaceMesh& mesh);

}  // namespace spacewarp
