#include <spacewarp/coords/green.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <limits>
#include <map>
#include <new>
#include <numbers>
#include <string>
#include <utility>
#include <vector>

#include <spacewarp/coords/detail/green_kernels.h>
#include <spacewarp/coords/detail/green_triangles.h>
#include <spacewarp/core/archive.h>
#include <spacewarp/core/detail/aligned_buffer.h>
#include <spacewarp/core/detail/simd.h>
#include <spacewarp/core/errors.h>

namespace spacewarp {

// Notation. For a query point x and a triangle with corners v_0, v_1, v_2 (outward, unit normal
// n, area A), r_k = v_k − x, R_k = |r_k|, h = n·r_0 (x is below the plane, on the inside, when
// h > 0) and p = x + h n the projection of x onto the plane. Edge i runs from corner i to corner
// i + 1 with unit direction e_i, length ℓ_i and in-plane outward normal m_i = e_i × n;
// d_i = m_i·r_i is the signed in-plane distance from p to the edge line (positive on the
// triangle's side), and L_i = ∫_edge dℓ / |ξ − x| = ln((R_b + t_b) / (R_a + t_a)) with t the
// coordinate of the end points along e_i measured from the foot of x on the edge line.
//
// With Ω the signed solid angle of the triangle seen from x (Ω = ∫ h / |ξ − x|³ dσ) and the
// in-plane identities ∫ ρ / |ξ − x|³ dσ = −Σ_i m_i L_i and ∫ dσ / |ξ − x| = Σ_i d_i L_i − h Ω
// (divergence theorem in the plane, ρ = ξ − p), the triangle's contributions are
//
//     4π ψ  = Σ_i d_i L_i − h Ω
//     4π φ_l += Γ_l(p) Ω − h Σ_i (g_l·m_i) L_i     (l = 0, 1, 2)
//
// where Γ_l is the barycentric coordinate of corner l (Γ_l(p) = d_{l+1} ℓ_{l+1} / 2A) and
// g_l = −m_{l+1} ℓ_{l+1} / 2A its in-plane gradient. This is the paper's GCTriInt result written
// without divisions by h or by the distance to an edge, so it holds unchanged on both sides of the
// plane, in the plane and above a vertex.
//
// Everything that depends on an edge alone is computed once per (undirected) cage edge and shared
// by its two triangles, bit for bit: L, and the pieces of the solid angle around that edge (below).
// Near an edge the solid angle of each of its triangles is ill-conditioned (it depends on the
// direction from the edge to x), but their sum is not; computing both from the same edge data
// keeps the sum accurate to round-off however close x is to the edge.

namespace detail {

// The rest data of the cage, per vertex, undirected edge and triangle.
struct GreenData {
  struct Edge {
    std::uint32_t a = 0, b = 0;  // a < b
    Vec3 direction{0.0};         // unit, from a to b
    double length = 0.0;
  };
  struct Face {
    std::uint32_t vertex[3] = {0, 0, 0};
    std::uint32_t edge[3] = {0, 0, 0};  // edge i: corner i -> corner i + 1
    Vec3 normal{0.0};
    double twiceArea = 0.0;
    Vec3 edgeNormal[3];        // m_i
    double edgeFactor[3];      // ℓ_i / 2A
    double gradDotEdge[2][3];  // (g_l · m_i), row l (corner 2's terms are the rest of Ω / 4π)
  };
  struct RestFrame {  // for the stretch factor
    double uu = 0.0, vv = 0.0, uv = 0.0, sqrt8Area = 0.0;
  };

