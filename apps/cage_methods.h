#pragma once
// The cage-coordinate methods the command line offers, by name. Adding a method is one line
// in cage_methods.cpp.

#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "apps/rig.h"
#include "coords/cage.h"
#include "core/coordinates.h"
#include "core/progress.h"
#include "core/warp.h"

namespace spacewarp::cli {

/// The names of the cage-coordinate methods ("green", "mvc", ...), sorted.
std::vector<std::string> cageMethods();

/// Options of the cage methods that have any, set from the command line.
struct CageMethodOptions {};

/// Adds the cage methods' options to a subcommand that takes --method.
void addCageMethodOptions(CLI::App* command, CageMethodOptions& options);

/// Coordinates of `method` for `cage`. Throws InvalidInput for an unknown method. Long
/// precomputation reports to `progress`.
std::shared_ptr<const Coordinates> cageCoordinates(const std::string& method,
                                                   std::shared_ptr<const Cage> cage,
                                                   const CageMethodOptions& options = {},
                                                   const ProgressCallback& progress = {});

/// The rig of `method` with the rest cage and posed cage read from files: a CoordinateWarp
/// and its coordinates.
Rig cageRig(const std::string& method, const std::filesystem::path& cage,
            const std::filesystem::path& pose, const CageMethodOptions& options = {},
            const ProgressCallback& progress = {});

}  // namespace spacewarp::cli
