#pragma once
// Applying a warp or its inverse to geometry: positions move through the map, normals through
// the inverse transpose of its Jacobian.

#include <spacewarp/core/geometry.h>
#include <spacewarp/core/inverse.h>
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

/// What deformInverse() found.
struct InverseDeformReport {
  /// Vertices whose preimage is the warp's closed form (Warp::exactInverse()), and those solved
  /// iteratively (Newton from the default seed, then continuation), of which `continuation`
  /// needed the continuation fallback.
  std::size_t closedForm = 0;
  std::size_t iterative = 0;
  std::size_t continuation = 0;
  /// The largest |warp(x) - y| over the vertices, world units.
  double maxResidual = 0.0;
  /// Vertices whose normals were carried through a singular Jacobian of the warp at their
  /// preimage (the inverse is not differentiable there), as in DeformReport.
  std::size_t singularNormals = 0;
};

/// The inverse of deform(): moves every position y to its preimage x under `warp` (warp(x) = y,
/// found by inverse() with `options`, in parallel), so that deform(warp, ·) of the result gives
/// the positions back to the tolerance; normals n are carried through the inverse's Jacobian,
/// J(x)^T n normalised (transformNormalByInverse()). Other attributes are untouched. The
/// tolerance is options.tolerance × options.lengthScale when that is positive (e.g. the
/// input's bounding-box diagonal), otherwise relative to each point (see InverseOptions).
/// All or nothing: throws SolverError if the solve of any vertex did not converge, naming the
/// first (index, position, residual, tolerance) and how many failed, and InvalidInput if a
/// position is not finite; the set is then unchanged. Reports the stage "inverse" to
/// `progress`; a cancel throws Cancelled and leaves the set unchanged.
InverseDeformReport deformInverse(const Warp& warp, PointSet& points,
                                  const InverseOptions& options = {},
                                  const ProgressCallback& progress = {});

/// The same for a polygon soup's vertices; per-corner normals are carried through the Jacobians
/// at their vertices' preimages, sharing kept as in deform(). Polygons, face attributes and
/// texture coordinates are untouched.
InverseDeformReport deformInverse(const Warp& warp, PolygonSoup& soup,
                                  const InverseOptions& options = {},
                                  const ProgressCallback& progress = {});

}  // namespace spacewarp
