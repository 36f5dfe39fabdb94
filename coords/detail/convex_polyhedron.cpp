#include <spacewarp/coords/detail/convex_polyhedron.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <numbers>
#include <numeric>
#include <unordered_map>
#include <utility>

#include <spacewarp/coords/detail/outside_hint.h>
#include <spacewarp/core/errors.h>

namespace spacewarp::detail {

namespace {

std::uint64_t edgeKey(std::uint32_t from, std::uint32_t to) {
  return (std::uint64_t{from} << 32) | to;
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
                   double diagonal, const std::string& prefix, std::size_t f) {
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
      char text[192];
      std::snprintf(text, sizeof text,
                    " is not planar: vertex %u is %.3g cage diagonals from its best-fit plane, "
                    "more than planarity = %.3g",
                    v, off / diagonal, tol / diagonal);
      throw InvalidInput(prefix + "face " + std::to_string(f) + " (vertices " + vertexList(face) +
                         ")" + text + " (a larger planarity option accepts it)");
    }
  }
  return plane;
}

// Signed area of (y, a, b) in the plane of normal n.
double area(const Vec3& n, const Vec3& qa, const Vec3& qb) {
  return 0.5 * glm::dot(n, glm::cross(qa, qb));
}

// The steps of buildConvexPolyhedron(), over one cage.
class Builder {
 public:
  Builder(const Cage& cage, const char* method, double planarity)
      : cage_(cage),
        p_(relativeVertices(cage)),
        prefix_(std::string(method) + ": " + cage.name() + ": "),
        planarity_(planarity),
        tol_(planarity * cage.diagonal()),
        planes_(cage.faceCount()),
        firstFace_(cage.vertexCount(), 0),
        incident_(cage.vertexCount(), 0) {
    for (std::size_t f = cage.faceCount(); f-- > 0;) {
      const auto face = cage.face(f);
      planes_[f] = polygonPlane(p_, face, tol_, cage.diagonal(), prefix_, f);
      for (std::uint32_t v : face) {
        firstFace_[v] = static_cast<std::uint32_t>(f);
        ++incident_[v];
      }
      for (std::size_t j = 0; j < face.size(); ++j)
        edgeFace_[edgeKey(face[j], face[(j + 1) % face.size()])] = static_cast<std::uint32_t>(f);
    }
  }

  ConvexPolyhedron build() {
    ConvexPolyhedron poly;
    poly.vertices.assign(cage_.vertices().begin(), cage_.vertices().end());
    poly.diagonal = cage_.diagonal();
    groupFaces(poly);
    for (std::size_t g = 0; g < poly.faces.size(); ++g) mergeFace(poly.faces[g], g);
    poly.ringOffsets.assign(1, 0);
    for (std::uint32_t v = 0; v < cage_.vertexCount(); ++v) {
      const std::vector<std::uint32_t> ring = vertexRing(v);
      poly.ring.insert(poly.ring.end(), ring.begin(), ring.end());
      poly.ringOffsets.push_back(static_cast<std::uint32_t>(poly.ring.size()));
    }
    for (const ConvexPolyhedron::Face& face : poly.faces) {
      checkSupporting(face);
      for (std::uint32_t f : face.source)
        for (std::uint32_t c : cage_.face(f))
          poly.flatness =
              std::max(poly.flatness, std::fabs(glm::dot(face.normal, p_[c]) - face.offset));
    }
    const Vec3 center = cage_.frame().center;
    for (ConvexPolyhedron::Face& face : poly.faces) face.offset += glm::dot(face.normal, center);
    return poly;
  }

 private:
  std::uint32_t faceOfEdge(std::uint32_t from, std::uint32_t to) const {
    return edgeFace_.at(edgeKey(from, to));
  }

