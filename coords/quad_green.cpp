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

#include <spacewarp/coords/detail/bilinear_quadrature.h>
#include <spacewarp/coords/detail/green_triangles.h>
#include <spacewarp/coords/detail/quad_fold.h>
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
// round-off relative to |r| and the faces around an edge see x at the same place. Near a vertex
// that is not enough: there the double layers of the faces around it cancel with a round-off
// ~1e-18 diag / δ at δ from the vertex, planar quads or not (|Σ φ − 1| 2e-4 at δ = 1e-14 of the
// diagonal, 9e-7 at 1e-12, in random directions; triangle Green is exact there), whatever the
// orders and admissibility: geometric round-off, not the quadrature, whose cause was not
// removed. So every row is then projected onto its four affine constraints (enforceAffine()):
// Σ φ = 1 and x are reproduced to ~5e-16 of the diagonal at 1e-14 to 1e-6 of the diagonal from
// every vertex and edge of planar and warped boxes, to ~1e-12 at 1000 diagonals (as triangle
// Green). What the projection cannot restore is the φ entries' own error next to a vertex: a row
// at δ = 1e-14 of the diagonal differs from the vertex's row by up to 5e-6 (9e-6 warped), at 1e-12
// by 2e-8 (5e-8), at 1e-10 by 5e-9 (the true variation); the normal coordinates are unaffected.
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
// warped quad) the nearest point itself; clamped to [0, 1]² (x beyond the quad's edges), so the
// terms grow as the distance r, as triangle Green's, not as r² through B_k far outside the patch
// (which cost ~r³ of reproduction: 3.7e-9 at 144 diagonals). On the quad (t = 0) this equals the
// surface limit, so
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
using namespace detail::patch;
constexpr int kStretchOrder = 8;
constexpr double kInf = std::numeric_limits<double>::infinity();
// Relative difference below which two faces are equally near (see evaluateMixed()).
constexpr double kTie = 1e-12;

// A quad face: the patch (coords/detail/bilinear_quadrature.h) and its corner normals.
struct Quad : Patch {
  Vec3 cornerNormal[4];
  std::size_t face = 0, column = 0;  // face index, first of its four ψ columns
};

Quad makeQuad(std::span<const Vec3> vertices, std::span<const std::uint32_t> face) {
  Quad q;
  setPatch(q, vertices, face);
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
// still close to (within (kAdmissible + 1) ρ) are contacts. Their double layer is the jump the
// surface limit accounts for; their single layer is O(ρ) and dropped.
[[gnu::always_inline]] inline void integrateQuad(const Quad& q, const Vec3& x, double touchRadius,
                                                 QuadSums& out) {
  Origin near;
  const auto square = [&](const Origin& o, double u0, double v0, double s, int n)
      __attribute__((always_inline)) {
    gaussSquare(q, o, u0, v0, s, n, out);
  };
  out.touched = !integrateAdaptive(q, x, touchRadius, square, near, out.u, out.v);
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
  // The affine constraints' columns in the cage frame (see enforceAffine()): (v_i − c) / scale
  // for a vertex, C_c(rest) / scale for a normal column.
  std::vector<Vec3> affineColumn;
};

}  // namespace detail

struct QuadGreenCoordinates::Impl : detail::QuadGreenData {};

