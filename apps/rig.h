#pragma once
// Rigs: JSON files that describe a warp (method, parameters, control data or paths to it),
// so the same rig deforms a soup, a point cloud or a volume. The keys of every method are
// documented in README.md.

#include <filesystem>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "apps/rig_reader.h"
#include "core/coordinates.h"
#include "core/warp.h"

namespace spacewarp::cli {

/// What a rig builds: always a warp, and for the methods that are linear in their controls
/// (cages, lattices, RBF handles) also their coordinates, for `spacewarp weights`.
struct Rig {
  std::shared_ptr<const Warp> warp;
  std::shared_ptr<const Coordinates> coordinates;  ///< null for warps without coordinates
};

/// Builds one rig method from its reader. A method's keys are read through the reader, which
/// reports unknown keys once the factory returns.
using RigFactory = std::function<Rig(RigReader&)>;

/// Builds the rig that `rig` describes. `baseDir` resolves relative paths inside the rig;
/// `where` names the rig in messages (usually its path). Throws InvalidInput naming the key
/// at fault for a missing, mistyped, unknown or out-of-range key or an unknown method.
Rig rigFromJson(const nlohmann::json& rig, const std::filesystem::path& baseDir,
                const std::string& where);

/// The JSON of a rig file, not yet checked as a rig. Throws IoError naming the file if it
/// cannot be read or is not JSON.
nlohmann::json readRigFile(const std::filesystem::path& path);

/// Reads and builds a rig file. Throws IoError if it cannot be read or is not JSON, and
/// InvalidInput as rigFromJson does.
Rig loadRig(const std::filesystem::path& path);

/// The method names a rig may use, sorted.
std::vector<std::string> rigMethods();

}  // namespace spacewarp::cli
