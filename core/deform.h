#pragma once
// Applying a warp to geometry: positions move through the warp, normals through J^-T.

#include "core/geometry.h"
#include "core/progress.h"
#include "core/warp.h"

namespace spacewarp {

/// Moves every position through `warp` (in parallel) and, if the set has normals, carries
/// each through the warp's Jacobian at its rest position (J^-T n, normalised). Other
/// attributes are untouched. Throws InvalidInput (naming the element) if a position is not
/// finite before or after the warp; the set is then left unchanged. Reports the stage "deform"
/// to `progress`; a cancel throws Cancelled and leaves the set unchanged.
void deform(const Warp& warp, PointSet& points, const ProgressCallback& progress = {});

/// The same for a polygon soup's vertices; polygons are untouched.
void deform(const Warp& warp, PolygonSoup& soup, const ProgressCallback& progress = {});

}  // namespace spacewarp
