#include <spacewarp/coords/quad_mean_value.h>

// Numerics
// ========
// Mean-value coordinates of a closed surface S around x are w_i(x) = ∫ φ_i(σ) / |σ − x| dΩ over
// the unit sphere of directions from x, σ the point of S seen in that direction and φ_i the
// interpolant of S's faces (linear on triangles, bilinear on quads); the row is w / Σ w. Every
// face F contributes weights W^F with Σ_i W^F_i (p_i − x) = m_F, the mean vector of F's
// spherical projection, ½ Σ θ_e C_e / |C_e| over F's boundary edges only (edgeMeanVector in
// coords/detail/mean_value_triangle.h). Summed over the closed cage the m_F cancel, so any
// weights with that property give partition of unity and linear precision.
//
// Triangles: Ju et al.'s weights, the per-triangle term of MeanValueCoordinates
// (coords/detail/mean_value_triangle.h): the fast double formula, or the careful long-double
// one where its error estimate asks for it. An all-triangle cage is handed whole to a
// MeanValueCoordinates, so its rows are those of MVC bit for bit.
//
// Quads (Thiery, Memari, Boubekeur 2018): σ is the bilinear patch ξ(u, v) and φ its bilinear
// basis B. The three equations Σ W_i v_i = m fix W up to the null vector N of (v_0 … v_3) (N_i
// the signed cofactors; N ∝ φ(u, v) exactly when x = σ(u, v)); the fourth degree of freedom is
// taken from the integral itself: W = W_p + (F − N̂·W_p) N̂ with W_p any solution of the three
// equations and
//     F = N̂·W = ∫∫ ψ(u, v) (ξ − x)·(ξ_u × ξ_v) / |ξ − x|⁴ du dv,   ψ = Σ N̂_k B_k,
// (dΩ / r = (ξ − x)·(ξ_u × ξ_v) / |ξ − x|⁴ du dv). ψ = N̂·B is the functional whose projection
// on N is |N̂|² = 1, the best conditioned there is; Σ W_i = ∫ dΩ / r would have projection
// Σ N_i, which vanishes for every planar quad (N is then the corners' affine dependence). F is
// integrated by the adaptive Gauss-Legendre quadrature of coords/detail/bilinear_quadrature.h
// (shared with QuadGreenCoordinates: admissibility ρ / D ≤ 1/2, orders from its table, node
// vectors from x's foot near the patch, compiled per simd::Path). W_p:
//  - where the quadrature went near x (some square not admissible): four triangles fanned
//    around x's foot, each with its exact MVC weights (the careful path where x is near its
//    plane or its fast error estimate exceeds 1e-10 of its weights: a sliver seen at close range
//    had weights 1e-4 off), the foot's weight passed on by φ(foot). The fan's triangles see x
//    as the patch does, so F − N̂·W_p stays O(1) against the weights' 1 / h. A foot within 16
//    heights of a side is put on it (no sliver triangle on that side);
//  - elsewhere, the least-norm solution by Householder QR (backward stable however nearly
//    parallel the v_i are); on the careful pass (outside, where the weights cancel), the fan
//    around the patch centre in long double.
// So the three equations, hence partition of unity and linear precision, hold to round-off; the
// result does not depend on a diagonal or (beyond round-off) on the starting vertex; it tends to
// φ(foot) as x approaches the patch (the fan's centre node is the foot), and is robust near the
// patch and its plane. Measured: rows equal a brute-force long-double integral (16-point rule,
// 5-radius admissibility) to 3e-16 (max |Δw|) inside, outside and at 1e-3 … 1e-12 diagonals from
// faces, edges and vertices of planar and warped quads, wherever that reference is itself
// accurate (its node vectors carry 1e-19 / distance: one point 1.7e-11 above a face differed by
// 6e-9); the tessellation this replaced was 1e-3 … 6e-3 off. Reproduction: ~2e-16 at 1e-4 …
// 1e-10 diagonals from edges and vertices; outside (2000 points per radius, the 2 × 2 per side
// cube planar / jittered by ±0.2) 1.4e-14 at 3, 3.5e-13 / 1e-14 at 10, 7e-14 / 8e-14 at 30,
// 1.2e-12 / 1.9e-12 at 100 and 3.6e-10 / 1.3e-9 at 1000 diagonals (MVC on the triangulation:
// 2e-15, 1e-14 / 5e-14, 4e-13 / 1.4e-12, 5e-10 / 1.5e-9). At 10 diagonals the planar cube's
// worst points (near the axes) are least-norm points whose estimate ε Σ |w| d / |W| stayed
// under kTauRepro while their error was ~3.5 times it; kTauRepro = 1e-14 brings them to
// 1.6e-14, but sends points 3 diagonals out to the careful pass too (4× their cost), so it is
// left at MVC's value. Independent check (the attack's NumPy quadrature, 64² Gauss points on
// 8 × 8 cells per quad): max |Δw| ≤ 1.7e-16 at 20 interior points of a planar and a warped cube.
// Cost (the bench's twisted 294-quad box, one thread, batch): 515 ns per (point × quad) against
// MVC's 25 ns for the quad's two triangles (21×; the tessellation this replaced: 2650 ns). Profile:
// 26% F (~90 nodes per quad; QGC's eight integrals take 220 ns), 24% the four edges' mean vector
// (asin), 44% the rest of quad() (null vector, Householder QR, sums). The 3× target would need F
// alone to cost ~2 MVC triangles.
//
// Polygons with more than 4 vertices (planar): Langer, Belyaev and Seidel's spherical
// mean-value construction. With m̂ = m / |m|, t_i the component of u_i = v_i / d_i orthogonal to
// m̂ and α_i the signed angle about m̂ from t_i to t_{i+1},
//     λ_i = (tan(α_{i−1} / 2) + tan(α_i / 2)) / |t_i|,   W_i = |m| λ_i / (d_i Σ_k λ_k (u_k · m̂)),
// which solves Σ W_i v_i = m exactly (Floater's identity Σ λ_i t_i = 0 holds for any unit
// vectors). On the face (within snapTolerance) the same formula on the in-plane vectors
// p_i − x₀ gives the polygon's 2D mean-value coordinates. Non-planar polygons with more than 4
// vertices are refused (InvalidInput naming the face): their interpolant is not defined.
//
// Outside the cage the weight sum W cancels; as in MeanValueCoordinates a point whose estimated
// reproduction error ε Σ |w| d / (|W| diagonal) exceeds 1e-13 is recomputed with every triangle
// by the careful path (long double; polygons are always computed in long double), and points
// beyond 3000 diagonals are refused.

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <numbers>
#include <string>
#include <utility>
#include <vector>

