#pragma once
// Whole warp archives: a header (the magic "spacewarp-archive", then the format version) and one
// Warp or Coordinates written by its save() (core/archive.h). Loading rebuilds the object from
// what was saved, solved state included (RBF weights, harmonic fields, fitted lattices): nothing
// is solved again, and the loaded object gives bit-identical results. Here, in rig/, because
// the table from tags to load functions sees every module.

#include <cstdint>
#include <memory>
#include <string>
#include <string_view>

#include <spacewarp/coords/cage.h>
#include <spacewarp/core/archive.h>
#include <spacewarp/core/coordinates.h>
#include <spacewarp/core/handle_distances.h>
#include <spacewarp/core/warp.h>

namespace spacewarp {

/// The magic every archive starts with, and the format version this build writes and reads.
inline constexpr std::string_view kArchiveMagic = "spacewarp-archive";
inline constexpr std::uint32_t kArchiveVersion = 2;

/// The load function of every tag this build knows (one line per class in warp_archive.cpp).
const ArchiveLoaders& archiveLoaders();

/// The archive of `warp`. Throws InvalidInput naming the type of a warp (or of a warp nested in
/// it) that cannot be saved.
std::string saveWarp(const Warp& warp);

/// The warp of an archive made by saveWarp(). Throws InvalidInput ("warp archive: ... (byte N)")
/// for anything else: another magic or version (naming both), an unknown tag (naming it), a
/// truncated archive, bytes after the warp, or parameters the warp's constructor refuses.
std::shared_ptr<const Warp> loadWarp(std::string_view bytes);

/// The same for Coordinates.
std::string saveCoordinates(const Coordinates& coordinates);
std::shared_ptr<const Coordinates> loadCoordinates(std::string_view bytes);

/// The same for HandleDistances (InsideDistances: its grid of distances, nothing marched again).
std::string saveDistances(const HandleDistances& distances);
std::shared_ptr<const HandleDistances> loadDistances(std::string_view bytes);

/// The same for a Cage (rebuilt through its constructor from its polygons).
std::string saveCage(const Cage& cage);
Cage loadCage(std::string_view bytes);

}  // namespace spacewarp
