#include "coords/green.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <map>
#include <numbers>
#include <string>
#include <utility>
#include <vector>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "core/errors.h"

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
};

}  // namespace detail

struct GreenCoordinates::Impl : detail::GreenData {};

namespace {

constexpr double kInv4Pi = 0.25 * std::numbers::inv_pi;
constexpr double kInf = std::numeric_limits<double>::infinity();

struct VertexTerm {
  Vec3 r{0.0};  // v − x
  double length = 0.0;
};

// The terms of one edge (a, b) for the current point. The solid angle of a triangle (a, b, c) is
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
struct EdgeTerm {
  double log = 0.0;    // L, 0 when x is on the segment (the triangles using it are surface ones)
  double dist2 = 0.0;  // squared distance from x to the segment
  double p = 0.0;
  double closeness = 2.0;  // P / (R_a R_b) when below 1/2, else 2
  double r02 = 0.0;        // R0² = |q|²
  Vec3 s{0.0};
  Vec3 q{0.0};  // from x to its foot on the edge line
};

// h and d of one triangle for the current point, kept for the nearest-triangle search.
struct FaceTerm {
  double h = 0.0;
  double d[3] = {0.0, 0.0, 0.0};
};

// Per-point work space, reused across points.
struct Scratch {
  std::vector<VertexTerm> vertices;
  std::vector<EdgeTerm> edges;
  std::vector<FaceTerm> faces;
};

constexpr int kOpposite[3] = {2, 0, 1};  // the corner opposite edge i

// atan2(y, x), accurate to about one ulp of π, and much cheaper than glibc's atan2, which was the
// largest single cost of the evaluation (one per triangle and point). With
// t = min(|x|, |y|) / max(|x|, |y|) ∈ [0, 1], atan(t) = atan(τ_k) + atan(u),
// u = (t − τ_k) / (1 + t τ_k), for the τ_k = tan(kπ/16) nearest in angle, so |u| ≤ tan(π/32) and
// the Taylor series u (1 − u²/3 + u⁴/5 − …) truncated after u¹⁵/15 is exact to 5e-18 relative.
// The octant is restored by a sign and an offset from a table (no unpredictable branches); small
// angles in the first octant, the common case (most triangles subtend small solid angles), take a
// shortcut.
constexpr double kTanSector[5] = {0.0, 0x1.975f5e0553158p-3, 0x1.a827999fcef32p-2,
                                  0x1.561b82ab7f990p-1, 1.0};  // tan(kπ/16), rounded
constexpr double kAtanSector[5] = {0.0, 0.19634954084936207, 0.39269908169872414,
                                   0.5890486225480862, 0.7853981633974483};  // atan(kTanSector)
constexpr double kSectorBound[4] = {0.09849140335716425, 0.3033466836073424, 0.5345111359507916,
                                    0.8206787908286602};  // tan((2k + 1)π/32)
constexpr double kPi = std::numbers::pi, kHalfPi = 0.5 * std::numbers::pi;
// Bits: |y| > |x|, x < 0, y < 0.
constexpr double kOctantOffset[8] = {0.0, kHalfPi, kPi, kHalfPi, -0.0, -kHalfPi, -kPi, -kHalfPi};
constexpr double kOctantSign[8] = {1.0, -1.0, -1.0, 1.0, -1.0, 1.0, 1.0, -1.0};

// atan(u) − u for |u| ≤ tan(π/32).
inline double atanSeries(double u) {
  const double s = u * u;
  return u * s *
         (-1.0 / 3 +
          s * (1.0 / 5 + s * (-1.0 / 7 +
                              s * (1.0 / 9 + s * (-1.0 / 11 + s * (1.0 / 13 + s * (-1.0 / 15)))))));
}

inline double angle(double y, double x) {
  if (x > 0.0 && std::abs(y) <= kSectorBound[0] * x) {
    const double u = y / x;
    return u + atanSeries(u);
  }
  const double ax = std::abs(x), ay = std::abs(y);
  const double lo = std::min(ax, ay), hi = std::max(ax, ay);
  if (hi == 0.0) return 0.0;
  const int k =
      static_cast<int>(lo > kSectorBound[0] * hi) + static_cast<int>(lo > kSectorBound[1] * hi) +
      static_cast<int>(lo > kSectorBound[2] * hi) + static_cast<int>(lo > kSectorBound[3] * hi);
  const double tau = kTanSector[k];
  const double u = (lo - tau * hi) / (hi + tau * lo);
  const double a = kAtanSector[k] + (u + atanSeries(u));
  const int octant = static_cast<int>(ay > ax) | (static_cast<int>(x < 0.0) << 1) |
                     (static_cast<int>(y < 0.0) << 2);
  return kOctantOffset[octant] + kOctantSign[octant] * a;
}

// The nearest triangle found so far, with what the exterior and surface formulas need of it.
struct Nearest {
  double dist2 = kInf;
  double beta = -kInf;  // signed distance of x from the triangle's plane (outside positive)
  std::size_t face = 0;
  double bary[3] = {0.0, 0.0, 0.0};  // Γ_l(p), p the projection of x onto the plane
};

// Evaluates one point. Kept out of the class so the hot loops see plain data only.
class Evaluator {
 public:
  using Impl = detail::GreenData;