#include <spacewarp/coords/detail/bilinear_quadrature.h>
#include <spacewarp/coords/detail/mean_value_triangle.h>
#include <spacewarp/coords/detail/quad_fold.h>
#include <spacewarp/coords/mean_value.h>
#include <spacewarp/core/archive.h>
#include <spacewarp/core/detail/simd.h>
#include <spacewarp/core/errors.h>
#include <spacewarp/core/geometry.h>

namespace spacewarp {

namespace {

using namespace detail::patch;
using Real = long double;
constexpr double kEps = std::numeric_limits<double>::epsilon();
// As MeanValueCoordinates' kTauW, kTauRepro and kFarLimit (see mean_value.cpp).
constexpr double kTauW = 1e-13;
constexpr double kTauRepro = 1e-13;
constexpr double kFarLimit = 3000.0;
// A triangle of a quad's fan takes the careful path when x's elevation over its plane is below
// this (the fast weights then solve their equations to ~1e-13 of m_T).
constexpr double kMinElevation = 1e-3;

// The cage's faces, edges and per-face boxes (for the snapping test).
struct CageData {
  std::vector<Vec3> p;
  std::vector<std::uint32_t> offsets, indices;
  std::vector<std::pair<std::uint32_t, std::uint32_t>> edges;  // each once, first < second
  std::vector<Vec3> normal;                                    // unit Newell normal per face
  std::vector<Patch> patch;  // per face (quads only; others default)
  std::vector<BoundingBox> box;
  double diagonal = 0.0;
  double snapLength = 0.0;
  double touchRadius = 0.0;  // integrateAdaptive's contact radius (world units)
  Vec3 center{0.0};

