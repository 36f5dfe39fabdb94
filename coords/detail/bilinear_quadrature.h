#pragma once
// Adaptive Gauss-Legendre quadrature over a bilinear patch in its parameters (u, v), shared by
// QuadGreenCoordinates (coords/quad_green.cpp) and QuadMeanValueCoordinates
// (coords/quad_mean_value.cpp): the patch, the rules, x's foot on the patch and the subdivision.
// The integrands (the tensor-rule loops) stay with each method, which compiles them once per
// simd::Path; everything here is inlined into them. Both files are compiled with
// -fno-math-errno -ffp-contract=off, so these inline functions have the same bits in both.
//
// A square of the parameter domain is integrated by a tensor rule when x is at least
// kAdmissible times the radius ρ of the square's patch piece from its centre (the piece lies in
// the convex hull of its corners, hence in that ball), with the order chosen from t = ρ / D
// (kOrderLimit: measured on 4000 random planar and warped quads against a 60-point rule in long
// double, for the kernels 1/r and r·N/r³ the rule's error is below 1e-15 of the piece's
// contribution; QMVC's r·N/r⁴ matches a stricter long-double reference to 3e-16, see
// quad_mean_value.cpp); otherwise it is cut in four. A
// square whose radius falls to `touchRadius` (or whose side to 2⁻⁶⁰) while x is still that close
// to it is a contact, reported to the caller.

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numbers>
#include <span>

#include <spacewarp/core/math.h>

namespace spacewarp::detail::patch {

constexpr int kMaxOrder = 14;
// x is at least kAdmissible ρ from a square's centre before the square is integrated.
constexpr double kAdmissible = 2.0;
// Gauss order n is used for ρ / D ≤ kOrderLimit[n] (n = 1 unused).
constexpr std::array<double, kMaxOrder + 1> kOrderLimit = {
    0.0, 0.0, 0.0, 0.0, 0.008, 0.02, 0.06, 0.1, 0.18, 0.25, 0.3, 0.36, 0.42, 0.47, 0.5};
constexpr int kBlock = 8;  // tensor nodes are summed in 8 interleaved partial sums
constexpr int kMaxTensor = (kMaxOrder * kMaxOrder + kBlock - 1) / kBlock * kBlock;

struct GaussRule {
  std::array<double, kMaxOrder> node{}, weight{};  // on [0, 1]
  // The n² tensor nodes (u, v) and weights, padded with weight-0 nodes to a multiple of kBlock.
  int tensorCount = 0;
  alignas(64) std::array<double, kMaxTensor> tu{}, tv{}, tw{};
};

// Gauss-Legendre rules of every order up to kMaxOrder on [0, 1]: Newton on the Legendre
// polynomial from the Chebyshev guess.
inline const std::array<GaussRule, kMaxOrder + 1>& gaussRules() {
  static const std::array<GaussRule, kMaxOrder + 1> rules = [] {
    std::array<GaussRule, kMaxOrder + 1> r{};
    for (int n = 1; n <= kMaxOrder; ++n) {
      for (int i = 0; i < n; ++i) {
        double z = std::cos(std::numbers::pi * (i + 0.75) / (n + 0.5)), dp = 0.0;
        for (int it = 0; it < 100; ++it) {
          double p0 = 1.0, p1 = z;
          for (int k = 2; k <= n; ++k) {
            const double p2 = ((2.0 * k - 1.0) * z * p1 - (k - 1.0) * p0) / k;
            p0 = p1;
            p1 = p2;
          }
          dp = n * (z * p1 - p0) / (z * z - 1.0);
          const double step = p1 / dp;
          z -= step;
          if (std::fabs(step) < 1e-17) break;
        }
        r[n].node[i] = 0.5 * (1.0 - z);
        r[n].weight[i] = 1.0 / ((1.0 - z * z) * dp * dp);  // 2 / ((1 − z²) P'²) halved
      }
      GaussRule& g = r[n];
      g.tensorCount = (n * n + kBlock - 1) / kBlock * kBlock;
      for (int t = 0; t < g.tensorCount; ++t) {
        const bool pad = t >= n * n;
        g.tu[t] = pad ? 0.5 : g.node[t / n];
        g.tv[t] = pad ? 0.5 : g.node[t % n];
        g.tw[t] = pad ? 0.0 : g.weight[t / n] * g.weight[t % n];
      }
    }
    return r;
  }();
  return rules;
}

// The bilinear basis at (u, v) for corners 0, 1, 2, 3 (ξ(0,0) = q_0, ξ(1,0) = q_1, ξ(1,1) = q_2).
inline std::array<double, 4> bilinear(double u, double v) {
  return {(1.0 - u) * (1.0 - v), u * (1.0 - v), u * v, (1.0 - u) * v};
}

// A quad face as the patch ξ = q_0 + u e_u + v e_v + uv e_uv (world units).
struct Patch {
  std::uint32_t vertex[4] = {0, 0, 0, 0};
  Vec3 corner[4];
  Vec3 eu{0.0}, ev{0.0}, euv{0.0};

