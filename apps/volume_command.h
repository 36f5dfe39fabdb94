#pragma once
// `spacewarp deform` on OpenVDB files: every grid of the file warped by the rig's warp.

#include <filesystem>
#include <string>

#include <CLI/CLI.hpp>

#include <spacewarp/core/geometry.h>
#include <spacewarp/core/warp.h>
#include "apps/cli_context.h"

namespace spacewarp::cli {

/// The deform options that only volumes use.
struct VolumeCliOptions {
  std::string sampler = "trilinear";  ///< --sampler trilinear|triquadratic
  bool conserveMass = false;          ///< --conserve-mass (fog volumes)
  std::string vectors = "auto";       ///< --vectors auto|push|normal|keep (vec3s grids)
};

/// Adds the volume options to `command`.
void addVolumeOptions(CLI::App* command, VolumeCliOptions& options);

/// True when this build can read and write volumes (SPACEWARP_WITH_OPENVDB).
bool volumesSupported();

/// Writes the narrow-band level set (half-width 3 voxels) of a closed polygon soup, with
/// voxels of `voxelSize` world units, as the grid "surface" of a VDB file: the demo's volume.
/// Throws InvalidInput if volumes are not supported by this build.
void writeMeshLevelSet(const PolygonSoup& closed, double voxelSize,
                       const std::filesystem::path& path);

/// True for paths the volume route handles (".vdb").
bool isVolumePath(const std::filesystem::path& path);

/// What deformVolumeFile did, for the command's summary line.
struct VolumeSummary {
  std::size_t grids = 0;            ///< grids written
  std::size_t activeVoxels = 0;     ///< active voxels of the written scalar and vector grids
  std::size_t points = 0;           ///< points moved in point data grids
  std::size_t inverseFailures = 0;  ///< voxels left inactive because the inverse failed
};

/// Throws IoError naming `path` unless it is an existing OpenVDB file (only its header, metadata
/// and grid descriptors are read, which is enough to refuse a truncated file), InvalidInput if this
/// build has no volume support: the checks `deform` makes before it builds a rig.
void checkVolumeFile(const std::filesystem::path& path);

/// Prints what `path` holds: the file's metadata, then for each grid its name, class (level
/// set, fog volume, staggered, unknown), value type, voxel size, active voxel count, active
/// bounding box (index and world space), point count (point data grids) and metadata.
/// Throws as deformVolumeFile does for a missing or non-VDB file. What OpenVDB logs while
/// reading is printed as warnings naming the file (CliContext::warn).
void printVolumeInfo(const std::filesystem::path& path, const CliContext& context);

/// Warps every supported grid of `input` (float, double and vec3s grids — level sets, fog
/// volumes, fields — and point data grids) and writes them, with their names and metadata and
/// the file's metadata, to `output` atomically (a temporary in the same folder, renamed).
/// Grids of other types are left out with a warning (CliContext::warn). Throws IoError naming the
/// file if it is missing, not a VDB file or truncated or corrupt, InvalidInput naming it if it
/// holds no supported grid or a grid cannot be warped (non-linear transform, non-cubic level set
/// voxels); nothing is written then. Voxels whose preimage was not found are reported as warnings,
/// and so is what OpenVDB logs (naming the file read or written then).
VolumeSummary deformVolumeFile(const Warp& warp, const std::filesystem::path& input,
                               const std::filesystem::path& output, const VolumeCliOptions& options,
                               const CliContext& context);

}  // namespace spacewarp::cli
