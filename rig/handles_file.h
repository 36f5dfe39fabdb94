#pragma once
// The handles file of surface editing (`spacewarp edit --handles`, spacewarp.load_handles):
//
//   {"handles": [{"vertices": [i, ...], "matrix": [[4 numbers] × 4 rows]},
//                {"vertices": [i, ...], "targets": [[x, y, z], ...]}, ...]}
//
// each region moved by a row-major affine matrix (last row 0 0 0 1; the identity pins it) or
// each vertex to its own target (world units). Indices are the model's vertices in file order.

#include <cstddef>
#include <filesystem>
#include <limits>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include <spacewarp/surface/handles.h>

namespace spacewarp {

/// The regions of a handles document. Throws InvalidInput naming `where` and the JSON path at
/// fault ("h.json: handles[2].vertices[5]: 1800 is out of range ..."): not an object, an
/// unknown or missing key, an empty list, an index that is not a whole number from 0 or not
/// below `vertexCount` (no range check when it is SIZE_MAX), a region with both or neither of
/// matrix and targets, a matrix that is not 4 × 4 finite numbers or not affine, a target count
/// that differs from the vertex count. Conflicts between regions are resolveHandles()'s.
std::vector<HandleRegion> parseHandlesJson(
    const nlohmann::json& document, const std::string& where,
    std::size_t vertexCount = std::numeric_limits<std::size_t>::max());

/// Reads a handles file: IoError naming it when it cannot be read or is not JSON (checked as rig
/// files are: duplicate keys, nesting depth, NaN), then parseHandlesJson.
std::vector<HandleRegion> readHandlesFile(
    const std::filesystem::path& path,
    std::size_t vertexCount = std::numeric_limits<std::size_t>::max());

}  // namespace spacewarp