  std::vector<Vec3> vertices;
  std::vector<Edge> edges;
  std::vector<Face> faces;
  std::vector<RestFrame> frames;
  double surfaceTolerance2 = 0.0;  // (surfaceTolerance × diagonal)², world units²
  double largestCoordinate = 0.0;  // max |coordinate| of the vertices, world units
};

}  // namespace detail

struct GreenCoordinates::Impl : detail::GreenData {};

namespace {

constexpr double kInv4Pi = 0.25 * std::numbers::inv_pi;
constexpr double kInf = std::numeric_limits<double>::infinity();

// ---- lanes ----
// The evaluation runs N points at once on detail::simd's vectors VD of N doubles (see
// core/detail/simd.h for the rules they follow): N = 4 up to x86-64-v3, 8 on x86-64-v4. A lane's
// values never depend on another lane's or on N (the only branches skip work that no lane of the
// group needs, see anyLane()), and a single point (weights(), locate()) runs through the same
// code with every lane set to it, so a row is bit-identical whichever call, lane, width, group of
// points or thread computes it.
using namespace detail::simd;

// Points per parallel task in weightsBatch (a multiple of every path's lane count).
constexpr std::size_t kPointsPerTask = 64;

// x = 2^e m with m ∈ [1, 2), for finite x > 0 (normal or subnormal): mant = m, expo = e + 1023.
template <class VD>
[[gnu::always_inline]] inline void splitLanes(const VD& x, VD& mant, MaskOf<VD>& expo) {
  using VI = MaskOf<VD>;
  using VU = BitsOf<VD>;
  const VI subnormal = x < 0x1p-1022;
  const VU bits = reinterpret_cast<VU>(subnormal ? x * 0x1p54 : x);
  mant = reinterpret_cast<VD>((bits & std::uint64_t{0x000fffffffffffff}) |
                              std::uint64_t{0x3ff0000000000000});
  expo = reinterpret_cast<VI>(bits >> 52) - (subnormal & 54);
}

// ln(num / den) for finite num, den > 0 (normal or subnormal), within about one ulp of the exact
// quotient's logarithm; the per-edge logarithm was a fifth of the scalar evaluation's time in
// glibc's log. With num / den = 2^k a / b, a / b ∈ [√½, √2] (a and b the mantissas, a halved or
// doubled), q = a − b is exact (Sterbenz), and with f = q / b and s = q / (a + b) = f / (2 + f),
//     ln(a / b) = ln(1 + f) = 2 atanh s = f − f²/2 + s (f²/2 + R),
//     R = Σ_{i≥1} 2 s^{2i} / (2i + 1),
// fdlibm's arrangement, where only f's rounding reaches the leading term and s only enters the
// correction, which is at most a quarter of the result. The two divisions are independent (no
// rounded quotient num / den first, whose rounding alone would cost 2 ulp of the logarithm near
// √2 and any number of ulps near 1). For |s| ≤ 3 − 2√2 < 0.1716, R is fdlibm's (e_log.c) minimax
// polynomial of degree 7 in s², within 2^-58.45 of it (checked in exact arithmetic), in two
// chains of even and odd powers as there. k ln 2 is added in two parts; kLn2Hi has 32
// significant bits, so k kLn2Hi is exact.
constexpr double kLn2Hi = 0x1.62e42feep-1;
constexpr double kLn2Lo = 0x1.a39ef35793c76p-33;
constexpr double kLg[7] = {0x1.5555555555593p-1, 0x1.999999997fa04p-2, 0x1.2492494229359p-2,
                           0x1.c71c51d8e78afp-3, 0x1.7466496cb03dep-3, 0x1.39a09d078c69fp-3,
                           0x1.2f112df3e5244p-3};
template <class VD>
[[gnu::always_inline]] inline void logRatioLanes(const VD& num, const VD& den, VD& y) {
  using VI = MaskOf<VD>;
  VD a, b;
  VI ea, eb;
  splitLanes(num, a, ea);
  splitLanes(den, b, eb);
  const VI high = a > std::numbers::sqrt2 * b;
  const VI low = std::numbers::sqrt2 * a < b;
  a = high ? 0.5 * a : (low ? 2.0 * a : a);
  const VI k = ea - eb + (high & 1) - (low & 1);
  // k as a double: 1.5 · 2^52 + k has k in its low mantissa bits.
  const VD kd = reinterpret_cast<VD>(k + std::int64_t{0x4338000000000000}) - 0x1.8p52;
  const VD q = a - b;
  const VD f = q / b;
  const VD s = q / (a + b);
  const VD z = s * s, w = z * z;
  const VD r = z * (kLg[0] + w * (kLg[2] + w * (kLg[4] + w * kLg[6]))) +
               w * (kLg[1] + w * (kLg[3] + w * kLg[5]));
  const VD hfsq = 0.5 * f * f;
  y = kd * kLn2Hi - ((hfsq - (s * (hfsq + r) + kd * kLn2Lo)) - f);
}

// atan2(y, x) within about one ulp (0 for x = y = 0, where the solid angle is not defined); the
// per-triangle arctangent was the largest single cost of the scalar evaluation in glibc's atan2.
// With lo, hi the smaller and the larger of |x| and |y|, t = lo / hi ∈ [0, 1] and τ ∈ {0, 1/8,
// 1/4, 1/2, 1} the nearest in angle, atan(t) = atan(τ) + atan(u), u = (lo − τ hi) / (hi + τ lo).
// τ is a power of two so that τ hi is exact, and so is lo − τ hi (Sterbenz: in its sector, lo is
// within a factor 2 of τ hi): u carries one rounding of the denominator and one of the quotient
// (with tan(kπ/16) as τ, the rounding of τ hi cost up to 3 ulp without FMA). |u| ≤
// tan((π/4 − atan ½) / 2) < 0.1623, where the Taylor series u (1 − u²/3 + u⁴/5 − …) truncated
// after u²¹/21 is exact to 8e-18 relative. The sector and the quadrant are chosen by selects;
// atan(τ), π/2 and π are added in two parts. Within 1.5 ulp of atan2 over all finite inputs
// (signed zeros included) in tests.
constexpr double kSectorTan[5] = {0.0, 0.125, 0.25, 0.5, 1.0};
constexpr double kSectorAtan[5] = {0.0, 0x1.fd5ba9aac2f6ep-4, 0x1.f5b75f92c80ddp-3,
                                   0x1.dac670561bb4fp-2, 0x1.921fb54442d18p-1};
constexpr double kSectorAtanLo[5] = {0.0, -0x1.cd37686760c17p-59, 0x1.8ab6e3cf7afbdp-57,
                                     0x1.a2b7f222f65e2p-56, 0x1.1a62633145c07p-55};
// Sector k + 1 starts at t = kSectorBound[k]: tan of the angle midway between atan(τ_k) and
// atan(τ_{k+1}), except the first, just above 1/16 instead of at 0.06226, so that lo ≥ τ hi / 2
// holds in sector 1 whatever the rounding of the comparison.
constexpr double kSectorBound[4] = {0.0626, 0x1.7e8e639a21440p-3, 0x1.7acd608564de1p-2,
                                    0x1.71075a3cdcf19p-1};
constexpr double kPiHi = 0x1.921fb54442d18p+1, kPiLo = 0x1.1a62633145c07p-53;
template <class VD>
[[gnu::always_inline]] inline void angleLanes(const VD& y, const VD& x, VD& out) {
  using VI = MaskOf<VD>;
  const VD zero{};
  VD ax, ay;
  absLanes(x, ax);
  absLanes(y, ay);
  const VI swap = ay > ax;
  const VD lo0 = swap ? ax : ay, hi0 = swap ? ay : ax;
  // atan2 is scale-invariant: hi is brought into [2^-1000, 2^1000], where τ hi is exact (not
  // subnormal) and hi + τ lo finite. (lo underflows only where the result is below 2^-1400.)
  const VD scale =
      hi0 > 0x1p1000 ? zero + 0x1p-600 : (hi0 < 0x1p-1000 ? zero + 0x1p600 : zero + 1.0);
  const VD lo = lo0 * scale, hi = hi0 * scale;
  VD tau = zero, atau = zero, atauLo = zero;
  for (int k = 1; k <= 4; ++k) {
    const VI beyond = lo > kSectorBound[k - 1] * hi;
    tau = beyond ? zero + kSectorTan[k] : tau;
    atau = beyond ? zero + kSectorAtan[k] : atau;
    atauLo = beyond ? zero + kSectorAtanLo[k] : atauLo;
  }
  const VD u0 = (lo - tau * hi) / (hi + tau * lo);
  const VD u = hi == 0.0 ? zero : u0;
  const VD s = u * u;
  VD p = s * (-1.0 / 21) + 1.0 / 19;
  p = p * s - 1.0 / 17;
  p = p * s + 1.0 / 15;
  p = p * s - 1.0 / 13;
  p = p * s + 1.0 / 11;
  p = p * s - 1.0 / 9;
  p = p * s + 1.0 / 7;
  p = p * s - 1.0 / 5;
  p = p * s + 1.0 / 3;
  const VD series = -(u * s * p);
  const VD a = atau + (u + (atauLo + series));
  // The quadrant: x < 0 reflects about π/2 (π − a, or π/2 + a when swapped), swapping about π/4
  // (π/2 − a); y < 0 negates. Signs are read from the sign bits, like atan2's.
  const VI xNeg = reinterpret_cast<VI>(x) < 0, yNeg = reinterpret_cast<VI>(y) < 0;
  const VD offHi = swap ? zero + 0.5 * kPiHi : (xNeg ? zero + kPiHi : zero);
  const VD offLo = swap ? zero + 0.5 * kPiLo : (xNeg ? zero + kPiLo : zero);
  // swap ^ xNeg as nested selects (see facePass()).
  const VD signedA = swap ? (xNeg ? a : -a) : (xNeg ? -a : a);
  const VD r = offHi + (offLo + signedA);
  out = hi == 0.0 ? zero : (yNeg ? -r : r);
}

using detail::AlignedBuffer;

template <class VD>
struct VertexLanes {
  VD r[3];  // v − x
  VD length;
};

// The terms of one edge (a, b) for the current points. The solid angle of a triangle (a, b, c) is
// Van Oosterom and Strackee's
//     tan(Ω/2) = det(r_a, r_b, r_c) / (R_a R_b R_c + (r_a·r_b) R_c + (r_b·r_c) R_a + (r_c·r_a) R_b)
//              = 2A h / (R_c P + S·r_c),
// with P = R_a R_b + r_a·r_b and S = R_a r_b + R_b r_a depending on the edge only, and
// h = n·q = n·r_c (q the perpendicular from x to the edge line). Close to the edge (r_a and r_b
// nearly opposite) P and S cancel badly as written; with R0 = |q| and t the coordinates of the
// ends along e measured from the foot of x, they are, without cancellation,
//     P = ℓ² R0² / (R_a R_b − r_a·r_b),
//     S = (R_a + R_b) q + K e,   K = R_a t_b + R_b t_a = R0² ℓ (t_a + t_b) / (R_a t_b − R_b t_a).
// Each triangle evaluates its solid angle around its edge with the smallest P / (R_a R_b)
// (1 + the cosine of the angle the edge subtends), the one where cancellation would occur, so the
// two triangles of an edge that x is close to use the same q, P and S.
template <class VD>
struct EdgeLanes {
  VD log;        // L, 0 when x is on the segment (the triangles using it are surface ones)
  VD p;          // P
  VD closeness;  // P / (R_a R_b) when below 1/2, else 2
  VD r02;        // R0² = |q|²
  VD s[3];
  VD q[3];  // from x to its foot on the edge line
};

// h and d of one triangle for the current points, kept for the nearest-triangle search.
template <class VD>
struct FaceLanes {
  VD h;
  VD d[3];
};

// Per-thread work space of one group of points.
template <class VD>
struct Scratch {
  AlignedBuffer<VertexLanes<VD>> vertices;
  AlignedBuffer<VD> phi;  // per vertex
  AlignedBuffer<EdgeLanes<VD>> edges;
  AlignedBuffer<VD> edgeDist2;  // squared distance from x to the segment
  AlignedBuffer<FaceLanes<VD>> faces;
  AlignedBuffer<VD> psi;  // per triangle
  // In: 0-2 the points' x, y, z; 3 the lanes of the surface pass (non-zero). Out: 4 the sum of
  // the solid angles, 5 near a plane (non-zero), 6 the smallest squared distance to an edge.
  AlignedBuffer<VD> io;

