#pragma once
// The "mls" rig method: a moving-least-squares warp of point handles to targets
// (nonlinear/mls.h). Keys are documented in README.md.

#include <spacewarp/rig/detail/rig_reader.h>
#include <spacewarp/rig/rig.h>

namespace spacewarp::detail {

/// Reads "handles" and "targets" (arrays of [x, y, z], the same length), optional "mode"
/// ("affine", "similarity" or "rigid"; default "rigid") and "alpha" (> 0, default 1), and
/// "distance" ("euclidean", the default, or "inside": weights by distances measured inside the
/// closed mesh file "model", on voxels of "voxelSize" world units, default the model's
/// bounding-box diagonal / 128; volume/inside_distance.h). Returns the MlsWarp and no
/// coordinates.
Rig mlsRig(RigReader& reader);

}  // namespace spacewarp::detail
