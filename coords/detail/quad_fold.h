#pragma once
// The one check QuadMeanValueCoordinates and QuadGreenCoordinates make of every quad: that its
// bilinear patch does not fold over. Both integrate over the patch ξ(u, v) (see
// coords/detail/bilinear_quadrature.h); where (u, v) → ξ is not one-to-one (a planar concave
// "dart" quad, a degenerate one, a quad twisted past flat) the patch covers some region twice
// with opposite orientations, so points near it see surface that is not there: QMVC's weights
// grow like 1 / distance and reproduction is lost (QGC's too).

#include <cstddef>
#include <cstdint>
#include <span>
#include <string>

#include <spacewarp/core/math.h>

namespace spacewarp::detail {

/// Throws InvalidInput naming `method`, `cageName`, face `f` and its vertices, and saying to split
/// it into triangles, unless the patch normal ξ_u × ξ_v of the quad `face` (4 indices into
/// `vertices`) points to the side of its Newell normal all over the unit square. ξ_u × ξ_v is
/// affine in (u, v) (its uv term is e_uv × e_uv = 0), so it is tested at the four corners (where
/// it is the cross product of the corner's two edges) and, for clarity of intent, the centre; a
/// corner counts as folded when the sine of its angle, seen along the normal, is below 1e-12
/// (collinear edges: the quad is a triangle with a vertex on a side). For a planar quad this
/// is strict convexity.
void checkQuadUnfolded(std::span<const Vec3> vertices, std::span<const std::uint32_t> face,
                       std::size_t f, const char* method, const std::string& cageName);

}  // namespace spacewarp::detail
