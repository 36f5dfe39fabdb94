#include <spacewarp/coords/mean_value.h>

// Numerics
// ========
// Notation, for a point x and a cage triangle T with corners p_0, p_1, p_2 (outward order):
// v_k = p_k − x, d_k = |v_k|, u_k = v_k / d_k; for corner i, the opposite edge runs from
// j = i+1 to k = i+2 and C_i = v_j × v_k (|C_i| = d_j d_k sin θ_i, θ_i the angle between u_j
// and u_k). The mean vector of T is m = ½ Σ_i θ_i C_i / |C_i| (Ju et al.'s ½ Σ θ_i n_i, signed
// by orientation), and T gives vertex i the unnormalised weight
//     w_i = λ_i / d_i = (C_i · m) / D,   D = det(v_0, v_1, v_2) = N_T · v_s,
// with N_T = (p_1 − p_0) × (p_2 − p_0) and v_s any corner (the nearest one is used). This is
// Cramer's rule for m = Σ_k λ_k u_k. The row is w / Σ w.
//
// Fast path (double, four points per SIMD pass, no libm calls). Per point, every vertex gives
// v, d, u (a reciprocal square root by Newton iterations, so that the loops vectorise); every
// edge, once for both of its triangles, gives its angle θ = 2 asin(|u_a − u_b| / 2), or
// π − 2 asin(|u_a + u_b| / 2) beyond 90° (both are stable; acos of a dot product is not),
// reduced further so that one minimax polynomial on [0, sin π/8] serves all angles; the
// factor θ / sin θ; and C = v × E from the nearer endpoint (E the edge vector), accurate to a
// few ulp relative to |C| even far from the cage. Sharing the edge terms makes Σ_T m_T vanish
// over the closed cage up to the rounding of the sums, which linear reproduction rests on.
//
// The rounding error of m is ≈ ε Σ_i θ_i (1 + L_i / (max d · sin θ_i)), so the error of w_i is
// about that times |C_i| / |D|. It is harmless unless w_i is much smaller than m's terms: when
// x is close to the plane of T but outside T (|D| → 0 and m → 0: the spherical triangle
// degenerates to an arc and the textbook formula is 0/0), near the line of an edge, or when the
// point's weight sum W is itself small (outside the cage). A triangle whose estimated error
// exceeds kTauW |W| is recomputed by the careful path instead (never skipped).
//
// Careful path (long double, per triangle): the same weights in the frame of T's plane. With
// unit normal n, height h = n · v_s and the projection x₀ of x, write v_k = q_k + h n, so that
// Σ_k w_k v_k = m splits into Σ_k w_k q_k = m_∥ and Σ_k w_k = (n · m) / h: a well-conditioned
// barycentric solve,
//     w_i = (s σ_i − n · (m_∥ × E_i)) / (2A),  s = (n · m) / h,  σ_i = n · C_i,
// with E_i = p_k − p_j and 2A = |N_T|. The in-plane part of C_i is exactly h (n × E_i), so
// m_∥ = ½ h Σ_i (θ_i / |C_i|) (n × E_i) keeps its factor h explicitly. The normal part is
// n · m = ½ Σ_i θ_i t_i with t_i = σ_i / |C_i| → ±1 near the plane, where the terms cancel to
// O(h²). There it is rewritten with the planar angles ψ_i = atan2(σ_i, q_j · q_k), whose signed
// sum is exactly 2πK (K = 1 if x₀ is inside T, 0 outside):
//     n · m = ½ Σ_i β_i + πK,   β_i = θ_i t_i − ψ_i,
// where each β_i = O(h²) is evaluated without cancellation: using
// |C_i| − |σ_i| = h² L_i² / (|C_i| + |σ_i|) and θ_i − |ψ_i| = atan2(h² X_i, Y_i),
//     β_i = t_i atan2(h² X_i, Y_i) − sign(σ_i) |ψ_i| h² L_i² / (|C_i| (|C_i| + |σ_i|)),
//     X_i = γ_i L_i² / (|C_i| + |σ_i|) − |σ_i|,  Y_i = (γ_i + h²) γ_i + |C_i| |σ_i|,
// (γ_i = q_j · q_k, L_i = |E_i|), or directly from θ_i, t_i, ψ_i when |σ_i| ≤ |h| L_i (x₀ near
// the edge line, where the direct form's errors cancel to first order). Every term of s and m_∥
// then carries its factor h analytically: T's weights go to 0 linearly and continuously as x
// approaches T's plane outside T, are exactly 0 on it, and no threshold below which a triangle
// is skipped is needed. Long double (64-bit mantissa) makes v_k = p_k − x exact for all
// practical inputs and adds 11 bits near edges and where W is small. Linear reproduction holds
// because these weights are forward-accurate.
//
// Whole-point fallback: outside the cage, Σ_k w_k v_k = 0 is a sum of terms |w_k| d_k that cancel
// ever more (W shrinks like d⁻⁴ far away, the terms like d⁻²). The fast path's reproduction
// error is ≈ ε κ with κ = Σ_T Σ_c |w_c| d_c / (|W| · diagonal), within a factor 0.3–20 in all
// measurements (4 test cages, 0.3–30 diagonals away). When ε κ exceeds kTauRepro (in practice
// beyond ~5–10 diagonals) the point is recomputed with the careful path for every triangle and
// long double sums.
//
// Snapping: points within MeanValueOptions::snapTolerance of a vertex, edge or face get the
// exact Lagrange, edge-linear or barycentric weights; candidates are detected in the fast
// passes (small d, |u_a + u_b| or |D|) and confirmed geometrically.

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <limits>
#include <map>
#include <new>
#include <numbers>
#include <string>
#include <utility>
#include <vector>

