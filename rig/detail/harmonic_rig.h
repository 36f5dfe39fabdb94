#pragma once
// The "harmonic" rig method (its coordinates are built in cage_rig.cpp).

#include <spacewarp/rig/detail/rig_reader.h>
#include <spacewarp/rig/rig.h>

namespace spacewarp::detail {

/// The "harmonic" rig: keys "cage", "pose" (paths), optional "tets" (target tet count) and
/// "cache" (a coordinate cache file, as --harmonic-cache) and "outside" ("raise" or "nearest").
/// Throws InvalidInput if spacewarp was built without TetGen.
Rig harmonicRig(RigReader& reader);

}  // namespace spacewarp::detail