  // Every edge between two faces turns outward or is flat; flat edges join their faces' groups.
  void groupFaces(ConvexPolyhedron& poly) {
    const std::size_t nF = cage_.faceCount();
    std::vector<std::uint32_t> parent(nF);
    std::iota(parent.begin(), parent.end(), 0u);
    for (std::size_t f = 0; f < nF; ++f) {
      const auto face = cage_.face(f);
      for (std::size_t j = 0; j < face.size(); ++j) {
        const std::uint32_t a = face[j], b = face[(j + 1) % face.size()], g = faceOfEdge(b, a);
        if (a > b || g == f) continue;  // each edge once
        if (edgeIsFlat(f, g, a, b)) parent[findRoot(parent, g)] = findRoot(parent, f);
      }
    }
    groupOf_.assign(nF, 0);
    std::vector<std::uint32_t> groupIndex(nF, UINT32_MAX);
    for (std::size_t f = 0; f < nF; ++f) {
      const std::uint32_t root = findRoot(parent, static_cast<std::uint32_t>(f));
      if (groupIndex[root] == UINT32_MAX) {
        groupIndex[root] = static_cast<std::uint32_t>(poly.faces.size());
        poly.faces.emplace_back();
      }
      groupOf_[f] = groupIndex[root];
      poly.faces[groupOf_[f]].source.push_back(static_cast<std::uint32_t>(f));
    }
  }

  // Whether faces f and g (edge a → b in f) are coplanar: turning by θ about the edge lifts a
  // corner at distance d from the edge line by d |sin θ| off the other face's plane, the distance
  // a single polygon's corners are judged by, so a face and its triangulation get the same
  // answer. Flat when that is within the planarity distance for the faces' widest corner; throws
  // if the edge turns inward by more, or the faces fold back onto each other.
  bool edgeIsFlat(std::size_t f, std::size_t g, std::uint32_t a, std::uint32_t b) const {
    const Vec3 nf = planes_[f].normal, ng = planes_[g].normal, e = glm::normalize(p_[b] - p_[a]);
    const double theta = std::atan2(glm::dot(glm::cross(nf, ng), e), glm::dot(nf, ng));
    double width = 0.0;  // the distance of the faces' farthest corner from the edge line
    for (std::size_t h : {f, g}) {
      for (std::uint32_t c : cage_.face(h)) {
        const Vec3 d = p_[c] - p_[a];
        width = std::max(width, glm::length(d - glm::dot(d, e) * e));
      }
    }
    const double lift = width * std::fabs(std::sin(theta));
    const bool sharp = std::fabs(theta) > 0.5 * std::numbers::pi;
    const bool folded = sharp && lift <= tol_, flat = !sharp && lift <= tol_;
    if (folded || (theta < 0.0 && !flat)) {
      char text[224];
      const double degrees = std::fabs(theta) * 180.0 / std::numbers::pi;
      if (folded) {
        std::snprintf(text, sizeof text, " folds back onto itself (turning by %.4g degrees)",
                      degrees);
      } else {
        std::snprintf(text, sizeof text,
                      " is reflex (turning inward by %.3g degrees, which lifts a corner %.3g cage "
                      "diagonals off the other face's plane, more than planarity = %.3g)",
                      degrees, (sharp ? width : lift) / cage_.diagonal(), planarity_);
      }
      throw InvalidInput(prefix_ + "the cage is not convex: the edge between vertices " +
                         std::to_string(a) + " and " + std::to_string(b) + " (faces " +
                         std::to_string(f) + " and " + std::to_string(g) + ")" + text);
    }
    return flat;
  }

  // Face g of the polyhedron: its plane and area from its cage faces, its corners the boundary
  // of their union (which must be one loop, in one plane).
  void mergeFace(ConvexPolyhedron::Face& face, std::size_t g) const {
    Vec3 weighted(0.0);
    std::unordered_map<std::uint32_t, std::uint32_t> next;  // boundary edges
    for (std::uint32_t f : face.source) {
      weighted += planes_[f].area * planes_[f].normal;
      face.area += planes_[f].area;
      const auto corners = cage_.face(f);
      for (std::size_t j = 0; j < corners.size(); ++j) {
        const std::uint32_t a = corners[j], b = corners[(j + 1) % corners.size()];
        if (groupOf_[faceOfEdge(b, a)] == g) continue;
        if (!next.emplace(a, b).second) {
          throw InvalidInput(prefix_ + "the cage is not convex: vertex " + std::to_string(a) +
                             " touches the flat region of face " + std::to_string(f) + " twice");
        }
      }
    }
    face.normal = glm::normalize(weighted);
    const auto first = cage_.face(face.source[0]);
    std::uint32_t v = *std::find_if(first.begin(), first.end(),
                                    [&](std::uint32_t c) { return next.count(c) > 0; });
    for (std::size_t steps = 0; steps < next.size(); ++steps) {
      face.loop.push_back(v);
      const auto it = next.find(v);
      if (it == next.end()) break;
      v = it->second;
    }
    if (face.loop.size() != next.size() || v != face.loop[0]) {
      throw InvalidInput(prefix_ + "the coplanar faces around face " +
                         std::to_string(face.source[0]) + " do not form one polygon");
    }
    for (std::uint32_t c : face.loop) face.offset += glm::dot(face.normal, p_[c]);
    face.offset /= static_cast<double>(face.loop.size());
    for (std::uint32_t f : face.source) {
      for (std::uint32_t c : cage_.face(f)) {
        if (std::fabs(glm::dot(face.normal, p_[c]) - face.offset) > tol_) {
          throw InvalidInput(prefix_ + "faces " + vertexList(face.source) +
                             " are almost but not exactly coplanar (at vertex " +
                             std::to_string(c) + "), so the cage is not convex");
        }
      }
    }
    const std::size_t m = face.loop.size();
    for (std::size_t j = 0; j < m; ++j) {
      const Vec3 a = p_[face.loop[(j + m - 1) % m]], b = p_[face.loop[j]],
                 c = p_[face.loop[(j + 1) % m]];
      face.cornerArea.push_back(area(face.normal, c - b, a - b));
    }
  }

