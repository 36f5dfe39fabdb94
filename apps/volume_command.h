#pragma once
// `spacewarp deform` on OpenVDB files: every grid of the file warped by the rig's warp.

#include <filesystem>
#include <string>

#include <CLI/CLI.hpp>

#include "apps/cli_context.h"
#include "core/geometry.h"
#include "core/warp.h"

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

/// Warps every supported grid of `input` (float, double and vec3s grids — level sets, fog
/// volumes, fields — and point data grids) and writes them, with their names and metadata and
/// the file's metadata, to `output` atomically (a temporary in the same folder, renamed).
/// Grids of other types are left out with a warning on stderr. Throws IoError naming the file
/// if it is missing or not a VDB file, InvalidInput naming it if it holds no supported grid or
/// a grid cannot be warped (non-linear transform, non-cubic level set voxels); nothing is
/// written then. Voxels whose preimage was not found are reported on stderr.
void deformVolumeFile(const Warp& warp, const std::filesystem::path& input,
                      const std::filesystem::path& output, const VolumeCliOptions& options,
                      const CliContext& context);

}  // namespace spacewarp::cli