  std::span<const std::uint32_t> face(std::size_t f) const {
    return {indices.data() + offsets[f], offsets[f + 1] - offsets[f]};
  }
};

// F = ∫∫ ψ(u, v) (ξ − x)·(ξ_u × ξ_v) / |ξ − x|⁴ du dv with ψ = Σ N̂_k B_k (see the top), and where
// the quadrature went: `near` if it measured from x's foot (then `foot` is that origin),
// `inside` false if x touched the patch.
struct QuadIntegral {
  double value = 0.0;
  bool near = false, inside = true;
  Origin foot;
};

// What a quad's weights need that does not change between a point's passes: N̂ (see
// nullVector) and the integral.
struct QuadTerms {
  std::array<Real, 4> n{};
  QuadIntegral integral;
};

// Per-thread buffers of one point.
struct Scratch {
  std::vector<QuadTerms> quads;  // per face (quads only), filled on the point's first pass
  std::vector<char> quadDone;
  std::vector<Vec3> v;  // p_i − x
  std::vector<double> d;
  std::vector<Real> acc;                              // Σ over faces of the unnormalised weights
  std::vector<Real> lambda;                           // a polygon's, and its terms:
  std::vector<glm::vec<3, Real>> polygonV, polygonT;  // p_i − x and the tangent vectors
  std::vector<Real> polygonD;
};

// λ_i = (tan(α_{i−1}/2) + tan(α_i/2)) / |t_i|, α_i the angle about `axis` from t_i to t_{i+1}:
// the mean-value coordinates of the origin in the plane normal to `axis` (unnormalised).
// False if some t_i vanishes (the origin is a vertex).
template <class T>
bool tangentMeanValue(std::span<const glm::vec<3, T>> t, const glm::vec<3, T>& axis,
                      std::span<T> lambda) {
  const std::size_t n = t.size();
  T prev = 0;  // tan(α_{i−1} / 2), first for i = 0
  for (std::size_t i = 0; i < n; ++i) {
    const auto& a = t[i];
    const auto& b = t[(i + 1) % n];
    const T la = glm::length(a), lb = glm::length(b);
    if (!(la > 0 && lb > 0)) return false;
    const T sine = glm::dot(axis, glm::cross(a, b)), cosine = glm::dot(a, b);
    // sin α / (1 + cos α) = (1 − cos α) / sin α: the form whose denominator is not small.
    const T half = cosine >= 0 ? sine / (la * lb + cosine) : (la * lb - cosine) / sine;
    lambda[i] = half;  // tan(α_i / 2) for now
    if (i + 1 == n) prev = half;
  }
  for (std::size_t i = 0; i < n; ++i) {
    const T here = lambda[i];
    lambda[i] = (prev + here) / glm::length(t[i]);
    prev = here;
  }
  return true;
}

std::string pointText(const Vec3& x) {
  char text[96];
  std::snprintf(text, sizeof text, "(%.17g, %.17g, %.17g)", x.x, x.y, x.z);
  return text;
}

// ---- snapping ----

// x's projection on the plane of polygon f, if x is within cd.snapLength of the face (its
// plane, and inside it); returns false otherwise. For quads, the inverse-bilinear parameters.
bool onFace(const CageData& cd, const Vec3& x, const Scratch& s, std::size_t f,
            std::span<double> row) {
  const auto face = cd.face(f);
  const std::size_t n = face.size();
  if (n == 4) {
    const Origin foot = footOf(cd.patch[f], x);
    if (!(glm::length(foot.offset) <= cd.snapLength)) return false;
    const std::array<double, 4> phi = bilinear(foot.u, foot.v);
    std::fill(row.begin(), row.end(), 0.0);
    for (int c = 0; c < 4; ++c) row[face[c]] += phi[c];
    return true;
  }
  const Vec3& nrm = cd.normal[f];
  const double h = glm::dot(nrm, s.v[face[0]]);
  if (!(std::fabs(h) <= cd.snapLength)) return false;
  // The in-plane vectors from x₀ to the corners; x₀ is inside if they wind once around it.
  std::vector<Vec3> t(n);
  double turn = 0.0;
  for (std::size_t i = 0; i < n; ++i) t[i] = s.v[face[i]] - h * nrm;
  for (std::size_t i = 0; i < n; ++i) {
    const Vec3& a = t[i];
    const Vec3& b = t[(i + 1) % n];
    turn += std::atan2(glm::dot(nrm, glm::cross(a, b)), glm::dot(a, b));
  }
  if (!(turn > std::numbers::pi)) return false;
  std::vector<double> lambda(n);
  if (!tangentMeanValue<double>(t, nrm, lambda)) return false;  // at a vertex: snapped before
  double sum = 0.0;
  for (double l : lambda) sum += l;
  std::fill(row.begin(), row.end(), 0.0);
  for (std::size_t i = 0; i < n; ++i) row[face[i]] += lambda[i] / sum;
  return true;
}

// Lagrange at a vertex, linear on an edge, the face's interpolant on a face: the nearest
// within cd.snapLength, in that order of precedence. False if x is not that close to the cage.
bool snapRow(const CageData& cd, const Vec3& x, const Scratch& s, std::span<double> row) {
  const double tol = cd.snapLength;
  std::size_t best = cd.p.size();
  double bestDist = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < cd.p.size(); ++i) {
    if (s.d[i] <= tol && s.d[i] < bestDist) {
      best = i;
      bestDist = s.d[i];
    }
  }
  if (best < cd.p.size()) {
    std::fill(row.begin(), row.end(), 0.0);
    row[best] = 1.0;
    return true;
  }
  double bestT = 0.0;
  best = cd.edges.size();
  for (std::size_t e = 0; e < cd.edges.size(); ++e) {
    const auto [a, b] = cd.edges[e];
    const Vec3 edge = cd.p[b] - cd.p[a];
    const double t = glm::dot(-s.v[a], edge) / glm::dot(edge, edge);
    if (!(t > 0.0 && t < 1.0)) continue;
    const double dist = glm::length(s.v[a] + t * edge);
    if (dist <= tol && dist < bestDist) {
      best = e;
      bestDist = dist;
      bestT = t;
    }
  }
  if (best < cd.edges.size()) {
    std::fill(row.begin(), row.end(), 0.0);
    row[cd.edges[best].first] = 1.0 - bestT;
    row[cd.edges[best].second] = bestT;
    return true;
  }
  for (std::size_t f = 0; f + 1 < cd.offsets.size(); ++f) {
    const BoundingBox& b = cd.box[f];
    if (glm::length(glm::clamp(x, b.min, b.max) - x) > tol) continue;
    if (onFace(cd, x, s, f, row)) return true;
  }
  return false;
}

// ---- a quad's integral ----

// The tensor rule of order n over [u0, u0 + s] × [v0, v0 + s], node vectors from `o`, kBlock
// nodes at a time into kBlock interleaved partial sums (vectorised without reordering any sum:
// the same bits on every simd::Path), as QuadGreenCoordinates' gaussSquare.
[[gnu::always_inline]] inline double gaussSquare(const Patch& q, const Origin& o,
                                                 const std::array<double, 4>& n, double u0,
                                                 double v0, double s, int order) {
  const GaussRule& rule = gaussRules()[order];
  const double bx = o.offset.x, by = o.offset.y, bz = o.offset.z;
  const double ux = q.eu.x, uy = q.eu.y, uz = q.eu.z, vx = q.ev.x, vy = q.ev.y, vz = q.ev.z;
  const double wx = q.euv.x, wy = q.euv.y, wz = q.euv.z;
  const double du0 = u0 - o.u, dv0 = v0 - o.v, uo = o.u;
  // ψ = n0 + a u + b v + c uv (the bilinear combination of the corner values).
  const double pa = n[1] - n[0], pb = n[3] - n[0], pc = n[0] - n[1] + n[2] - n[3];
  alignas(64) double acc[kBlock] = {};
  for (int t0 = 0; t0 < rule.tensorCount; t0 += kBlock) {
    for (int l = 0; l < kBlock; ++l) {
      const double su = s * rule.tu[t0 + l], sv = s * rule.tv[t0 + l];
      const double u = u0 + su, v = v0 + sv, du = du0 + su, dv = dv0 + sv;
      const double dw = du * v + uo * dv;
      const double rx = bx + du * ux + dv * vx + dw * wx;
      const double ry = by + du * uy + dv * vy + dw * wy;
      const double rz = bz + du * uz + dv * vz + dw * wz;
      const double ax = ux + v * wx, ay = uy + v * wy, az = uz + v * wz;  // ξ_u
      const double cx = vx + u * wx, cy = vy + u * wy, cz = vz + u * wz;  // ξ_v
      const double det =
          rx * (ay * cz - az * cy) + ry * (az * cx - ax * cz) + rz * (ax * cy - ay * cx);
      const double r2 = rx * rx + ry * ry + rz * rz;
      const double psi = n[0] + pa * u + pb * v + pc * (u * v);
      acc[l] += rule.tw[t0 + l] * psi * det / (r2 * r2);
    }
  }
  double sum = 0.0;
  for (int l = 0; l < kBlock; ++l) sum += acc[l];
  return s * s * sum;
}

[[gnu::always_inline]] inline void integrateQuad(const Patch& q, const Vec3& x,
                                                 const std::array<double, 4>& n, double touchRadius,
                                                 QuadIntegral& out) {
  const auto square = [&](const Origin& o, double u0, double v0, double s, int order)
      __attribute__((always_inline)) {
    out.value += gaussSquare(q, o, n, u0, v0, s, order);
  };
  out.foot.u = -1.0;  // unset
  double tu = 0.0, tv = 0.0;
  out.inside = integrateAdaptive(q, x, touchRadius, square, out.foot, tu, tv);
  out.near = out.foot.u >= 0.0;
}

// integrateQuad compiled for each simd::Path (core/detail/simd.h), as in quad_green.cpp.
using IntegrateFn = void (*)(const Patch&, const Vec3&, const std::array<double, 4>&, double,
                             QuadIntegral&);
void integrateBaseline(const Patch& q, const Vec3& x, const std::array<double, 4>& n,
                       double touchRadius, QuadIntegral& out) {
  integrateQuad(q, x, n, touchRadius, out);
}
SPACEWARP_SIMD_TARGET_V3 void integrateV3(const Patch& q, const Vec3& x,
                                          const std::array<double, 4>& n, double touchRadius,
                                          QuadIntegral& out) {
  integrateQuad(q, x, n, touchRadius, out);
}
SPACEWARP_SIMD_TARGET_V4 void integrateV4(const Patch& q, const Vec3& x,
                                          const std::array<double, 4>& n, double touchRadius,
                                          QuadIntegral& out) {
  integrateQuad(q, x, n, touchRadius, out);
}
constexpr IntegrateFn kIntegrate[detail::simd::kPathCount] = {integrateBaseline, integrateV3,
                                                              integrateV4};

// The fan's centre (u, v): x's foot, put on a side of the patch when it is closer to it than
// kSideSnap times x's distance to the patch. The fan's triangle on that side would be a sliver
// that x sees at close range, whose fast weights err by ~ε / width (only the three equations
// matter, as the integral fixes the rest, but their error is then amplified). Any fan centre
// gives the same weights up to round-off, so moving it is no discontinuity.
constexpr double kSideSnap = 16.0;
void fanCentre(const Patch& q, const Origin& foot, double& u, double& v) {
  const double reach = kSideSnap * glm::length(foot.offset);
  const double lu = glm::length(q.tangentU(foot.v)), lv = glm::length(q.tangentV(foot.u));
  const auto snap = [reach](double t, double length) {
    return t * length <= reach || t < 0x1p-40                 ? 0.0
           : (1.0 - t) * length <= reach || t > 1.0 - 0x1p-40 ? 1.0
                                                              : t;
  };
  u = snap(foot.u, lu);
  v = snap(foot.v, lv);
}

// ---- the kernel of one point ----

class PointKernel {
 public:
  // Triangles whose fast weights have an estimated error above `fastLimit` (world-independent:
  // weights are in units of 1 / length) take the careful path.
  PointKernel(const CageData& cd, const Vec3& x, Scratch& s, double fastLimit)
      : cd_(cd), x_(x), s_(s), fastLimit_(fastLimit) {}

