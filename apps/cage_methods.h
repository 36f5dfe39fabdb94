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
struct CageMethodOptions {
  /// harmonic (--tets): the target tet count of the tetrahedralisation; 0 keeps the library's
  /// default (HarmonicOptions::targetTetCount, about 200k tets).
  std::size_t harmonicTets = 0;
  /// harmonic (--harmonic-cache): a file of solved coordinates (see HarmonicCoordinates::save).
  /// If it exists and was solved for the same cage at the same resolution it is loaded;
  /// otherwise the coordinates are solved and saved there. A file that is not a valid
  /// coordinate file (corrupt, truncated, another version) is an error. Empty: no cache.
  std::filesystem::path harmonicCache;
  /// harmonic (--outside): what points outside the cage get: "raise" (an error counting them)
  /// or "nearest" (the coordinates of the nearest point on the cage).
  std::string harmonicOutside = "raise";
};

/// Adds the cage methods' options to a subcommand that takes --method.
void addCageMethodOptions(CLI::App* command, CageMethodOptions& options);

/// Throws a usage error (exit 2) naming the first option of addCageMethodOptions given on
/// `command` that `method` does not use; `method` "" stands for a rig, whose keys set them.
void checkCageMethodOptions(const CLI::App& command, const std::string& method);

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

/// The "harmonic" rig: keys "cage", "pose" (paths), optional "tets" (target tet count) and
/// "cache" (a coordinate cache file, as --harmonic-cache) and "outside" ("raise" or "nearest").
/// Throws InvalidInput if spacewarp was built without TetGen.
Rig harmonicRig(RigReader& reader);

}  // namespace spacewarp::cli
