#pragma once
// Warping one grid brick by brick, so that the expensive part of warpVolume() (the inverse
// solve of every output voxel) can run on other processes or machines, each reading only the
// part of the input it needs, and still give the single-process result.
//
//   1. planVolumeBricks() (the driver, cheap: the warp at the seeding cells only) computes
//      where every seeding cell's image lands, splits the output's index space into cubic
//      bricks and lists for each brick the cells that reach it and the input box (those cells
//      and a halo) that it reads.
//   2. warpVolumeBrick() (a worker) resamples the output leaves of one brick from those cells,
//      with the input read through readVdbGridRegion() (OpenVDB's clipped, partial read).
//   3. mergeVolumeBricks() (the driver) puts the bricks' leaves into one grid and, for level
//      sets, runs the re-distancing once over the whole of it (LevelSetTracker's stencils and
//      band growth are not brick-local).
//
// Equality: every output voxel is seeded from the same cells, in the same order, as in
// warpVolume() and samples the same input values, so the merged grid has the same active
// voxels and bit-identical values as warpVolume() on one process, provided the warp's
// apply/jacobian/applyBatch give a point the same bits wherever it is evaluated. A voxel whose
// preimage lands outside the brick's input box is reported (WarpedBrick::haloMisses); the
// brick must then be warped again from the whole input (the caller's fallback), which again
// gives the same bits. Report counts are sums over the bricks; massAfter is the same sum in
// another order (equal within rounding). Not supported: cacheSpacing (its lattice depends on
// every cell) and point data grids (warp those with warpPoints()).

#include <cstddef>
#include <filesystem>
#include <string>
#include <vector>

#include <openvdb/openvdb.h>

#include <spacewarp/core/warp.h>
#include <spacewarp/volume/warp_volume.h>

namespace spacewarp {

/// One brick: the output voxels it resamples and what it reads.
struct VolumeBrick {
  /// Output voxels (index space, leaf-aligned, inclusive).
  openvdb::CoordBBox output;
  /// Input voxels it reads (index space, inclusive): its cells widened by the halo.
  openvdb::CoordBBox input;
  /// The seeding cells that reach it: keys k of input voxels k·c .. k·c + c − 1 per axis,
  /// c = WarpVolumeOptions::seedSpacing; sorted (x, then y, then z).
  std::vector<openvdb::Coord> cells;
};

/// Options of planVolumeBricks().
struct VolumeBrickOptions {
  /// Edge of a brick in output voxels, rounded up to a multiple of the leaf size (8).
  /// Default 64.
  int brickSize = 64;
  /// Input voxels read around a brick's cells, beyond the 2-voxel sampling stencil. The
  /// preimages of a brick's voxels lie within about a voxel of its cells for warps smooth at
  /// the cell scale, so the default 4 rarely misses (misses are detected and redone, see
  /// WarpedBrick::haloMisses).
  int halo = 4;
};

/// The plan of a grid: its bricks (those that some cell reaches, in order of their corner) and
/// what the merge needs from the whole grid.
struct VolumeBrickPlan {
  std::vector<VolumeBrick> bricks;
  /// Jᵀ J = I at every cell center (level sets are then not re-distanced).
  bool rigid = true;
  /// min(1, smallest singular value of J over the cells): the band growth of level sets.
  double smallestStretch = 1.0;
  /// What is known before solving: input counts, massBefore, halfWidth, unmappedVoxels.
  WarpVolumeReport report;
};

/// Plans `grid` (float, double or vec3s; the whole grid). Throws InvalidInput as warpVolume()
/// does, for options.cacheSpacing > 0, for point data grids and for brickSize < 1 or halo < 0.
VolumeBrickPlan planVolumeBricks(const Warp& warp, const openvdb::GridBase& grid,
                                 const WarpVolumeOptions& options,
                                 const VolumeBrickOptions& brickOptions = {});

/// A warped brick: its output leaves (not re-distanced), the report of its voxels, and the
/// voxels it could not settle because their preimage's stencil left brick.input.
struct WarpedBrick {
  openvdb::GridBase::Ptr grid;
  WarpVolumeReport report;
  std::size_t haloMisses = 0;
};

/// Resamples `brick` of a grid planned with planVolumeBricks() (same warp and options).
/// `input` is the grid, whole or read with readVdbGridRegion() over at least brick.input;
/// `rigid` is VolumeBrickPlan::rigid. With `clipped`, stencils outside brick.input are counted
/// in haloMisses (and those voxels left out); the caller must then warp the brick again from
/// the whole grid (clipped false), which never misses.
WarpedBrick warpVolumeBrick(const Warp& warp, const openvdb::GridBase& input,
                            const WarpVolumeOptions& options, const VolumeBrick& brick, bool rigid,
                            bool clipped);

/// The grid of the bricks of `plan` merged into one (name, class, transform and metadata of
/// the bricks'), level sets re-distanced as warpVolume() does; `inputBackground` is the input
/// grid's background. The report sums the bricks' with the plan's. Throws InvalidInput when
/// `bricks` is empty or the bricks' types differ.
WarpedGrid<openvdb::GridBase> mergeVolumeBricks(const std::vector<WarpedBrick>& bricks,
                                                const VolumeBrickPlan& plan, double inputBackground,
                                                const WarpVolumeOptions& options);

/// Reads grid `name` of the VDB file at `path`, only the voxels in (and near) the index box
/// `region`: OpenVDB reads the leaf buffers that intersect it and clips the rest; voxels inside
/// `region` keep their values and states. Throws IoError naming the file for a missing or
/// corrupt file or grid.
openvdb::GridBase::Ptr readVdbGridRegion(const std::filesystem::path& path, const std::string& name,
                                         const openvdb::CoordBBox& region);

/// A grid to bytes (OpenVDB's stream format) and back: how bricks travel between processes.
std::string gridToBytes(const openvdb::GridBase& grid);
openvdb::GridBase::Ptr gridFromBytes(const std::string& bytes);

}  // namespace spacewarp
