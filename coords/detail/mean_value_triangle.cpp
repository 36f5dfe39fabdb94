#include <spacewarp/coords/detail/mean_value_triangle.h>

// The numerics of both paths are described at the top of coords/mean_value.cpp; this file must
// be compiled like it (-ffp-contract=off), so that the two give the same bits.

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

namespace spacewarp::detail {

namespace {

using Real = long double;
struct V3 {
  Real x, y, z;
};
inline V3 operator-(const V3& a, const V3& b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
inline V3 operator*(Real s, const V3& a) { return {s * a.x, s * a.y, s * a.z}; }
inline V3& operator+=(V3& a, const V3& b) {
  a.x += b.x;
  a.y += b.y;
  a.z += b.z;
  return a;
}
inline Real dot(const V3& a, const V3& b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
inline V3 cross(const V3& a, const V3& b) {
  return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}

}  // namespace

CarefulTriangle carefulMeanValueTriangle(const std::array<Vec3, 3>& corners, const Vec3& x) {
  CarefulTriangle r;
  V3 p[3], v[3];
  Real d[3];
  for (int c = 0; c < 3; ++c) {
    p[c] = {corners[c].x, corners[c].y, corners[c].z};
    v[c] = p[c] - V3{x.x, x.y, x.z};
    d[c] = std::sqrt(dot(v[c], v[c]));
  }
  const V3 big = cross(p[1] - p[0], p[2] - p[0]);
  const Real area2 = std::sqrt(dot(big, big));
  const V3 n = (1 / area2) * big;
  const int nearest = d[0] <= d[1] ? (d[0] <= d[2] ? 0 : 2) : (d[1] <= d[2] ? 1 : 2);
  const Real h = dot(n, v[nearest]);
  const Real h2 = h * h;

  // The planar-angle identity Σψ = 2πK needs x₀ off T's corners; it is only needed near the
  // plane, |h| < ½ min d, where every |q_k| > 0.8 d_k. Elsewhere n · m = ½ Σ θ t directly.
  const bool planeCandidate = std::fabs(h) < std::min({d[0], d[1], d[2]}) / 2;
  V3 edge[3], mIn{0, 0, 0};
  Real sigma[3], sumPsi = 0, sumBeta = 0, sumDirect = 0;
  for (int c = 0; c < 3; ++c) {
    const int j = (c + 1) % 3, k = (c + 2) % 3;
    edge[c] = p[k] - p[j];
    const V3 cr = cross(d[j] <= d[k] ? v[j] : v[k], edge[c]);  // = v_j × v_k
    const Real rho = std::sqrt(dot(cr, cr));
    const Real sig = dot(n, cr);
    const Real g3 = dot(v[j], v[k]);  // γ + h²
    const Real theta = std::atan2(rho, g3);
    const Real thetaOverRho =
        rho > 0 ? theta / rho : (g3 > 0 ? 1 / g3 : std::numeric_limits<Real>::infinity());
    mIn += thetaOverRho * cross(n, edge[c]);
    sigma[c] = sig;
    sumDirect += rho > 0 ? theta * sig / rho : Real{0};
    if (!planeCandidate) continue;
    const Real absSig = std::fabs(sig);
    const Real g2 = g3 - h2;  // γ = q_j · q_k
    const Real len2 = dot(edge[c], edge[c]);
    const Real psi = std::atan2(sig, g2);
    Real beta;
    if (absSig <= std::fabs(h) * std::sqrt(len2)) {
      beta = (rho > 0 ? theta * sig / rho : Real{0}) - psi;
    } else {
      const Real sum = rho + absSig;
      const Real xx = g2 * len2 / sum - absSig;
      const Real yy = g3 * g2 + rho * absSig;
      beta = sig / rho * std::atan2(h2 * xx, yy) -
             std::copysign(std::fabs(psi), sig) * h2 * len2 / (rho * sum);
    }
    sumPsi += psi;
    sumBeta += beta;
  }
  const Real turnsReal = sumPsi / (2 * std::numbers::pi_v<Real>);
  const Real turns = std::round(turnsReal);
  const bool nearPlane = planeCandidate && std::fabs(turnsReal - turns) < Real{0.01};
  if (h == 0) {
    r.onFace = nearPlane && turns != 0;
    return r;  // w = 0: every term carries the factor h
  }
  mIn = (h / 2) * mIn;
  const Real mn = nearPlane ? sumBeta / 2 + std::numbers::pi_v<Real> * turns : sumDirect / 2;
  const Real sum = mn / h;
  for (int c = 0; c < 3; ++c) r.w[c] = (sum * sigma[c] - dot(n, cross(mIn, edge[c]))) / area2;
  return r;
}

std::array<long double, 3> carefulEdgeMeanVector(const Vec3& pj, const Vec3& pk, const Vec3& x) {
  const V3 a{pj.x, pj.y, pj.z}, b{pk.x, pk.y, pk.z}, o{x.x, x.y, x.z};
  const V3 vj = a - o, vk = b - o;
  const Real dj = std::sqrt(dot(vj, vj)), dk = std::sqrt(dot(vk, vk));
  const V3 c = cross(dj <= dk ? vj : vk, b - a);  // = v_j × v_k
  const Real rho = std::sqrt(dot(c, c)), g = dot(vj, vk);
  const Real factor = rho > 0 ? std::atan2(rho, g) / rho : (g > 0 ? 1 / g : Real{0});
  return {factor * c.x, factor * c.y, factor * c.z};
}

Vec3 edgeMeanVector(const Vec3& vj, const Vec3& vk, double dj, double dk, double& theta,
                    double& rho) {
  const Vec3 uj = vj / dj, uk = vk / dk;
  const double chord = glm::length(uj - uk);
  theta = chord <= std::numbers::sqrt2
              ? 2.0 * std::asin(chord / 2.0)
              : std::numbers::pi - 2.0 * std::asin(glm::length(uj + uk) / 2.0);
  const Vec3 c = glm::cross(dj <= dk ? vj : vk, vk - vj);  // = v_j × v_k
  rho = glm::length(c);
  const double sine = rho / (dj * dk);
  const double factor = sine > 1e-8 ? theta / rho : (1.0 + theta * theta / 6.0) / (dj * dk);
  return factor * c;
}

FastTriangle fastMeanValueTriangle(const std::array<Vec3, 3>& v, const std::array<double, 3>& d,
                                   std::array<double, 3>& w) {
  constexpr double kInf = std::numeric_limits<double>::infinity();
  constexpr double kEps = std::numeric_limits<double>::epsilon();
  std::array<Vec3, 3> c;
  std::array<double, 3> rho;
  Vec3 m(0.0);
  double err = 0.0;  // ≈ ε Σ θ (1 + L / (max d · sin θ)), the error of m (mean_value.cpp's kErrM)
  const double dMax = std::max({d[0], d[1], d[2]});
  for (int i = 0; i < 3; ++i) {
    const int j = (i + 1) % 3, k = (i + 2) % 3;
    double theta = 0.0;
    const double edgeLength = glm::length(v[k] - v[j]);
    const Vec3 share = edgeMeanVector(v[j], v[k], d[j], d[k], theta, rho[i]);
    c[i] = glm::cross(d[j] <= d[k] ? v[j] : v[k], v[k] - v[j]);
    m += 0.5 * share;
    const double sine = rho[i] / (d[j] * d[k]);
    err += theta * (1.0 + edgeLength / (dMax * std::max(sine, kEps)));
  }
  const int s = d[0] <= d[1] ? (d[0] <= d[2] ? 0 : 2) : (d[1] <= d[2] ? 1 : 2);
  const Vec3 normal = glm::cross(v[1] - v[0], v[2] - v[0]);
  const double det = glm::dot(normal, v[s]);
  if (!(det != 0.0)) return {kInf, 0.0};
  double wMax = 0.0;
  for (int i = 0; i < 3; ++i) {
    w[i] = glm::dot(c[i], m) / det;
    wMax = std::max(wMax, std::fabs(w[i]));
  }
  const double wErr = 4.0 * kEps * err * std::max({rho[0], rho[1], rho[2]}) / std::fabs(det);
  const double elevation = std::fabs(det) / (glm::length(normal) * d[s]);
  return {std::isfinite(wMax) && wErr <= 1e-3 * wMax ? wErr : kInf, elevation};
}

}  // namespace spacewarp::detail
