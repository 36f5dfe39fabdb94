#pragma once
// The "rbf" rig method: an RBF warp fitted to handle centers and targets (rbf/rbf_warp.h),
// with its RbfCoordinates for `spacewarp weights`. Keys are documented in README.md.

#include <spacewarp/rig/detail/rig_reader.h>
#include <spacewarp/rig/rig.h>

namespace spacewarp::detail {

/// Reads "kernel" (optional, default "triharmonic"), "centers" and "targets" (arrays of
/// [x, y, z], the same length), optional "fixed" (centers that stay put), "smoothing" (λ ≥ 0,
/// default 0), "scale" (gaussian, inverse-multiquadric; default 1) and "radius" (wendland;
/// default 1). Returns the RbfWarp and the RbfCoordinates of the centers (built on first use).
Rig rbfRig(RigReader& reader);

/// The coordinates of an RBF rig (built on first use) saved in an archive (tag
/// "lazy-rbf-coordinates", rig/warp_archive.cpp).
std::shared_ptr<const Coordinates> loadLazyRbfCoordinates(ArchiveReader& in);

}  // namespace spacewarp::detail
