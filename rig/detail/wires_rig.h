#pragma once
// The "wires" rig method: Singh & Fiume's wires (nonlinear/wires.h). Keys are documented in
// README.md.

#include <spacewarp/rig/detail/rig_reader.h>
#include <spacewarp/rig/rig.h>

namespace spacewarp::detail {

/// Reads "wires" (a non-empty array of wire objects, each with "rest" and "deformed" (arrays of
/// at least 2 [x, y, z] points, the same length), "radius" (> 0) and optional "innerRadius"
/// ([0, radius), default 0), "scale" (> 0, default 1), "dropoff" ("smooth" or "linear", default
/// "smooth") and "curve" ("polyline" or "catmull-rom", default "polyline")) and optional
/// "locality" (>= 0, default 1). Errors name the wire: "rig.json: wires[1]: 'radius' must be > 0".
/// Returns the WiresWarp and no coordinates.
Rig wiresRig(RigReader& reader);

}  // namespace spacewarp::detail
