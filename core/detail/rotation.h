#pragma once
// Rotations fitted to 3 × 3 matrices and point sets: the local steps of MLS, the deformation
// graph and ARAP.

#include <span>

#include <spacewarp/core/math.h>

namespace spacewarp::detail {

/// The cross-product matrix [y]×, [y]× v = y × v: the generator of rotations about y.
inline Mat3 crossMatrix(const Vec3& y) {
  Mat3 m(0.0);
  m[0] = Vec3(0.0, y.z, -y.y);
  m[1] = Vec3(-y.z, 0.0, y.x);
  m[2] = Vec3(y.y, -y.x, 0.0);
  return m;
}

/// Eigen-decomposition of the symmetric 3 × 3 matrix m by cyclic Jacobi: eigenvalues e (not
/// sorted), eigenvectors as the columns of v. Deterministic.
void symmetricEigen(const Mat3& m, double e[3], Mat3& v);

/// The rotation R (det +1) maximising tr(Rᵀ b): the orthogonal polar factor of b when det b > 0,
/// U diag(1, 1, −1) Vᵀ for the SVD b = U Σ Vᵀ when det b < 0 (reflections excluded), a
/// deterministic choice among the optima when b has rank < 2. Accurate to rounding.
Mat3 closestRotation(const Mat3& b);

/// closestRotation(b) computed from a nearby rotation `guess` (e.g. the previous iteration's in
/// ARAP): Newton steps on the rotation group, each about a tenth of the cost of
/// closestRotation, stopped when a step is below 1e-8 (the result is then exact to rounding);
/// closestRotation(b) itself when the guess is not within the quadratic convergence region
/// (more than 4 steps, or an indefinite Hessian). The result agrees with closestRotation(b) to
/// rounding wherever the optimum is unique.
Mat3 closestRotationNear(const Mat3& b, const Mat3& guess);

/// The rigid motion x -> r x + shift that best maps `points` onto `targets` in the
/// least-squares sense (Kabsch: the rotation from the SVD of the cross-covariance, a reflection
/// turned into a rotation). The identity for no points; for collinear points r is one of the
/// rotations that fit equally well.
struct RigidFit {
  Mat3 r{1.0};
  Vec3 shift{0.0};
};
RigidFit rigidFit(std::span<const Vec3> points, std::span<const Vec3> targets);

}  // namespace spacewarp::detail
