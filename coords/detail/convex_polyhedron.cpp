#include <spacewarp/coords/detail/convex_polyhedron.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <numbers>
#include <numeric>
#include <unordered_map>
#include <utility>

#include <spacewarp/core/errors.h>

namespace spacewarp::detail {

namespace {

std::uint64_t edgeKey(std::uint32_t from, std::uint32_t to) {
  return (std::uint64_t{from} << 32) | to;
}

std::string vertexList(std::span<const std::uint32_t> face) {
  std::string text;
  for (std::uint32_t v : face) text += (text.empty() ? "" : ", ") + std::to_string(v);
  return text;
}

std::uint32_t findRoot(std::vector<std::uint32_t>& parent, std::uint32_t f) {
  while (parent[f] != f) f = parent[f] = parent[parent[f]];
  return f;
}

// Outward unit normal (Newell) and offset of one input polygon; throws if it is not planar.
struct Plane {
  Vec3 normal{0.0};
  double offset = 0.0;
  double area = 0.0;
};

Plane polygonPlane(std::span<const Vec3> p, std::span<const std::uint32_t> face, double tol,
                   const std::string& prefix, std::size_t f) {
  Vec3 newell(0.0);
  for (std::size_t j = 0; j < face.size(); ++j)
    newell += glm::cross(p[face[j]], p[face[(j + 1) % face.size()]]);
  Plane plane;
  plane.area = 0.5 * glm::length(newell);
  plane.normal = newell / (2.0 * plane.area);
  for (std::uint32_t v : face) plane.offset += glm::dot(plane.normal, p[v]);
  plane.offset /= static_cast<double>(face.size());
  for (std::uint32_t v : face) {
    const double off = std::fabs(glm::dot(plane.normal, p[v]) - plane.offset);
    if (off > tol) {
      char text[160];
      std::snprintf(text, sizeof text, " is not planar (vertex %u is %.3g from its plane)", v, off);
      throw InvalidInput(prefix + "face " + std::to_string(f) + " (vertices " + vertexList(face) +
                         ")" + text +
                         ", so the cage is not convex in some triangulation of that face");
    }
  }
  return plane;
}

// Whether the corners lie on one circle (then 2D discrete harmonic = 2D Wachspress coordinates).
bool onOneCircle(std::span<const Vec3> p, const std::vector<std::uint32_t>& loop, double tol) {
  if (loop.size() == 3) return true;
  const Vec3 a = p[loop[0]], u = p[loop[1]] - a, w = p[loop[2]] - a;
  const Vec3 n = glm::cross(u, w);
  const Vec3 centre = a + (glm::dot(u, u) * glm::cross(w, n) + glm::dot(w, w) * glm::cross(n, u)) /
                              (2.0 * glm::dot(n, n));
  const double radius = glm::length(a - centre);
  return std::all_of(loop.begin(), loop.end(), [&](std::uint32_t v) {
    return std::fabs(glm::length(p[v] - centre) - radius) <= tol;
  });
}

// Signed area of (y, a, b) in the plane of normal n.
double area(const Vec3& n, const Vec3& qa, const Vec3& qb) {
  return 0.5 * glm::dot(n, glm::cross(qa, qb));
}

}  // namespace

ConvexPolyhedron buildConvexPolyhedron(const Cage& cage, const char* method) {
  const std::string prefix = std::string(method) + ": " + cage.name() + ": ";
  const std::span<const Vec3> p = cage.vertices();
  const double tol = kConvexTolerance * cage.diagonal();
  const std::size_t nF = cage.faceCount(), nV = cage.vertexCount();

  std::vector<Plane> planes(nF);
  std::unordered_map<std::uint64_t, std::uint32_t> edgeFace;  // directed edge -> face
  for (std::size_t f = 0; f < nF; ++f) {
    const auto face = cage.face(f);
    planes[f] = polygonPlane(p, face, tol, prefix, f);
    for (std::size_t j = 0; j < face.size(); ++j)
      edgeFace[edgeKey(face[j], face[(j + 1) % face.size()])] = static_cast<std::uint32_t>(f);
  }

  // Every edge between two faces turns outward or is flat (then the faces merge).
  std::vector<std::uint32_t> parent(nF);
  std::iota(parent.begin(), parent.end(), 0u);
  for (std::size_t f = 0; f < nF; ++f) {
    const auto face = cage.face(f);
    for (std::size_t j = 0; j < face.size(); ++j) {
      const std::uint32_t a = face[j], b = face[(j + 1) % face.size()];
      const std::uint32_t g = edgeFace.at(edgeKey(b, a));
      if (a > b || g == f) continue;  // each edge once
      // sin of the turn from F to G about a → b: positive outward, 0 where they are coplanar.
      const double turn =
          glm::dot(glm::cross(planes[f].normal, planes[g].normal), glm::normalize(p[b] - p[a]));
      const bool flat = std::fabs(turn) <= kConvexTolerance;
      if (turn < -kConvexTolerance || (flat && glm::dot(planes[f].normal, planes[g].normal) < 0)) {
        char text[96];
        std::snprintf(text, sizeof text, " (turning inward by %.3g degrees)",
                      std::atan2(-turn, glm::dot(planes[f].normal, planes[g].normal)) * 180.0 /
                          std::numbers::pi);
        throw InvalidInput(prefix + "the cage is not convex: the edge between vertices " +
                           std::to_string(a) + " and " + std::to_string(b) + " (faces " +
                           std::to_string(f) + " and " + std::to_string(g) + ") is reflex" + text);
      }
      if (flat) parent[findRoot(parent, g)] = findRoot(parent, f);
    }
  }

  // One face per coplanar group, its corners the boundary of the group.
  ConvexPolyhedron poly;
  poly.vertices.assign(p.begin(), p.end());
  poly.diagonal = cage.diagonal();
  std::vector<std::uint32_t> groupOf(nF, 0), groupIndex(nF, UINT32_MAX);
  for (std::size_t f = 0; f < nF; ++f) {
    const std::uint32_t root = findRoot(parent, static_cast<std::uint32_t>(f));
    if (groupIndex[root] == UINT32_MAX) {
      groupIndex[root] = static_cast<std::uint32_t>(poly.faces.size());
      poly.faces.emplace_back();
    }
    groupOf[f] = groupIndex[root];
    poly.faces[groupOf[f]].source.push_back(static_cast<std::uint32_t>(f));
  }
  for (std::size_t g = 0; g < poly.faces.size(); ++g) {
    ConvexPolyhedron::Face& face = poly.faces[g];
    Vec3 weighted(0.0);
    std::unordered_map<std::uint32_t, std::uint32_t> next;  // boundary edges
    for (std::uint32_t f : face.source) {
      weighted += planes[f].area * planes[f].normal;
      face.area += planes[f].area;
      const auto corners = cage.face(f);
      for (std::size_t j = 0; j < corners.size(); ++j) {
        const std::uint32_t a = corners[j], b = corners[(j + 1) % corners.size()];
        if (groupOf[edgeFace.at(edgeKey(b, a))] == g) continue;
        if (!next.emplace(a, b).second) {
          throw InvalidInput(prefix + "the cage is not convex: vertex " + std::to_string(a) +
                             " touches the flat region of face " + std::to_string(f) + " twice");
        }
      }
    }
    face.normal = glm::normalize(weighted);
    std::uint32_t v = cage.face(face.source[0])[0];
    for (std::uint32_t c : cage.face(face.source[0])) {
      if (next.count(c)) {
        v = c;
        break;
      }
    }
    for (std::size_t steps = 0; steps < next.size(); ++steps) {
      face.loop.push_back(v);
      const auto it = next.find(v);
      if (it == next.end()) break;
      v = it->second;
    }
    if (face.loop.size() != next.size() || v != face.loop[0]) {
      throw InvalidInput(prefix + "the coplanar faces around face " +
                         std::to_string(face.source[0]) + " do not form one polygon");
    }
    for (std::uint32_t c : face.loop) face.offset += glm::dot(face.normal, p[c]);
    face.offset /= static_cast<double>(face.loop.size());
    for (std::uint32_t f : face.source) {
      for (std::uint32_t c : cage.face(f)) {
        if (std::fabs(glm::dot(face.normal, p[c]) - face.offset) > tol) {
          throw InvalidInput(prefix + "faces " + vertexList(face.source) +
                             " are almost but not exactly coplanar (at vertex " +
                             std::to_string(c) + "), so the cage is not convex");
        }
      }
    }
    const std::size_t m = face.loop.size();
    for (std::size_t j = 0; j < m; ++j) {
      const Vec3 a = p[face.loop[(j + m - 1) % m]], b = p[face.loop[j]],
                 c = p[face.loop[(j + 1) % m]];
      face.cornerArea.push_back(area(face.normal, a - b, c - b) * -1.0);
    }
    face.cyclic = onOneCircle(p, face.loop, tol);
  }

  // The faces around every vertex, counter-clockwise from outside: after face F (…, u, v, …) comes
  // the face of the edge v → u.
  std::vector<std::uint32_t> incident(nV, 0);
  for (std::uint32_t v : cage.faceIndices()) ++incident[v];
  poly.ringOffsets.assign(1, 0);
  std::vector<std::uint32_t> firstFace(nV, UINT32_MAX);
  for (std::size_t f = nF; f-- > 0;)
    for (std::uint32_t v : cage.face(f)) firstFace[v] = static_cast<std::uint32_t>(f);
  for (std::uint32_t v = 0; v < nV; ++v) {
    std::vector<std::uint32_t> groups;
    std::uint32_t f = firstFace[v];
    std::size_t visited = 0;
    do {
      const auto face = cage.face(f);
      const std::size_t j =
          static_cast<std::size_t>(std::find(face.begin(), face.end(), v) - face.begin());
      const std::uint32_t u = face[(j + face.size() - 1) % face.size()];
      if (groups.empty() || groups.back() != groupOf[f]) groups.push_back(groupOf[f]);
      f = edgeFace.at(edgeKey(v, u));
      ++visited;
    } while (f != firstFace[v] && visited <= incident[v]);
    if (visited != incident[v]) {
      throw InvalidInput(prefix + "the surface is not a disk around vertex " + std::to_string(v));
    }
    if (groups.size() > 1 && groups.back() == groups.front()) groups.pop_back();
    std::vector<std::uint32_t> sorted = groups;
    std::sort(sorted.begin(), sorted.end());
    if (std::adjacent_find(sorted.begin(), sorted.end()) != sorted.end()) {
      throw InvalidInput(prefix + "the cage is not convex: its faces wind around vertex " +
                         std::to_string(v) + " more than once");
    }
    if (groups.size() < 3) {
      throw InvalidInput(prefix + "vertex " + std::to_string(v) +
                         " is not a corner of the polyhedron: its faces lie in " +
                         std::to_string(groups.size()) +
                         (groups.size() == 1 ? " plane" : " planes") +
                         " (remove it, or move it out of the plane(s))");
    }
    poly.ring.insert(poly.ring.end(), groups.begin(), groups.end());
    poly.ringOffsets.push_back(static_cast<std::uint32_t>(poly.ring.size()));
  }

  // Locally convex everywhere; a supporting plane per face makes it globally so.
  for (std::size_t g = 0; g < poly.faces.size(); ++g) {
    const ConvexPolyhedron::Face& face = poly.faces[g];
    for (std::uint32_t v = 0; v < nV; ++v) {
      if (glm::dot(face.normal, p[v]) - face.offset > tol) {
        throw InvalidInput(prefix + "the cage is not convex: vertex " + std::to_string(v) +
                           " lies outside the plane of face " + std::to_string(face.source[0]));
      }
    }
    for (std::size_t j = 0; j < face.loop.size(); ++j) {
      if (!(face.cornerArea[j] > 0.0)) {
        throw InvalidInput(prefix + "the cage is not convex: face " +
                           std::to_string(face.source[0]) + " has a reflex corner at vertex " +
                           std::to_string(face.loop[j]));
      }
    }
  }
  return poly;
}

// Product form of the 2D coordinates (so that points on an edge line need no division by 0):
// corner j gets N_j = c_j Π_{k ∉ {j−1, j}} A_k with A_k = area(y, v_k, v_{k+1}) and
//   Wachspress:          c_j = area(v_{j−1}, v_j, v_{j+1}),
//   discrete harmonic:   c_j = r²_{j+1} A_{j−1} − r²_j B_j + r²_{j−1} A_j,  B_j = area(y, v_{j−1},
//                        v_{j+1}), r_k = |v_k − y|
// (Floater's three-point family, p = 0 and p = 2), divided by their sum. Both coincide on a
// polygon whose corners lie on a circle, where the Wachspress form is used: its sum does not
// vanish on the rectangle's lines where the discrete harmonic form's does (removably). Lengths are
// scaled by the face's √area so that the products of m − 2 areas stay representable.
bool faceCoordinates(const ConvexPolyhedron::Face& face, std::span<const Vec3> vertices,
                     const Vec3& y, FaceCoordinates kind, std::span<double> out) {
  const std::size_t m = face.loop.size();
  const double scale = 1.0 / std::sqrt(face.area);
  thread_local std::vector<Vec3> q;
  thread_local std::vector<double> a, prefix;
  q.resize(m);
  a.resize(m);
  prefix.resize(m + 1);
  for (std::size_t j = 0; j < m; ++j) {
    q[j] = (vertices[face.loop[j]] - y) * scale;
    if (q[j] == Vec3(0.0)) {  // at a corner every product vanishes (the 0/0 of Lagrange)
      std::fill(out.begin(), out.end(), 0.0);
      out[j] = 1.0;
      return true;
    }
  }
  for (std::size_t j = 0; j < m; ++j) a[j] = area(face.normal, q[j], q[(j + 1) % m]);
  prefix[0] = 1.0;
  for (std::size_t j = 0; j < m; ++j) prefix[j + 1] = prefix[j] * a[j];
  const bool harmonic = kind == FaceCoordinates::DiscreteHarmonic && !face.cyclic;
  double sum = 0.0, suffix = 1.0;  // suffix = Π_{k > j} A_k
  for (std::size_t j = m; j-- > 0;) {
    double others;  // Π over k ∉ {j−1, j}
    if (j == 0) {
      others = 1.0;
      for (std::size_t k = 1; k + 1 < m; ++k) others *= a[k];
    } else {
      others = prefix[j - 1] * suffix;
    }
    const std::size_t prev = (j + m - 1) % m, next = (j + 1) % m;
    double c = face.cornerArea[j] * scale * scale;
    if (harmonic) {
      const double b = area(face.normal, q[prev], q[next]);
      c = glm::dot(q[next], q[next]) * a[prev] - glm::dot(q[j], q[j]) * b +
          glm::dot(q[prev], q[prev]) * a[j];
    }
    out[j] = c * others;
    sum += out[j];
    suffix *= a[j];
  }
  if (!(std::isfinite(sum) && sum != 0.0)) return false;
  for (std::size_t j = 0; j < m; ++j) out[j] /= sum;
  return true;
}

SurfacePoint nearestSurfacePoint(const ConvexPolyhedron& poly, const Vec3& x) {
  SurfacePoint best;
  best.distance = std::numeric_limits<double>::infinity();
  const std::span<const Vec3> p = poly.vertices;
  for (std::size_t g = 0; g < poly.faces.size(); ++g) {
    const ConvexPolyhedron::Face& face = poly.faces[g];
    const double h = glm::dot(face.normal, x) - face.offset;
    if (std::fabs(h) >= best.distance) continue;  // the face is no nearer than its plane
    const Vec3 y = x - h * face.normal;
    const std::size_t m = face.loop.size();
    bool inside = true;
    for (std::size_t j = 0; j < m && inside; ++j)
      inside = area(face.normal, p[face.loop[j]] - y, p[face.loop[(j + 1) % m]] - y) >= 0.0;
    if (inside) {
      best = {g, y, std::fabs(h)};
      continue;
    }
    for (std::size_t j = 0; j < m; ++j) {
      const Vec3 a = p[face.loop[j]], e = p[face.loop[(j + 1) % m]] - a;
      const double t = std::clamp(glm::dot(x - a, e) / glm::dot(e, e), 0.0, 1.0);
      const Vec3 z = a + t * e;
      const double d = glm::length(x - z);
      if (d < best.distance) best = {g, z, d};
    }
  }
  return best;
}

bool convexRow(const ConvexPolyhedron& poly, const Vec3& x, double snapLength,
               ConvexOutsidePolicy policy, FaceCoordinates kind, InteriorRow interior,
               const void* data, std::span<double> row) {
  thread_local std::vector<double> heights;
  heights.resize(poly.faces.size());
  double lowest = std::numeric_limits<double>::infinity();
  for (std::size_t g = 0; g < poly.faces.size(); ++g) {
    heights[g] = poly.faces[g].offset - glm::dot(poly.faces[g].normal, x);
    lowest = std::min(lowest, heights[g]);
  }
  if (lowest > snapLength) {
    interior(data, poly, x, heights, row);
    return true;
  }
  const SurfacePoint s = nearestSurfacePoint(poly, x);
  if (lowest < 0.0 && s.distance > snapLength && policy == ConvexOutsidePolicy::Throw) return false;
  const ConvexPolyhedron::Face& face = poly.faces[s.face];
  thread_local std::vector<double> local;
  local.resize(face.loop.size());
  if (!faceCoordinates(face, poly.vertices, s.point, kind, local))
    throw SolverError("convex cage coordinates: no surface coordinates at " + pointText(s.point));
  std::fill(row.begin(), row.end(), 0.0);
  for (std::size_t j = 0; j < face.loop.size(); ++j) row[face.loop[j]] = local[j];
  return true;
}

std::string pointText(const Vec3& x) {
  char text[96];
  std::snprintf(text, sizeof text, "(%.17g, %.17g, %.17g)", x.x, x.y, x.z);
  return text;
}

std::string outsideMessage(const char* method, std::size_t count, std::size_t total,
                           std::size_t first, const Vec3& x) {
  return std::string(method) + ": " + std::to_string(count) + " of " + std::to_string(total) +
         " points are outside the convex cage (the first is point " + std::to_string(first) +
         " at " + pointText(x) +
         "); ConvexOutsidePolicy::NearestPoint gives them the coordinates " +
         "of the nearest surface point";
}

void checkSnapTolerance(const char* method, double snapTolerance) {
  if (!(snapTolerance >= 0.0 && snapTolerance <= 1e-3)) {
    throw InvalidInput(std::string(method) + ": snapTolerance must be in [0, 1e-3], got " +
                       std::to_string(snapTolerance));
  }
}

}  // namespace spacewarp::detail
