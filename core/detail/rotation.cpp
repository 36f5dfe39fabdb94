#include <spacewarp/core/detail/rotation.h>

#include <algorithm>
#include <cmath>
#include <utility>

#include <Eigen/LU>
#include <Eigen/SVD>

namespace spacewarp::detail {

// Cyclic Jacobi eigen-decomposition of the symmetric matrix a: eigenvalues e, eigenvectors as
// the columns of v. Deterministic; stops when a sweep rotates nothing (quadratic convergence,
// typically 3 to 4 sweeps), at most 20 sweeps.
void symmetricEigen(const Mat3& m, double e[3], Mat3& v) {
  double a[3][3];
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) a[r][c] = m[c][r];
  double vv[3][3] = {{1.0, 0.0, 0.0}, {0.0, 1.0, 0.0}, {0.0, 0.0, 1.0}};
  constexpr int kPairs[3][2] = {{0, 1}, {0, 2}, {1, 2}};
  for (int sweep = 0; sweep < 20; ++sweep) {
    bool rotated = false;
    for (const auto& pair : kPairs) {
      const int p = pair[0];
      const int q = pair[1];
      const double apq = a[p][q];
      if (apq == 0.0) continue;
      const double app = a[p][p];
      const double aqq = a[q][q];
      const double g = 100.0 * std::abs(apq);
      if (std::abs(app) + g == std::abs(app) && std::abs(aqq) + g == std::abs(aqq)) {
        a[p][q] = a[q][p] = 0.0;
        continue;
      }
      rotated = true;
      const double theta = (aqq - app) / (2.0 * apq);
      const double t =
          std::abs(theta) > 1e150
              ? 0.5 / theta
              : std::copysign(1.0, theta) / (std::abs(theta) + std::sqrt(theta * theta + 1.0));
      const double c = 1.0 / std::sqrt(t * t + 1.0);
      const double sn = t * c;
      a[p][p] = app - t * apq;
      a[q][q] = aqq + t * apq;
      a[p][q] = a[q][p] = 0.0;
      const int r = 3 - p - q;
      const double arp = a[r][p];
      const double arq = a[r][q];
      a[r][p] = a[p][r] = c * arp - sn * arq;
      a[r][q] = a[q][r] = sn * arp + c * arq;
      for (int k = 0; k < 3; ++k) {
        const double vp = vv[k][p];
        const double vq = vv[k][q];
        vv[k][p] = c * vp - sn * vq;
        vv[k][q] = sn * vp + c * vq;
      }
    }
    if (!rotated) break;
  }
  for (int i = 0; i < 3; ++i) {
    e[i] = a[i][i];
    v[i] = Vec3(vv[0][i], vv[1][i], vv[2][i]);
  }
}

namespace {

// A unit vector perpendicular to the unit vector u.
Vec3 anyPerpendicular(const Vec3& u) {
  const Vec3 helper = std::abs(u.x) < 0.6 ? Vec3(1.0, 0.0, 0.0) : Vec3(0.0, 1.0, 0.0);
  return glm::normalize(glm::cross(u, helper));
}

// The rotation R maximising tr(Rᵀ b): U diag(1, 1, det(U Vᵀ)) Vᵀ for the SVD b = U Σ Vᵀ, from the
// eigenvectors v_1, v_2 of bᵀb (largest first) as u_1 = b v_1 / σ_1, u_2 = b v_2 / σ_2
// (re-orthogonalised), u_3 = u_1 × u_2, v_3 = v_1 × v_2: both frames are right-handed, so det R =
// +1 and tr(Rᵀ b) = σ_1 + σ_2 + sign(det b) σ_3, the optimum. Rank < 2: a deterministic choice.
Mat3 rotationByEigen(const Mat3& b) {
  double e[3];
  Mat3 v;
  symmetricEigen(glm::transpose(b) * b, e, v);
  int i0 = 0, i1 = 1, i2 = 2;
  if (e[i0] < e[i1]) std::swap(i0, i1);
  if (e[i1] < e[i2]) std::swap(i1, i2);
  if (e[i0] < e[i1]) std::swap(i0, i1);
  const Vec3 v1 = v[i0];
  const Vec3 v2 = v[i1];
  const Vec3 v3 = glm::cross(v1, v2);
  const Vec3 b1 = b * v1;
  const double n1 = glm::length(b1);
  if (!(n1 > 0.0)) return Mat3(1.0);
  const Vec3 u1 = b1 / n1;
  const Vec3 b2 = b * v2;
  Vec3 t = b2 - glm::dot(u1, b2) * u1;
  double n2 = glm::length(t);
  if (!(n2 > 1e-12 * n1)) {
    t = v2 - glm::dot(u1, v2) * u1;  // rank 1: keep v_2 as unturned as the constraint allows
    n2 = glm::length(t);
    if (!(n2 > 1e-6)) {
      t = anyPerpendicular(u1);
      n2 = 1.0;
    }
  }
  const Vec3 u2 = t / n2;
  const Vec3 u3 = glm::cross(u1, u2);
  return glm::outerProduct(u1, v1) + glm::outerProduct(u2, v2) + glm::outerProduct(u3, v3);
}

inline double frobenius2(const Mat3& a) {
  return glm::dot(a[0], a[0]) + glm::dot(a[1], a[1]) + glm::dot(a[2], a[2]);
}

}  // namespace