#include <spacewarp/coords/detail/mean_value_triangle.h>
#include <spacewarp/core/archive.h>
#include <spacewarp/core/detail/aligned_buffer.h>
#include <spacewarp/core/detail/simd.h>
#include <spacewarp/core/errors.h>
#include <spacewarp/core/geometry.h>

namespace spacewarp {

namespace {

constexpr double kEps = std::numeric_limits<double>::epsilon();

// Fast-path acceptance (see the top of the file). kErrM scales ε Σ θ (1 + ...) to the error of
// m. A triangle's weights are kept when their estimated error is at most kTauW |W| (W the
// point's weight sum, so this bounds the error of the normalised weights; measured errors stay
// about ten times below); otherwise, or if the estimate exceeds kHard times the weights
// themselves (they are noise, and are left out of W), the triangle is recomputed by the careful
// path. A point goes to the careful path when ε κ (its estimated reproduction error in cage
// diagonals) exceeds kTauRepro.
constexpr double kErrM = 4.0;
constexpr double kTauW = 1e-13;
constexpr double kHard = 1e-3;
constexpr double kTauRepro = 1e-13;

// Farther than this many cage diagonals from the cage's box centre a point is refused: there the
// row's weights grow like the distance and the per-triangle terms cancel in them and in their sum
// (W falls like d⁻⁴ while its terms fall like d⁻²), so even the careful path's long double loses
// ε (d / diagonal)² of the distance in linear reproduction (measured 1.7e-12 at 1e3 diagonals,
// 1.6e-6 at 1e6, 11% at 1e9). At 3000 diagonals that is about 2e-11.
constexpr double kFarLimit = 3000.0;

// Points per parallel task in weightsBatch (a multiple of every path's lane count; fixed, for
// determinism).
constexpr std::size_t kPointsPerTask = 64;

constexpr double kPi = std::numbers::pi;
const double kS8 = std::sin(kPi / 8);
const double kC8 = std::cos(kPi / 8);

// asin(z) = z (1 + t R(t)), t = z², on z ∈ [0, sin π/8]: a Chebyshev (near-minimax) fit of
// degree 9 in t; the relative error of asin is below 3e-17.
constexpr double kAsin[10] = {0.166666666666666541491,   0.0750000000001708394265,
                              0.0446428571044871075974,  0.0303819477773321340902,
                              0.0223720126078201396756,  0.0173564441007062125019,
                              0.0139089858872261009865,  0.0120701122659661718816,
                              0.00692529909733411594078, 0.016467470525355094967};

// ---- lanes ----
// The fast passes work on detail::simd's vectors of N doubles (see core/detail/simd.h for the
// rules they follow): N = 4 on the baseline and x86-64-v3 paths, 8 on x86-64-v4. A single point
// (weights()) runs through the same code in lane 0, and no lane's value depends on another lane
// or on N, so a row is bit-identical whichever call, lane, width or thread computes it. Vectors
// are kept in 64-byte aligned buffers, because the baseline target aligns these types less than
// the wider targets assume.
using namespace detail::simd;

// 1 + t R(t), so that asin(z) = z (1 + t R(t)) for t = z². R by Estrin's scheme: a chain of 5
// dependent operations rather than Horner's 18, which bounded the edge loop by latency (t ≤ 0.15
// and the coefficients shrink, so the rounding is as small as Horner's).
template <class V>
[[gnu::always_inline]] inline void asinFactor(const V& t, V& q) {
  const V t2 = t * t;
  const V t4 = t2 * t2;
  const V p01 = kAsin[0] + kAsin[1] * t, p23 = kAsin[2] + kAsin[3] * t;
  const V p45 = kAsin[4] + kAsin[5] * t, p67 = kAsin[6] + kAsin[7] * t;
  const V p89 = kAsin[8] + kAsin[9] * t;
  const V p03 = p01 + p23 * t2, p47 = p45 + p67 * t2;
  const V r = (p03 + p47 * t4) + p89 * (t4 * t4);
  q = 1.0 + t * r;
}

using detail::AlignedBuffer;

// The cage in structure-of-arrays form, with its edges (each once) and, per triangle, the edge
// opposite each corner and the sign that orients it like the triangle.
struct CageData {
  std::size_t nV = 0, nE = 0, nT = 0;
  std::vector<double> px, py, pz;
  std::vector<std::uint32_t> ea, eb;  // edge endpoints, ea < eb
  std::vector<double> ex, ey, ez;     // p[eb] − p[ea]
  std::vector<double> elen;
  std::vector<std::uint32_t> tv;  // 3 corners per triangle
  std::vector<std::uint32_t> te;  // 3 per triangle: the edge from corner c+1 to corner c+2
  std::vector<double> tsgn;       // +1 if that directed edge is (ea, eb), −1 otherwise
  std::vector<double> tnx, tny, tnz, tarea2;  // N_T = (p1 − p0) × (p2 − p0) and |N_T|
  double diagonal = 0.0;
  double snapLength = 0.0;
  Vec3 center{0.0};  // of the bounding box
};

// Per-thread buffers of one pass over N points.
template <int N>
struct Scratch {
  using VD = typename Lanes<N>::D;
  AlignedBuffer<VD> vx, vy, vz, ux, uy, uz, d, inv, acc;  // per vertex (acc: Σ_T w)
  AlignedBuffer<VD> cx, cy, cz, k, cn, ew;                // per edge
  AlignedBuffer<VD> tw0, tw1, tw2, terr;                  // per triangle: w, error estimate
  AlignedBuffer<VD> io;  // x, y, z in; snap candidates, reproduction estimate out
  std::vector<std::pair<std::uint32_t, std::uint32_t>> flagged;  // (triangle, lane mask)
  std::vector<long double> accLong;                              // careful path