  double kappa() const { return kappa_; }
  double error() const { return error_; }               // Σ of the fast triangles' error estimates
  std::size_t triangles() const { return triangles_; }  // triangle terms evaluated

  // Adds every face; false if x turned out to lie on a face (row filled).
  bool addFaces(std::span<double> row) {
    for (std::size_t f = 0; f + 1 < cd_.offsets.size(); ++f) {
      const auto face = cd_.face(f);
      if (face.size() == 3) {
        const std::array<Vec3, 3> v = {s_.v[face[0]], s_.v[face[1]], s_.v[face[2]]};
        const std::array<double, 3> d = {s_.d[face[0]], s_.d[face[1]], s_.d[face[2]]};
        std::array<Real, 3> w;
        if (!triangle(v, d, w)) {
          // On the triangle: its barycentric coordinates are the careful path's face row.
          std::fill(row.begin(), row.end(), 0.0);
          triangleRow(v, face, row);
          return false;
        }
        for (int c = 0; c < 3; ++c) add(face[c], w[c], d[c]);
      } else if (face.size() == 4) {
        if (!quad(f, face, row)) return false;
      } else {
        polygon(f, face);
      }
    }
    return true;
  }

 private:
  void add(std::uint32_t i, Real w, double d) {
    s_.acc[i] += w;
    kappa_ += std::fabs(static_cast<double>(w)) * d;
  }

  // The weights of the triangle x + v; false if x lies on it.
  // The triangles of a quad's tessellation (`part`) only approximate an integral, so their
  // weights need not be accurate to MVC's standard: only Σ w_i v_i = m_T, which Cramer's rule
  // keeps to ε / elevation (and the shared boundary of the tessellation turns into linear
  // precision). They take the fast path unless x is near their plane.
  bool triangle(const std::array<Vec3, 3>& v, const std::array<double, 3>& d,
                std::array<Real, 3>& w, bool part = false) {
    std::array<double, 3> fw;
    const detail::FastTriangle fast = detail::fastMeanValueTriangle(v, d, fw);
    w = {fw[0], fw[1], fw[2]};
    if (part) {
      if (fastLimit_ > 0.0 && fast.elevation >= kMinElevation &&
          fast.error <= 1e-10 * (std::fabs(fw[0]) + std::fabs(fw[1]) + std::fabs(fw[2])))
        return true;
    } else {
      ++triangles_;
      if (fast.error <= fastLimit_) {
        error_ += fast.error;
        return true;
      }
    }
    const std::array<Vec3, 3> corners = {x_ + v[0], x_ + v[1], x_ + v[2]};
    const detail::CarefulTriangle r = detail::carefulMeanValueTriangle(corners, x_);
    if (r.onFace) return false;
    w = r.w;
    return true;
  }

