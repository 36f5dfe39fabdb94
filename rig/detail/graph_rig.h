#pragma once
// The "graph" rig method: an embedded deformation graph (nonlinear/deformation_graph.h) solved
// so that handles reach their targets. Keys are documented in README.md.

#include <spacewarp/rig/detail/rig_reader.h>
#include <spacewarp/rig/rig.h>

namespace spacewarp::detail {

/// Reads "handles" and "targets" (arrays of [x, y, z], the same length), "spacing" (> 0, world
/// units), optional "k" (nearest nodes per point, integer >= 1, default 4), optional "nodes"
/// (explicit node positions) and optional "rotationWeight", "regularizationWeight",
/// "constraintWeight" (>= 0; defaults 1, 10, 100), optional "maxIterations" (integer >= 0,
/// default 50) and "tolerance" (>= 0, default 1e-6) of the solve. The rig does not see the input it
/// will deform, so without "nodes" the nodes are a regular grid of spacing "spacing" over the
/// bounding box of the handles padded by 2 · spacing on every side (at most 2,000,000 nodes,
/// and no more than the memory estimate of the solve allows, see checkGraphMemory); giving
/// "spacing" with "nodes" is an error. Unknown keys are reported before the solve. Returns the
/// solved DeformationGraphWarp and no coordinates; warns on stderr (one line each) when the solve
/// did not converge and when parts of the graph are reached by no handle.
Rig graphRig(RigReader& reader);

}  // namespace spacewarp::detail