namespace {

// The normal columns of a mixed cage's column controls for `posed` (checked): see the file
// comment.
void normalControls(const detail::QuadGreenData& m, std::span<const Vec3> posed,
                    std::span<Vec3> out) {
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

// Solves the symmetric positive semi-definite 4 × 4 system a x = b by Gaussian elimination with
// partial pivoting; false if a pivot is not above `floor` (then x is not written).
bool solve4(double (&a)[4][4], double (&b)[4], double floor) {
  for (int k = 0; k < 4; ++k) {
    int p = k;
    for (int i = k + 1; i < 4; ++i)
      if (std::fabs(a[i][k]) > std::fabs(a[p][k])) p = i;
    if (!(std::fabs(a[p][k]) > floor)) return false;
    std::swap(a[k], a[p]);
    std::swap(b[k], b[p]);
    for (int i = k + 1; i < 4; ++i) {
      const double f = a[i][k] / a[k][k];
      for (int j = k; j < 4; ++j) a[i][j] -= f * a[k][j];
      b[i] -= f * b[k];
    }
  }
  for (int k = 3; k >= 0; --k) {
    for (int j = k + 1; j < 4; ++j) b[k] -= a[k][j] * b[j];
    b[k] /= a[k][k];
  }
  return true;
}

// Makes a mixed cage's row satisfy the four affine constraints Σ_i φ_i = 1 and
// Σ_i φ_i v_i + Σ_c ψ_c C_c(rest) = x to round-off (Xiao and Chen's "global projection" for
// Green-like coordinates, 2025): near a cage vertex the double-layer integrals of the faces
// around it cancel with a round-off that grows as the vertex is approached (|Σ φ − 1| was 2e-4 at
// 1e-14 of the diagonal from a vertex of a planar box). Only the φ are changed (the single layer
// has a positive integrand, no cancellation: changing ψ too smeared 2e-7 into it), by the least
// relative change, δ_i = φ_i ε_i with |ε| minimal: a φ that is 0 stays 0 and large ones take
// most. The constraints are written in the cage frame, so their residual is measured to the
// round-off of the row's own terms wherever x is. Two passes (the second takes the round-off of
// the first); a row that already satisfies them exactly is left as it is. Measured (planar and
// warped 2 × 2 × 2 boxes): the change is ≤ 4e-16 at interior points, 2e-4 at 1e-14 of the
// diagonal from a vertex (the error it removes), ~1e-12 at 1000 diagonals (round-off of entries
// ~7e3, as triangle Green's).
void enforceAffine(const detail::QuadGreenData& m, const Vec3& x, double* row) {
  const std::size_t nv = m.cage->vertexCount();
  const Vec3 target = m.cage->frame().toLocal(x);
  for (int pass = 0; pass < 2; ++pass) {
    double e[4] = {-1.0, -target.x, -target.y, -target.z};
    for (std::size_t c = 0; c < m.columns; ++c) {
      const Vec3& a = m.affineColumn[c];
      if (c < nv) e[0] += row[c];
      e[1] += row[c] * a.x;
      e[2] += row[c] * a.y;
      e[3] += row[c] * a.z;
    }
    if (e[0] == 0.0 && e[1] == 0.0 && e[2] == 0.0 && e[3] == 0.0) return;
    // Minimise Σ ε_i² subject to the constraints: M λ = e with M = Σ_i φ_i² a_i a_iᵀ,
    // a_i = (1, (v_i − c) / scale), then ε_i = −φ_i a_i·λ.
    double mat[4][4] = {};
    for (std::size_t i = 0; i < nv; ++i) {
      const double w = row[i] * row[i];
      const double a[4] = {1.0, m.affineColumn[i].x, m.affineColumn[i].y, m.affineColumn[i].z};
      for (int r = 0; r < 4; ++r)
        for (int c = r; c < 4; ++c) mat[r][c] += w * a[r] * a[c];
    }
    double trace = 0.0;
    for (int r = 0; r < 4; ++r) {
      trace += mat[r][r];
      for (int c = 0; c < r; ++c) mat[r][c] = mat[c][r];
    }
    if (!solve4(mat, e, 1e-14 * trace)) return;  // no well-posed correction: keep the row
    for (std::size_t i = 0; i < nv; ++i) {
      const Vec3& a = m.affineColumn[i];
      row[i] -= row[i] * row[i] * (e[0] + a.x * e[1] + a.y * e[2] + a.z * e[3]);
    }
  }
}

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
      // x = ξ(u, v) + a ξ_u + b ξ_v + t N at the foot (a = b = 0) or, failing that, at the seed;
      // a foot beyond the quad is clamped to it: there B_k(u, v) would grow as r² and cancel.
      double u = bu, v = bv, t = 0.0;
      if (!quadFoot(*nearest, x, m.footTolerance, u, v, t)) u = bu, v = bv;
      u = std::clamp(u, 0.0, 1.0);
      v = std::clamp(v, 0.0, 1.0);
      const Vec3 pu = nearest->tangentU(v), pv = nearest->tangentV(u);
      const Vec3 abt = glm::inverse(Mat3(pu, pv, glm::cross(pu, pv))) * (x - nearest->at(u, v));
      const std::array<double, 4> b = bilinear(u, v);
      const double du[4] = {-(1.0 - v), 1.0 - v, v, -v}, dv[4] = {-(1.0 - u), -u, u, 1.0 - u};
      for (int k = 0; k < 4; ++k) {
        row[nearest->vertex[k]] += b[k] + abt.x * du[k] + abt.y * dv[k];
        row[nearest->column + k] += abt.z * b[k];
      }
    }
    for (std::size_t l = 0; l < n; ++l)
      enforceAffine(m, points[start + l], rows + (start + l) * stride);
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
      detail::checkQuadUnfolded(cage->vertices(), face, f, "QuadGreenCoordinates", cage->name());
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

    // The rest column controls in the cage frame, for enforceAffine().
    std::vector<Vec3> rest(column);
    std::copy(cage->vertices().begin(), cage->vertices().end(), rest.begin());
    normalControls(*m, cage->vertices(), rest);
    const CageFrame& frame = cage->frame();
    m->affineColumn.resize(column);
    for (std::size_t c = 0; c < column; ++c)
      m->affineColumn[c] = c < nv ? frame.toLocal(rest[c]) : rest[c] / frame.scale;
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
  normalControls(m, posed, out);
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