  // Barycentric coordinates of x's projection on the triangle x + v, into row at `ids`.
  static void triangleRow(const std::array<Vec3, 3>& v, std::span<const std::uint32_t> ids,
                          std::span<double> row) {
    const Vec3 n = glm::cross(v[1] - v[0], v[2] - v[0]);
    std::array<double, 3> b;
    double sum = 0.0;
    for (int c = 0; c < 3; ++c) {
      b[c] = std::max(0.0, glm::dot(n, glm::cross(v[(c + 1) % 3], v[(c + 2) % 3])));
      sum += b[c];
    }
    for (int c = 0; c < 3; ++c) row[ids[c]] += b[c] / sum;
  }

  // The quad's weights (see the top): W = W_fan + (F − N̂·W_fan) N̂, W_fan the weights of four
  // triangles fanned around a point of the patch (they solve the three equations), F = N̂·W the
  // integral of ψ = Σ N̂_i B_i by adaptive quadrature. False if x lies on the patch (row filled).
  bool quad(std::size_t f, std::span<const std::uint32_t> face, std::span<double> row) {
    const Patch& q = cd_.patch[f];
    QuadTerms& terms = s_.quads[f];
    const std::array<Real, 4>& nl = terms.n;
    if (!s_.quadDone[f]) {
      s_.quadDone[f] = 1;
      terms.n = nullVector(face);
      terms.integral = QuadIntegral{};
      const std::array<double, 4> nd = {static_cast<double>(nl[0]), static_cast<double>(nl[1]),
                                        static_cast<double>(nl[2]), static_cast<double>(nl[3])};
      kIntegrate[static_cast<int>(detail::simd::activePath())](q, x_, nd, cd_.touchRadius,
                                                               terms.integral);
    }
    const QuadIntegral& integral = terms.integral;
    // The three equations: where the quadrature went near x, from four triangles fanned around
    // x's foot (they then see x as the patch does, at a distance like the patch's); otherwise
    // by the least-norm solution (leastNorm), but on the careful pass (outside, where the
    // weights cancel) from the fan around the patch's centre in long double.
    double u = 0.5, v = 0.5;
    if (integral.near) fanCentre(q, integral.foot, u, v);
    const std::array<double, 4> phi = bilinear(u, v);
    const auto onPatch = [&] {
      std::fill(row.begin(), row.end(), 0.0);
      for (int k = 0; k < 4; ++k) row[face[k]] += phi[k];
      return false;
    };
    if (!integral.inside) return onPatch();
    std::array<Real, 4> w4 = {0, 0, 0, 0};
    if (!integral.near && fastLimit_ > 0.0) {
      leastNorm(face, w4);
      return addQuad(face, nl, integral.value, w4);
    }
    // The fan: nodes 0 … 3 are the corners, 4 its centre; the triangle on side c (corners c,
    // c + 1) is empty when the centre is on that side.
    std::array<std::array<int, 3>, 4> tris;
    int count = 0;
    const std::array<bool, 4> empty = {v == 0.0, u == 1.0, v == 1.0, u == 0.0};
    for (int c = 0; c < 4; ++c)
      if (!empty[c]) tris[count++] = {4, c, (c + 1) % 4};
    const Vec3 centre = integral.near ? fromOrigin(q, integral.foot, u, v) : q.at(u, v) - x_;
    const double centreD = glm::length(centre);
    for (int t = 0; t < count; ++t) {
      std::array<Vec3, 3> tv;
      std::array<double, 3> td;
      for (int c = 0; c < 3; ++c) {
        const int node = tris[t][c];
        tv[c] = node == 4 ? centre : s_.v[face[node]];
        td[c] = node == 4 ? centreD : s_.d[face[node]];
      }
      std::array<Real, 3> w;
      // False: x lies on this triangle (so within rounding of the patch, as it passed the
      // snapping test only when snapTolerance is 0): the interpolant at the centre.
      if (!triangle(tv, td, w, true)) return onPatch();
      for (int c = 0; c < 3; ++c) {
        const int node = tris[t][c];
        if (node < 4) {
          w4[node] += w[c];
        } else {
          for (int k = 0; k < 4; ++k) w4[k] += w[c] * phi[k];
        }
      }
    }
    return addQuad(face, nl, integral.value, w4);
  }

  // W = W_p + (F − N̂·W_p) N̂ into the sums.
  // In long double: N̂'s rounding would add free · ε |p − x| to the reproduction, and the careful
  // triangles' rounding to double ε |W| |p − x|, which outside, where the weights cancel,
  // reaches the coordinates.
  bool addQuad(std::span<const std::uint32_t> face, const std::array<Real, 4>& n, double F,
               const std::array<Real, 4>& wp) {
    const Real free = F - (n[0] * wp[0] + n[1] * wp[1] + n[2] * wp[2] + n[3] * wp[3]);
    for (int k = 0; k < 4; ++k) add(face[k], wp[k] + free * n[k], s_.d[face[k]]);
    return true;
  }