  // The polyhedron's faces around vertex v, counter-clockwise from outside: after cage face
  // (…, u, v, …) comes the face of the edge v → u. Throws unless v is a corner.
  std::vector<std::uint32_t> vertexRing(std::uint32_t v) const {
    const std::size_t first = firstFace_[v], incident = incident_[v];
    std::vector<std::uint32_t> groups;
    std::size_t f = first, visited = 0;
    do {
      const auto face = cage_.face(f);
      const auto j =
          static_cast<std::size_t>(std::find(face.begin(), face.end(), v) - face.begin());
      if (groups.empty() || groups.back() != groupOf_[f]) groups.push_back(groupOf_[f]);
      f = faceOfEdge(v, face[(j + face.size() - 1) % face.size()]);
      ++visited;
    } while (f != first && visited <= incident);
    if (visited != incident) {
      throw InvalidInput(prefix_ + "the surface is not a disk around vertex " + std::to_string(v));
    }
    if (groups.size() > 1 && groups.back() == groups.front()) groups.pop_back();
    std::vector<std::uint32_t> sorted = groups;
    std::sort(sorted.begin(), sorted.end());
    if (std::adjacent_find(sorted.begin(), sorted.end()) != sorted.end()) {
      throw InvalidInput(prefix_ + "the cage is not convex: its faces wind around vertex " +
                         std::to_string(v) + " more than once");
    }
    if (groups.size() < 3) {
      throw InvalidInput(prefix_ + "vertex " + std::to_string(v) +
                         " is not a corner of the polyhedron: its faces lie in " +
                         std::to_string(groups.size()) +
                         (groups.size() == 1 ? " plane" : " planes") +
                         " (remove it, or move it out of the plane(s))");
    }
    return groups;
  }

  // Locally convex everywhere; a supporting plane per face and convex faces make it globally so.
  void checkSupporting(const ConvexPolyhedron::Face& face) const {
    for (std::uint32_t v = 0; v < p_.size(); ++v) {
      if (glm::dot(face.normal, p_[v]) - face.offset > tol_) {
        throw InvalidInput(prefix_ + "the cage is not convex: vertex " + std::to_string(v) +
                           " lies outside the plane of face " + std::to_string(face.source[0]));
      }
    }
    for (std::size_t j = 0; j < face.loop.size(); ++j) {
      if (!(face.cornerArea[j] > 0.0)) {
        throw InvalidInput(prefix_ + "the cage is not convex: face " +
                           std::to_string(face.source[0]) + " has a " +
                           (face.loop.size() == 3 ? "degenerate" : "reflex") +
                           " corner at vertex " + std::to_string(face.loop[j]));
      }
    }
  }

  // The vertices relative to the cage frame's center, so that the checks' cross products and
  // plane offsets lose nothing to a cage far from the origin (world coordinates of 1e8 would
  // round the Newell normal of a unit triangle to noise).
  static std::vector<Vec3> relativeVertices(const Cage& cage) {
    std::vector<Vec3> p(cage.vertices().begin(), cage.vertices().end());
    for (Vec3& v : p) v -= cage.frame().center;
    return p;
  }

