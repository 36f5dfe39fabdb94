#pragma once
// The "kelvinlet" rig method: one regularized Kelvinlet brush (nonlinear/kelvinlet.h). Keys are
// documented in README.md.

#include <spacewarp/rig/detail/rig_reader.h>
#include <spacewarp/rig/rig.h>

namespace spacewarp::detail {

/// Reads "brush" ("grab", "twist", "scale" or "pinch"), "center" ([x, y, z]), "radius" (ε > 0),
/// optional "poisson" (ν in [0, 0.5], default 0.45), "falloff" ("single", "bi" or "tri", default
/// "single") and "steps" (1..10000, default 1), and the
/// brush's own keys: grab "displacement" ([dx, dy, dz]); twist "axis" ([x, y, z], non-zero) and
/// "angle" (radians); scale "factor" (> 0); pinch "matrix" (3 rows of 3, symmetric, traceless).
/// Keys of another brush are refused. Returns the KelvinletWarp and no coordinates.
Rig kelvinletRig(RigReader& reader);

}  // namespace spacewarp::detail
