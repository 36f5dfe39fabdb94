#pragma once
// File-to-file work shared by the subcommands and the demo.

#include <filesystem>

#include <nlohmann/json.hpp>

#include <spacewarp/core/coordinates.h>
#include <spacewarp/core/geometry.h>
#include <spacewarp/core/progress.h>
#include <spacewarp/core/warp.h>
#include <spacewarp/rig/rig.h>
#include "apps/cli_context.h"

namespace spacewarp::cli {

/// Writes `soup` to `output` atomically (`ascii`: PLY as ASCII), with a warning through
/// `context` naming what the output's format cannot store.
void writeSoupFile(const PolygonSoup& soup, const std::filesystem::path& output, bool ascii,
                   const CliContext& context);

/// Warns (one counted line naming `input`) about what the reader read through but the soup
/// does not keep (PolygonSoup::notKept); nothing when there is none.
void warnNotKept(const std::filesystem::path& input, const PolygonSoup& soup,
                 const CliContext& context);

/// A warning through `context` when `singular` of the `total` vertices of `input` had their
/// normals carried through a singular Jacobian (nothing when there are none).
void warnSingularNormals(const std::filesystem::path& input, std::size_t singular,
                         std::size_t total, const CliContext& context);

/// Warps `soup`, read from `input` (named in messages), and writes it to `output` atomically.
/// `ascii` writes PLY as ASCII. Progress and warnings (formats that drop attributes, normals
/// undefined where the warp is singular) go through `context`.
void deformSoup(const Warp& warp, PolygonSoup& soup, const std::filesystem::path& input,
                const std::filesystem::path& output, bool ascii, const CliContext& context);

/// Reads a soup or point cloud (OBJ, OFF, PLY), warps it and writes it atomically (deformSoup).
/// The output format is checked before any work.
void deformSoupFile(const Warp& warp, const std::filesystem::path& input,
                    const std::filesystem::path& output, bool ascii, const CliContext& context);

/// The coordinate matrix of every point in `points` (any soup file; faces ignored), one row per
/// point in input order and one column per coordinate, written atomically as CSV (a header of
/// column names, full double precision) or NumPy .npy (float64, C order, rows × columns),
/// chosen by the output's extension.
void writeWeightsFile(const Coordinates& coordinates, const std::filesystem::path& points,
                      const std::filesystem::path& output);

/// Reads and builds a rig file (loadRig) and prints its warnings through `context`.
Rig loadRigFile(const std::filesystem::path& path, const CliContext& context);

/// Creates `dir` and its parents if needed. Throws IoError naming it if that fails (a file in
/// the way, no permission).
void createOutputFolder(const std::filesystem::path& dir);

/// Writes `j` pretty-printed, atomically.
void writeJsonFile(const nlohmann::json& j, const std::filesystem::path& path);

}  // namespace spacewarp::cli