  Vec3 at(double u, double v) const { return corner[0] + u * eu + v * ev + (u * v) * euv; }
  Vec3 tangentU(double v) const { return eu + v * euv; }
  Vec3 tangentV(double u) const { return ev + u * euv; }
};

inline void setPatch(Patch& q, std::span<const Vec3> vertices,
                     std::span<const std::uint32_t> face) {
  for (int k = 0; k < 4; ++k) {
    q.vertex[k] = face[k];
    q.corner[k] = vertices[face[k]];
  }
  q.eu = q.corner[1] - q.corner[0];
  q.ev = q.corner[3] - q.corner[0];
  q.euv = q.corner[0] - q.corner[1] + q.corner[2] - q.corner[3];
}

// The squared distance from x to triangle abc and the barycentric coordinates of the nearest
// point (Ericson, Real-Time Collision Detection, 5.1.5).
inline double triangleDistance2(const Vec3& x, const Vec3& a, const Vec3& b, const Vec3& c,
                                double (&bary)[3]) {
  const Vec3 ab = b - a, ac = c - a, ap = x - a;
  const double d1 = glm::dot(ab, ap), d2 = glm::dot(ac, ap);
  auto result = [&](double wa, double wb, double wc) {
    bary[0] = wa;
    bary[1] = wb;
    bary[2] = wc;
    const Vec3 d = x - (wa * a + wb * b + wc * c);
    return glm::dot(d, d);
  };
  if (d1 <= 0.0 && d2 <= 0.0) return result(1, 0, 0);
  const Vec3 bp = x - b;
  const double d3 = glm::dot(ab, bp), d4 = glm::dot(ac, bp);
  if (d3 >= 0.0 && d4 <= d3) return result(0, 1, 0);
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0) {
    const double w = d1 / (d1 - d3);
    return result(1 - w, w, 0);
  }
  const Vec3 cp = x - c;
  const double d5 = glm::dot(ab, cp), d6 = glm::dot(ac, cp);
  if (d6 >= 0.0 && d5 <= d6) return result(0, 0, 1);
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0) {
    const double w = d2 / (d2 - d6);
    return result(1 - w, 0, w);
  }
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0) {
    const double w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
    return result(0, 1 - w, w);
  }
  const double denom = 1.0 / (va + vb + vc);
  const double v = vb * denom, w = vc * denom;
  return result(1 - v - w, v, w);
}

// The squared distance from x to the four triangles of a quad's two triangulations (so that it
// does not depend on the quad's first vertex) and the (u, v) of the nearest point.
inline double quadDistance2(const Patch& q, const Vec3& x, double& u, double& v) {
  static constexpr int kTriangles[4][3] = {{0, 1, 2}, {0, 2, 3}, {0, 1, 3}, {1, 2, 3}};
  static constexpr double kU[4] = {0, 1, 1, 0}, kV[4] = {0, 0, 1, 1};
  double best = std::numeric_limits<double>::infinity();
  for (const auto& t : kTriangles) {
    double b[3];
    const double d2 = triangleDistance2(x, q.corner[t[0]], q.corner[t[1]], q.corner[t[2]], b);
    if (d2 < best) {
      best = d2;
      u = b[0] * kU[t[0]] + b[1] * kU[t[1]] + b[2] * kU[t[2]];
      v = b[0] * kV[t[0]] + b[1] * kV[t[1]] + b[2] * kV[t[2]];
    }
  }
  return best;
}

// Where the node vectors r = ξ(u, v) − x are measured from: a point (u_o, v_o) of the patch and
// ξ(u_o, v_o) − x, computed once. r = offset + Δ with Δ = ξ(u, v) − ξ(u_o, v_o) in differences of
// the parameters, so that near x (origin at its foot) r has round-off relative to |r|, not to
// the coordinates' size.
struct Origin {
  double u = 0.0, v = 0.0;
  Vec3 offset{0.0};
};

inline Vec3 fromOrigin(const Patch& q, const Origin& o, double u, double v) {
  const double du = u - o.u, dv = v - o.v;
  return o.offset + du * q.eu + dv * q.ev + (du * v + o.u * dv) * q.euv;
}