  Evaluator(const Impl& g, Scratch& s) : g_(g), s_(s) {
    s_.vertices.resize(g.vertices.size());
    s_.edges.resize(g.edges.size());
    s_.faces.resize(g.faces.size());
  }

  // Fills row (V + F entries) and returns where x is; the nearest triangle and the distance are
  // searched for only when needed (x outside or near the surface) or when `locate` is set.
  GreenCoordinates::Location run(const Vec3& x, double* row, bool locate) {
    const std::size_t nv = g_.vertices.size();
    for (std::size_t i = 0; i < nv; ++i) {
      VertexTerm& t = s_.vertices[i];
      t.r = g_.vertices[i] - x;
      t.length = std::sqrt(glm::dot(t.r, t.r));
    }
    double minEdgeDist2 = kInf;
    for (std::size_t e = 0; e < g_.edges.size(); ++e)
      minEdgeDist2 = std::min(minEdgeDist2, edgeTerm(e));

    double* phi = row;
    double* psi = row + nv;
    std::fill(phi, phi + nv, 0.0);
    bool nearPlane = false;
    const double omegaSum = faceLoop<false>(phi, psi, nearPlane);

    GreenCoordinates::Location loc;
    loc.windingNumber = omegaSum * kInv4Pi;
    const bool inside = loc.windingNumber > 0.5;
    // The distance to a triangle is that to its plane or to one of its edges, so x can only be
    // within the tolerance of the surface if it is of a plane or an edge.
    const bool maybeSurface = nearPlane || minEdgeDist2 <= g_.surfaceTolerance2;
    if (inside && !maybeSurface && !locate) {
      loc.region = GreenCoordinates::Region::Inside;
      return loc;
    }
    const Nearest nearest = findNearest();
    loc.triangle = nearest.face;
    loc.distance = std::sqrt(nearest.dist2);
    const Impl::Face& f = g_.faces[nearest.face];
    if (nearest.dist2 <= g_.surfaceTolerance2) {
      // Surface: principal value plus (1 − σ) times the hat values at the point.
      std::fill(phi, phi + nv, 0.0);
      const double sigma = faceLoop<true>(phi, psi, nearPlane) * kInv4Pi;
      loc.region = GreenCoordinates::Region::Surface;
      loc.windingNumber = sigma;
      for (int l = 0; l < 3; ++l) phi[f.vertex[l]] += (1.0 - sigma) * nearest.bary[l];
      return loc;
    }
    if (inside) {
      loc.region = GreenCoordinates::Region::Inside;
      return loc;
    }
    // Outside: continue the interior coordinates through the nearest triangle.
    loc.region = GreenCoordinates::Region::Outside;
    for (int l = 0; l < 3; ++l) phi[f.vertex[l]] += nearest.bary[l];
    psi[nearest.face] += nearest.beta;
    return loc;
  }