  // The least-norm solution of the three equations Σ W_i v_i = m (m from the quad's four edges)
  // by Householder QR of the 4 × 3 matrix of rows v_i: backward stable, so its residual is
  // ~ε |v| |W_p| with |W_p| ≤ |W| (the exact weights solve the same equations), however nearly
  // parallel the v_i are (a small quad far away) or coplanar (x near a planar quad's plane).
  // Cramer's rule on three corners, tried first, erred by ε times the systems' condition
  // (reproduction 3e-12 at 10 diagonals).
  void leastNorm(std::span<const std::uint32_t> face, std::array<Real, 4>& w) const {
    Vec3 m(0.0);
    for (int c = 0; c < 4; ++c) {
      double theta, rho;
      const std::uint32_t a = face[c], b = face[(c + 1) % 4];
      m += 0.5 * detail::edgeMeanVector(s_.v[a], s_.v[b], s_.d[a], s_.d[b], theta, rho);
    }
    // A = Vᵀ (rows v_c) = Q R by three Householder reflections H_j = I − 2 h_j h_jᵀ (rows j …
    // 3); V = Rᵀ Qᵀ, so W = Q (R⁻ᵀ m, 0) = H_0 H_1 H_2 (y, 0) with Rᵀ y = m.
    double a[4][3];
    for (int c = 0; c < 4; ++c)
      for (int k = 0; k < 3; ++k) a[c][k] = s_.v[face[c]][k];
    double h[3][4] = {};
    for (int j = 0; j < 3; ++j) {
      double norm2 = 0.0;
      for (int r = j; r < 4; ++r) norm2 += a[r][j] * a[r][j];
      const double norm = std::sqrt(norm2);
      const double alpha = a[j][j] > 0.0 ? -norm : norm;
      for (int r = j; r < 4; ++r) h[j][r] = a[r][j];
      h[j][j] -= alpha;
      double hn2 = 0.0;
      for (int r = j; r < 4; ++r) hn2 += h[j][r] * h[j][r];
      if (!(hn2 > 0.0)) continue;  // the column is already reduced: H_j = I
      const double hn = std::sqrt(hn2);
      for (int r = j; r < 4; ++r) h[j][r] /= hn;
      for (int k = j; k < 3; ++k) {
        double dot = 0.0;
        for (int r = j; r < 4; ++r) dot += h[j][r] * a[r][k];
        for (int r = j; r < 4; ++r) a[r][k] -= 2.0 * dot * h[j][r];
      }
    }
    const double mm[3] = {m.x, m.y, m.z};
    double z[4] = {0.0, 0.0, 0.0, 0.0};
    for (int k = 0; k < 3; ++k) {  // Rᵀ y = m, Rᵀ lower triangular
      double sum = mm[k];
      for (int r = 0; r < k; ++r) sum -= a[r][k] * z[r];
      z[k] = sum / a[k][k];
    }
    for (int j = 2; j >= 0; --j) {
      double dot = 0.0;
      for (int r = j; r < 4; ++r) dot += h[j][r] * z[r];
      for (int r = j; r < 4; ++r) z[r] -= 2.0 * dot * h[j][r];
    }
    for (int c = 0; c < 4; ++c) w[c] = z[c];
  }

  // N̂, the unit null vector of (p_0 − x, …, p_3 − x): N_i = (−1)^i det(the other three), in long
  // double where |N| < 1e-3 of the scale of its terms, else in double. Near the plane of a nearly
  // planar quad every N_i is ~h d² with round-off ~u d³, so N̂'s direction errs by u d / h; that
  // error multiplies only the free component F − N̂·W_fan, which the fan keeps O(1) against the
  // weights' 1 / h (measured: reproduction ~2e-16 at 1e-10 diagonals from edges and vertices,
  // unchanged with N in double-double). Zero if x is in the plane of a planar
  // quad: then F = 0 and the fan alone gives the weights (zero outside the quad; on it, the fan's
  // triangles find x).
  std::array<Real, 4> nullVector(std::span<const std::uint32_t> face) const {
    const auto cofactors = [&]<class T>(T) {
      using V = glm::vec<3, T>;
      std::array<V, 4> v;
      for (int c = 0; c < 4; ++c) v[c] = V(cd_.p[face[c]]) - V(x_);
      const auto det = [&](int a, int b, int c) { return glm::dot(v[a], glm::cross(v[b], v[c])); };
      const std::array<T, 4> n = {det(1, 2, 3), -det(0, 2, 3), det(0, 1, 3), -det(0, 1, 2)};
      const T length = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2] + n[3] * n[3]);
      std::array<Real, 4> unit = {0, 0, 0, 0};
      if (length > 0)
        for (int i = 0; i < 4; ++i) unit[i] = n[i] / length;
      return std::pair{unit, static_cast<double>(length)};
    };
    // In double where |N| is not small against its terms (x well off the quad's plane).
    const auto [unit, length] = cofactors(0.0);
    const double* d = &s_.d[0];
    const double scale =
        d[face[1]] * d[face[2]] * d[face[3]] + d[face[0]] * d[face[2]] * d[face[3]] +
        d[face[0]] * d[face[1]] * d[face[3]] + d[face[0]] * d[face[1]] * d[face[2]];
    if (length >= 1e-3 * scale) return unit;
    return cofactors(Real{0}).first;
  }

  // Langer et al.'s spherical mean-value weights of a planar polygon (see the top), in long
  // double: near the polygon's edges the tangent directions of their ends are nearly opposite
  // and the half-angle tangents lose ε / distance (in double, reproduction erred by 1e-9 at 1e-9
  // diagonals from an edge; 4e-16 in long double), and outside the cage the mean vector's terms
  // cancel ever more with the distance. Polygons are few (caps), so this costs little.
  void polygon(std::size_t f, std::span<const std::uint32_t> face) {
    using V = glm::vec<3, Real>;
    const std::size_t n = face.size();
    // Exactly in the plane outside the face every weight is 0 (the limit; m vanishes there).
    if (glm::dot(cd_.normal[f], s_.v[face[0]]) == 0.0) return;
    const V x(x_);
    auto& v = s_.polygonV;
    auto& d = s_.polygonD;
    auto& t = s_.polygonT;
    auto& lambda = s_.lambda;
    v.resize(n);
    d.resize(n);
    t.resize(n);
    lambda.resize(n);
    for (std::size_t i = 0; i < n; ++i) {
      v[i] = V(cd_.p[face[i]]) - x;
      d[i] = glm::length(v[i]);
    }
    V m(0);
    for (std::size_t i = 0; i < n; ++i) {
      const auto share =
          detail::carefulEdgeMeanVector(cd_.p[face[i]], cd_.p[face[(i + 1) % n]], x_);
      m += V(share[0], share[1], share[2]) / Real{2};
    }
    const Real length = glm::length(m);
    if (!(length > 0)) return;
    const V axis = m / length;
    for (std::size_t i = 0; i < n; ++i) {
      const V u = v[i] / d[i];
      t[i] = u - glm::dot(u, axis) * axis;
    }
    if (!tangentMeanValue<Real>(t, axis, lambda)) {
      // m points at a vertex: all of m is that vertex's.
      for (std::size_t i = 0; i < n; ++i) {
        if (glm::length(t[i]) == 0) add(face[i], static_cast<double>(length / d[i]), s_.d[face[i]]);
      }
      return;
    }
    Real along = 0;
    for (std::size_t i = 0; i < n; ++i) along += lambda[i] * glm::dot(v[i], axis) / d[i];
    const Real scale = length / along;
    for (std::size_t i = 0; i < n; ++i)
      add(face[i], static_cast<double>(scale * lambda[i] / d[i]), s_.d[face[i]]);
  }

  const CageData& cd_;
  const Vec3& x_;
  Scratch& s_;
  double fastLimit_;
  double kappa_ = 0.0, error_ = 0.0;
  std::size_t triangles_ = 0;
};

