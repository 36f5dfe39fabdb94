#pragma once
// Rigs: JSON files that describe a warp (method, parameters, control data or paths to it),
// so the same rig deforms a soup, a point cloud or a volume, from the command line or from C++
// (spacewarp::rig: `loadRig("rig.json").warp`). The keys of every method are documented in
// README.md.

#include <filesystem>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

#include <spacewarp/core/progress.h>

#include <spacewarp/core/coordinates.h>
#include <spacewarp/core/warp.h>

namespace spacewarp {

/// What a rig builds: always a warp, and for the methods that are linear in their controls
/// (cages, lattices, RBF handles) also their coordinates, for `spacewarp weights`.
struct Rig {
  std::shared_ptr<const Warp> warp;
  std::shared_ptr<const Coordinates> coordinates;  ///< null for warps without coordinates
  /// One line each, naming the rig: the warp is usable but not what was asked (a graph solve
  /// that did not converge, parts of the graph that no handle reaches). The CLI prints them as
  /// warnings; nested rigs' warnings are their compose rig's.
  std::vector<std::string> warnings = {};
};

/// The deepest nesting of compose rigs (a compose inside a compose ... ), and of JSON arrays and
/// objects in a rig file: deeper input is refused rather than recursed into.
inline constexpr int kMaxComposeDepth = 64;
inline constexpr int kMaxJsonDepth = 256;

/// Parses the text of a rig file. Throws IoError (naming `where` and the position) if it is not
/// JSON, and InvalidInput naming `where` and the key for a key given twice in one object, a
/// number outside the range of double ("1e999") or nesting deeper than kMaxJsonDepth.
nlohmann::json parseRigJson(std::string_view text, const std::string& where);

/// Builds the rig that `rig` describes. `baseDir` resolves relative paths inside the rig;
/// `where` names the rig in messages (usually its path; a rig nested in compose rigs as
/// "rig.json: warps[1].warps[0]"). Throws InvalidInput naming the key at fault for a missing,
/// mistyped, unknown or out-of-range key (unknown keys first: they are usually the misspelling
/// that makes a required key missing), an unknown method or compose rigs nested deeper than
/// kMaxComposeDepth; errors of the library while building the warp (InvalidInput, SolverError,
/// IoError) are rethrown with `where` in front.
Rig rigFromJson(const nlohmann::json& rig, const std::filesystem::path& baseDir,
                const std::string& where, const ProgressCallback& progress = {});

/// Checks `rig` exactly as rigFromJson() does — the same code, every key, the cage files
/// read — but stops before the expensive solves (harmonic coordinates, FFD fits, RBF fits,
/// deformation graph solves) and builds nothing. Failures of those solves themselves (a
/// singular fit, a solver that gives up, a job too large for the memory) are therefore only
/// found by rigFromJson(). Throws as rigFromJson() does.
void checkRig(const nlohmann::json& rig, const std::filesystem::path& baseDir,
              const std::string& where);

/// The JSON of a rig file, checked as JSON (duplicate keys, depth, number range) but not yet
/// as a rig. Throws IoError naming the file if it cannot be read (a folder, a missing file) or
/// is not JSON, and InvalidInput as parseRigJson does.
nlohmann::json readRigFile(const std::filesystem::path& path);

/// Reads and builds a rig file: readRigFile, then rigFromJson. `progress` is told about the
/// rig's solves (graph, lattice fit, RBF fit; harmonic coordinates report their own stages).
Rig loadRig(const std::filesystem::path& path, const ProgressCallback& progress = {});

/// The method names a rig may use, sorted.
std::vector<std::string> rigMethods();

}  // namespace spacewarp
