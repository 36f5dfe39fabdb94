#include <spacewarp/coords/cage.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <numbers>
#include <string>
#include <utility>

#include <spacewarp/core/archive.h>
#include <spacewarp/core/errors.h>
#include <spacewarp/core/io/mesh_io.h>

namespace spacewarp {

namespace {

std::string str(std::size_t i) { return std::to_string(i); }

// Newell's normal of a polygon (area-weighted, robust for non-planar and concave polygons),
// relative to its first corner: the sums a + b would otherwise carry the round-off of the
// absolute coordinates far from the origin.
Vec3 newellNormal(std::span<const Vec3> p) {
  Vec3 n(0.0);
  for (std::size_t i = 0; i < p.size(); ++i) {
    const Vec3 a = p[i] - p[0];
    const Vec3 b = p[(i + 1) % p.size()] - p[0];
    n += Vec3((a.y - b.y) * (a.z + b.z), (a.z - b.z) * (a.x + b.x), (a.x - b.x) * (a.y + b.y));
  }
  return n;
}

double cross2(const glm::dvec2& a, const glm::dvec2& b) { return a.x * b.y - a.y * b.x; }

// Triangulates one polygon (local indices into `p`): a fan when it is convex in its plane,
// ear clipping otherwise. Returns false if no ear can be found (a self-intersecting polygon).
bool triangulatePolygon(std::span<const Vec3> p, std::vector<glm::uvec3>& out) {
  const std::size_t n = p.size();
  if (n == 3) {
    out.emplace_back(0, 1, 2);
    return true;
  }
  // Project onto the plane orthogonal to the Newell normal, keeping orientation.
  const Vec3 normal = newellNormal(p);
  const double len = glm::length(normal);
  if (!(len > 0.0)) return false;
  const Vec3 w = normal / len;
  const Vec3 helper = std::abs(w.x) < 0.9 ? Vec3(1, 0, 0) : Vec3(0, 1, 0);
  const Vec3 u = glm::normalize(glm::cross(helper, w));
  const Vec3 v = glm::cross(w, u);
  std::vector<glm::dvec2> q(n);
  for (std::size_t i = 0; i < n; ++i) q[i] = {glm::dot(p[i] - p[0], u), glm::dot(p[i] - p[0], v)};

  bool convex = true;
  for (std::size_t i = 0; i < n && convex; ++i)
    convex = cross2(q[(i + 1) % n] - q[i], q[(i + 2) % n] - q[(i + 1) % n]) > 0.0;
  if (convex) {
    for (std::size_t i = 1; i + 1 < n; ++i)
      out.emplace_back(0, static_cast<unsigned>(i), static_cast<unsigned>(i + 1));
    return true;
  }

  std::vector<unsigned> ring(n);
  for (std::size_t i = 0; i < n; ++i) ring[i] = static_cast<unsigned>(i);
  auto inside = [&](const glm::dvec2& x, const glm::dvec2& a, const glm::dvec2& b,
                    const glm::dvec2& c) {
    return cross2(b - a, x - a) >= 0.0 && cross2(c - b, x - b) >= 0.0 &&
           cross2(a - c, x - c) >= 0.0;
  };
  while (ring.size() > 3) {
    bool clipped = false;
    for (std::size_t i = 0; i < ring.size() && !clipped; ++i) {
      const unsigned ia = ring[(i + ring.size() - 1) % ring.size()], ib = ring[i],
                     ic = ring[(i + 1) % ring.size()];
      if (cross2(q[ib] - q[ia], q[ic] - q[ib]) <= 0.0) continue;  // reflex or flat corner
      bool ear = true;
      for (unsigned j : ring) {
        if (j != ia && j != ib && j != ic && inside(q[j], q[ia], q[ib], q[ic])) {
          ear = false;
          break;
        }
      }
      if (!ear) continue;
      out.emplace_back(ia, ib, ic);
      ring.erase(ring.begin() + static_cast<std::ptrdiff_t>(i));
      clipped = true;
    }
    if (!clipped) return false;
  }
  out.emplace_back(ring[0], ring[1], ring[2]);
  return true;
}

[[noreturn]] void fail(const std::string& cageName, const std::string& what) {
  throw InvalidInput(cageName + ": " + what);
}

// What the soup must be before it is triangulated: enough finite vertices, some faces, valid
// indices.
void checkSoup(const PolygonSoup& soup, const std::string& name) {
  if (soup.positions.size() < 4)
    fail(name, "a cage needs at least 4 vertices, this one has " + str(soup.positions.size()));
  for (std::size_t i = 0; i < soup.positions.size(); ++i)
    if (!isFinite(soup.positions[i]))
      fail(name, "vertex " + str(i) + " has a non-finite coordinate");
  if (soup.polygonCount() == 0) fail(name, "a cage needs faces, this one has none");
  try {
    soup.validate();
  } catch (const InvalidInput& e) {
    fail(name, e.what());
  }
}

// The center is the box's, rounded to a multiple of the (power-of-two) scale: then the frame
// of a cage around the origin is an exact power-of-two scaling (its TetGen mesh is the one of
// the world coordinates, scaled), while local coordinates stay within ~1 of zero.
CageFrame cageFrame(const BoundingBox& box) {
  CageFrame frame;
  frame.scale = std::exp2(std::ceil(std::log2(box.diagonal())));
  frame.center = frame.scale * glm::round(0.5 * (box.min + box.max) / frame.scale);
  return frame;
}

// 6 × the signed volume of the cone from `center` (the box center) over triangle t. About the
// center, not the origin: far from the origin the products of absolute coordinates cancel
// catastrophically (a unit box at 1e8 got a volume wrong by orders of magnitude).
double coneVolume(std::span<const Vec3> vertices, const Vec3& center, const Triangle& t) {
  const Vec3 a = vertices[t.x] - center, b = vertices[t.y] - center, c = vertices[t.z] - center;
  return glm::dot(a, glm::cross(b, c));
}

struct Triangulation {
  std::vector<Triangle> triangles;
  std::vector<std::uint32_t> source;  // the input polygon of each triangle
};

// Triangulates every face, refusing faces that cannot be triangulated or have zero area.
Triangulation triangulateFaces(const PolygonSoup& soup, std::span<const Vec3> vertices,
                               double diagonal, const std::string& name) {
  const double minArea = 1e-12 * diagonal * diagonal;
  Triangulation result;
  std::vector<glm::uvec3> local;
  std::vector<Vec3> corners;
  for (std::size_t f = 0; f < soup.polygonCount(); ++f) {
    const auto poly = soup.polygon(f);
    corners.clear();
    for (std::uint32_t v : poly) corners.push_back(vertices[v]);
    local.clear();
    if (!triangulatePolygon(corners, local))
      fail(name, "face " + str(f) + " could not be triangulated (degenerate or self-intersecting)");
    for (const glm::uvec3& t : local) {
      const Triangle tri(poly[t.x], poly[t.y], poly[t.z]);
      const Vec3 cross =
          glm::cross(vertices[tri.y] - vertices[tri.x], vertices[tri.z] - vertices[tri.x]);
      if (0.5 * glm::length(cross) <= minArea)
        fail(name, "face " + str(f) + " has zero area (vertices " + str(tri.x) + ", " + str(tri.y) +
                       ", " + str(tri.z) + ")");
      result.triangles.push_back(tri);
      result.source.push_back(static_cast<std::uint32_t>(f));
    }
  }
  return result;
}

void checkEveryVertexUsed(std::size_t vertexCount, std::span<const Triangle> triangles,
                          const std::string& name) {
  std::vector<bool> used(vertexCount, false);
  for (const Triangle& t : triangles) used[t.x] = used[t.y] = used[t.z] = true;
  for (std::size_t i = 0; i < used.size(); ++i)
    if (!used[i]) fail(name, "vertex " + str(i) + " is not used by any face");
}

// A triangle using an edge, with the direction it traverses the edge in.
struct EdgeUse {
  std::uint32_t triangle;
  bool forward;  // traverses the edge from its smaller to its larger vertex
};
using EdgeUses = std::map<std::pair<std::uint32_t, std::uint32_t>, std::vector<EdgeUse>>;

// Edge (smaller vertex, larger vertex) -> the triangles using it; refuses open boundaries and
// non-manifold edges, so that every edge has exactly two uses.
EdgeUses manifoldEdges(std::span<const Triangle> triangles, const std::string& name) {
  EdgeUses edges;
  for (std::uint32_t t = 0; t < triangles.size(); ++t) {
    for (int k = 0; k < 3; ++k) {
      const std::uint32_t a = triangles[t][k], b = triangles[t][(k + 1) % 3];
      edges[{std::min(a, b), std::max(a, b)}].push_back({t, a < b});
    }
  }
  for (const auto& [edge, uses] : edges) {
    const std::string e = "edge (" + str(edge.first) + ", " + str(edge.second) + ")";
    if (uses.size() == 1) fail(name, "the cage is not closed: open boundary at " + e);
    if (uses.size() > 2)
      fail(name, "non-manifold " + e + " is shared by " + str(uses.size()) + " triangles");
  }
  return edges;
}

// Per triangle, its neighbours across its edges and whether the two traverse their shared edge
// in the same direction (then one of them must flip).
std::vector<std::vector<std::pair<std::uint32_t, bool>>> neighbours(const EdgeUses& edges,
                                                                    std::size_t triangleCount) {
  std::vector<std::vector<std::pair<std::uint32_t, bool>>> result(triangleCount);
  for (const auto& [edge, uses] : edges) {
    const bool same = uses[0].forward == uses[1].forward;
    result[uses[0].triangle].push_back({uses[1].triangle, same});
    result[uses[1].triangle].push_back({uses[0].triangle, same});
  }
  return result;
}

// Which triangles to flip (1) so that all are oriented consistently and outwards: a breadth-
// first walk over each component, in which neighbours across an edge must traverse it in
// opposite directions, then the whole component is flipped if its signed volume is negative.
std::vector<int> outwardFlips(std::span<const Triangle> triangles,
                              std::span<const std::uint32_t> source, const EdgeUses& edges,
                              std::span<const Vec3> vertices, const Vec3& center,
                              const std::string& name) {
  const auto next = neighbours(edges, triangles.size());
  std::vector<int> flip(triangles.size(), -1);  // -1 unvisited, 0 keep, 1 flip
  std::vector<std::uint32_t> component;
  for (std::uint32_t seed = 0; seed < triangles.size(); ++seed) {
    if (flip[seed] != -1) continue;
    component.assign(1, seed);
    flip[seed] = 0;
    for (std::size_t head = 0; head < component.size(); ++head) {
      const std::uint32_t t = component[head];
      for (const auto& [u, differ] : next[t]) {
        const int want = flip[t] ^ static_cast<int>(differ);
        if (flip[u] == -1) {
          flip[u] = want;
          component.push_back(u);
        } else if (flip[u] != want) {
          fail(name, "the cage is not orientable (triangles " + str(t) + " and " + str(u) +
                         " of face " + str(source[u]) + " cannot agree)");
        }
      }
    }
    // Outward: the component's signed volume (after the consistent flips) must be positive.
    double signedVolume = 0.0;
    for (std::uint32_t t : component) {
      const double v = coneVolume(vertices, center, triangles[t]);
      signedVolume += flip[t] ? -v : v;
    }
    if (signedVolume < 0.0)
      for (std::uint32_t t : component) flip[t] ^= 1;
  }
  return flip;
}

}  // namespace

Cage::Cage(const PolygonSoup& soup, const std::string& name) : name_(name) {
  checkSoup(soup, name_);
  vertices_ = soup.positions;
  inputOffsets_ = soup.faceOffsets;
  inputIndices_ = soup.faceIndices;
  const BoundingBox box = boundingBox(vertices_);
  diagonal_ = box.diagonal();
  frame_ = cageFrame(box);

  Triangulation triangulation = triangulateFaces(soup, vertices_, diagonal_, name_);
  triangles_ = std::move(triangulation.triangles);
  triangleSource_ = std::move(triangulation.source);
  checkEveryVertexUsed(vertices_.size(), triangles_, name_);
  const EdgeUses edges = manifoldEdges(triangles_, name_);
  const std::vector<int> flip =
      outwardFlips(triangles_, triangleSource_, edges, vertices_, frame_.center, name_);
  for (std::size_t t = 0; t < triangles_.size(); ++t) {
    if (flip[t]) std::swap(triangles_[t].y, triangles_[t].z);
  }
  for (const Triangle& t : triangles_) volume_ += coneVolume(vertices_, frame_.center, t) / 6.0;
  if (!(volume_ > 0.0)) fail(name_, "the cage encloses no volume");
  orientFaces(flip);
}

// The faces take the orientation of their triangles: the triangles of one face share its inner
// diagonals, traversed in opposite directions, so they are all flipped or none is.
void Cage::orientFaces(std::span<const int> triangleFlips) {
  faceOffsets_ = inputOffsets_;
  faceIndices_ = inputIndices_;
  std::vector<int> faceFlip(faceCount(), 0);
  for (std::size_t t = 0; t < triangles_.size(); ++t)
    faceFlip[triangleSource_[t]] = triangleFlips[t];
  for (std::size_t f = 0; f < faceCount(); ++f) {
    maxFaceSize_ = std::max<std::size_t>(maxFaceSize_, faceOffsets_[f + 1] - faceOffsets_[f]);
    if (!faceFlip[f]) continue;
    ++reorientedCount_;
    std::reverse(faceIndices_.begin() + faceOffsets_[f] + 1,
                 faceIndices_.begin() + faceOffsets_[f + 1]);
  }
}

Cage Cage::fromFile(const std::filesystem::path& path) {
  return Cage(readSoup(path), path.string());
}

Vec3 Cage::normal(std::size_t t) const {
  const Triangle& tri = triangles_[t];
  return glm::normalize(
      glm::cross(vertices_[tri.y] - vertices_[tri.x], vertices_[tri.z] - vertices_[tri.x]));
}

double Cage::area(std::size_t t) const {
  const Triangle& tri = triangles_[t];
  return 0.5 * glm::length(glm::cross(vertices_[tri.y] - vertices_[tri.x],
                                      vertices_[tri.z] - vertices_[tri.x]));
}

std::vector<Vec3> Cage::posedVertices(const PolygonSoup& posed, const std::string& name) const {
  if (posed.positions.size() != vertices_.size()) {
    throw InvalidInput(name + ": the posed cage has " + str(posed.positions.size()) +
                       " vertices but the rest cage " + name_ + " has " + str(vertices_.size()));
  }
  if (posed.polygonCount() != 0) {
    const std::size_t restFaces = inputOffsets_.size() - 1;
    if (posed.polygonCount() != restFaces) {
      throw InvalidInput(name + ": the posed cage has " + str(posed.polygonCount()) +
                         " faces but the rest cage " + name_ + " has " + str(restFaces));
    }
    if (posed.faceOffsets != inputOffsets_ || posed.faceIndices != inputIndices_) {
      for (std::size_t f = 0; f < restFaces; ++f) {
        const auto p = posed.polygon(f);
        const auto* begin = inputIndices_.data() + inputOffsets_[f];
        const auto* end = inputIndices_.data() + inputOffsets_[f + 1];
        if (!std::equal(p.begin(), p.end(), begin, end))
          throw InvalidInput(name + ": face " + str(f) + " differs from the rest cage's face " +
                             str(f));
      }
    }
  }
  for (std::size_t i = 0; i < posed.positions.size(); ++i)
    if (!isFinite(posed.positions[i]))
      throw InvalidInput(name + ": vertex " + str(i) + " has a non-finite coordinate");
  return posed.positions;
}

std::vector<Vec3> Cage::posedVerticesFromFile(const std::filesystem::path& path) const {
  return posedVertices(readSoup(path), path.string());
}

double Cage::windingNumber(const Vec3& x) const {
  double total = 0.0;
  for (const Triangle& t : triangles_) {
    const Vec3 a = vertices_[t.x] - x, b = vertices_[t.y] - x, c = vertices_[t.z] - x;
    const double la = glm::length(a), lb = glm::length(b), lc = glm::length(c);
    const double numerator = glm::dot(a, glm::cross(b, c));
    const double denominator =
        la * lb * lc + glm::dot(a, b) * lc + glm::dot(b, c) * la + glm::dot(c, a) * lb;
    total += 2.0 * std::atan2(numerator, denominator);
  }
  return total / (4.0 * std::numbers::pi);
}

void Cage::save(ArchiveWriter& out) const {
  out.tag("cage");
  out.string(name_);
  out.vec3s(vertices_);
  out.u32s(inputOffsets_);
  out.u32s(inputIndices_);
}

Cage Cage::load(ArchiveReader& in) {
  if (const std::string tag = in.string(); tag != "cage")
    in.fail("expected a cage, found '" + printable(tag) + "'");
  const std::string name = in.string();
  PolygonSoup soup;
  soup.positions = in.vec3s();
  soup.faceOffsets = in.u32s();
  soup.faceIndices = in.u32s();
  return Cage(soup, name);
}

}  // namespace spacewarp
