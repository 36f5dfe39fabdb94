#pragma once
// The harmonic coordinate file: what HarmonicCoordinates::save() writes and load() reads (the
// format is documented at save() in coords/harmonic.h). Separate from the solve so that the
// format's checks (header, counts, size, checksum, content) read as stages.

#include <cstdint>
#include <filesystem>
#include <span>
#include <string>
#include <vector>

#include <spacewarp/coords/cage.h>
#include <spacewarp/coords/harmonic.h>
#include <spacewarp/coords/tet_mesh.h>

namespace spacewarp::detail {

// A file's content, checked against its cage.
struct HarmonicFileData {
  TetMesh mesh;                  // in the cage's frame, world vertices included
  std::vector<double> values;    // mesh vertex count × cage vertex count, row-major
  double radiusEdgeRatio = 0.0;  // the bounds the mesh was made with
  double volumeBound = 0.0;      // world units³
};

// FNV-1a (64-bit) of the cage's vertex coordinates (bit patterns) and triangle indices.
std::uint64_t harmonicCageHash(const Cage& cage);

// The file's bytes.
std::vector<char> encodeHarmonicFile(const Cage& cage, const TetMesh& mesh,
                                     std::span<const double> values, double radiusEdgeRatio,
                                     double volumeBound);

// Writes the file atomically; throws IoError naming it.
void writeHarmonicFile(const std::filesystem::path& path, const Cage& cage, const TetMesh& mesh,
                       std::span<const double> values, double radiusEdgeRatio, double volumeBound);

// The header only (no checksum verification). Throws IoError naming the file if it cannot be
// read, is too short for a header, or has a bad magic or an unsupported version.
HarmonicCoordinates::FileInfo readHarmonicFileInfo(const std::filesystem::path& path);

// The whole file, versions 1 and 2. Throws IoError naming the file if it cannot be read or is
// not a valid coordinate file, InvalidInput naming it if it was solved for another cage.
HarmonicFileData readHarmonicFile(const std::filesystem::path& path, const Cage& cage);

// The same from the file's bytes (a warp archive holds them), named `name` in errors.
HarmonicFileData decodeHarmonicFile(std::span<const char> data, const Cage& cage,
                                    const std::string& name);

// How many harmonic solves (HarmonicCoordinates constructions) this process has run: tests
// check that loading a saved field solves nothing.
std::size_t harmonicSolveCount();

}  // namespace spacewarp::detail
