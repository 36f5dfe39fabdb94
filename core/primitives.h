#pragma once
// Procedurally generated geometry for examples, tests and benchmarks, so that none of them
// needs files on disk.

#include <cstdint>
#include <span>

#include <spacewarp/core/geometry.h>

namespace spacewarp {

/// The surface of the box [min, max] as a quad soup, each face split into
/// divisions.x × divisions.y × divisions.z cells along the box's axes, outward oriented,
/// with shared vertices (a closed manifold). Per-vertex normals are the face normals
/// averaged at shared vertices. Throws InvalidInput if a division is < 1 or the box is
/// empty or not finite.
PolygonSoup makeBoxSurface(const Vec3& min, const Vec3& max, const glm::ivec3& divisions);

/// The surface of a union of cubes: cell c is the cube origin + cellSize × [c, c + 1]. Faces
/// between two cells are left out, the rest are quads, outward oriented, with shared vertices
/// (closed; manifold unless two cells touch along an edge or a corner only). For L-, U- and
/// finger-shaped test models. Duplicate cells count once. Throws InvalidInput for no cells, or
/// a non-finite origin or cell size, or one <= 0.
PolygonSoup makeBlocksSurface(std::span<const glm::ivec3> cells, const Vec3& origin,
                              double cellSize);

/// n points uniformly distributed in the box [min, max] (deterministic for a given seed),
/// with a per-point attribute "index" (UInt32). Throws InvalidInput for an empty box.
PointSet makeRandomPoints(const Vec3& min, const Vec3& max, std::size_t n, std::uint64_t seed = 1);

}  // namespace spacewarp