  void reserve(const detail::GreenData& g) {
    vertices.reserve(g.vertices.size());
    phi.reserve(g.vertices.size());
    edges.reserve(g.edges.size());
    edgeDist2.reserve(g.edges.size());
    faces.reserve(g.faces.size());
    psi.reserve(g.faces.size());
    io.reserve(7);
  }
};

// The stages of edgePass() and facePass(), always inlined so that each clone compiles them for
// its own target.

// r = v − x and R = |r| of every vertex for the points in s.io[0..2].
template <class VD>
[[gnu::always_inline]] inline void vertexTerms(const detail::GreenData& g, Scratch<VD>& s) {
  const VD px = s.io[0], py = s.io[1], pz = s.io[2];
  VertexLanes<VD>* __restrict vl = s.vertices.data();
  for (std::size_t i = 0; i < g.vertices.size(); ++i) {
    const Vec3& v = g.vertices[i];
    VertexLanes<VD>& t = vl[i];
    t.r[0] = v.x - px;
    t.r[1] = v.y - py;
    t.r[2] = v.z - pz;
    sqrtLanes(t.r[0] * t.r[0] + t.r[1] * t.r[1] + t.r[2] * t.r[2], t.length);
  }
}

// The terms of one edge (see EdgeLanes) from its end points' terms; dist2 is the squared
// distance from x to the segment.
template <class VD>
[[gnu::always_inline]] inline void edgeTerms(const detail::GreenData::Edge& edge,
                                             const VertexLanes<VD>& a, const VertexLanes<VD>& b,
                                             EdgeLanes<VD>& out, VD& dist2) {
  using VI = MaskOf<VD>;
  const VD zero{};
  const double e[3] = {edge.direction.x, edge.direction.y, edge.direction.z};
  const double len = edge.length;
  const VD ra = a.length, rb = b.length;
  const VD ta = e[0] * a.r[0] + e[1] * a.r[1] + e[2] * a.r[2];
  const VD tb = e[0] * b.r[0] + e[1] * b.r[1] + e[2] * b.r[2];
  // The perpendicular from x to the edge line, from the nearer end (its error is then relative
  // to that end's distance).
  const VI aNearer = ra <= rb;
  const VD tn = aNearer ? ta : tb;
  VD q[3];
  for (int c = 0; c < 3; ++c) q[c] = (aNearer ? a.r[c] : b.r[c]) - tn * e[c];
  const VD r02 = q[0] * q[0] + q[1] * q[1] + q[2] * q[2];
  // L: when the foot of x is before a (ta ≥ 0) every R + t is a sum of non-negatives; after b
  // (tb ≤ 0) R + t = R0² / (R − t) at both ends and R0² cancels; in between
  // R_a + t_a = R0² / (R_a − t_a), with R0² from the perpendicular itself.
  const VI before = ta >= 0.0, after = tb <= 0.0;
  const VD rbtb = rb + tb, rata = ra - ta;
  const VD num = before ? rbtb : (after ? rata : rbtb * rata);
  const VD den = before ? ra + ta : (after ? rb - tb : r02);
  dist2 = before ? ra * ra : (after ? rb * rb : r02);
  // P and S as written are accurate unless r_a and r_b are far from each other's direction
  // (1 + cos < 1/2, which needs the foot inside the segment); then the cancellation-free forms,
  // computed in every lane when some lane needs them (about 1% of the edges for points inside
  // a cage) and kept where needed.
  const VD rarb = ra * rb;
  const VD dot = a.r[0] * b.r[0] + a.r[1] * b.r[1] + a.r[2] * b.r[2];
  const VD pFar = rarb + dot;
  // Not ≥ (NaN included), as a comparison of the mask with 0: ~(a >= b) is an unordered
  // comparison, which GCC 12 evaluates lane by lane in scalar code.
  const VI close = (pFar >= 0.5 * rarb) == 0;
  out.p = pFar;
  for (int c = 0; c < 3; ++c) {
    out.s[c] = ra * b.r[c] + rb * a.r[c];
    out.q[c] = q[c];
  }
  out.closeness = zero + 2.0;
  if (anyLane(close)) {
    const VD d1 = rarb - dot;         // ≥ R_a R_b where close
    const VD d2 = ra * tb - rb * ta;  // > 0 where close
    const VD inv = 1.0 / (d1 * d2);
    const VD pClose = len * len * r02 * d2 * inv;
    const VD k = r02 * len * (ta + tb) * d1 * inv;
    // q made orthogonal to e to round-off in |q|: a residual along e would enter S·r_c
    // differently for the two triangles of the edge.
    const VD qe = q[0] * e[0] + q[1] * e[1] + q[2] * e[2];
    const VD rab = ra + rb;
    out.p = close ? pClose : out.p;
    for (int c = 0; c < 3; ++c) out.s[c] = close ? rab * (q[c] - qe * e[c]) + k * e[c] : out.s[c];
    out.closeness = close ? pClose / rarb : out.closeness;
  }
  out.r02 = r02;
  VD log;
  logRatioLanes(num, den, log);
  // Not finite only for x on the segment: every triangle using the edge then touches x and is
  // a surface triangle, whose terms do not use L.
  // num and den in (0, ∞), by one unsigned comparison of the larger of their bits minus one
  // (0, negatives, ∞ and NaN wrap around or exceed the largest finite double's bits minus one):
  // GCC 12 evaluates combined double comparisons lane by lane in scalar code in x86-64-v4
  // functions.
  using VU = BitsOf<VD>;
  const VU bn = reinterpret_cast<VU>(num) - 1, bd = reinterpret_cast<VU>(den) - 1;
  const VU worst = bn > bd ? bn : bd;
  out.log = worst < std::uint64_t{0x7fefffffffffffff} ? log : zero;
}

// The vertex and edge terms of the points in s.io[0..2]; the smallest squared distance from a
// point to an edge goes to s.io[6].
template <class VD>
[[gnu::always_inline]] inline void edgePass(const detail::GreenData& g, Scratch<VD>& s) {
  const VD zero{};
  vertexTerms(g, s);
  const VertexLanes<VD>* __restrict vl = s.vertices.data();
  EdgeLanes<VD>* __restrict el = s.edges.data();
  VD* __restrict edgeDist2 = s.edgeDist2.data();
  VD minDist2 = zero + kInf;
  for (std::size_t index = 0; index < g.edges.size(); ++index) {
    const detail::GreenData::Edge& edge = g.edges[index];
    VD dist2;
    edgeTerms(edge, vl[edge.a], vl[edge.b], el[index], dist2);
    edgeDist2[index] = dist2;
    minDist2 = dist2 < minDist2 ? dist2 : minDist2;
  }
  s.io[6] = minDist2;
}

constexpr int kOpposite[3] = {2, 0, 1};  // the corner opposite edge i

// The solid angle Ω of face f seen from x (v: its corners' terms, e: its edges'), evaluated
// around the edge with the smallest closeness (the first of equals): edge 0 unless some lane
// is close to an edge.
template <class VD>
[[gnu::always_inline]] inline void faceSolidAngle(const detail::GreenData::Face& f,
                                                  const VertexLanes<VD>* const (&v)[3],
                                                  const EdgeLanes<VD>* const (&e)[3], VD& omega) {
  using VI = MaskOf<VD>;
  const Vec3& n = f.normal;
  const VI pick1 = e[1]->closeness < e[0]->closeness;
  const VD closeness01 = pick1 ? e[1]->closeness : e[0]->closeness;
  const VI pick2 = e[2]->closeness < closeness01;
  VD p = e[0]->p, r02 = e[0]->r02, cLength = v[kOpposite[0]]->length;
  VD sv[3], qv[3], c[3];
  for (int i = 0; i < 3; ++i) {
    sv[i] = e[0]->s[i];
    qv[i] = e[0]->q[i];
    c[i] = v[kOpposite[0]]->r[i];
  }
  // Whether some lane picks edge 1 or 2, through a select rather than pick1 | pick2 (see
  // facePass()): anyLane() reads the sign bits.
  const VD zero{}, minusOne = zero - 1.0;
  if (anyLane(pick1 ? minusOne : (pick2 ? minusOne : zero))) {
    const VertexLanes<VD>& c1 = *v[kOpposite[1]];
    const VertexLanes<VD>& c2 = *v[kOpposite[2]];
    p = pick2 ? e[2]->p : (pick1 ? e[1]->p : p);
    r02 = pick2 ? e[2]->r02 : (pick1 ? e[1]->r02 : r02);
    cLength = pick2 ? c2.length : (pick1 ? c1.length : cLength);
    for (int i = 0; i < 3; ++i) {
      sv[i] = pick2 ? e[2]->s[i] : (pick1 ? e[1]->s[i] : sv[i]);
      qv[i] = pick2 ? e[2]->q[i] : (pick1 ? e[1]->q[i] : qv[i]);
      c[i] = pick2 ? c2.r[i] : (pick1 ? c1.r[i] : c[i]);
    }
  }
  // det(r_a, r_b, r_c) = 2A h with h = n·q = n·r_c, from the shorter vector (its error is
  // relative to its length): q close to the edge, r_c close to the opposite corner.
  const VI useQ = r02 <= cLength * cLength;
  const VD toPlane[3] = {useQ ? qv[0] : c[0], useQ ? qv[1] : c[1], useQ ? qv[2] : c[2]};
  const VD num = f.twiceArea * (n.x * toPlane[0] + n.y * toPlane[1] + n.z * toPlane[2]);
  const VD den = cLength * p + (sv[0] * c[0] + sv[1] * c[1] + sv[2] * c[2]);
  angleLanes(num, den, omega);
  omega = 2.0 * omega;
}

// Adds every triangle's φ and ψ terms (into s.phi, s.psi) for the points whose vertex and edge
// terms edgePass() left; leaves the sum of the solid angles in s.io[4] and, in the regular pass,
// flags in s.io[5] the points within the surface tolerance of some triangle's plane. In the
// surface pass, for the lanes set in s.io[3], the triangles touching x (within the tolerance)
// contribute their principal value: no double layer (Ω = 0, h = 0) and the single layer at h = 0.
template <class VD>
[[gnu::always_inline]] inline void facePass(const detail::GreenData& g, Scratch<VD>& s,
                                            bool surface) {
  using VI = MaskOf<VD>;
  const VD zero{};
  const VD infinity = zero + kInf;
  const double tol2 = g.surfaceTolerance2;
  // Masks are combined through selects of doubles, not with & and |: GCC 12 evaluates
  // combined comparisons lane by lane in scalar code in x86-64-v4 functions. NaN fails every
  // comparison.
  const VD nan = zero + std::numeric_limits<double>::quiet_NaN();
  const VD surfaceOnly =
      s.io[3] != 0.0 ? zero : nan;  // added to a distance: NaN off the surface lanes
  const VertexLanes<VD>* __restrict vl = s.vertices.data();
  const EdgeLanes<VD>* __restrict el = s.edges.data();
  const VD* __restrict edgeDist2 = s.edgeDist2.data();
  FaceLanes<VD>* __restrict fl = s.faces.data();
  VD* __restrict phi = s.phi.data();
  VD* __restrict psi = s.psi.data();
  for (std::size_t i = 0; i < g.vertices.size(); ++i) phi[i] = zero;
  VD omegaSum = zero;
  VD nearPlane = zero;
  for (std::size_t j = 0; j < g.faces.size(); ++j) {
    const detail::GreenData::Face& f = g.faces[j];
    const VertexLanes<VD>* const v[3] = {&vl[f.vertex[0]], &vl[f.vertex[1]], &vl[f.vertex[2]]};
    const EdgeLanes<VD>* const e[3] = {&el[f.edge[0]], &el[f.edge[1]], &el[f.edge[2]]};
    const Vec3& n = f.normal;
    VD h = n.x * v[0]->r[0] + n.y * v[0]->r[1] + n.z * v[0]->r[2];
    VD d[3];
    for (int i = 0; i < 3; ++i) {
      const Vec3& m = f.edgeNormal[i];
      d[i] = m.x * v[i]->r[0] + m.y * v[i]->r[1] + m.z * v[i]->r[2];
    }
    const VD lg[3] = {e[0]->log, e[1]->log, e[2]->log};
    if (!surface) {
      fl[j].h = h;
      for (int i = 0; i < 3; ++i) fl[j].d[i] = d[i];
    }
    VD omega;
    faceSolidAngle(f, v, e, omega);
    if (surface) {
      // The squared distance from x to the triangle: to its plane if the projection is inside
      // it, else to the nearest edge the projection is outside of.
      VD edge2 = infinity;
      for (int i = 0; i < 3; ++i) {
        const VD di = d[i] < 0.0 ? edgeDist2[f.edge[i]] : infinity;
        edge2 = di < edge2 ? di : edge2;
      }
      const VD dist2 = edge2 == kInf ? h * h : edge2;
      const VI touching = dist2 + surfaceOnly <= tol2;
      omega = touching ? zero : omega;
      h = touching ? zero : h;
    } else {
      nearPlane = h * h <= tol2 ? zero + 1.0 : nearPlane;
    }
    omegaSum += omega;

    // The three corners' terms add up to Ω / 4π (Σ Γ_l = 1, Σ_l g_l = 0): the third is the rest.
    const VD w = kInv4Pi * omega, hw = kInv4Pi * h;
    psi[j] = kInv4Pi * (d[0] * lg[0] + d[1] * lg[1] + d[2] * lg[2]) - hw * omega;
    const double* g0 = f.gradDotEdge[0];
    const double* g1 = f.gradDotEdge[1];
    const VD phi0 =
        d[1] * f.edgeFactor[1] * w - hw * (g0[0] * lg[0] + g0[1] * lg[1] + g0[2] * lg[2]);
    const VD phi1 =
        d[2] * f.edgeFactor[2] * w - hw * (g1[0] * lg[0] + g1[1] * lg[1] + g1[2] * lg[2]);
    phi[f.vertex[0]] += phi0;
    phi[f.vertex[1]] += phi1;
    phi[f.vertex[2]] += w - phi0 - phi1;
  }
  s.io[4] = omegaSum;
  s.io[5] = nearPlane;
}

// The passes for each simd::Path: four lanes (ymm) up to x86-64-v3, eight (zmm) on x86-64-v4.
// This file is compiled with -ffp-contract=off, so every path gives the same bits.
using V4D = Lanes<4>::D;
using V8D = Lanes<8>::D;
void edgePassBaseline(const detail::GreenData& g, Scratch<V4D>& s) { edgePass(g, s); }
SPACEWARP_SIMD_TARGET_V3 void edgePassV3(const detail::GreenData& g, Scratch<V4D>& s) {
  edgePass(g, s);
}
SPACEWARP_SIMD_TARGET_V4 void edgePassV4(const detail::GreenData& g, Scratch<V8D>& s) {
  edgePass(g, s);
}
void facePassBaseline(const detail::GreenData& g, Scratch<V4D>& s, bool surface) {
  facePass(g, s, surface);
}
SPACEWARP_SIMD_TARGET_V3 void facePassV3(const detail::GreenData& g, Scratch<V4D>& s,
                                         bool surface) {
  facePass(g, s, surface);
}
SPACEWARP_SIMD_TARGET_V4 void facePassV4(const detail::GreenData& g, Scratch<V8D>& s,
                                         bool surface) {
  facePass(g, s, surface);
}

// The nearest triangle found so far, with what the exterior and surface formulas need of it.
struct Nearest {
  double dist2 = kInf;
  double beta = -kInf;  // signed distance of x from the triangle's plane (outside positive)
  std::size_t face = 0;
  double bary[3] = {0.0, 0.0, 0.0};  // Γ_l(p), p the projection of x onto the plane
};

// The triangle containing the point of the surface nearest to the point of lane l; ties (the
// point is on an edge or a vertex) go to the largest β (x farthest in front of the plane), then
// the lowest index. The squared distance to a triangle is that to its plane if the projection p
// is inside it, else that to the nearest edge p is outside of (the nearest point is on such an
// edge).
template <class VD>
Nearest findNearest(const detail::GreenData& g, const Scratch<VD>& s, int l) {
  Nearest nearest;
  for (std::size_t j = 0; j < g.faces.size(); ++j) {
    const detail::GreenData::Face& f = g.faces[j];
    const double h = s.faces[j].h[l];
    const double d[3] = {s.faces[j].d[0][l], s.faces[j].d[1][l], s.faces[j].d[2][l]};
    double edgeDist2 = kInf;
    for (int i = 0; i < 3; ++i)
      if (d[i] < 0.0) edgeDist2 = std::min(edgeDist2, s.edgeDist2[f.edge[i]][l]);
    const double dist2 = edgeDist2 == kInf ? h * h : edgeDist2;
    const double beta = -h;
    if (dist2 < nearest.dist2 || (dist2 == nearest.dist2 && beta > nearest.beta)) {
      nearest.dist2 = dist2;
      nearest.beta = beta;
      nearest.face = j;
      nearest.bary[0] = d[1] * f.edgeFactor[1];
      nearest.bary[1] = d[2] * f.edgeFactor[2];
      nearest.bary[2] = d[0] * f.edgeFactor[0];
    }
  }
  return nearest;
}

// The rows of count ≤ N points (N the lanes of VD), written at rows + i * stride (V + F entries
// each), by the passes of one path, and, if `locations` is set, where they are (the nearest
// triangle is then searched for every point; otherwise only for points outside or near the
// surface). Unused lanes repeat the last point.
// With `raw` set (GreenTriangleTerms), the nearest triangle is searched for every point and the
// rows are left without the surface limit's hat term and the exterior extension; raw gets the
// solid angles and the nearest triangles.
template <class VD>
void evaluate(const detail::GreenData& g, const Vec3* points, std::size_t count, double* rows,
              std::size_t stride, GreenCoordinates::Location* locations,
              detail::GreenTriangleTerms::Point* raw,
              void (*edgePassOf)(const detail::GreenData&, Scratch<VD>&),
              void (*facePassOf)(const detail::GreenData&, Scratch<VD>&, bool)) {
  constexpr int kN = kLanesOf<VD>;
  static thread_local Scratch<VD> scratch;
  Scratch<VD>& s = scratch;
  s.reserve(g);
  for (int l = 0; l < kN; ++l) {
    const Vec3& x = points[std::min(static_cast<std::size_t>(l), count - 1)];
    s.io[0][l] = x.x;
    s.io[1][l] = x.y;
    s.io[2][l] = x.z;
    s.io[3][l] = 0.0;
  }
  edgePassOf(g, s);
  facePassOf(g, s, false);

  const std::size_t nv = g.vertices.size(), nf = g.faces.size();
  auto copyRow = [&](std::size_t l) {
    double* row = rows + l * stride;
    for (std::size_t i = 0; i < nv; ++i) row[i] = s.phi[i][l];
    for (std::size_t j = 0; j < nf; ++j) row[nv + j] = s.psi[j][l];
  };
  GreenCoordinates::Location loc[kN];
  Nearest nearest[kN];
  bool anySurface = false;
  for (std::size_t l = 0; l < count; ++l) {
    copyRow(l);
    loc[l].windingNumber = s.io[4][l] * kInv4Pi;
    const bool inside = loc[l].windingNumber > 0.5;
    // The distance to a triangle is that to its plane or to one of its edges, so x can only be
    // within the tolerance of the surface if it is of a plane or an edge.
    const bool maybeSurface = s.io[5][l] != 0.0 || s.io[6][l] <= g.surfaceTolerance2;
    loc[l].region = inside ? GreenCoordinates::Region::Inside : GreenCoordinates::Region::Outside;
    if (inside && !maybeSurface && locations == nullptr && raw == nullptr) continue;
    nearest[l] = findNearest(g, s, static_cast<int>(l));
    loc[l].triangle = nearest[l].face;
    loc[l].distance = std::sqrt(nearest[l].dist2);
    if (nearest[l].dist2 <= g.surfaceTolerance2) {
      loc[l].region = GreenCoordinates::Region::Surface;
      s.io[3][l] = 1.0;
      anySurface = true;
    }
  }
  // Surface: principal value plus (1 − σ) times the hat values at the point.
  if (anySurface) facePassOf(g, s, true);
  if (raw != nullptr) {
    for (std::size_t l = 0; l < count; ++l) {
      const bool surface = loc[l].region == GreenCoordinates::Region::Surface;
      if (surface) copyRow(l);
      raw[l] = {s.io[4][l],
                nearest[l].dist2,
                nearest[l].face,
                nearest[l].beta,
                {nearest[l].bary[0], nearest[l].bary[1], nearest[l].bary[2]},
                surface};
    }
    return;
  }
  for (std::size_t l = 0; l < count; ++l) {
    double* row = rows + l * stride;
    const detail::GreenData::Face& f = g.faces[nearest[l].face];
    if (loc[l].region == GreenCoordinates::Region::Surface) {
      copyRow(l);
      const double sigma = s.io[4][l] * kInv4Pi;
      loc[l].windingNumber = sigma;
      for (int k = 0; k < 3; ++k) row[f.vertex[k]] += (1.0 - sigma) * nearest[l].bary[k];
    } else if (loc[l].region == GreenCoordinates::Region::Outside) {
      // Outside: continue the interior coordinates through the nearest triangle.
      for (int k = 0; k < 3; ++k) row[f.vertex[k]] += nearest[l].bary[k];
      row[nv + nearest[l].face] += nearest[l].beta;
    }
    if (locations != nullptr) locations[l] = loc[l];
  }
}

// Far enough from the origin (from ~1e110 world units) the kernels' products of lengths
// overflow and a row turns to NaN, whose sign bit differs between paths: refuse it instead.
// Out of line, so that evaluateRange's code (and speed) stays as it was.
// Only rows of points (or cages) beyond kOverflowScan world units are scanned: nearer, the
// products stay far from overflow, and scanning every row cost 4% of the armadillo kernel.
constexpr double kOverflowScan = 1e100;
[[gnu::noinline]] void refuseNonFiniteRows(const detail::GreenData& g, const Vec3* points,
                                           std::size_t count, const double* rows,
                                           std::size_t stride) {
  // (Integer tests of the exponent bits, which vectorise: std::isfinite per weight cost 5% of
  // the armadillo kernel's time.)
  constexpr std::uint64_t kExponent = 0x7ff0000000000000;
  for (std::size_t i = 0; i < count; ++i) {
    const Vec3& x = points[i];
    const double largest = std::max({std::fabs(x.x), std::fabs(x.y), std::fabs(x.z)});
    if (!(largest > kOverflowScan || g.largestCoordinate > kOverflowScan)) continue;
    const double* row = rows + i * stride;
    std::uint64_t nonFinite = 0;
    for (std::size_t c = 0; c < stride; ++c)
      nonFinite |= (~std::bit_cast<std::uint64_t>(row[c]) & kExponent) == 0;
    if (nonFinite == 0) continue;
    char text[200];
    std::snprintf(text, sizeof text,
                  "GreenCoordinates: the point (%.17g, %.17g, %.17g) is too far from the cage: "
                  "its weights overflow",
                  points[i].x, points[i].y, points[i].z);
    throw InvalidInput(text);
  }
}

// The rows (and locations, if set) of any number of points, N at a time on activePath().
void evaluateRange(const detail::GreenData& g, const Vec3* points, std::size_t count, double* rows,
                   std::size_t stride, GreenCoordinates::Location* locations,
                   detail::GreenTriangleTerms::Point* raw = nullptr) {
  const Path path = activePath();
  const std::size_t lanes = path == Path::V4 ? 8 : 4;
  for (std::size_t i = 0; i < count; i += lanes) {
    const std::size_t n = std::min(lanes, count - i);
    GreenCoordinates::Location* at = locations ? locations + i : nullptr;
    detail::GreenTriangleTerms::Point* rawAt = raw ? raw + i : nullptr;
    if (path == Path::V4) {
      evaluate<V8D>(g, points + i, n, rows + i * stride, stride, at, rawAt, edgePassV4, facePassV4);
    } else if (path == Path::V3) {
      evaluate<V4D>(g, points + i, n, rows + i * stride, stride, at, rawAt, edgePassV3, facePassV3);
    } else {
      evaluate<V4D>(g, points + i, n, rows + i * stride, stride, at, rawAt, edgePassBaseline,
                    facePassBaseline);
    }
  }
  refuseNonFiniteRows(g, points, count, rows, stride);
}

// ---- the elementary functions on arrays, for their tests (detail::greenLogRatio, greenAtan2) ----

template <bool kLog, class VD>
[[gnu::always_inline]] inline void lanewise(const double* a, const double* b, double* out,
                                            std::size_t n) {
  constexpr int kN = kLanesOf<VD>;
  for (std::size_t i = 0; i < n; i += kN) {
    VD va, vb, y;
    for (int l = 0; l < kN; ++l) {
      const std::size_t k = std::min(i + static_cast<std::size_t>(l), n - 1);
      va[l] = a[k];
      vb[l] = b[k];
    }
    if constexpr (kLog) {
      logRatioLanes(va, vb, y);
    } else {
      angleLanes(va, vb, y);
    }
    for (std::size_t l = 0; l < kN && i + l < n; ++l) out[i + l] = y[l];
  }
}

void logRatioBaseline(const double* num, const double* den, double* out, std::size_t n) {
  lanewise<true, V4D>(num, den, out, n);
}
SPACEWARP_SIMD_TARGET_V3 void logRatioV3(const double* num, const double* den, double* out,
                                         std::size_t n) {
  lanewise<true, V4D>(num, den, out, n);
}
SPACEWARP_SIMD_TARGET_V4 void logRatioV4(const double* num, const double* den, double* out,
                                         std::size_t n) {
  lanewise<true, V8D>(num, den, out, n);
}
void atan2Baseline(const double* y, const double* x, double* out, std::size_t n) {
  lanewise<false, V4D>(y, x, out, n);
}
SPACEWARP_SIMD_TARGET_V3 void atan2V3(const double* y, const double* x, double* out,
                                      std::size_t n) {
  lanewise<false, V4D>(y, x, out, n);
}
SPACEWARP_SIMD_TARGET_V4 void atan2V4(const double* y, const double* x, double* out,
                                      std::size_t n) {
  lanewise<false, V8D>(y, x, out, n);
}
using LanewiseFn = void (*)(const double*, const double*, double*, std::size_t);
constexpr LanewiseFn kLogRatio[kPathCount] = {logRatioBaseline, logRatioV3, logRatioV4};
constexpr LanewiseFn kAtan2[kPathCount] = {atan2Baseline, atan2V3, atan2V4};

void checkSizes(const char* what, std::size_t a, std::size_t b, std::size_t out) {
  if (a != b || a != out) {
    throw InvalidInput(std::string(what) + ": the spans have different sizes (" +
                       std::to_string(a) + ", " + std::to_string(b) + ", " + std::to_string(out) +
                       ")");
  }
}

// The rest data of triangles `tris` over vertices `v`; tol: the surface tolerance, world units.
void buildGreenData(detail::GreenData& g, std::span<const Vec3> v, std::span<const Triangle> tris,
                    double tol) {
  g.vertices.assign(v.begin(), v.end());
  for (const Vec3& p : v)
    g.largestCoordinate =
        std::max({g.largestCoordinate, std::fabs(p.x), std::fabs(p.y), std::fabs(p.z)});
  g.surfaceTolerance2 = tol * tol;

  std::map<std::pair<std::uint32_t, std::uint32_t>, std::uint32_t> edgeIndex;
  g.faces.resize(tris.size());
  g.frames.resize(tris.size());
  for (std::size_t j = 0; j < tris.size(); ++j) {
    detail::GreenData::Face& f = g.faces[j];
    const std::uint32_t idx[3] = {tris[j].x, tris[j].y, tris[j].z};
    const Vec3 p[3] = {v[idx[0]], v[idx[1]], v[idx[2]]};
    const Vec3 cross = glm::cross(p[1] - p[0], p[2] - p[0]);
    const double twiceArea = glm::length(cross);
    f.normal = cross / twiceArea;  // the Cage rejects zero-area triangles
    f.twiceArea = twiceArea;
    for (int i = 0; i < 3; ++i) {
      f.vertex[i] = idx[i];
      const std::uint32_t a = idx[i], b = idx[(i + 1) % 3];
      const Vec3 edgeVector = p[(i + 1) % 3] - p[i];
      const double length = glm::length(edgeVector);
      f.edgeNormal[i] = glm::normalize(glm::cross(edgeVector, f.normal));
      f.edgeFactor[i] = length / twiceArea;
      const auto key = std::minmax(a, b);
      auto [it, inserted] = edgeIndex.try_emplace(key, static_cast<std::uint32_t>(g.edges.size()));
      if (inserted) {
        const Vec3 ab = v[key.second] - v[key.first];
        g.edges.push_back({key.first, key.second, ab / glm::length(ab), glm::length(ab)});
      }
      f.edge[i] = it->second;
    }
    // g_l = −m_{l+1} ℓ_{l+1} / 2A, the in-plane gradient of the barycentric coordinate of corner l.
    for (int l = 0; l < 2; ++l) {
      const int opposite = (l + 1) % 3;
      for (int i = 0; i < 3; ++i) {
        f.gradDotEdge[l][i] =
            -f.edgeFactor[opposite] * glm::dot(f.edgeNormal[opposite], f.edgeNormal[i]);
      }
    }
    const Vec3 u = p[1] - p[0], w = p[2] - p[0];
    g.frames[j] = {glm::dot(u, u), glm::dot(w, w), glm::dot(u, w),
                   std::sqrt(8.0) * 0.5 * twiceArea};
  }
}

}  // namespace

namespace detail {

void greenLogRatio(std::span<const double> num, std::span<const double> den, std::span<double> out,
                   bool baseline) {
  checkSizes("greenLogRatio", num.size(), den.size(), out.size());
  if (out.empty()) return;
  if (baseline) return logRatioBaseline(num.data(), den.data(), out.data(), out.size());
  kLogRatio[static_cast<int>(activePath())](num.data(), den.data(), out.data(), out.size());
}

GreenTriangleTerms::GreenTriangleTerms(std::span<const Vec3> vertices,
                                       std::span<const Triangle> triangles,
                                       double surfaceTolerance) {
  auto data = std::make_unique<GreenData>();
  buildGreenData(*data, vertices, triangles, surfaceTolerance);
  data_ = std::move(data);
}

GreenTriangleTerms::~GreenTriangleTerms() = default;

std::size_t GreenTriangleTerms::lanes() const { return activePath() == Path::V4 ? 8 : 4; }

void GreenTriangleTerms::evaluate(const Vec3* points, std::size_t count, double* rows,
                                  std::size_t stride, Point* info) const {
  evaluateRange(*data_, points, count, rows, stride, nullptr, info);
}

void greenAtan2(std::span<const double> y, std::span<const double> x, std::span<double> out,
                bool baseline) {
  checkSizes("greenAtan2", y.size(), x.size(), out.size());
  if (out.empty()) return;
  if (baseline) return atan2Baseline(y.data(), x.data(), out.data(), out.size());
  kAtan2[static_cast<int>(activePath())](y.data(), x.data(), out.data(), out.size());
}

}  // namespace detail

GreenCoordinates::GreenCoordinates(std::shared_ptr<const Cage> cage, GreenOptions options)
    : cage_(std::move(cage)), options_(options) {
  if (!cage_) throw InvalidInput("GreenCoordinates: the cage is null");
  // Bounded as MeanValueOptions::snapTolerance: a point a sizeable fraction of the cage away
  // from its surface is not on it (at 1, the cage's center was).
  if (!(options_.surfaceTolerance >= 0.0 && options_.surfaceTolerance <= 1e-3)) {
    throw InvalidInput("GreenCoordinates: surfaceTolerance must be in [0, 1e-3], not " +
                       std::to_string(options_.surfaceTolerance));
  }
  auto impl = std::make_unique<Impl>();
  buildGreenData(*impl, cage_->vertices(), cage_->triangles(),
                 options_.surfaceTolerance * cage_->diagonal());
  impl_ = std::move(impl);
}

GreenCoordinates::~GreenCoordinates() = default;

std::size_t GreenCoordinates::controlPointCount() const { return impl_->vertices.size(); }

std::span<const Vec3> GreenCoordinates::restControlPoints() const { return impl_->vertices; }

std::size_t GreenCoordinates::columnCount() const {
  return impl_->vertices.size() + impl_->faces.size();
}

void GreenCoordinates::weights(const Vec3& x, std::span<double> row) const {
  checkWeightsArguments(x, row.size());
  evaluateRange(*impl_, &x, 1, row.data(), row.size(), nullptr);
}

std::size_t GreenCoordinates::batchGrain() const { return kPointsPerTask; }

UnmappedPoints GreenCoordinates::weightsRange(std::span<const Vec3> points, std::span<double> rows,
                                              std::size_t begin, std::size_t end) const {
  const std::size_t m = columnCount();
  evaluateRange(*impl_, points.data() + begin, end - begin, rows.data() + begin * m, m, nullptr);
  return {};
}

void GreenCoordinates::columnControls(std::span<const Vec3> posed, std::span<Vec3> out) const {
  Coordinates::columnControls(posed, out);  // checks sizes and finiteness, copies the vertices
  const std::size_t nv = impl_->vertices.size();
  for (std::size_t j = 0; j < impl_->faces.size(); ++j) {
    const detail::GreenData::Face& f = impl_->faces[j];
    const detail::GreenData::RestFrame& rest = impl_->frames[j];
    const Vec3 u = posed[f.vertex[1]] - posed[f.vertex[0]];
    const Vec3 w = posed[f.vertex[2]] - posed[f.vertex[0]];
    const Vec3 cross = glm::cross(u, w);
    const double length = glm::length(cross);
    if (!(length > 0.0)) {
      out[nv + j] = Vec3(0.0);
      continue;
    }
    const double radicand =
        glm::dot(u, u) * rest.vv - 2.0 * glm::dot(u, w) * rest.uv + glm::dot(w, w) * rest.uu;
    const double stretch = std::sqrt(std::max(radicand, 0.0)) / rest.sqrt8Area;
    out[nv + j] = cross * (stretch / length);
  }
}

GreenCoordinates::Location GreenCoordinates::locate(const Vec3& x) const {
  if (!isFinite(x)) throw InvalidInput("GreenCoordinates: the query point is not finite");
  thread_local std::vector<double> row;
  row.resize(columnCount());
  Location location;
  evaluateRange(*impl_, &x, 1, row.data(), row.size(), &location);
  return location;
}

void GreenCoordinates::save(ArchiveWriter& out) const {
  out.tag("green");
  cage_->save(out);
  out.f64(options_.surfaceTolerance);
}

std::shared_ptr<const GreenCoordinates> GreenCoordinates::load(ArchiveReader& in) {
  auto cage = std::make_shared<const Cage>(Cage::load(in));
  GreenOptions options;
  options.surfaceTolerance = in.f64();
  return std::make_shared<const GreenCoordinates>(std::move(cage), options);
}

}  // namespace spacewarp
