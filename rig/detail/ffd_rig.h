#pragma once
// The "ffd" rig method: a lattice free-form deformation (ffd/lattice_warp.h), posed by its
// control points or fitted to point constraints, with its LatticeCoordinates for
// `spacewarp weights`. Keys are documented in README.md.

#include <spacewarp/rig/detail/rig_reader.h>
#include <spacewarp/rig/rig.h>

namespace spacewarp::detail {

/// Reads "basis" ("trilinear", "bernstein" or "bspline"), "origin" (the box corner), "size"
/// (edge lengths), "resolution" ([l, m, n] integers), optional "axes" (three orthogonal
/// directions, normalised here; default x, y, z), optional "ends" ("extrapolate" (default) or
/// "repeat", Blender's; bspline only), optional "outside" ("identity" (default),
/// "clamp" or "falloff") and "falloff" (relative to the box diagonal, default 0.1), and either
/// "controlPoints" (l·m·n posed points, i fastest, then j, then k) or "constraints"
/// ({"from": [...], "to": [...]}, solved by direct manipulation) with optional "smoothness"
/// (default 1e-4). Returns the LatticeWarp and the LatticeCoordinates.
Rig ffdRig(RigReader& reader);

}  // namespace spacewarp::detail