// The row of x (finite, within kFarLimit diagonals).
void computeRow(const CageData& cd, const Vec3& x, Scratch& s, std::span<double> row) {
  const std::size_t nV = cd.p.size();
  s.v.resize(nV);
  s.d.resize(nV);
  s.acc.resize(nV);
  for (std::size_t i = 0; i < nV; ++i) {
    s.v[i] = cd.p[i] - x;
    s.d[i] = glm::length(s.v[i]);
  }
  if (snapRow(cd, x, s, row)) return;
  // Pass 1 takes every usable fast triangle; if their summed error estimate exceeds kTauW |W|,
  // pass 2 recomputes those above an equal share of that budget by the careful path; pass 3,
  // for points whose reproduction estimate ε Σ |w| d / (|W| diagonal) exceeds kTauRepro
  // (outside, where W cancels), takes the careful path everywhere.
  double limit = std::numeric_limits<double>::infinity();
  s.quads.resize(cd.offsets.size() - 1);
  s.quadDone.assign(cd.offsets.size() - 1, 0);
  for (int pass = 1;; ++pass) {
    std::fill(s.acc.begin(), s.acc.end(), Real{0});
    PointKernel kernel(cd, x, s, limit);
    if (!kernel.addFaces(row)) return;
    Real sum = 0;
    for (std::size_t i = 0; i < nV; ++i) sum += s.acc[i];
    const double w = static_cast<double>(sum);
    const bool finite = std::isfinite(w) && w != 0.0;
    if (pass == 1 && !(finite && kernel.error() <= kTauW * std::fabs(w))) {
      limit = finite ? kTauW * std::fabs(w) / static_cast<double>(kernel.triangles()) : 0.0;
      continue;
    }
    if (limit > 0.0 &&
        !(finite && kEps * kernel.kappa() <= kTauRepro * std::fabs(w) * cd.diagonal)) {
      limit = 0.0;
      continue;
    }
    if (!finite)
      throw SolverError("QuadMeanValueCoordinates: the weight sum vanishes at " + pointText(x));
    for (std::size_t i = 0; i < nV; ++i) row[i] = static_cast<double>(s.acc[i] / sum);
    return;
  }
}

void computeRange(const CageData& cd, const Vec3* points, std::size_t count, double* rows) {
  static thread_local Scratch scratch;
  const std::size_t nV = cd.p.size();
  for (std::size_t i = 0; i < count; ++i) {
    const double distance = glm::length(points[i] - cd.center) / cd.diagonal;
    if (!(distance <= kFarLimit)) {
      char text[200];
      std::snprintf(text, sizeof text,
                    "QuadMeanValueCoordinates: the point %s is %.3g cage diagonals from the cage; "
                    "mean value weights lose their accuracy beyond %g diagonals",
                    pointText(points[i]).c_str(), distance, kFarLimit);
      throw InvalidInput(text);
    }
    computeRow(cd, points[i], scratch, std::span<double>(rows + i * nV, nV));
  }
}

