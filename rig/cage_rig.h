#pragma once
// The cage-coordinate methods by name ("mvc", "green", "harmonic", "qmvc", "qgc", "wachspress",
// "discrete-harmonic"), as rigs and the command line use them. Adding a method is one line in
// cage_rig.cpp.

#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include <spacewarp/coords/cage.h>
#include <spacewarp/core/coordinates.h>
#include <spacewarp/core/progress.h>
#include <spacewarp/core/warp.h>
#include <spacewarp/rig/rig.h>

namespace spacewarp {

/// The names of the cage-coordinate methods ("green", "mvc", ...), sorted.
std::vector<std::string> cageMethods();

/// Options of the cage methods that have any (the command line's --tets, --precision,
/// --harmonic-cache and --outside; a harmonic rig's keys tets, precision, cache and outside, and
/// the wachspress and discrete-harmonic rigs' key outside).
struct CageMethodOptions {
  /// harmonic (--tets): the target tet count of the tetrahedralisation; 0 keeps the library's
  /// default (HarmonicOptions::targetTetCount, about 200k tets).
  std::size_t harmonicTets = 0;
  /// harmonic (--harmonic-cache): a file of solved coordinates (see HarmonicCoordinates::save).
  /// If it exists and was solved for the same cage at the same resolution it is loaded;
  /// otherwise the coordinates are solved and saved there. A file that is not a valid
  /// coordinate file (corrupt, truncated, another version) is an error. Empty: no cache.
  std::filesystem::path harmonicCache;
  /// harmonic, wachspress and discrete-harmonic (--outside): what points outside the cage get:
  /// "raise" (an error counting them) or "nearest" (the coordinates of the nearest point on the
  /// cage; HarmonicOutsidePolicy, ConvexOutsidePolicy).
  std::string outside = "raise";
  /// harmonic (--precision): a precision level, any number in [1, 7] (harmonicPrecisionTets(),
  /// coords/harmonic.h: 200000 · 4^(p − 5) tets); 0: none. Giving it with harmonicTets is an
  /// InvalidInput.
  double harmonicPrecision = 0.0;
};

/// Coordinates of `method` for `cage`. Throws InvalidInput for an unknown method. Long
/// precomputation reports to `progress`.
std::shared_ptr<const Coordinates> cageCoordinates(const std::string& method,
                                                   std::shared_ptr<const Cage> cage,
                                                   const CageMethodOptions& options = {},
                                                   const ProgressCallback& progress = {});

/// Throws InvalidInput (naming the cage and the face or reflex edge at fault) unless `method`
/// can take `cage`: qmvc and qgc need quads whose bilinear patch does not fold over (a concave
/// planar quad, say), qgc triangle and quad faces only, wachspress a convex cage
/// (checkConvexCage()), discrete-harmonic a convex cage of triangles
/// (checkSimplicialConvexCage()); the others take any valid cage. Throws InvalidInput for an
/// unknown method.
void checkCageMethodApplies(const std::string& method, const Cage& cage);

/// The columns of the coordinates of `method` for `cage` (their columnCount()), known before
/// they are made: the cage's vertex count, plus one per triangle for green, one per triangle
/// face and four per quad face for qgc. Throws InvalidInput for an unknown method.
std::size_t cageCoordinatesColumns(const std::string& method, const Cage& cage);

/// The peak memory (bytes) that making the coordinates of `method` for `cage` and evaluating
/// them on every worker thread takes, weight rows aside: for the closed-form methods their
/// precomputation and per-thread scratch (a few hundred bytes a cage vertex and triangle), for
/// harmonic HarmonicCoordinates::memoryEstimate() (a solve, even when options.harmonicCache holds
/// one). An upper bound within a small factor. Throws InvalidInput for an unknown method.
double cageCoordinatesMemory(const std::string& method, const Cage& cage,
                             const CageMethodOptions& options = {});

/// The rig of `method` with the rest cage and posed cage read from files: a CoordinateWarp
/// and its coordinates.
Rig cageRig(const std::string& method, const std::filesystem::path& cage,
            const std::filesystem::path& pose, const CageMethodOptions& options = {},
            const ProgressCallback& progress = {});

}  // namespace spacewarp