// The rotation maximising tr(Rᵀ b). For det b clearly positive (the common case: handles
// around x in general position, targets not folded) it is the orthogonal polar factor of b, by
// Higham's scaled Newton iteration X <- (γ X + X⁻ᵀ / γ) / 2 (a cofactor inverse per step) until
// near orthogonal, then Newton-Schulz steps (both quadratic; stopped by fixed relative
// tolerances, so deterministic). Near
// singular or reflecting b go through the eigen-decomposition of bᵀb (rotationByEigen), which
// handles rank 2 and det b < 0.
Mat3 closestRotation(const Mat3& b) {
  const double norm2 = frobenius2(b);
  const double det = glm::determinant(b);
  if (!(det > 1e-8 * norm2 * std::sqrt(norm2))) return rotationByEigen(b);
  Mat3 x = b * (1.0 / std::sqrt(norm2));
  for (int k = 0; k < 30; ++k) {
    const Vec3 c0 = glm::cross(x[1], x[2]);
    const Vec3 c1 = glm::cross(x[2], x[0]);
    const Vec3 c2 = glm::cross(x[0], x[1]);
    const double d = glm::dot(x[0], c0);
    if (!(d > 0.0)) break;
    const double invD = 1.0 / d;
    // x⁻ᵀ = (c0, c1, c2) / d; γ = (|x⁻¹|_F / |x|_F)^(1/2).
    const double cof2 = glm::dot(c0, c0) + glm::dot(c1, c1) + glm::dot(c2, c2);
    const double gamma = std::sqrt(std::sqrt(cof2 / frobenius2(x)) * invD);
    const double a = 0.5 * gamma;
    const double c = 0.5 * invD / gamma;
    const Mat3 next(a * x[0] + c * c0, a * x[1] + c * c1, a * x[2] + c * c2);
    const double delta = frobenius2(next - x);
    x = next;
    // The error after a step is about half the square of the step: |step| <= 1e-9 leaves ~1e-18.
    if (delta <= 1e-18) return x;
    if (delta <= 1e-2) {
      // Close to orthogonal (singular values within ~0.1 of 1): Newton-Schulz steps
      // X <- X (3 I - XᵀX) / 2 converge quadratically there with no division or root.
      for (int j = 0; j < 10; ++j) {
        const Mat3 e = glm::transpose(x) * x;
        const Mat3 ns = x * (1.5 * Mat3(1.0) - 0.5 * e);
        const double step = frobenius2(ns - x);
        x = ns;
        if (step <= 1e-18) return x;
      }
      break;
    }
  }
  return rotationByEigen(b);
}

RigidFit rigidFit(std::span<const Vec3> handles, std::span<const Vec3> targets) {
  RigidFit fit;
  if (handles.empty()) return fit;
  Vec3 ch(0.0), ct(0.0);
  for (std::size_t l = 0; l < handles.size(); ++l) {
    ch += handles[l];
    ct += targets[l];
  }
  ch /= double(handles.size());
  ct /= double(handles.size());
  Eigen::Matrix3d h = Eigen::Matrix3d::Zero();
  for (std::size_t l = 0; l < handles.size(); ++l)
    h += toEigen(handles[l] - ch) * toEigen(targets[l] - ct).transpose();
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(h, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d d = Eigen::Matrix3d::Identity();
  d(2, 2) = (svd.matrixV() * svd.matrixU().transpose()).determinant() < 0.0 ? -1.0 : 1.0;
  fit.r = toMat3(svd.matrixV() * d * svd.matrixU().transpose());
  fit.shift = ct - fit.r * ch;
  return fit;
}

}  // namespace spacewarp::detail
