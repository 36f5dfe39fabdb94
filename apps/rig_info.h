#pragma once
// `spacewarp info RIG.json`: what a rig is and will do, read from its JSON without building
// it (building may mean a long solve: harmonic coordinates, RBF fits, deformation graphs).

#include <filesystem>

namespace spacewarp::cli {

/// Prints the rig's method, its controls (counts of cage vertices and faces, lattice
/// resolution, handles, centers, nodes; the cage files are read for their counts) and a
/// sentence of what it will do; the warps of a "compose" rig are described in turn. The rig
/// is first checked as `deform` checks it (checkRig: the same code, without the solves), so
/// info refuses what deform refuses, with the same message, and prints nothing then. Throws
/// IoError naming the file if it cannot be read or is not JSON (or a cage file cannot be
/// read), InvalidInput naming it and the key at fault as rigFromJson() does.
void printRigInfo(const std::filesystem::path& path);

}  // namespace spacewarp::cli