  void reserve(const CageData& cd) {
    for (auto* a : {&vx, &vy, &vz, &ux, &uy, &uz, &d, &inv, &acc}) a->reserve(cd.nV);
    for (auto* a : {&cx, &cy, &cz, &k, &cn, &ew}) a->reserve(cd.nE);
    for (auto* a : {&tw0, &tw1, &tw2, &terr}) a->reserve(cd.nT);
    io.reserve(5);
    if (accLong.size() < cd.nV) accLong.resize(cd.nV);
  }
};

// The stages of fastPass(), always inlined so that each clone compiles them for its own target.

// Vertices: v = p − x, d = |v|, u = v / d; clears acc. Flags snap candidates (near a vertex).
template <int N, class V = typename Lanes<N>::D>
[[gnu::always_inline]] inline void vertexTerms(const CageData& cd, Scratch<N>& s, V& cand) {
  const V zero{}, one = zero + 1.0;
  const V X = s.io[0], Y = s.io[1], Z = s.io[2];
  const double snap2 = 2.0 * cd.snapLength;
  V* __restrict vx = s.vx.data();
  V* __restrict vy = s.vy.data();
  V* __restrict vz = s.vz.data();
  V* __restrict ux = s.ux.data();
  V* __restrict uy = s.uy.data();
  V* __restrict uz = s.uz.data();
  V* __restrict dd = s.d.data();
  V* __restrict ii = s.inv.data();
  V* __restrict acc = s.acc.data();
  for (std::size_t v = 0; v < cd.nV; ++v) {
    const V ax = cd.px[v] - X, ay = cd.py[v] - Y, az = cd.pz[v] - Z;
    const V sq = ax * ax + ay * ay + az * az;
    V y;
    rsqrt(sq, y);
    const V dist = sq * y;
    vx[v] = ax;
    vy[v] = ay;
    vz[v] = az;
    ux[v] = ax * y;
    uy[v] = ay * y;
    uz[v] = az * y;
    dd[v] = dist;
    ii[v] = y;
    acc[v] = zero;
    cand = dist <= snap2 ? one : cand;
  }
}

// Edges, once for both of their triangles: C, θ / |C| and the error terms. Flags snap
// candidates (near an edge).
template <int N, class V = typename Lanes<N>::D>
[[gnu::always_inline]] inline void edgeTerms(const CageData& cd, Scratch<N>& s, V& cand) {
  const V zero{}, one = zero + 1.0;
  const double snap2 = 2.0 * cd.snapLength;
  const V* __restrict vx = s.vx.data();
  const V* __restrict vy = s.vy.data();
  const V* __restrict vz = s.vz.data();
  const V* __restrict ux = s.ux.data();
  const V* __restrict uy = s.uy.data();
  const V* __restrict uz = s.uz.data();
  const V* __restrict dd = s.d.data();
  const V* __restrict ii = s.inv.data();
  V* __restrict cx = s.cx.data();
  V* __restrict cy = s.cy.data();
  V* __restrict cz = s.cz.data();
  V* __restrict kk = s.k.data();
  V* __restrict cn = s.cn.data();
  V* __restrict ew = s.ew.data();
  for (std::size_t e = 0; e < cd.nE; ++e) {
    const std::size_t a = cd.ea[e], b = cd.eb[e];
    const double ex = cd.ex[e], ey = cd.ey[e], ez = cd.ez[e];
    const V mx = ux[a] - ux[b], my = uy[a] - uy[b], mz = uz[a] - uz[b];
    const V qx = ux[a] + ux[b], qy = uy[a] + uy[b], qz = uz[a] + uz[b];
    const V s2 = mx * mx + my * my + mz * mz;  // |u_a − u_b|² = (2 sin θ/2)²
    const V p2 = qx * qx + qy * qy + qz * qz;  // |u_a + u_b|² = (2 cos θ/2)²
    V rc, rp;
    rsqrt(s2, rc);
    rsqrt(p2, rp);
    const V c = s2 * rc, cp = p2 * rp;
    // α = θ/2 from sin α = c/2, cos α = cp/2, reduced to asin on [0, sin π/8].
    const auto r0 = c * kC8 <= cp * kS8;  // α ≤ π/8
    const auto r1 = c <= cp;              // α ≤ π/4
    const auto r2 = c * kS8 <= cp * kC8;  // α ≤ 3π/8
    const V z =
        r0 ? 0.5 * c
           : (r1 ? 0.5 * (c * kC8 - cp * kS8) : (r2 ? 0.5 * (cp * kC8 - c * kS8) : 0.5 * cp));
    V q;
    asinFactor(z * z, q);
    const V as = z * q;
    const V alpha = r0 ? as : (r1 ? kPi / 8 + as : (r2 ? 3 * kPi / 8 - as : kPi / 2 - as));
    // θ / sin θ with sin θ = c cp / 2; for small angles without dividing by c.
    const V f = r0 ? 2.0 * q * rp : 4.0 * alpha * rc * rp;
    const auto aNear = dd[a] <= dd[b];
    const V wx = aNear ? vx[a] : vx[b];
    const V wy = aNear ? vy[a] : vy[b];
    const V wz = aNear ? vz[a] : vz[b];
    cx[e] = wy * ez - wz * ey;  // v_a × v_b = v_a × E = v_b × E
    cy[e] = wz * ex - wx * ez;
    cz[e] = wx * ey - wy * ex;
    kk[e] = f * ii[a] * ii[b];  // θ / |C|
    cn[e] = 0.5 * dd[a] * dd[b] * c * cp;
    ew[e] = 2.0 * alpha + f * cd.elen[e] * (aNear ? ii[b] : ii[a]);
    cand = cp <= snap2 * (ii[a] + ii[b]) + 8.0 * kEps ? one : cand;
  }
}

// Triangles: weights and error estimates; sums the kept weights into wsum and Σ |w| d into
// repro. Flags snap candidates (near a face's plane).
template <int N, class V = typename Lanes<N>::D>
[[gnu::always_inline]] inline void triangleWeights(const CageData& cd, Scratch<N>& s, V& cand,
                                                   V& wsum, V& repro) {
  const V zero{}, one = zero + 1.0;
  const double snap2 = 2.0 * cd.snapLength;
  const V* __restrict vx = s.vx.data();
  const V* __restrict vy = s.vy.data();
  const V* __restrict vz = s.vz.data();
  const V* __restrict dd = s.d.data();
  const V* __restrict cx = s.cx.data();
  const V* __restrict cy = s.cy.data();
  const V* __restrict cz = s.cz.data();
  const V* __restrict kk = s.k.data();
  const V* __restrict cn = s.cn.data();
  const V* __restrict ew = s.ew.data();
  V* __restrict tw0 = s.tw0.data();
  V* __restrict tw1 = s.tw1.data();
  V* __restrict tw2 = s.tw2.data();
  V* __restrict terr = s.terr.data();
  const V infinity = zero + std::numeric_limits<double>::infinity();
  for (std::size_t t = 0; t < cd.nT; ++t) {
    const std::size_t i0 = cd.tv[3 * t], i1 = cd.tv[3 * t + 1], i2 = cd.tv[3 * t + 2];
    const std::size_t e0 = cd.te[3 * t], e1 = cd.te[3 * t + 1], e2 = cd.te[3 * t + 2];
    const double s0 = cd.tsgn[3 * t], s1 = cd.tsgn[3 * t + 1], s2 = cd.tsgn[3 * t + 2];
    const V a0x = s0 * cx[e0], a0y = s0 * cy[e0], a0z = s0 * cz[e0];
    const V a1x = s1 * cx[e1], a1y = s1 * cy[e1], a1z = s1 * cz[e1];
    const V a2x = s2 * cx[e2], a2y = s2 * cy[e2], a2z = s2 * cz[e2];
    const V mx = 0.5 * (kk[e0] * a0x + kk[e1] * a1x + kk[e2] * a2x);
    const V my = 0.5 * (kk[e0] * a0y + kk[e1] * a1y + kk[e2] * a2y);
    const V mz = 0.5 * (kk[e0] * a0z + kk[e1] * a1z + kk[e2] * a2z);
    const V n0 = a0x * mx + a0y * my + a0z * mz;
    const V n1 = a1x * mx + a1y * my + a1z * mz;
    const V n2 = a2x * mx + a2y * my + a2z * mz;
    // D = N_T · v of the nearest corner.
    const auto near01 = dd[i0] <= dd[i1];
    const V dn = near01 ? dd[i0] : dd[i1];
    const auto near2 = dd[i2] < dn;
    const V sx = near2 ? vx[i2] : (near01 ? vx[i0] : vx[i1]);
    const V sy = near2 ? vy[i2] : (near01 ? vy[i0] : vy[i1]);
    const V sz = near2 ? vz[i2] : (near01 ? vz[i0] : vz[i1]);
    const V dmin = near2 ? dd[i2] : dn;
    const V det = cd.tnx[t] * sx + cd.tny[t] * sy + cd.tnz[t] * sz;
    const V absDet = det < 0.0 ? -det : det;
    const V invDet = 1.0 / det;
    const V w0 = n0 * invDet, w1 = n1 * invDet, w2 = n2 * invDet;
    // Error estimate of the w, from the rounding of m.
    const V errM = (kErrM * kEps) * (ew[e0] + ew[e1] + ew[e2]);
    const V cmax01 = cn[e0] < cn[e1] ? cn[e1] : cn[e0];
    const V cmax = cmax01 < cn[e2] ? cn[e2] : cmax01;
    const V err = errM * cmax * (invDet < 0.0 ? -invDet : invDet);
    const V a0 = w0 < 0.0 ? -w0 : w0, a1 = w1 < 0.0 ? -w1 : w1, a2 = w2 < 0.0 ? -w2 : w2;
    const V wmax01 = a0 < a1 ? a1 : a0;
    const V wmax = wmax01 < a2 ? a2 : wmax01;
    // Kept where |D| > 0 and err ≤ kHard wmax (NaN fails both), as one comparison: GCC 12
    // evaluates combined comparisons (& or | of masks) lane by lane in scalar code in
    // x86-64-v4 functions.
    const V errIfDet = absDet > 0.0 ? err : zero + std::numeric_limits<double>::quiet_NaN();
    const auto kept = errIfDet <= kHard * wmax;
    tw0[t] = kept ? w0 : zero;
    tw1[t] = kept ? w1 : zero;
    tw2[t] = kept ? w2 : zero;
    terr[t] = kept ? err : infinity;
    wsum += kept ? w0 + w1 + w2 : zero;
    // Σ |w| d: the scale of the terms that cancel in Σ_k w_k v_k = 0 (the conditioning κ).
    repro += kept ? a0 * dd[i0] + a1 * dd[i1] + a2 * dd[i2] : zero;
    const double area2 = cd.tarea2[t];
    cand = absDet <= area2 * snap2 + (8.0 * kEps * area2) * dmin ? one : cand;
  }
}

// Acceptance against the weight sum, and accumulation per vertex; the rejected triangles go to
// s.flagged with the lanes that need the careful path.
template <int N, class V = typename Lanes<N>::D>
[[gnu::always_inline]] inline void acceptTriangles(const CageData& cd, Scratch<N>& s,
                                                   const V& wsum) {
  const V zero{};
  V* __restrict acc = s.acc.data();
  const V* __restrict tw0 = s.tw0.data();
  const V* __restrict tw1 = s.tw1.data();
  const V* __restrict tw2 = s.tw2.data();
  const V* __restrict terr = s.terr.data();
  const V threshold = kTauW * (wsum < 0.0 ? -wsum : wsum);
  s.flagged.clear();
  for (std::size_t t = 0; t < cd.nT; ++t) {
    const auto ok = terr[t] <= threshold;
    acc[cd.tv[3 * t]] += ok ? tw0[t] : zero;
    acc[cd.tv[3 * t + 1]] += ok ? tw1[t] : zero;
    acc[cd.tv[3 * t + 2]] += ok ? tw2[t] : zero;
    std::uint32_t mask = 0;
    for (int l = 0; l < N; ++l) mask |= static_cast<std::uint32_t>(ok[l] == 0) << l;
    if (mask != 0) s.flagged.emplace_back(static_cast<std::uint32_t>(t), mask);
  }
}

// The fast passes for the points in s.io[0..2] (x, y, z). Leaves acc (Σ of the accepted
// triangle weights), io[3] (snap candidates), io[4] (reproduction error estimate) and flagged
// (triangles for the careful path).
template <int N>
[[gnu::always_inline]] inline void fastPass(const CageData& cd, Scratch<N>& s) {
  using VD = typename Lanes<N>::D;
  const VD zero{};
  VD cand = zero, repro = zero, wsum = zero;
  vertexTerms(cd, s, cand);
  edgeTerms(cd, s, cand);
  triangleWeights(cd, s, cand, wsum, repro);
  acceptTriangles(cd, s, wsum);
  s.io[3] = cand;
  s.io[4] = repro;
}

// fastPass for each simd::Path: four lanes (ymm) up to x86-64-v3, eight (zmm) on x86-64-v4. This
// file is compiled with -ffp-contract=off, so every path gives the same bits.
void fastPassBaseline(const CageData& cd, Scratch<4>& s) { fastPass(cd, s); }
SPACEWARP_SIMD_TARGET_V3 void fastPassV3(const CageData& cd, Scratch<4>& s) { fastPass(cd, s); }
SPACEWARP_SIMD_TARGET_V4 void fastPassV4(const CageData& cd, Scratch<8>& s) { fastPass(cd, s); }

// ---- careful path (long double, coords/detail/mean_value_triangle.h) ----

using Real = long double;
using detail::CarefulTriangle;

// The weights of triangle t for point x in the triangle's plane frame (see the top of the file).
CarefulTriangle carefulTriangle(const CageData& cd, const Vec3& x, std::size_t t) {
  std::array<Vec3, 3> p;
  for (int c = 0; c < 3; ++c) {
    const std::uint32_t i = cd.tv[3 * t + c];
    p[c] = Vec3(cd.px[i], cd.py[i], cd.pz[i]);
  }
  return detail::carefulMeanValueTriangle(p, x);
}

// The barycentric weights of x's projection on triangle t.
void faceRow(const CageData& cd, const Vec3& x, std::size_t t, std::span<double> row) {
  std::fill(row.begin(), row.end(), 0.0);
  const Vec3 n(cd.tnx[t], cd.tny[t], cd.tnz[t]);
  Vec3 p[3];
  for (int c = 0; c < 3; ++c) {
    const std::uint32_t i = cd.tv[3 * t + c];
    p[c] = Vec3(cd.px[i], cd.py[i], cd.pz[i]);
  }
  double b[3], sum = 0.0;
  for (int c = 0; c < 3; ++c) {
    b[c] = std::max(0.0, glm::dot(n, glm::cross(p[(c + 1) % 3] - x, p[(c + 2) % 3] - x)));
    sum += b[c];
  }
  for (int c = 0; c < 3; ++c) row[cd.tv[3 * t + c]] += b[c] / sum;
}

// Snapping to a vertex, edge or face within cd.snapLength; false if x is not that close.
bool snapRow(const CageData& cd, const Vec3& x, std::span<double> row) {
  const double tol = cd.snapLength;
  std::size_t best = cd.nV;
  double bestDist = std::numeric_limits<double>::infinity();
  for (std::size_t v = 0; v < cd.nV; ++v) {
    const double dist = glm::length(Vec3(cd.px[v], cd.py[v], cd.pz[v]) - x);
    if (dist <= tol && dist < bestDist) {
      best = v;
      bestDist = dist;
    }
  }
  if (best < cd.nV) {
    std::fill(row.begin(), row.end(), 0.0);
    row[best] = 1.0;
    return true;
  }
  double bestT = 0.0;
  best = cd.nE;
  for (std::size_t e = 0; e < cd.nE; ++e) {
    const Vec3 a(cd.px[cd.ea[e]], cd.py[cd.ea[e]], cd.pz[cd.ea[e]]);
    const Vec3 edge(cd.ex[e], cd.ey[e], cd.ez[e]);
    const double t = glm::dot(x - a, edge) / glm::dot(edge, edge);
    if (!(t > 0.0 && t < 1.0)) continue;
    const double dist = glm::length(x - (a + t * edge));
    if (dist <= tol && dist < bestDist) {
      best = e;
      bestDist = dist;
      bestT = t;
    }
  }
  if (best < cd.nE) {
    std::fill(row.begin(), row.end(), 0.0);
    row[cd.ea[best]] = 1.0 - bestT;
    row[cd.eb[best]] = bestT;
    return true;
  }
  best = cd.nT;
  for (std::size_t t = 0; t < cd.nT; ++t) {
    const Vec3 n = Vec3(cd.tnx[t], cd.tny[t], cd.tnz[t]) / cd.tarea2[t];
    Vec3 p[3];
    for (int c = 0; c < 3; ++c) {
      const std::uint32_t i = cd.tv[3 * t + c];
      p[c] = Vec3(cd.px[i], cd.py[i], cd.pz[i]);
    }
    const double dist = std::fabs(glm::dot(n, p[0] - x));
    if (!(dist <= tol && dist < bestDist)) continue;
    bool inside = true;
    for (int c = 0; c < 3; ++c)
      inside = inside && glm::dot(n, glm::cross(p[(c + 1) % 3] - x, p[(c + 2) % 3] - x)) >= 0.0;
    if (inside) {
      best = t;
      bestDist = dist;
    }
  }
  if (best < cd.nT) {
    faceRow(cd, x, best, row);
    return true;
  }
  return false;
}

double vertexDistance2(const CageData& cd, std::size_t v, const Vec3& x) {
  const Vec3 d = Vec3(cd.px[v], cd.py[v], cd.pz[v]) - x;
  return glm::dot(d, d);
}

std::string pointText(const Vec3& x) {
  char text[96];
  std::snprintf(text, sizeof text, "(%.17g, %.17g, %.17g)", x.x, x.y, x.z);
  return text;
}

// Every triangle by the careful path, summed and normalised in long double.
void carefulRow(const CageData& cd, const Vec3& x, std::vector<Real>& acc, std::span<double> row) {
  std::fill(acc.begin(), acc.begin() + static_cast<std::ptrdiff_t>(cd.nV), Real{0});
  for (std::size_t t = 0; t < cd.nT; ++t) {
    const CarefulTriangle r = carefulTriangle(cd, x, t);
    if (r.onFace) return faceRow(cd, x, t, row);
    for (int c = 0; c < 3; ++c) acc[cd.tv[3 * t + c]] += r.w[c];
  }
  Real sum = 0;
  for (std::size_t v = 0; v < cd.nV; ++v) sum += acc[v];
  if (!(std::isfinite(sum) && sum != 0))
    throw SolverError("MeanValueCoordinates: the weight sum vanishes at " + pointText(x));
  for (std::size_t v = 0; v < cd.nV; ++v) row[v] = static_cast<double>(acc[v] / sum);
}

// The rows of `count` ≤ N points, written at rows + i * nV, by `pass` (fastPass for one path).
// Unused lanes repeat the last point; every lane runs the same instructions, so a row does not
// depend on its lane.
template <int N>
void computeRows(const CageData& cd, const Vec3* points, std::size_t count, double* rows,
                 void (*pass)(const CageData&, Scratch<N>&)) {
  static thread_local Scratch<N> scratch;
  Scratch<N>& s = scratch;
  s.reserve(cd);
  for (int l = 0; l < N; ++l) {
    const Vec3& x = points[std::min(static_cast<std::size_t>(l), count - 1)];
    s.io[0][l] = x.x;
    s.io[1][l] = x.y;
    s.io[2][l] = x.z;
  }
  pass(cd, s);
  // Per lane: snapping, the careful path's triangles (into acc) and the conditioning estimate.
  bool done[N] = {};
  double kappa[N];
  for (std::size_t i = 0; i < count; ++i) {
    const int l = static_cast<int>(i);
    const Vec3& x = points[i];
    const std::span<double> row(rows + i * cd.nV, cd.nV);
    done[i] = s.io[3][l] != 0.0 && snapRow(cd, x, row);
    kappa[i] = s.io[4][l];
    for (const auto& [t, mask] : s.flagged) {
      if (done[i]) break;
      if (!(mask >> l & 1u)) continue;
      const CarefulTriangle r = carefulTriangle(cd, x, t);
      if (r.onFace) {
        faceRow(cd, x, t, row);
        done[i] = true;
        break;
      }
      for (int c = 0; c < 3; ++c) {
        const std::uint32_t v = cd.tv[3 * t + c];
        const double w = static_cast<double>(r.w[c]);
        s.acc[v][l] += w;
        kappa[i] += std::fabs(w) * std::sqrt(vertexDistance2(cd, v, x));
      }
    }
  }
  // The sums and the normalised weights of all lanes at once: each lane's sum runs over the
  // vertices in order and each weight is one division, as lane by lane, in N times fewer
  // instructions.
  using VD = typename Lanes<N>::D;
  VD sum{};
  for (std::size_t v = 0; v < cd.nV; ++v) sum += s.acc[v];
  for (std::size_t v = 0; v < cd.nV; ++v) s.acc[v] /= sum;
  for (std::size_t i = 0; i < count; ++i) {
    if (done[i]) continue;
    const int l = static_cast<int>(i);
    const std::span<double> row(rows + i * cd.nV, cd.nV);
    if (std::isfinite(sum[l]) && sum[l] != 0.0 &&
        kEps * kappa[i] <= kTauRepro * std::fabs(sum[l]) * cd.diagonal) {
      for (std::size_t v = 0; v < cd.nV; ++v) row[v] = s.acc[v][l];
    } else {
      carefulRow(cd, points[i], s.accLong, row);
    }
  }
}

// The rows of any number of points, written at rows + i * nV, N at a time on activePath().
// Throws InvalidInput for a point beyond kFarLimit diagonals.
void computeRange(const CageData& cd, const Vec3* points, std::size_t count, double* rows) {
  for (std::size_t i = 0; i < count; ++i) {
    const double distance = glm::length(points[i] - cd.center) / cd.diagonal;
    if (!(distance <= kFarLimit)) {
      char text[200];
      std::snprintf(text, sizeof text,
                    "MeanValueCoordinates: the point %s is %.3g cage diagonals from the cage; "
                    "mean value weights lose their accuracy beyond %g diagonals",
                    pointText(points[i]).c_str(), distance, kFarLimit);
      throw InvalidInput(text);
    }
  }
  const Path path = activePath();
  const std::size_t lanes = path == Path::V4 ? 8 : 4;
  for (std::size_t i = 0; i < count; i += lanes) {
    const std::size_t n = std::min(lanes, count - i);
    double* out = rows + i * cd.nV;
    if (path == Path::V4) {
      computeRows<8>(cd, points + i, n, out, fastPassV4);
    } else {
      computeRows<4>(cd, points + i, n, out, path == Path::V3 ? fastPassV3 : fastPassBaseline);
    }
  }
}

CageData buildCageData(const Cage& cage, double snapTolerance) {
  CageData cd;
  cd.nV = cage.vertexCount();
  cd.nT = cage.triangleCount();
  for (const Vec3& p : cage.vertices()) {
    cd.px.push_back(p.x);
    cd.py.push_back(p.y);
    cd.pz.push_back(p.z);
  }
  std::map<std::pair<std::uint32_t, std::uint32_t>, std::uint32_t> edgeIndex;
  for (std::size_t t = 0; t < cd.nT; ++t) {
    const Triangle& tri = cage.triangles()[t];
    const std::uint32_t corner[3] = {tri.x, tri.y, tri.z};
    for (int c = 0; c < 3; ++c) {
      const std::uint32_t from = corner[(c + 1) % 3], to = corner[(c + 2) % 3];
      const auto key = std::minmax(from, to);
      auto [it, inserted] =
          edgeIndex.try_emplace({key.first, key.second}, static_cast<std::uint32_t>(cd.ea.size()));
      if (inserted) {
        cd.ea.push_back(key.first);
        cd.eb.push_back(key.second);
        const Vec3 e = cage.vertices()[key.second] - cage.vertices()[key.first];
        cd.ex.push_back(e.x);
        cd.ey.push_back(e.y);
        cd.ez.push_back(e.z);
        cd.elen.push_back(glm::length(e));
      }
      cd.tv.push_back(corner[c]);
      cd.te.push_back(it->second);
      cd.tsgn.push_back(from < to ? 1.0 : -1.0);
    }
    const Vec3 p0 = cage.vertices()[tri.x];
    const Vec3 big = glm::cross(cage.vertices()[tri.y] - p0, cage.vertices()[tri.z] - p0);
    cd.tnx.push_back(big.x);
    cd.tny.push_back(big.y);
    cd.tnz.push_back(big.z);
    cd.tarea2.push_back(glm::length(big));
  }
  cd.nE = cd.ea.size();
  cd.diagonal = cage.diagonal();
  const BoundingBox box = boundingBox(cage.vertices());
  cd.center = 0.5 * (box.min + box.max);
  cd.snapLength = snapTolerance * cage.diagonal();
  return cd;
}

}  // namespace

struct MeanValueCoordinates::Impl {
  std::shared_ptr<const Cage> cage;
  MeanValueOptions options;
  CageData data;
};

MeanValueCoordinates::MeanValueCoordinates(std::shared_ptr<const Cage> cage,
                                           const MeanValueOptions& options) {
  if (!cage) throw InvalidInput("MeanValueCoordinates: the cage is null");
  if (!(options.snapTolerance >= 0.0 && options.snapTolerance <= 1e-3)) {
    throw InvalidInput("MeanValueCoordinates: snapTolerance must be in [0, 1e-3], got " +
                       std::to_string(options.snapTolerance));
  }
  auto impl = std::make_unique<Impl>();
  impl->data = buildCageData(*cage, options.snapTolerance);
  impl->cage = std::move(cage);
  impl->options = options;
  impl_ = std::move(impl);
}

MeanValueCoordinates::~MeanValueCoordinates() = default;

std::size_t MeanValueCoordinates::controlPointCount() const { return impl_->data.nV; }

std::span<const Vec3> MeanValueCoordinates::restControlPoints() const {
  return impl_->cage->vertices();
}

const Cage& MeanValueCoordinates::cage() const { return *impl_->cage; }
const MeanValueOptions& MeanValueCoordinates::options() const { return impl_->options; }

void MeanValueCoordinates::weights(const Vec3& x, std::span<double> row) const {
  checkWeightsArguments(x, row.size());
  computeRange(impl_->data, &x, 1, row.data());
}

std::size_t MeanValueCoordinates::batchGrain() const { return kPointsPerTask; }

UnmappedPoints MeanValueCoordinates::weightsRange(std::span<const Vec3> points,
                                                  std::span<double> rows, std::size_t begin,
                                                  std::size_t end) const {
  computeRange(impl_->data, points.data() + begin, end - begin,
               rows.data() + begin * columnCount());
  return {};
}

void MeanValueCoordinates::save(ArchiveWriter& out) const {
  out.tag("mean-value");
  impl_->cage->save(out);
  out.f64(impl_->options.snapTolerance);
}

std::shared_ptr<const MeanValueCoordinates> MeanValueCoordinates::load(ArchiveReader& in) {
  auto cage = std::make_shared<const Cage>(Cage::load(in));
  MeanValueOptions options;
  options.snapTolerance = in.f64();
  return std::make_shared<const MeanValueCoordinates>(std::move(cage), options);
}

}  // namespace spacewarp
