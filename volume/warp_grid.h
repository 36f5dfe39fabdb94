#pragma once
// Warping a grid of any supported type, chosen at run time (files hold grids of many types):
// dispatches to warpVolume() or warpPoints().

#include <string>

#include <openvdb/openvdb.h>

#include <spacewarp/core/warp.h>
#include <spacewarp/volume/warp_volume.h>

namespace spacewarp {

/// True for the grid types warpGrid() handles: float, double and float-vector grids (level
/// sets, fog volumes, fields) and point data grids.
bool isWarpableGrid(const openvdb::GridBase& grid);

/// True for the grids WarpVolumeOptions::conserveMass applies to: float and double grids that
/// are not level sets.
bool isFogVolume(const openvdb::GridBase& grid);

/// Throws InvalidInput starting with `where` (the file) when none of `grids` is one that
/// isWarpableGrid() accepts, listing the names and types of those there are.
void checkWarpableGrids(const openvdb::GridPtrVec& grids, const std::string& where);

/// Warps `grid` with warpVolume() or warpPoints(), whichever its type needs. Throws
/// InvalidInput naming the grid and its type if isWarpableGrid() is false, and whatever the
/// chosen function throws.
WarpedGrid<openvdb::GridBase> warpGrid(const Warp& warp, const openvdb::GridBase& grid,
                                       const WarpVolumeOptions& options = {});

}  // namespace spacewarp