CageData buildCageData(const Cage& cage, const QuadMeanValueOptions& options) {
  CageData cd;
  cd.p.assign(cage.vertices().begin(), cage.vertices().end());
  cd.offsets.assign(cage.faceOffsets().begin(), cage.faceOffsets().end());
  cd.indices.assign(cage.faceIndices().begin(), cage.faceIndices().end());
  cd.diagonal = cage.diagonal();
  cd.snapLength = options.snapTolerance * cage.diagonal();
  cd.touchRadius = std::max(cd.snapLength, 1e-16 * cd.diagonal) / kAdmissible;
  const BoundingBox all = boundingBox(cage.vertices());
  cd.center = 0.5 * (all.min + all.max);
  std::map<std::pair<std::uint32_t, std::uint32_t>, bool> edges;
  for (std::size_t f = 0; f < cage.faceCount(); ++f) {
    const auto face = cage.face(f);
    const std::size_t n = face.size();
    Vec3 normal(0.0), centroid(0.0);
    BoundingBox box;
    for (std::size_t i = 0; i < n; ++i) {
      const Vec3& a = cd.p[face[i]];
      const Vec3& b = cd.p[face[(i + 1) % n]];
      // Newell, relative to the first corner: far from the origin, cross(a, b) would cancel.
      normal += glm::cross(a - cd.p[face[0]], b - cd.p[face[0]]);
      centroid += a / static_cast<double>(n);
      box.min = glm::min(box.min, a);
      box.max = glm::max(box.max, a);
      edges.try_emplace(std::minmax(face[i], face[(i + 1) % n]), true);
    }
    normal = glm::normalize(normal);
    if (n > 4) {
      double worst = 0.0;
      for (std::size_t i = 0; i < n; ++i)
        worst = std::max(worst, std::fabs(glm::dot(normal, cd.p[face[i]] - centroid)));
      if (!(worst <= options.polygonPlanarity * cd.diagonal)) {
        char text[300];
        std::snprintf(text, sizeof text,
                      "QuadMeanValueCoordinates: %s: face %zu (%zu vertices) is not planar (a "
                      "vertex is %.3g cage diagonals off its plane, more than polygonPlanarity "
                      "= %.3g); polygons of more than 4 vertices must be planar",
                      cage.name().c_str(), f, n, worst / cd.diagonal, options.polygonPlanarity);
        throw InvalidInput(text);
      }
    }
    cd.normal.push_back(normal);
    cd.box.push_back(box);
    cd.patch.emplace_back();
    if (n == 4) {
      detail::checkQuadUnfolded(cd.p, face, f, "QuadMeanValueCoordinates", cage.name());
      setPatch(cd.patch.back(), cd.p, face);
    }
  }
  for (const auto& [edge, unused] : edges) cd.edges.push_back(edge);
  return cd;
}

}  // namespace

struct QuadMeanValueCoordinates::Impl {
  std::shared_ptr<const Cage> cage;
  QuadMeanValueOptions options;
  std::shared_ptr<const MeanValueCoordinates> triangles;  // for an all-triangle cage
  CageData data;                                          // otherwise
};

QuadMeanValueCoordinates::QuadMeanValueCoordinates(std::shared_ptr<const Cage> cage,
                                                   const QuadMeanValueOptions& options) {
  if (!cage) throw InvalidInput("QuadMeanValueCoordinates: the cage is null");
  if (!(options.snapTolerance >= 0.0 && options.snapTolerance <= 1e-3)) {
    throw InvalidInput("QuadMeanValueCoordinates: snapTolerance must be in [0, 1e-3], got " +
                       std::to_string(options.snapTolerance));
  }
  if (!(options.polygonPlanarity >= 0.0 && options.polygonPlanarity <= 1e-2)) {
    throw InvalidInput("QuadMeanValueCoordinates: polygonPlanarity must be in [0, 1e-2], got " +
                       std::to_string(options.polygonPlanarity));
  }
  auto impl = std::make_unique<Impl>();
  if (cage->maxFaceSize() == 3) {
    MeanValueOptions mvc;
    mvc.snapTolerance = options.snapTolerance;
    impl->triangles = std::make_shared<const MeanValueCoordinates>(cage, mvc);
  } else {
    impl->data = buildCageData(*cage, options);
  }
  impl->cage = std::move(cage);
  impl->options = options;
  impl_ = std::move(impl);
}

QuadMeanValueCoordinates::~QuadMeanValueCoordinates() = default;

std::size_t QuadMeanValueCoordinates::controlPointCount() const {
  return impl_->cage->vertexCount();
}

std::span<const Vec3> QuadMeanValueCoordinates::restControlPoints() const {
  return impl_->cage->vertices();
}

const Cage& QuadMeanValueCoordinates::cage() const { return *impl_->cage; }
const QuadMeanValueOptions& QuadMeanValueCoordinates::options() const { return impl_->options; }

void QuadMeanValueCoordinates::weights(const Vec3& x, std::span<double> row) const {
  checkWeightsArguments(x, row.size());
  if (impl_->triangles) return impl_->triangles->weights(x, row);
  computeRange(impl_->data, &x, 1, row.data());
}

UnmappedPoints QuadMeanValueCoordinates::weightsRange(std::span<const Vec3> points,
                                                      std::span<double> rows, std::size_t begin,
                                                      std::size_t end) const {
  const std::size_t n = columnCount();
  if (impl_->triangles) {
    impl_->triangles->weightsBatch(points.subspan(begin, end - begin),
                                   rows.subspan(begin * n, (end - begin) * n));
  } else {
    computeRange(impl_->data, points.data() + begin, end - begin, rows.data() + begin * n);
  }
  return {};
}

void QuadMeanValueCoordinates::save(ArchiveWriter& out) const {
  out.tag("quad-mean-value");
  impl_->cage->save(out);
  out.f64(impl_->options.snapTolerance);
  out.f64(impl_->options.polygonPlanarity);
}

std::shared_ptr<const QuadMeanValueCoordinates> QuadMeanValueCoordinates::load(ArchiveReader& in) {
  auto cage = std::make_shared<const Cage>(Cage::load(in));
  QuadMeanValueOptions options;
  options.snapTolerance = in.f64();
  options.polygonPlanarity = in.f64();
  return std::make_shared<const QuadMeanValueCoordinates>(std::move(cage), options);
}

}  // namespace spacewarp
