#pragma once
// The cage rig methods: "mvc", "green", "harmonic", "qmvc", "qgc", "wachspress" and
// "discrete-harmonic" (built in cage_rig.cpp).

#include <spacewarp/rig/detail/rig_reader.h>
#include <spacewarp/rig/rig.h>

namespace spacewarp::detail {

/// The "harmonic" rig: keys "cage", "pose" (paths), optional "tets" (target tet count) or
/// "precision" (a level in [1, 7], harmonicPrecisionTets(); not both), "cache" (a coordinate cache
/// file, as --harmonic-cache) and "outside" ("raise" or "nearest"). Throws InvalidInput if
/// spacewarp was built without TetGen.
Rig harmonicRig(RigReader& reader);

/// The closed-form cage rigs ("mvc", "green", "qmvc", "qgc", "wachspress",
/// "discrete-harmonic"): keys "cage" and "pose" (paths), and for wachspress and
/// discrete-harmonic "outside" ("raise" or "nearest"; rig.cpp's key lists say which method may
/// have it). When the reader is checking, the cage and the pose are read and checked but no
/// coordinates are built (an empty Rig).
Rig cageRig(RigReader& reader, const std::string& method);

}  // namespace spacewarp::detail
