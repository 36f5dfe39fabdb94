#pragma once
// The per-triangle term of mean-value coordinates (Ju, Schaefer, Warren 2005), shared by
// MeanValueCoordinates (coords/mean_value.cpp, whose vectorised fast path evaluates the same
// formula for many points at once) and QuadMeanValueCoordinates (coords/quad_mean_value.cpp,
// for triangle faces and for the triangles its quads are integrated over). The notation and the
// numerics are described at the top of coords/mean_value.cpp.

#include <array>

#include <spacewarp/core/math.h>

namespace spacewarp::detail {

/// One edge's share of a mean vector: (θ / |C|) C with C = v_j × v_k, θ the angle between v_j
/// and v_k (v = corner − x, d = |v|), so that the mean vector of a spherical polygon is ½ Σ over
/// its edges. Half-chord arcsines (stable at every angle, unlike acos of a dot product); C from
/// the nearer corner; θ / |C| → 1 / (d_j d_k) on the line of the edge outside it. `theta` and
/// `rho` (|C|) are returned for error estimates.
Vec3 edgeMeanVector(const Vec3& vj, const Vec3& vk, double dj, double dk, double& theta,
                    double& rho);

/// The same share in long double from the corners p_j, p_k and x (world units), θ by atan2: for
/// the careful path of a polygon's mean vector.
std::array<long double, 3> carefulEdgeMeanVector(const Vec3& pj, const Vec3& pk, const Vec3& x);

/// The unnormalised weights of one triangle's corners, by the careful path.
struct CarefulTriangle {
  std::array<long double, 3> w{};  ///< weights of the corners, in the triangle's order
  bool onFace = false;             ///< x lies on the triangle (h = 0 with x₀ inside); w = 0
};

/// The careful (long double, plane-frame) weights of the triangle with corners p (outward
/// order, world units) for the point x: accurate on, near and far from the triangle's plane.
/// The triangle must have a non-zero area.
CarefulTriangle carefulMeanValueTriangle(const std::array<Vec3, 3>& p, const Vec3& x);

/// What fastMeanValueTriangle() knows of its weights' accuracy.
struct FastTriangle {
  /// Estimated absolute error of the weights (mean_value.cpp's estimate: ≈ 4 ε Σ θ_i (1 + L_i /
  /// (max d · sin θ_i)) · max |C_i| / |det|), to be compared with the point's weight sum as
  /// MeanValueCoordinates does; infinity when the weights are unusable (x in the triangle's
  /// plane, or the estimate above 1e-3 of the weights themselves).
  double error = 0.0;
  /// |h| / min d: the sine of x's elevation over the triangle's plane seen from its nearest
  /// corner. Cramer's rule solves Σ w_i v_i = m to about ε / elevation relative to m.
  double elevation = 0.0;
};

/// The fast (double) weights of a triangle for a point x, from v_k = p_k − x and d_k = |v_k|
/// (the corners in outward order): w_i = (C_i · m) / det(v_0, v_1, v_2) with the mean vector
/// m = ½ Σ θ_i C_i / |C_i|, as the fast path of mean_value.cpp; the careful path must be used
/// where the accuracy returned is not enough.
FastTriangle fastMeanValueTriangle(const std::array<Vec3, 3>& v, const std::array<double, 3>& d,
                                   std::array<double, 3>& w);

}  // namespace spacewarp::detail
