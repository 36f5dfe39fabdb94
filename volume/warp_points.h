#pragma once
// Warping OpenVDB point data grids with any Warp: every point moves to warp(position), with
// its attributes, through OpenVDB's own point-moving API (openvdb::points::movePoints), which
// re-buckets the points into the leaves of their new positions.

#include <openvdb/points/PointDataGrid.h>

#include <spacewarp/volume/warp_volume.h>
#include <spacewarp/core/warp.h>

namespace spacewarp {

/// A deep copy of `grid` with every point at warp(p) (world units), attributes and groups
/// kept, the same transform, name and metadata. Only `options.progress` is used (stage "warp
/// volume", fraction of leaves done); the report gives the number of points
/// (WarpVolumeReport::points). Throws InvalidInput if a moved point is not finite (it names
/// the point's old position), Cancelled if progress asks.
WarpedGrid<openvdb::points::PointDataGrid> warpPoints(const Warp& warp,
                                                      const openvdb::points::PointDataGrid& grid,
                                                      const WarpVolumeOptions& options = {});

}  // namespace spacewarp
