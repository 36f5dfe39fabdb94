#pragma once
// Procedurally generated geometry for examples, tests and benchmarks, so that none of them
// needs files on disk.

#include <cstdint>

#include <spacewarp/core/geometry.h>

namespace spacewarp {

/// The surface of the box [min, max] as a quad soup, each face split into
/// divisions.x × divisions.y × divisions.z cells along the box's axes, outward oriented,
/// with shared vertices (a closed manifold). Per-vertex normals are the face normals
/// averaged at shared vertices. Throws InvalidInput if a division is < 1 or the box is
/// empty or not finite.
PolygonSoup makeBoxSurface(const Vec3& min, const Vec3& max, const glm::ivec3& divisions);

/// n points uniformly distributed in the box [min, max] (deterministic for a given seed),
/// with a per-point attribute "index" (UInt32). Throws InvalidInput for an empty box.
PointSet makeRandomPoints(const Vec3& min, const Vec3& max, std::size_t n, std::uint64_t seed = 1);

}  // namespace spacewarp
