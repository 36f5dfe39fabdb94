#include <spacewarp/coords/quad_green.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numbers>
#include <string>
#include <utility>
#include <vector>

#include <spacewarp/coords/detail/green_triangles.h>
#include <spacewarp/coords/green.h>
#include <spacewarp/core/archive.h>
#include <spacewarp/core/detail/simd.h>
#include <spacewarp/core/errors.h>

namespace spacewarp {

// The coordinates. A quad q_0 q_1 q_2 q_3 (outward) is the bilinear patch
//
//     ξ(u, v) = Σ_k B_k(u, v) q_k,  B = ((1−u)(1−v), u(1−v), uv, (1−u)v),  (u, v) ∈ [0, 1]²,
//
// whose area-weighted normal N(u, v) = ξ_u × ξ_v is itself bilinear: N = Σ_k B_k N_k with the
// corner normals N_k = (q_{k+1} − q_k) × (q_{k−1} − q_k). Green's third identity for f(ξ) = ξ
// (boundary values Σ B_k q_k on the patch, exactly the patch itself) then writes a point inside
// the cage as x = Σ_i φ_i v_i + Σ_faces (normal terms), a quad adding
//
//     φ_{q_k} += 1/4π ∫∫ B_k (ξ − x)·N / |ξ − x|³ du dv       (the double layer)
//     ψ_{q,k}  = 1/4π ∫∫ B_k / |ξ − x| du dv                  (the single layer, control N_k)
//
// which is the paper's Neumann condition: the normal derivative of the identity, n dσ = N du dv,
// split over the four corner normals. Triangles are coords/green.h's, computed by its kernels
// (detail::GreenTriangleTerms); an all-triangle cage is handed to a GreenCoordinates whole.
//
// The quad integrals are computed by adaptive Gauss-Legendre quadrature in (u, v): a square of
// the parameter domain is integrated by a tensor rule when x is at least kAdmissible times the
// radius ρ of the square's patch piece from its centre (the piece lies in the convex hull of its
// corners, hence in that ball), with the order chosen from t = ρ / D (kOrderLimit: measured on
// 4000 random planar and warped quads against a 60-point rule in long double, the rule's error is
// below 1e-15 of the piece's contribution); otherwise it is cut in four. A square whose radius
// falls to the surface tolerance (or to 1e-16 of the cage diagonal) while x is still that close
// to it is a surface contact (below). Accuracy measured (tests): at rest x is reproduced to
// ~5e-15 of the diagonal and Σ φ = 1 to ~1e-15, inside and outside, on planar, concave and warped
// quad cages; on parallelograms A Σ_k ψ_k equals triangle Green's closed-form single layer to
// 3e-15 relative, down to 1e-9 of the diagonal from the face. Near a quad the node vectors
// r = ξ − x are measured from x's foot on it, and that offset from the nearest point of the quad's
// boundary (the same bits for every face at that edge or vertex, see footOf()): r then has
// round-off relative to |r| and the faces around an edge see x at the same place. Measured: x is
// reproduced to ~1e-15 of the diagonal and Σ φ = 1 to ~1e-15 at 1e-12 of the diagonal from a
// face or an edge (planar or warped quads) and from a vertex of planar quads. Near a vertex
// where warped quads meet, on a line towards the cage centre, the error still grows as
// ~1e-18 diag / δ (4e-12 at δ = 1e-6 of the diagonal, 3e-6 at 1e-12) whatever the orders and
// admissibility (checked): a geometric round-off, not the quadrature; probably x there is far
// closer to one face (h) than to the vertex and that face's offset, written from the vertex,
// carries round-off ~1e-16 δ, i.e. 1e-16 δ / h relative. Not resolved.
// A typical point inside a 216-quad box needs ~90 nodes per quad (orders 7 to 14).
//
// Inside: the integrals. Σ φ = 1 there (the solid angle of the closed surface).
// Surface (x within the tolerance of a triangle, or of a quad as above): the limit from inside,
// φ = φ_pv + (1 − σ) Γ(x0) as in green.h: the pieces touching x contribute no double layer,
// σ = Σ φ_pv, Γ(x0) the hat values where x touches (B_k(u, v) on a quad).
// Outside: the raw integrals reproduce 0; the coordinates are continued through the nearest face.
// For a triangle as in green.h. For a quad, x is written in the frame of the patch at a point
// (u, v): x = ξ(u, v) + a ξ_u + b ξ_v + t N (a 3 × 3 solve), and B_k + a ∂_u B_k + b ∂_v B_k
// (at (u, v)) is added to φ_{q_k}, t B_k(u, v) to ψ_{q,k}. This reproduces x exactly (Σ_k ∂B_k
// q_k = ξ_u, ..., N = Σ B_k N_k) and keeps Σ φ = 1 (Σ_k ∂B_k = 0). (u, v) is the foot of x on
// the extended patch, x = ξ(u, v) + t N(u, v) (then a = b = 0), by damped Newton from the nearest
// point of the quad's four triangles (both diagonals); where that has no solution (far from a
// warped quad) the nearest point itself. On the quad (t = 0) this equals the surface limit, so
// the coordinates are continuous across quads. It is not the analytic continuation of the
// interior coordinates (a curved patch has none in closed form; for a planar quad the continuation
// of the bilinear hats is not bilinear either): the derivatives jump across a quad. The nearest
// face is found by distances to the triangles (a quad by the four triangles of its two diagonals,
// which do not depend on its first vertex); distances equal to 1e-12 relative are ties, going to
// the face x is farthest in front of, then to the lowest index. As for triangles, the outside
// coordinates are discontinuous across the exterior's medial surface.
//
// Posed controls (columnControls): the posed vertices; for a triangle, GreenCoordinates' stretched
// unit normal; for quad corner k, σ_k N'_k with N'_k the posed corner normal and
//     σ_k = ∫∫ B_k σ_L / |N| du dv  /  ∫∫ B_k σ_a / |N| du dv,
// σ_a = |N'| / |N| the area stretch and σ_L = sqrt((|ξ'_u|²|ξ_v|² + |ξ_u|²|ξ'_v|² −
// 2 (ξ'_u·ξ'_v)(ξ_u·ξ_v)) / (2 |N|²)) the length stretch of the bilinear map at (u, v), as the
// authors' code (integrated here by an 8 × 8 Gauss rule). A similarity of scale s gives σ_k = 1/s
// at every node, so σ_k N'_k = s R N_k: similarities are reproduced.

namespace {

constexpr double kInv4Pi = 0.25 * std::numbers::inv_pi;
constexpr int kMaxOrder = 14;
// x is at least kAdmissible ρ from a square's centre before the square is integrated.
constexpr double kAdmissible = 2.0;
// Gauss order n is used for ρ / D ≤ kOrderLimit[n] (n = 1 unused).
constexpr std::array<double, kMaxOrder + 1> kOrderLimit = {
    0.0, 0.0, 0.0, 0.0, 0.008, 0.02, 0.06, 0.1, 0.18, 0.25, 0.3, 0.36, 0.42, 0.47, 0.5};
constexpr int kStretchOrder = 8;
constexpr double kInf = std::numeric_limits<double>::infinity();
// Relative difference below which two faces are equally near (see evaluateMixed()).
constexpr double kTie = 1e-12;

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
const std::array<GaussRule, kMaxOrder + 1>& gaussRules() {
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

std::array<double, 4> bilinear(double u, double v) {
  return {(1.0 - u) * (1.0 - v), u * (1.0 - v), u * v, (1.0 - u) * v};
}

// A quad face: corners, the patch ξ = q_0 + u e_u + v e_v + uv e_uv and its corner normals.
struct Quad {
  std::uint32_t vertex[4] = {0, 0, 0, 0};
  Vec3 corner[4];
  Vec3 eu{0.0}, ev{0.0}, euv{0.0};
  Vec3 cornerNormal[4];
  std::size_t face = 0, column = 0;  // face index, first of its four ψ columns

  Vec3 at(double u, double v) const { return corner[0] + u * eu + v * ev + (u * v) * euv; }
  Vec3 tangentU(double v) const { return eu + v * euv; }
  Vec3 tangentV(double u) const { return ev + u * euv; }
};

Quad makeQuad(std::span<const Vec3> vertices, std::span<const std::uint32_t> face) {
  Quad q;
  for (int k = 0; k < 4; ++k) {
    q.vertex[k] = face[k];
    q.corner[k] = vertices[face[k]];
  }
  q.eu = q.corner[1] - q.corner[0];
  q.ev = q.corner[3] - q.corner[0];
  q.euv = q.corner[0] - q.corner[1] + q.corner[2] - q.corner[3];
  for (int k = 0; k < 4; ++k) {
    q.cornerNormal[k] =
        glm::cross(q.corner[(k + 1) % 4] - q.corner[k], q.corner[(k + 3) % 4] - q.corner[k]);
  }
  return q;
}

// The integrals of one quad at one point (φ: 4 corners, ψ: 4 corners) and whether x touches it.
struct QuadSums {
  double phi[4] = {0.0, 0.0, 0.0, 0.0};
  double psi[4] = {0.0, 0.0, 0.0, 0.0};
  bool touched = false;
  double u = 0.0, v = 0.0;  // where (first contact found)
};

// The squared distance from x to triangle abc and the barycentric coordinates of the nearest
// point (Ericson, Real-Time Collision Detection, 5.1.5).
double triangleDistance2(const Vec3& x, const Vec3& a, const Vec3& b, const Vec3& c,
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
double quadDistance2(const Quad& q, const Vec3& x, double& u, double& v) {
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

Vec3 fromOrigin(const Quad& q, const Origin& o, double u, double v) {
  const double du = u - o.u, dv = v - o.v;
  return o.offset + du * q.eu + dv * q.ev + (du * v + o.u * dv) * q.euv;
}

// The point of the patch nearest to x, near enough: Gauss-Newton on |ξ(u, v) − x|² in the unit
// square from the nearest point of the quad's triangles.
Origin footOf(const Quad& q, const Vec3& x) {
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
  double best = kInf, au = 0.0, av = 0.0;
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

// Tensor Gauss rule of order n over the square [u0, u0 + s] × [v0, v0 + s]: every node
// directly (r·N = det(r, ξ_u, ξ_v)), kBlock nodes at a time into kBlock interleaved partial sums,
// which the compiler vectorises without reordering any sum: the same bits on every simd::Path.
[[gnu::always_inline]] inline void gaussSquare(const Quad& q, const Origin& o, double u0, double v0,
                                               double s, int n, QuadSums& out) {
  const GaussRule& rule = gaussRules()[n];
  const double bx = o.offset.x, by = o.offset.y, bz = o.offset.z;
  const double ux = q.eu.x, uy = q.eu.y, uz = q.eu.z, vx = q.ev.x, vy = q.ev.y, vz = q.ev.z;
  const double wx = q.euv.x, wy = q.euv.y, wz = q.euv.z;
  const double du0 = u0 - o.u, dv0 = v0 - o.v, uo = o.u;
  alignas(64) double acc[8][kBlock] = {};
  for (int t0 = 0; t0 < rule.tensorCount; t0 += kBlock) {
    for (int l = 0; l < kBlock; ++l) {
      const double su = s * rule.tu[t0 + l], sv = s * rule.tv[t0 + l];
      const double u = u0 + su, v = v0 + sv, du = du0 + su, dv = dv0 + sv;
      const double dw = du * v + uo * dv;
      const double rx = bx + du * ux + dv * vx + dw * wx;
      const double ry = by + du * uy + dv * vy + dw * wy;
      const double rz = bz + du * uz + dv * vz + dw * wz;
      const double uv = u * v;
      const double ax = ux + v * wx, ay = uy + v * wy, az = uz + v * wz;  // ξ_u
      const double cx = vx + u * wx, cy = vy + u * wy, cz = vz + u * wz;  // ξ_v
      const double det =
          rx * (ay * cz - az * cy) + ry * (az * cx - ax * cz) + rz * (ax * cy - ay * cx);
      const double inv = 1.0 / std::sqrt(rx * rx + ry * ry + rz * rz);
      const double single = rule.tw[t0 + l] * inv;
      const double dbl = single * inv * inv * det;
      const double b0 = (1.0 - u) * (1.0 - v), b1 = u * (1.0 - v), b2 = uv, b3 = (1.0 - u) * v;
      acc[0][l] += b0 * dbl;
      acc[1][l] += b1 * dbl;
      acc[2][l] += b2 * dbl;
      acc[3][l] += b3 * dbl;
      acc[4][l] += b0 * single;
      acc[5][l] += b1 * single;
      acc[6][l] += b2 * single;
      acc[7][l] += b3 * single;
    }
  }
  const double area = s * s;
  for (int k = 0; k < 8; ++k) {
    double sum = 0.0;
    for (int l = 0; l < kBlock; ++l) sum += acc[k][l];
    (k < 4 ? out.phi[k] : out.psi[k - 4]) += area * sum;
  }
}

// The integrals of quad q at x (see the file comment); touchRadius: squares this small that x is
// still close to (within (kAdmissible + 1) ρ) are contacts.
[[gnu::always_inline]] inline void integrateQuad(const Quad& q, const Vec3& x, double touchRadius,
                                                 QuadSums& out) {
  struct Square {
    double u0, v0, s;
  };
  Square stack[4 * 80];
  int top = 0;
  stack[top++] = {0.0, 0.0, 1.0};
  Origin origin{0.0, 0.0, q.corner[0] - x};
  bool near = false;
  while (top > 0) {
    const Square sq = stack[--top];
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
      gaussSquare(q, origin, sq.u0, sq.v0, sq.s, n, out);
      continue;
    }
    if (!near) {
      // x is near the quad: measure from its foot from now on.
      near = true;
      origin = footOf(q, x);
    }
    const double rho = std::sqrt(rho2);
    if (rho <= touchRadius || sq.s < 0x1p-60) {
      // x is within (kAdmissible + 1) ρ of this tiny piece: a contact. Its double layer is the
      // jump the surface limit accounts for; its single layer is O(ρ) and dropped.
      if (!out.touched) {
        out.touched = true;
        out.u = sq.u0 + h;
        out.v = sq.v0 + h;
      }
      continue;
    }
    stack[top++] = {sq.u0, sq.v0, h};
    stack[top++] = {sq.u0 + h, sq.v0, h};
    stack[top++] = {sq.u0, sq.v0 + h, h};
    stack[top++] = {sq.u0 + h, sq.v0 + h, h};
  }
  for (int k = 0; k < 4; ++k) {
    out.phi[k] *= kInv4Pi;
    out.psi[k] *= kInv4Pi;
  }
}

// integrateQuad compiled for each simd::Path (core/detail/simd.h): the node loop vectorises to
// the path's width, with the same bits on every path (IEEE square roots and divisions, no FMA
// contraction, sums in node order).
void integrateBaseline(const Quad& q, const Vec3& x, double touchRadius, QuadSums& out) {
  integrateQuad(q, x, touchRadius, out);
}
SPACEWARP_SIMD_TARGET_V3 void integrateV3(const Quad& q, const Vec3& x, double touchRadius,
                                          QuadSums& out) {
  integrateQuad(q, x, touchRadius, out);
}
SPACEWARP_SIMD_TARGET_V4 void integrateV4(const Quad& q, const Vec3& x, double touchRadius,
                                          QuadSums& out) {
  integrateQuad(q, x, touchRadius, out);
}
using IntegrateFn = void (*)(const Quad&, const Vec3&, double, QuadSums&);
constexpr IntegrateFn kIntegrate[detail::simd::kPathCount] = {integrateBaseline, integrateV3,
                                                              integrateV4};

// Solves x = ξ(u, v) + t N(u, v) by Newton's method from (u, v, 0), halving steps that do not
// reduce the residual; returns whether it converged (to `tolerance`, world units).
bool quadFoot(const Quad& q, const Vec3& x, double tolerance, double& u, double& v, double& t) {
  auto residual = [&](double uu, double vv, double tt) {
    return q.at(uu, vv) + tt * glm::cross(q.tangentU(vv), q.tangentV(uu)) - x;
  };
  t = 0.0;
  Vec3 f = residual(u, v, t);
  double err = glm::length(f);
  for (int it = 0; it < 100 && err > tolerance; ++it) {
    const Vec3 pu = q.tangentU(v), pv = q.tangentV(u);
    const Vec3 nu = glm::cross(pu, q.euv), nv = glm::cross(q.euv, pv);
    const Mat3 jac(pu + t * nu, pv + t * nv, glm::cross(pu, pv));
    if (!(std::fabs(glm::determinant(jac)) > 0.0)) break;
    const Vec3 step = glm::inverse(jac) * f;
    double scale = 1.0;
    bool reduced = false;
    for (int h = 0; h < 40 && !reduced; ++h, scale *= 0.5) {
      const Vec3 g = residual(u - scale * step.x, v - scale * step.y, t - scale * step.z);
      const double e = glm::length(g);
      if (e < err) {
        u -= scale * step.x;
        v -= scale * step.y;
        t -= scale * step.z;
        f = g;
        err = e;
        reduced = true;
      }
    }
    if (!reduced) break;
  }
  return err <= tolerance;
}

}  // namespace

namespace detail {

// The rest data of the coordinates.
struct QuadGreenData {
  std::shared_ptr<const Cage> cage;
  QuadGreenOptions options;
  // Over the cage's triangulation: the whole evaluation of an all-triangle cage, and the
  // triangles' stretched normals of any cage.
  std::unique_ptr<GreenCoordinates> green;
  bool allTriangles = true;
  // Mixed cages: the triangle faces' terms, their faces and columns; the quads.
  std::unique_ptr<detail::GreenTriangleTerms> triangles;
  std::vector<Triangle> triangleVertices;  // the triangle faces, as their faces list them
  std::vector<std::size_t> triangleFace, triangleColumn, greenTriangle;
  std::vector<Quad> quads;
  std::vector<std::size_t> faceColumn;  // the first column of each face
  std::size_t columns = 0;
  double tolerance = 0.0;    // world units
  double touchRadius = 0.0;  // world units
  double footTolerance = 0.0;
};

}  // namespace detail

struct QuadGreenCoordinates::Impl : detail::QuadGreenData {};

namespace {

// The rows of `count` points of a mixed cage (see the file comment), row i at rows + i · stride.
void evaluateMixed(const detail::QuadGreenData& m, const Vec3* points, std::size_t count,
                   double* rows, std::size_t stride) {
  const std::size_t nv = m.cage->vertexCount(), nt = m.triangleFace.size();
  const std::size_t lanes = m.triangles->lanes();
  thread_local std::vector<double> triRows;
  thread_local std::vector<detail::GreenTriangleTerms::Point> info;
  triRows.assign(lanes * (nv + nt), 0.0);
  info.resize(lanes);
  for (std::size_t start = 0; start < count; start += lanes) {
    const std::size_t n = std::min(lanes, count - start);
    if (nt > 0) {
      m.triangles->evaluate(points + start, n, triRows.data(), nv + nt, info.data());
    } else {
      std::fill(info.begin(), info.end(), detail::GreenTriangleTerms::Point{});
    }
    for (std::size_t l = 0; l < n; ++l) {
      const Vec3& x = points[start + l];
      double* row = rows + (start + l) * stride;
      const double* tri = triRows.data() + l * (nv + nt);
      std::fill(row, row + stride, 0.0);
      std::copy(tri, tri + nv, row);
      for (std::size_t t = 0; t < nt; ++t) row[m.triangleColumn[t]] = tri[nv + t];
      double solidAngle = info[l].solidAngle;
      bool touchedQuad = false;
      std::size_t touchQuad = 0;
      double tu = 0.0, tv = 0.0;
      const IntegrateFn integrate = kIntegrate[static_cast<int>(detail::simd::activePath())];
      for (std::size_t j = 0; j < m.quads.size(); ++j) {
        const Quad& q = m.quads[j];
        QuadSums sums;
        integrate(q, x, m.touchRadius, sums);
        for (int k = 0; k < 4; ++k) {
          row[q.vertex[k]] += sums.phi[k];
          row[q.column + k] = sums.psi[k];
          solidAngle += 4.0 * std::numbers::pi * sums.phi[k];
        }
        if (sums.touched && !touchedQuad) {
          touchedQuad = true;
          touchQuad = j;
          tu = sums.u;
          tv = sums.v;
        }
      }
      if (touchedQuad || info[l].surface) {
        // Surface: principal value plus (1 − σ) times the hat values where x touches.
        double sigma = 0.0;
        for (std::size_t i = 0; i < nv; ++i) sigma += row[i];
        if (touchedQuad) {
          const Quad& q = m.quads[touchQuad];
          const std::array<double, 4> b = bilinear(tu, tv);
          for (int k = 0; k < 4; ++k) row[q.vertex[k]] += (1.0 - sigma) * b[k];
        } else {
          const Triangle& t = m.triangleVertices[info[l].triangle];
          const std::uint32_t idx[3] = {t.x, t.y, t.z};
          for (int k = 0; k < 3; ++k) row[idx[k]] += (1.0 - sigma) * info[l].bary[k];
        }
        continue;
      }
      if (solidAngle * kInv4Pi > 0.5) continue;  // inside
      // Outside: through the nearest face. Distances within a relative 1e-12 of each other are
      // ties (a nearest point on a shared edge or vertex, where round-off would decide): they go
      // to the face whose plane x is farthest in front of, then to the lowest face index.
      double best = info[l].dist2, bestBeta = info[l].beta, bu = 0.0, bv = 0.0;
      std::size_t bestFace =
          info[l].dist2 < kInf ? m.triangleFace[info[l].triangle] : m.cage->faceCount();
      const Quad* nearest = nullptr;
      for (const Quad& q : m.quads) {
        double u = 0.0, v = 0.0;
        const double d2 = quadDistance2(q, x, u, v);
        if (d2 > best * (1.0 + kTie)) continue;
        const Vec3 normal = glm::normalize(glm::cross(q.tangentU(v), q.tangentV(u)));
        const double beta = glm::dot(x - q.at(u, v), normal);
        const bool tie = d2 >= best * (1.0 - kTie);
        if (tie && (beta < bestBeta || (beta == bestBeta && q.face > bestFace))) continue;
        best = std::min(best, d2);
        bestBeta = beta;
        bestFace = q.face;
        nearest = &q;
        bu = u;
        bv = v;
      }
      if (nearest == nullptr) {
        const Triangle& t = m.triangleVertices[info[l].triangle];
        const std::uint32_t idx[3] = {t.x, t.y, t.z};
        for (int k = 0; k < 3; ++k) row[idx[k]] += info[l].bary[k];
        row[m.triangleColumn[info[l].triangle]] += info[l].beta;
        continue;
      }
      // x = ξ(u, v) + a ξ_u + b ξ_v + t N at the foot (a = b = 0) or, failing that, at the seed.
      double u = bu, v = bv, t = 0.0;
      if (!quadFoot(*nearest, x, m.footTolerance, u, v, t)) u = bu, v = bv;
      const Vec3 pu = nearest->tangentU(v), pv = nearest->tangentV(u);
      const Vec3 abt = glm::inverse(Mat3(pu, pv, glm::cross(pu, pv))) * (x - nearest->at(u, v));
      const std::array<double, 4> b = bilinear(u, v);
      const double du[4] = {-(1.0 - v), 1.0 - v, v, -v}, dv[4] = {-(1.0 - u), -u, u, 1.0 - u};
      for (int k = 0; k < 4; ++k) {
        row[nearest->vertex[k]] += b[k] + abt.x * du[k] + abt.y * dv[k];
        row[nearest->column + k] += abt.z * b[k];
      }
    }
  }
}

}  // namespace

QuadGreenCoordinates::QuadGreenCoordinates(std::shared_ptr<const Cage> cage,
                                           const QuadGreenOptions& options) {
  if (!cage) throw InvalidInput("QuadGreenCoordinates: the cage is null");
  if (!(options.surfaceTolerance >= 0.0 && options.surfaceTolerance <= 1e-3)) {
    throw InvalidInput("QuadGreenCoordinates: surfaceTolerance must be in [0, 1e-3], not " +
                       std::to_string(options.surfaceTolerance));
  }
  auto m = std::make_unique<Impl>();
  m->cage = cage;
  m->options = options;
  const std::size_t nv = cage->vertexCount();
  std::size_t column = nv;
  m->faceColumn.resize(cage->faceCount());
  for (std::size_t f = 0; f < cage->faceCount(); ++f) {
    const std::span<const std::uint32_t> face = cage->face(f);
    m->faceColumn[f] = column;
    if (face.size() == 3) {
      m->triangleVertices.push_back({face[0], face[1], face[2]});
      m->triangleFace.push_back(f);
      m->triangleColumn.push_back(column);
      column += 1;
    } else if (face.size() == 4) {
      Quad q = makeQuad(cage->vertices(), face);
      q.face = f;
      q.column = column;
      m->quads.push_back(q);
      column += 4;
    } else {
      throw InvalidInput(cage->name() + ": QuadGreenCoordinates: face " + std::to_string(f) +
                         " has " + std::to_string(face.size()) +
                         " vertices; only triangles and quads are supported");
    }
  }
  m->columns = column;
  m->allTriangles = m->quads.empty();
  GreenOptions greenOptions;
  greenOptions.surfaceTolerance = options.surfaceTolerance;
  m->green = std::make_unique<GreenCoordinates>(cage, greenOptions);
  if (!m->allTriangles) {
    // The triangulation keeps a triangle face as one triangle: find it for the stretched normals
    // of the triangle faces (GreenCoordinates' columns follow the triangulation).
    std::vector<std::size_t> triangleOfFace(cage->faceCount(), 0);
    const std::span<const std::uint32_t> source = cage->triangleSource();
    for (std::size_t t = 0; t < source.size(); ++t) triangleOfFace[source[t]] = t;
    for (std::size_t f : m->triangleFace) m->greenTriangle.push_back(triangleOfFace[f]);
    const double diagonal = cage->diagonal();
    m->tolerance = options.surfaceTolerance * diagonal;
    m->touchRadius = std::max(m->tolerance, 1e-16 * diagonal) / kAdmissible;
    m->footTolerance = 1e-14 * diagonal;
    m->triangles = std::make_unique<detail::GreenTriangleTerms>(cage->vertices(),
                                                                m->triangleVertices, m->tolerance);
  }
  impl_ = std::move(m);
}

QuadGreenCoordinates::~QuadGreenCoordinates() = default;

std::size_t QuadGreenCoordinates::controlPointCount() const { return impl_->cage->vertexCount(); }

std::span<const Vec3> QuadGreenCoordinates::restControlPoints() const {
  return impl_->cage->vertices();
}

std::size_t QuadGreenCoordinates::columnCount() const { return impl_->columns; }

std::string QuadGreenCoordinates::columnName(std::size_t c) const {
  const std::size_t nv = impl_->cage->vertexCount();
  if (c < nv || c >= impl_->columns) return Coordinates::columnName(c);
  const auto& offsets = impl_->faceColumn;
  const std::size_t f = static_cast<std::size_t>(
                            std::upper_bound(offsets.begin(), offsets.end(), c) - offsets.begin()) -
                        1;
  // Built by append: GCC 12 warns (-Wrestrict, falsely) on "literal" + std::string.
  std::string name(1, 'f');
  name += std::to_string(f);
  if (impl_->cage->face(f).size() == 3) return name;
  name += '.';
  name += std::to_string(c - offsets[f]);
  return name;
}

void QuadGreenCoordinates::weights(const Vec3& x, std::span<double> row) const {
  checkWeightsArguments(x, row.size());
  if (impl_->allTriangles) return impl_->green->weights(x, row);
  evaluateMixed(*impl_, &x, 1, row.data(), row.size());
}

UnmappedPoints QuadGreenCoordinates::weightsRange(std::span<const Vec3> points,
                                                  std::span<double> rows, std::size_t begin,
                                                  std::size_t end) const {
  const std::size_t m = columnCount();
  if (impl_->allTriangles) {
    // Through the public batch call on the sub-range: the same kernel as GreenCoordinates'.
    impl_->green->weightsBatch(points.subspan(begin, end - begin),
                               rows.subspan(begin * m, (end - begin) * m));
    return {};
  }
  evaluateMixed(*impl_, points.data() + begin, end - begin, rows.data() + begin * m, m);
  return {};
}

void QuadGreenCoordinates::columnControls(std::span<const Vec3> posed, std::span<Vec3> out) const {
  const Impl& m = *impl_;
  if (m.allTriangles) return m.green->columnControls(posed, out);
  Coordinates::columnControls(posed, out);  // checks sizes and finiteness, copies the vertices
  const std::size_t nv = m.cage->vertexCount();
  thread_local std::vector<Vec3> greenControls;
  greenControls.resize(m.green->columnCount());
  m.green->columnControls(posed, greenControls);
  for (std::size_t t = 0; t < m.triangleFace.size(); ++t)
    out[m.triangleColumn[t]] = greenControls[nv + m.greenTriangle[t]];
  const GaussRule& rule = gaussRules()[kStretchOrder];
  for (const Quad& q : m.quads) {
    Vec3 c[4];
    for (int k = 0; k < 4; ++k) c[k] = posed[q.vertex[k]];
    const Vec3 eu = c[1] - c[0], ev = c[3] - c[0], euv = c[0] - c[1] + c[2] - c[3];
    double lengthSum[4] = {0, 0, 0, 0}, areaSum[4] = {0, 0, 0, 0};
    for (int i = 0; i < kStretchOrder; ++i) {
      for (int j = 0; j < kStretchOrder; ++j) {
        const double u = rule.node[i], v = rule.node[j];
        const Vec3 a = q.tangentU(v), b = q.tangentV(u);
        const Vec3 pa = eu + v * euv, pb = ev + u * euv;
        const double rest2 = glm::dot(glm::cross(a, b), glm::cross(a, b));
        const double restArea = std::sqrt(rest2);
        if (!(restArea > 0.0)) continue;  // a node where a folded quad has no normal
        const double lengthStretch = std::sqrt(
            std::max(0.0, (glm::dot(pa, pa) * glm::dot(b, b) + glm::dot(a, a) * glm::dot(pb, pb) -
                           2.0 * glm::dot(pa, pb) * glm::dot(a, b)) /
                              (2.0 * rest2)));
        const double areaStretch = glm::length(glm::cross(pa, pb)) / restArea;
        const std::array<double, 4> bk = bilinear(u, v);
        const double w = rule.weight[i] * rule.weight[j] / restArea;
        for (int k = 0; k < 4; ++k) {
          lengthSum[k] += w * bk[k] * lengthStretch;
          areaSum[k] += w * bk[k] * areaStretch;
        }
      }
    }
    for (int k = 0; k < 4; ++k) {
      const Vec3 normal = glm::cross(c[(k + 1) % 4] - c[k], c[(k + 3) % 4] - c[k]);
      out[q.column + k] = areaSum[k] > 0.0 ? normal * (lengthSum[k] / areaSum[k]) : Vec3(0.0);
    }
  }
}

const Cage& QuadGreenCoordinates::cage() const { return *impl_->cage; }

const QuadGreenOptions& QuadGreenCoordinates::options() const { return impl_->options; }

void QuadGreenCoordinates::save(ArchiveWriter& out) const {
  out.tag("quad-green");
  impl_->cage->save(out);
  out.f64(impl_->options.surfaceTolerance);
}

std::shared_ptr<const QuadGreenCoordinates> QuadGreenCoordinates::load(ArchiveReader& in) {
  auto cage = std::make_shared<const Cage>(Cage::load(in));
  QuadGreenOptions options;
  options.surfaceTolerance = in.f64();
  return std::make_shared<const QuadGreenCoordinates>(std::move(cage), options);
}

}  // namespace spacewarp
