#pragma once
// Handle regions of a surface edit: vertex sets that move by an affine map (the identity pins
// them) or to given targets. Every other vertex is free.

#include <cstdint>
#include <optional>
#include <span>
#include <vector>

#include <spacewarp/core/math.h>

namespace spacewarp {

/// One handle region: `vertices` move by `matrix` (an affine map of world space) or, when it
/// is empty, each to its entry of `targets` (as many as vertices, world units).
struct HandleRegion {
  std::vector<std::uint32_t> vertices;
  std::optional<Mat4> matrix;
  std::vector<Vec3> targets;
};

/// The constrained vertices of an edit and where they go, one target per vertex, in
/// increasing vertex order.
struct VertexConstraints {
  std::vector<std::uint32_t> vertices;
  std::vector<Vec3> targets;
};

/// The constraints of `regions` on the vertices `rest` (world units). A vertex in several
/// regions must get the same target from each (to 1e-9 of the rest bounding-box diagonal).
/// Throws InvalidInput naming the region and entry at fault: a vertex index out of range, a
/// region without vertices, targets of the wrong count or not finite, a matrix that is not
/// finite or not affine (last row 0 0 0 1), conflicting targets.
VertexConstraints resolveHandles(std::span<const HandleRegion> regions, std::span<const Vec3> rest);

/// The constraints carried through a weld map (mesh vertex of each input vertex, e.g.
/// SurfaceMesh::soupToMesh): conflicting targets of vertices welded into one throw
/// InvalidInput naming both input vertices.
VertexConstraints mapConstraints(const VertexConstraints& constraints,
                                 std::span<const std::uint32_t> vertexMap, double tolerance);

}  // namespace spacewarp
