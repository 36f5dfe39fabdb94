#pragma once
// `spacewarp compare`: heat maps of one control's coordinate function on a slice plane for
// several methods, with one colour scale, and a report of every method's properties.

#include <filesystem>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include <spacewarp/core/math.h>
#include <spacewarp/rig/cage_rig.h>
#include "apps/cli_context.h"

namespace spacewarp::cli {

/// The coordinate methods compare knows: every cage method plus "rbf" (triharmonic RBF
/// coordinates with the cage vertices as handles) and "ffd" (a Bernstein lattice around the
/// cage), sorted. Adding a method is one line in compare.cpp (cage methods come automatically).
std::vector<std::string> compareMethods();

struct CompareRequest {
  std::filesystem::path cage;        ///< rest cage file
  std::vector<std::string> methods;  ///< names from compareMethods(); empty = all that apply
  Vec3 planePoint{0.0};              ///< a point of the slice plane, world units
  Vec3 planeNormal{0.0, 0.0, 1.0};   ///< its normal (any length > 0)
  std::size_t control = 0;           ///< the cage vertex whose coordinate function is drawn
  int resolution = 256;              ///< pixels along the longer side of each image
  std::size_t samples = 2000;        ///< interior points for the property kit
  std::uint64_t seed = 1;            ///< seed of those points (coords/properties.h)
  CageMethodOptions cageOptions;     ///< options of the cage methods
  std::filesystem::path output;      ///< folder for the images and reports
};

/// Computes every method, then writes the folder `request.output`: <method>.png per method,
/// compare.png (all side by side under their names, the colour bar with its numbers
/// underneath), colour_bar.png, report.md and report.json. Returns the JSON report.
///
/// The folder is written as a whole (writeFolderAtomically): a failed write or an interruption
/// leaves the previous folder exactly as it was, and no temporary; a successful run replaces
/// it, so files of an earlier run with other methods do not linger. An existing folder may
/// therefore hold only files compare writes (any method's image, the reports): anything else is
/// an IoError naming it, before any work.
///
/// A method that throws while it is set up, bound or measured (e.g. harmonic coordinates whose
/// tet mesh misses some interior points) does not stop the others: its report entry has
/// "status": "failed" with "errorType" and "error" (the exception's message), its panel is
/// grey and says "failed", and "failedMethods" lists it; the colour scale covers the methods
/// that succeeded, and a warning line per failed method goes to stderr (even when quiet).
/// Cancelled still stops everything, writing nothing.
///
/// Without request.methods, every method that takes the cage runs (checkCageMethodApplies():
/// wachspress needs a convex cage, discrete-harmonic a convex cage of triangles, qgc triangle and
/// quad faces); each one left out is a note (context.say) and an entry {"name", "reason"} of
/// "leftOutMethods".
///
/// Throws InvalidInput for an unknown or repeated method, a method named in request.methods that
/// cannot take the cage (naming e.g. the reflex edge), a control index out of range, or a plane
/// that misses the cage, and whatever reading the cage throws; nothing is written then.
nlohmann::json runComparison(const CompareRequest& request, const CliContext& context);

}  // namespace spacewarp::cli
