#pragma once
// Applying a warp to geometry: positions move through the warp, normals through J^-T.

#include <spacewarp/core/geometry.h>
#include <spacewarp/core/progress.h>
#include <spacewarp/core/warp.h>

namespace spacewarp {

/// What deform() found while carrying normals.
struct DeformReport {
  /// Vertices whose normals (per vertex or per corner) were carried through a singular
  /// Jacobian (isSingularJacobian: the warp flattens space there), where the normal is
  /// undefined. They get transformNormal's fallback: the image plane's normal at rank 2, a
  /// zero vector below. 0 when there are no normals.
  std::size_t singularNormals = 0;
};

/// Moves every position through `warp` (in parallel) and, if the set has normals, carries
/// each through the warp's Jacobian at its rest position (J^-T n, normalised). Other
/// attributes are untouched. Throws InvalidInput (naming the element) if a position is not
/// finite before or after the warp; the set is then left unchanged. Reports the stage "deform"
/// to `progress`; a cancel throws Cancelled and leaves the set unchanged.
DeformReport deform(const Warp& warp, PointSet& points, const ProgressCallback& progress = {});

/// The same for a polygon soup's vertices. Per-corner normals are carried through the
/// Jacobian at their corner's vertex; corners that share a normal keep sharing it where the
/// results agree bit for bit (always under an affine warp), and otherwise get new normals
/// appended to cornerNormals.values. Normals that no corner uses are left as they are.
/// Polygons, face attributes and texture coordinates are untouched.
DeformReport deform(const Warp& warp, PolygonSoup& soup, const ProgressCallback& progress = {});

}  // namespace spacewarp