// The point of the patch nearest to x, near enough: Gauss-Newton on |ξ(u, v) − x|² in the unit
// square from the nearest point of the quad's triangles.
inline Origin footOf(const Patch& q, const Vec3& x) {
  double u = 0.0, v = 0.0;
  quadDistance2(q, x, u, v);
  for (int it = 0; it < 8; ++it) {
    const Vec3 r = q.at(u, v) - x, a = q.tangentU(v), b = q.tangentV(u);
    const double aa = glm::dot(a, a), ab = glm::dot(a, b), bb = glm::dot(b, b);
    const double ga = glm::dot(r, a), gb = glm::dot(r, b);
    const double det = aa * bb - ab * ab;
    if (!(det > 0.0)) break;
    u = std::clamp(u - (bb * ga - ab * gb) / det, 0.0, 1.0);
    v = std::clamp(v - (aa * gb - ab * ga) / det, 0.0, 1.0);
  }
  // The offset ξ(u, v) − x is measured from the nearest point of the quad's boundary, written
  // from the nearer end vertex of its edge (v_k − x + μ (v_other − v_k), end points in
  // vertex-index order): the same bits, up to round-off relative to |μ (v_other − v_k)|, for
  // every face at that vertex or edge. So all the faces near x see it at the same rounded place;
  // with ξ(u, v) − x from each face's own parametrisation, their round-off (~1e-16 of the
  // coordinates) would move x differently for each face, which at distance δ from an edge
  // changes their solid angles inconsistently by ~1e-16 / δ.
  // Edges: v = 0 from q0 to q1 along u, u = 1 from q1 to q2 along v, v = 1 from q3 to q2
  // along u, u = 0 from q0 to q3 along v.
  static constexpr int kStart[4] = {0, 1, 3, 0}, kEnd[4] = {1, 2, 2, 3};
  static constexpr double kCornerU[4] = {0, 1, 1, 0}, kCornerV[4] = {0, 0, 1, 1};
  double best = std::numeric_limits<double>::infinity(), au = 0.0, av = 0.0;
  Vec3 anchor(0.0);
  for (int e = 0; e < 4; ++e) {
    const bool swap = q.vertex[kStart[e]] > q.vertex[kEnd[e]];
    const int ia = swap ? kEnd[e] : kStart[e], ib = swap ? kStart[e] : kEnd[e];
    const Vec3 ab = q.corner[ib] - q.corner[ia];
    const double lambda = std::clamp(glm::dot(x - q.corner[ia], ab) / glm::dot(ab, ab), 0.0, 1.0);
    const Vec3 d =
        lambda <= 0.5 ? (q.corner[ia] - x) + lambda * ab : (q.corner[ib] - x) - (1.0 - lambda) * ab;
    if (!(glm::dot(d, d) < best)) continue;
    best = glm::dot(d, d);
    anchor = d;
    au = kCornerU[ia] + lambda * (kCornerU[ib] - kCornerU[ia]);
    av = kCornerV[ia] + lambda * (kCornerV[ib] - kCornerV[ia]);
  }
  const double du = u - au, dv = v - av;
  const Vec3 offset = anchor + du * q.eu + dv * q.ev + (du * v + au * dv) * q.euv;
  // Near the boundary (x not much farther from it than from the patch) the boundary point itself
  // is the origin: no difference from a foot, whose own round-off would differ between faces.
  if (glm::dot(anchor, anchor) <= 4.0 * glm::dot(offset, offset)) return {au, av, anchor};
  return {u, v, offset};
}

// Adaptive quadrature of the patch q at x: `square(origin, u0, v0, s, n)` integrates the square
// [u0, u0 + s] × [v0, v0 + s] with the tensor rule of order n, node vectors measured from
// `origin` (fromOrigin). The origin is q_0 until a square is not admissible, then x's foot
// (footOf), which `near` receives (unchanged if x was admissible from the patch as a whole).
// Returns false, with (u, v) the square's centre, at the first contact (a square of radius at
// most touchRadius that x is within (kAdmissible + 1) ρ of); the caller decides what it means.
template <class Square>
[[gnu::always_inline]] inline bool integrateAdaptive(const Patch& q, const Vec3& x,
                                                     double touchRadius, Square&& square,
                                                     Origin& near, double& u, double& v) {
  struct Piece {
    double u0, v0, s;
  };
  Piece stack[4 * 80];
  int top = 0;
  stack[top++] = {0.0, 0.0, 1.0};
  Origin origin{0.0, 0.0, q.corner[0] - x};
  bool isNear = false, touched = false;
  while (top > 0) {
    const Piece sq = stack[--top];
    const double h = 0.5 * sq.s;
    const Vec3 centre = fromOrigin(q, origin, sq.u0 + h, sq.v0 + h);
    double rho2 = 0.0;
    for (int k = 0; k < 4; ++k) {
      const double cu = sq.u0 + ((k == 1 || k == 2) ? sq.s : 0.0);
      const double cv = sq.v0 + (k >= 2 ? sq.s : 0.0);
      const Vec3 d = fromOrigin(q, origin, cu, cv) - centre;
      rho2 = std::max(rho2, glm::dot(d, d));
    }
    const double d2 = glm::dot(centre, centre);
    if (d2 >= kAdmissible * kAdmissible * rho2) {
      const double t = std::sqrt(rho2 / d2);
      int n = 4;
      while (n < kMaxOrder && t > kOrderLimit[n]) ++n;
      square(origin, sq.u0, sq.v0, sq.s, n);
      continue;
    }
    if (!isNear) {
      // x is near the quad: measure from its foot from now on.
      isNear = true;
      origin = footOf(q, x);
      near = origin;
    }
    if (std::sqrt(rho2) <= touchRadius || sq.s < 0x1p-60) {
      if (!touched) {
        touched = true;
        u = sq.u0 + h;
        v = sq.v0 + h;
      }
      continue;
    }
    stack[top++] = {sq.u0, sq.v0, h};
    stack[top++] = {sq.u0 + h, sq.v0, h};
    stack[top++] = {sq.u0, sq.v0 + h, h};
    stack[top++] = {sq.u0 + h, sq.v0 + h, h};
  }
  return !touched;
}

}  // namespace spacewarp::detail::patch