 private:
  // Fills the terms of edge `index`; returns the squared distance from x to the edge.
  double edgeTerm(std::size_t index) {
    const Impl::Edge& edge = g_.edges[index];
    const Vec3& e = edge.direction;
    const VertexTerm& a = s_.vertices[edge.a];
    const VertexTerm& b = s_.vertices[edge.b];
    EdgeTerm& out = s_.edges[index];
    const double ra = a.length, rb = b.length;
    const double ta = glm::dot(e, a.r);
    const double tb = glm::dot(e, b.r);
    // The perpendicular from x to the edge line, from the nearer end (its error is then relative
    // to that end's distance).
    const bool aNearer = ra <= rb;
    const Vec3 q = (aNearer ? a.r : b.r) - (aNearer ? ta : tb) * e;
    out.q = q;
    const double r02 = glm::dot(q, q);
    out.r02 = r02;
    // L: when the foot of x is before a (ta ≥ 0) every R + t is a sum of non-negatives; after b
    // (tb ≤ 0) R + t = R0² / (R − t) at both ends and R0² cancels; in between
    // R_a + t_a = R0² / (R_a − t_a), with R0² from the perpendicular itself.
    const bool before = ta >= 0.0, after = tb <= 0.0;
    const double num = before ? rb + tb : after ? ra - ta : (rb + tb) * (ra - ta);
    const double den = before ? ra + ta : after ? rb - tb : r02;
    out.dist2 = before ? ra * ra : after ? rb * rb : r02;
    // P and S as written are accurate unless r_a and r_b are far from each other's direction
    // (1 + cos < 1/2, which needs the foot inside the segment); then the cancellation-free forms.
    const double rarb = ra * rb;
    const double p = rarb + glm::dot(a.r, b.r);
    if (p >= 0.5 * rarb) {
      out.p = p;
      out.s = ra * b.r + rb * a.r;
      out.closeness = 2.0;
    } else {
      const double d1 = rarb - glm::dot(a.r, b.r);  // ≥ R_a R_b
      const double d2 = ra * tb - rb * ta;          // > 0
      const double inv = 1.0 / (d1 * d2);
      out.p = edge.length * edge.length * r02 * d2 * inv;
      const double k = r02 * edge.length * (ta + tb) * d1 * inv;
      // q made orthogonal to e to round-off in |q|: a residual along e would enter S·r_c
      // differently for the two triangles of the edge.
      out.s = (ra + rb) * (q - glm::dot(q, e) * e) + k * e;
      out.closeness = out.p / rarb;
    }
    const double log = std::log(num / den);
    // Not finite only for x on the segment: every triangle using the edge then touches x and is
    // a surface triangle, whose terms do not use L.
    out.log = std::isfinite(log) ? log : 0.0;
    return out.dist2;
  }

  // The squared distance from x to triangle f: to its plane if the projection p is inside it,
  // else to the nearest edge p is outside of (the nearest point is on such an edge).
  double faceDist2(const Impl::Face& f, double h, const double d[3]) const {
    const EdgeTerm* e[3] = {&s_.edges[f.edge[0]], &s_.edges[f.edge[1]], &s_.edges[f.edge[2]]};
    const double edgeDist2 =
        std::min(std::min(d[0] < 0.0 ? e[0]->dist2 : kInf, d[1] < 0.0 ? e[1]->dist2 : kInf),
                 d[2] < 0.0 ? e[2]->dist2 : kInf);
    return edgeDist2 == kInf ? h * h : edgeDist2;
  }

