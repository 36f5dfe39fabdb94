#pragma once
// Rigs: JSON files that describe a warp (method, parameters, control data or paths to it),
// so the same rig deforms a soup, a point cloud or a volume. The keys of every method are
// documented in README.md.

#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "core/warp.h"

namespace spacewarp::cli {

/// Builds the warp that `rig` describes. `baseDir` resolves relative paths inside the rig;
/// `where` names the rig in messages (usually its path). Throws InvalidInput naming the key
/// at fault for a missing, mistyped, unknown or out-of-range key or an unknown method.
std::shared_ptr<const Warp> warpFromRig(const nlohmann::json& rig,
                                        const std::filesystem::path& baseDir,
                                        const std::string& where);

/// Reads and builds a rig file. Throws IoError if it cannot be read or is not JSON, and
/// InvalidInput as warpFromRig does.
std::shared_ptr<const Warp> loadRig(const std::filesystem::path& path);

/// The method names a rig may use, sorted.
std::vector<std::string> rigMethods();

}  // namespace spacewarp::cli