  const Cage& cage_;
  std::vector<Vec3> p_;  // cage-relative (see relativeVertices)
  std::string prefix_;
  double planarity_, tol_;
  std::vector<Plane> planes_;
  std::unordered_map<std::uint64_t, std::uint32_t> edgeFace_;  // directed edge -> cage face
  std::vector<std::uint32_t> firstFace_, incident_;  // per vertex: its first face, how many
  std::vector<std::uint32_t> groupOf_;               // cage face -> polyhedron face
};

}  // namespace

ConvexPolyhedron buildConvexPolyhedron(const Cage& cage, const char* method, double planarity) {
  checkPlanarity(method, planarity);
  return Builder(cage, method, planarity).build();
}

void checkSimplicial(const ConvexPolyhedron& poly, const Cage& cage, const char* method) {
  for (const ConvexPolyhedron::Face& face : poly.faces) {
    const std::size_t m = face.loop.size();
    if (m == 3) continue;
    const char* kinds[] = {"quad", "pentagon", "hexagon"};
    const std::string kind = m <= 6 ? kinds[m - 4] : std::to_string(m) + "-gon";
    const std::string corners = "(vertices " + vertexList(face.loop) + ")";
    const std::string what =
        face.source.size() == 1
            ? "face " + std::to_string(face.source[0]) + " " + corners + " is a planar " + kind
            : "the coplanar faces " + vertexList(face.source) + " merge into a planar " + kind +
                  " " + corners;
    throw InvalidInput(std::string(method) + ": " + cage.name() + ": " + what +
                       ": discrete harmonic coordinates need triangle faces (a simplicial "
                       "polytope); use wachspress, which takes polygon faces");
  }
}

// Product form of the 2D Wachspress coordinates (so that points on an edge line need no division
// by 0): corner j gets N_j = C_j Π_{k ∉ {j−1, j}} A_k with A_k = area(y, v_k, v_{k+1}) and C_j =
// area(v_{j−1}, v_j, v_{j+1}), divided by their sum. Lengths are scaled by the face's √area so that
// the products of m − 2 areas stay representable.
bool faceCoordinates(const ConvexPolyhedron::Face& face, std::span<const Vec3> vertices,
                     const Vec3& y, std::span<double> out) {
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
  double sum = 0.0, suffix = 1.0;  // suffix = Π_{k > j} A_k
  for (std::size_t j = m; j-- > 0;) {
    double others;  // Π over k ∉ {j−1, j}
    if (j == 0) {
      others = 1.0;
      for (std::size_t k = 1; k + 1 < m; ++k) others *= a[k];
    } else {
      others = prefix[j - 1] * suffix;
    }
    out[j] = face.cornerArea[j] * scale * scale * others;
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
               ConvexOutsidePolicy policy, InteriorRow interior, const void* data,
               std::span<double> row) {
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
  // The cage's own surface may be off the best-fit planes by the flatness: never "outside".
  if (lowest < 0.0 && s.distance > std::max(snapLength, poly.flatness) &&
      policy == ConvexOutsidePolicy::Throw)
    return false;
  const ConvexPolyhedron::Face& face = poly.faces[s.face];
  thread_local std::vector<double> local;
  local.resize(face.loop.size());
  if (!faceCoordinates(face, poly.vertices, s.point, local))
    throw SolverError("convex cage coordinates: no surface coordinates at " + pointText(s.point));
  std::fill(row.begin(), row.end(), 0.0);
  for (std::size_t j = 0; j < face.loop.size(); ++j) row[face.loop[j]] = local[j];
  return true;
}

std::string vertexList(std::span<const std::uint32_t> vertices) {
  std::string text;
  for (std::uint32_t v : vertices) text += (text.empty() ? "" : ", ") + std::to_string(v);
  return text;
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
         " at " + pointText(x) + "); " + detail::kNearestHint;
}

void checkPlanarity(const char* method, double planarity) {
  if (!(planarity >= 0.0 && planarity <= 1e-2)) {
    throw InvalidInput(std::string(method) + ": planarity must be in [0, 1e-2], got " +
                       std::to_string(planarity));
  }
}

void checkSnapTolerance(const char* method, double snapTolerance) {
  if (!(snapTolerance >= 0.0 && snapTolerance <= 1e-3)) {
    throw InvalidInput(std::string(method) + ": snapTolerance must be in [0, 1e-3], got " +
                       std::to_string(snapTolerance));
  }
}

}  // namespace spacewarp::detail
