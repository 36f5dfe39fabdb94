#pragma once
// The "skinning" rig method: linear blend or dual-quaternion skinning (nonlinear/skinning.h).
// Keys are documented in README.md.

#include <filesystem>
#include <vector>

#include <spacewarp/rig/detail/rig_reader.h>
#include <spacewarp/rig/rig.h>

namespace spacewarp::detail {

/// Reads "mode" ("lbs" or "dqs", default "lbs"), "bones" (row-major 4 × 4 matrices, rest to
/// posed), "influences" (weights kept per point, default 4, 0 for all) and either "weights" (a
/// dense points × bones .csv or .npy file) with "model" (the OBJ/OFF/PLY whose vertices they
/// weigh; other points take their nearest vertex's weights), or "handles" (one [x, y, z] per
/// bone) with "coordinates" ("mls-affine" or "rbf"; default "rbf"), which compute the weights.
/// Returns the SkinningWarp, and the coordinates when they give the weights.
Rig skinningRig(RigReader& reader);

/// The dense weight matrix of a .csv (rows of comma- or space-separated numbers; a first line
/// that is not numeric, such as `spacewarp weights`'s column names, is skipped) or .npy file
/// (float64 or float32, little-endian, C or Fortran order, 2-D), row-major, with its column
/// count in `columns`. Throws IoError naming the file (and the line) for unreadable or malformed
/// content; a .npy whose shape does not fit the file, or differs from a non-zero expectedRows or
/// expectedColumns, is refused from its header, before its data is allocated or read.
std::vector<double> readWeightMatrix(const std::filesystem::path& path, std::size_t& columns,
                                     std::size_t expectedRows = 0, std::size_t expectedColumns = 0);

}  // namespace spacewarp::detail
