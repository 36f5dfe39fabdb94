#pragma once
// The "idw" rig method: Shepard's inverse-distance weighting of point handles moved to targets
// (nonlinear/shepard.h). Keys are documented in README.md.

#include <spacewarp/rig/detail/rig_reader.h>
#include <spacewarp/rig/rig.h>

namespace spacewarp::detail {

/// Reads "handles" and "targets" (arrays of [x, y, z], the same length), optional "power" (> 0,
/// default 2) and "radius" (> 0, default none: global weights). Returns the ShepardWarp and its
/// coordinates (for `spacewarp weights`).
Rig idwRig(RigReader& reader);

}  // namespace spacewarp::detail
