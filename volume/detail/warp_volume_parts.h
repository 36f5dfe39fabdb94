#pragma once
// Hooks into warpVolume() (volume/warp_volume.cpp) for warping a grid piece by piece
// (volume/warp_volume_bricks.h): the seeding cells' output boxes, a resampling restricted to
// some output leaves and seeding cells, and the level-set re-distancing applied afterwards to
// the merged pieces. Each piece gives its voxels the same bits as the whole warp does, because
// a voxel's value depends only on the cells whose images reach its leaf (taken in the same
// relative order) and on the input near its preimage.

#include <cstddef>
#include <optional>
#include <vector>

#include <openvdb/openvdb.h>

#include <spacewarp/core/warp.h>
#include <spacewarp/volume/warp_volume.h>

namespace spacewarp::detail {

/// The seeding cells of a grid (keys k: input voxels k·c .. k·c + c − 1 per axis, c =
/// seedSpacing) and, for each, the box of output voxels its images may reach (the union over
/// the cell and the pieces it was split into; empty where the warp is not usable there).
struct VolumeCellImages {
  std::vector<openvdb::Coord> keys;          ///< sorted (x, then y, then z)
  std::vector<openvdb::CoordBBox> outBoxes;  ///< one per key, output index space
  bool rigid = true;                         ///< Jᵀ J = I at every cell center
  double smallestStretch = 1.0;              ///< min(1, smallest singular value of J over cells)
};

/// Stages 1–3 of warpVolume() on `grid` (float, double or vec3s): the cells and what the
/// report knows before any voxel is solved (input counts, mass before, half-width, unmapped
/// voxels). Throws as warpVolume() does (bad options, transforms, the candidate bound).
VolumeCellImages volumeCellImages(const Warp& warp, const openvdb::GridBase& grid,
                                  const WarpVolumeOptions& options, WarpVolumeReport& report);

/// A restriction of warpVolume() to a part of its output.
struct VolumePart {
  /// Seed only from these cells (keys as in VolumeCellImages, sorted), not from every cell
  /// with active voxels.
  std::vector<openvdb::Coord> cellKeys;
  /// Solve only the output voxels of the leaves inside this box (leaf-aligned, index space).
  openvdb::CoordBBox outputBox;
  /// The whole grid's rigidity (VolumeCellImages::rigid), which decides how level-set values
  /// are scaled.
  bool rigid = true;
  /// When set, the input is known only inside this index box (a clipped read): voxels whose
  /// sampling stencil reaches outside it are not stored but counted in `haloMisses`.
  std::optional<openvdb::CoordBBox> validInput;
  /// Out: voxels left out because their stencil left `validInput`.
  std::size_t haloMisses = 0;
};

/// Resamples the part of `grid` that `part` names, as warpVolume() would, without the level-set
/// re-distancing (and without its signed flood fill). Throws InvalidInput for
/// options.cacheSpacing > 0 (the cache lattice depends on every cell).
WarpedGrid<openvdb::GridBase> warpVolumePart(const Warp& warp, const openvdb::GridBase& grid,
                                             const WarpVolumeOptions& options, VolumePart& part);

/// The re-distancing step of warpVolume() for a resampled level set `grid` (float or double,
/// modified in place or replaced), with the whole input's `inputBackground`, rigidity and
/// smallest stretch. Sets report.redistanced and report.bandLayersAdded; needs
/// report.halfWidth.
void redistanceVolume(openvdb::GridBase::Ptr& grid, double inputBackground, bool rigid,
                      double smallestStretch, const WarpVolumeOptions& options,
                      WarpVolumeReport& report);

/// Joins a piece's range of |det J| (a leaf of warpVolume(), a brick) into `report`'s. A piece
/// with maxChange 0 divided nothing and is left out; the report's range is [0, 0] until one did.
void joinVolumeChange(WarpVolumeReport& report, double minChange, double maxChange);

}  // namespace spacewarp::detail
