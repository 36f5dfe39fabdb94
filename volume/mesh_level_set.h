#pragma once
// A narrow-band signed distance level set of a closed polygon soup, by OpenVDB's
// tools::meshToLevelSet (triangles and quads as they are, larger polygons fanned).

#include <openvdb/openvdb.h>

#include <spacewarp/core/geometry.h>

namespace spacewarp {

/// The level set of `closed` (world units) on a grid of voxel edge `voxelSize` whose voxel
/// (0, 0, 0) is centred at the world origin, with `halfWidth` voxels of active band on each
/// side of the surface; negative inside. Inactive voxels hold ±halfWidth × voxelSize, negative
/// inside (OpenVDB's sign flood fill), which is meaningful only when the soup is closed. Throws
/// InvalidInput for a non-positive or non-finite voxel size or half width, and what
/// PolygonSoup::validate() throws.
openvdb::FloatGrid::Ptr meshLevelSet(const PolygonSoup& closed, double voxelSize,
                                     float halfWidth = 3.0f);

}  // namespace spacewarp