  // The triangle containing the point of the surface nearest to x; ties (the point is on an edge
  // or a vertex) go to the largest β (x farthest in front of the plane), then the lowest index.
  Nearest findNearest() const {
    Nearest nearest;
    for (std::size_t j = 0; j < g_.faces.size(); ++j) {
      const Impl::Face& f = g_.faces[j];
      const double h = s_.faces[j].h;
      const double* d = s_.faces[j].d;
      const double dist2 = faceDist2(f, h, d);
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

  // Adds every triangle's φ and ψ terms; returns the sum of the solid angles and sets nearPlane
  // if x is within the surface tolerance of some triangle's plane. In the surface pass the
  // triangles touching x (within the tolerance) contribute their principal value: no double layer
  // (Ω = 0, h = 0) and the single layer at h = 0.
  template <bool kSurface>
  double faceLoop(double* phi, double* psi, bool& nearPlane) const {
    double omegaSum = 0.0;
    const double tol2 = g_.surfaceTolerance2;
    for (std::size_t j = 0; j < g_.faces.size(); ++j) {
      const Impl::Face& f = g_.faces[j];
      const VertexTerm* v[3] = {&s_.vertices[f.vertex[0]], &s_.vertices[f.vertex[1]],
                                &s_.vertices[f.vertex[2]]};
      const EdgeTerm* e[3] = {&s_.edges[f.edge[0]], &s_.edges[f.edge[1]], &s_.edges[f.edge[2]]};
      double h = glm::dot(f.normal, v[0]->r);
      const double d[3] = {glm::dot(f.edgeNormal[0], v[0]->r), glm::dot(f.edgeNormal[1], v[1]->r),
                           glm::dot(f.edgeNormal[2], v[2]->r)};
      const double lg[3] = {e[0]->log, e[1]->log, e[2]->log};
      if constexpr (!kSurface) s_.faces[j] = {h, {d[0], d[1], d[2]}};

      double omega;
      if (kSurface && faceDist2(f, h, d) <= tol2) {
        omega = 0.0;
        h = 0.0;
      } else {
        if constexpr (!kSurface) nearPlane |= h * h <= tol2;
        int i = e[1]->closeness < e[0]->closeness ? 1 : 0;
        if (e[2]->closeness < e[i]->closeness) i = 2;
        const EdgeTerm& et = *e[i];
        const VertexTerm& c = *v[kOpposite[i]];
        // det(r_a, r_b, r_c) = 2A h with h = n·q = n·r_c, from the shorter vector (its error is
        // relative to its length): q close to the edge, r_c close to the opposite corner.
        const Vec3& toPlane = et.r02 <= c.length * c.length ? et.q : c.r;
        const double num = f.twiceArea * glm::dot(f.normal, toPlane);
        const double den = c.length * et.p + glm::dot(et.s, c.r);
        omega = 2.0 * angle(num, den);
      }
      omegaSum += omega;

      // The three corners' terms add up to Ω / 4π (Σ Γ_l = 1, Σ_l g_l = 0): the third is the rest.
      const double w = kInv4Pi * omega, hw = kInv4Pi * h;
      psi[j] = kInv4Pi * (d[0] * lg[0] + d[1] * lg[1] + d[2] * lg[2]) - hw * omega;
      const double* c0 = f.gradDotEdge[0];
      const double* c1 = f.gradDotEdge[1];
      const double phi0 =
          d[1] * f.edgeFactor[1] * w - hw * (c0[0] * lg[0] + c0[1] * lg[1] + c0[2] * lg[2]);
      const double phi1 =
          d[2] * f.edgeFactor[2] * w - hw * (c1[0] * lg[0] + c1[1] * lg[1] + c1[2] * lg[2]);
      phi[f.vertex[0]] += phi0;
      phi[f.vertex[1]] += phi1;
      phi[f.vertex[2]] += w - phi0 - phi1;
    }
    return omegaSum;
  }

  const Impl& g_;
  Scratch& s_;
};

}  // namespace

GreenCoordinates::GreenCoordinates(std::shared_ptr<const Cage> cage, GreenOptions options)
    : cage_(std::move(cage)), options_(options) {
  if (!cage_) throw InvalidInput("GreenCoordinates: the cage is null");
  if (!std::isfinite(options_.surfaceTolerance) || options_.surfaceTolerance < 0.0) {
    throw InvalidInput("GreenCoordinates: surfaceTolerance must be finite and non-negative, not " +
                       std::to_string(options_.surfaceTolerance));
  }
  auto impl = std::make_unique<Impl>();
  const std::span<const Vec3> v = cage_->vertices();
  const std::span<const Triangle> tris = cage_->triangles();
  impl->vertices.assign(v.begin(), v.end());
  const double tol = options_.surfaceTolerance * cage_->diagonal();
  impl->surfaceTolerance2 = tol * tol;

  std::map<std::pair<std::uint32_t, std::uint32_t>, std::uint32_t> edgeIndex;
  impl->faces.resize(tris.size());
  impl->frames.resize(tris.size());
  for (std::size_t j = 0; j < tris.size(); ++j) {
    detail::GreenData::Face& f = impl->faces[j];
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
      auto [it, inserted] =
          edgeIndex.try_emplace(key, static_cast<std::uint32_t>(impl->edges.size()));
      if (inserted) {
        const Vec3 ab = v[key.second] - v[key.first];
        impl->edges.push_back({key.first, key.second, ab / glm::length(ab), glm::length(ab)});
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
    impl->frames[j] = {glm::dot(u, u), glm::dot(w, w), glm::dot(u, w),
                       std::sqrt(8.0) * 0.5 * twiceArea};
  }
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
  thread_local Scratch scratch;
  Evaluator(*impl_, scratch).run(x, row.data(), false);
}

void GreenCoordinates::weightsBatch(std::span<const Vec3> points, std::span<double> rows) const {
  const std::size_t m = columnCount();
  if (rows.size() != points.size() * m) {
    throw InvalidInput("GreenCoordinates: " + std::to_string(points.size()) + " points need " +
                       std::to_string(points.size() * m) + " weights but the output has " +
                       std::to_string(rows.size()));
  }
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (!isFinite(points[i]))
      throw InvalidInput("GreenCoordinates: point " + std::to_string(i) + " is not finite");
  }
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, points.size(), 16),
                    [&](const tbb::blocked_range<std::size_t>& r) {
                      Scratch scratch;
                      Evaluator evaluator(*impl_, scratch);
                      for (std::size_t i = r.begin(); i != r.end(); ++i)
                        evaluator.run(points[i], rows.data() + i * m, false);
                    });
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
  thread_local Scratch scratch;
  thread_local std::vector<double> row;
  row.resize(columnCount());
  return Evaluator(*impl_, scratch).run(x, row.data(), true);
}

}  // namespace spacewarp
