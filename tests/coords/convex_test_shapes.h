#pragma once
// Convex test cages for the convex-polyhedron coordinates (Wachspress, discrete harmonic): the
// convex hull of points that are all its vertices, faces merged where coplanar, so a cube comes out
// as six quads, a truncated octahedron as squares and hexagons, random points on a sphere as
// triangles.

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numbers>
#include <random>
#include <set>
#include <vector>

#include <spacewarp/coords/cage.h>
#include <spacewarp/coords/detail/convex_polyhedron.h>
#include <spacewarp/coords/properties.h>
#include <spacewarp/core/coordinates.h>
#include <spacewarp/core/geometry.h>
#include "coords_test_shapes.h"

namespace spacewarp::test {

/// The convex hull of `points`, every one of which must be a vertex of it (no point inside the
/// hull or inside a face): one polygon per supporting plane, counter-clockwise seen from outside.
/// Brute force over triples (O(n⁴)): for a few hundred points at most.
inline PolygonSoup convexHull(const std::vector<Vec3>& points) {
  const std::size_t n = points.size();
  BoundingBox box = boundingBox(points);
  const double tol = 1e-9 * glm::length(box.extent());
  std::set<std::vector<std::uint32_t>> seen;
  PolygonSoup soup;
  soup.positions = points;
  for (std::size_t i = 0; i < n; ++i) {
    for (std::size_t j = i + 1; j < n; ++j) {
      for (std::size_t k = j + 1; k < n; ++k) {
        Vec3 normal = glm::cross(points[j] - points[i], points[k] - points[i]);
        if (glm::length(normal) <= tol * tol) continue;
        normal = glm::normalize(normal);
        double lo = 0.0, hi = 0.0;
        for (const Vec3& p : points) {
          const double h = glm::dot(normal, p - points[i]);
          lo = std::min(lo, h);
          hi = std::max(hi, h);
        }
        if (lo < -tol && hi > tol) continue;
        if (hi > tol) normal = -normal;
        std::vector<std::uint32_t> face;
        for (std::size_t v = 0; v < n; ++v)
          if (std::fabs(glm::dot(normal, points[v] - points[i])) <= tol)
            face.push_back(static_cast<std::uint32_t>(v));
        if (!seen.insert(face).second) continue;
        Vec3 centre(0.0);
        for (std::uint32_t v : face) centre += points[v];
        centre /= static_cast<double>(face.size());
        const Vec3 u = glm::normalize(points[face[0]] - centre), w = glm::cross(normal, u);
        std::sort(face.begin(), face.end(), [&](std::uint32_t a, std::uint32_t b) {
          const Vec3 pa = points[a] - centre, pb = points[b] - centre;
          return std::atan2(glm::dot(pa, w), glm::dot(pa, u)) <
                 std::atan2(glm::dot(pb, w), glm::dot(pb, u));
        });
        soup.addPolygon(face);
      }
    }
  }
  return soup;
}

/// Every polygon of `soup` split into a fan of triangles from its first corner.
inline PolygonSoup triangulated(const PolygonSoup& soup) {
  PolygonSoup out;
  out.positions = soup.positions;
  for (std::size_t f = 0; f < soup.polygonCount(); ++f) {
    const auto face = soup.polygon(f);
    for (std::size_t j = 1; j + 1 < face.size(); ++j)
      out.addPolygon({face[0], face[j], face[j + 1]});
  }
  return out;
}

/// The box [lo, hi] as six quads.
inline PolygonSoup convexBox(const Vec3& lo, const Vec3& hi) {
  std::vector<Vec3> corners;
  for (int c = 0; c < 8; ++c)
    corners.push_back(Vec3(c & 1 ? hi.x : lo.x, c & 2 ? hi.y : lo.y, c & 4 ? hi.z : lo.z));
  return convexHull(corners);
}

/// A right prism of height 1 over a convex polygon given counter-clockwise in the xy plane.
inline PolygonSoup prism(const std::vector<glm::dvec2>& base) {
  std::vector<Vec3> points;
  for (double z : {0.0, 1.0})
    for (const auto& p : base) points.push_back(Vec3(p.x, p.y, z));
  return convexHull(points);
}

/// The regular octahedron with corners ±e_x, ±e_y, ±e_z (in that order): eight triangles.
inline PolygonSoup octahedron() {
  return convexHull({Vec3(1, 0, 0), Vec3(-1, 0, 0), Vec3(0, 1, 0), Vec3(0, -1, 0), Vec3(0, 0, 1),
                     Vec3(0, 0, -1)});
}

/// The prism over a regular hexagon of circumradius 1: two hexagons, six squares.
inline PolygonSoup hexagonalPrism() {
  std::vector<glm::dvec2> base;
  for (int k = 0; k < 6; ++k) {
    const double a = k * std::numbers::pi / 3.0;
    base.push_back({std::cos(a), std::sin(a)});
  }
  return prism(base);
}

/// The prism over an irregular convex pentagon (not on a circle): its caps are not cyclic.
inline PolygonSoup pentagonalPrism() {
  return prism({{0.0, 0.0}, {1.3, -0.2}, {1.8, 0.9}, {0.7, 1.6}, {-0.4, 0.8}});
}

/// The truncated octahedron: the 24 permutations of (0, ±1, ±2), six squares and eight hexagons.
inline PolygonSoup truncatedOctahedron() {
  std::vector<Vec3> points;
  const int perm[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
  for (const auto& p : perm) {
    for (int s = 0; s < 4; ++s) {
      const double value[3] = {0.0, s & 1 ? -1.0 : 1.0, s & 2 ? -2.0 : 2.0};
      points.push_back(Vec3(value[p[0]], value[p[1]], value[p[2]]));
    }
  }
  return convexHull(points);
}

/// `count` random points on the sphere of radius `radius` about `centre`, and their hull (all
/// triangles, in general position).
inline PolygonSoup randomSphereHull(std::size_t count, std::uint64_t seed, double radius = 1.0,
                                    const Vec3& centre = Vec3(0.0)) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> normal;
  std::vector<Vec3> points;
  for (std::size_t i = 0; i < count; ++i) {
    const Vec3 d(normal(rng), normal(rng), normal(rng));
    points.push_back(centre + radius * glm::normalize(d));
  }
  return convexHull(points);
}

// ---- checks shared by the Wachspress and discrete harmonic tests ----

/// A named convex cage.
struct ConvexCase {
  const char* name;
  PolygonSoup soup;
};

/// The convex cages every convex coordinate is tested on.
inline std::vector<ConvexCase> convexCases() {
  return {{"tetrahedron", tetrahedron()},
          {"box of quads", convexBox(Vec3(-1.0, -0.5, 0.0), Vec3(2.0, 1.0, 1.5))},
          {"triangulated box", triangulated(convexBox(Vec3(-1.0, -0.5, 0.0), Vec3(2.0, 1.0, 1.5)))},
          {"hexagonal prism", hexagonalPrism()},
          {"pentagonal prism", pentagonalPrism()},
          {"truncated octahedron", truncatedOctahedron()},
          {"random hull", randomSphereHull(40, 11, 2.0, Vec3(5.0, -3.0, 1.0))}};
}

/// max |w(x) − linear interpolation| at points along every edge of the polyhedron (not the inner
/// diagonals of a triangulated face).
inline double edgeLinearityError(const Coordinates& coordinates, const Cage& cage) {
  const detail::ConvexPolyhedron poly =
      detail::buildConvexPolyhedron(cage, "test", kDefaultPlanarity);
  std::vector<double> row(cage.vertexCount());
  double worst = 0.0;
  for (const auto& face : poly.faces) {
    for (std::size_t j = 0; j < face.loop.size(); ++j) {
      const std::uint32_t a = face.loop[j], b = face.loop[(j + 1) % face.loop.size()];
      for (double t : {0.1, 0.5, 0.77}) {
        coordinates.weights((1.0 - t) * cage.vertices()[a] + t * cage.vertices()[b], row);
        for (std::size_t v = 0; v < row.size(); ++v) {
          const double expected = v == a ? 1.0 - t : (v == b ? t : 0.0);
          worst = std::max(worst, std::fabs(row[v] - expected));
        }
      }
    }
  }
  return worst;
}

/// max |row(x) − row(y)| over every column.
inline double rowDistance(const Coordinates& coordinates, const Vec3& x, const Vec3& y) {
  std::vector<double> a(coordinates.columnCount()), b(coordinates.columnCount());
  coordinates.weights(x, a);
  coordinates.weights(y, b);
  double worst = 0.0;
  for (std::size_t c = 0; c < a.size(); ++c) worst = std::max(worst, std::fabs(a[c] - b[c]));
  return worst;
}

/// What nearSurface() found: the largest partition-of-unity or reproduction error (in diagonals)
/// and the smallest weight.
struct NearSurfaceReport {
  double error = 0.0;
  double minWeight = 0.0;
};

/// The rows at points approaching every corner and edge midpoint of the polyhedron from inside
/// (towards the centre of its box), from 1e-3 down to 1e-13 of the distance.
inline NearSurfaceReport nearSurface(const Coordinates& coordinates, const Cage& cage) {
  const BoundingBox box = boundingBox(cage.vertices());
  const Vec3 centre = 0.5 * (box.min + box.max);
  std::vector<double> row(cage.vertexCount());
  NearSurfaceReport report;
  const detail::ConvexPolyhedron poly =
      detail::buildConvexPolyhedron(cage, "test", kDefaultPlanarity);
  for (const auto& face : poly.faces) {
    for (std::size_t j = 0; j < face.loop.size(); ++j) {
      const Vec3 corner = cage.vertices()[face.loop[j]];
      const Vec3 mid = 0.5 * (corner + cage.vertices()[face.loop[(j + 1) % face.loop.size()]]);
      for (double delta : {1e-3, 1e-7, 1e-11, 1e-13}) {
        for (const Vec3& x : {corner + delta * (centre - corner), mid + delta * (centre - mid)}) {
          coordinates.weights(x, row);
          Vec3 reproduced(0.0);
          double sum = 0.0;
          for (std::size_t c = 0; c < row.size(); ++c) {
            reproduced += row[c] * cage.vertices()[c];
            sum += row[c];
            report.minWeight = std::min(report.minWeight, row[c]);
          }
          report.error = std::max(
              {report.error, glm::length(reproduced - x) / cage.diagonal(), std::fabs(sum - 1.0)});
        }
      }
    }
  }
  return report;
}

/// What gradientErrors() found: the largest deviation from Σ_v ∇w_v = 0 (times the diagonal) and
/// Σ_v p_v ⊗ ∇w_v = I (the derivatives of partition of unity and linear precision), and the
/// largest difference from central differences (times the diagonal).
struct GradientReport {
  double identities = 0.0;
  double differences = 0.0;
};

/// Checks weightGradients() at 100 interior points.
inline GradientReport gradientErrors(const Coordinates& coordinates, const Cage& cage) {
  const std::size_t n = cage.vertexCount();
  std::vector<Vec3> gradients(n);
  std::vector<double> plus(n), minus(n);
  GradientReport report;
  for (const Vec3& x : interiorSamples(cage, 100, 6)) {
    if (!coordinates.weightGradients(x, gradients)) {
      report.identities = std::numeric_limits<double>::infinity();
      continue;
    }
    Vec3 total(0.0);
    Mat3 moment(0.0);
    for (std::size_t v = 0; v < n; ++v) {
      total += gradients[v];
      moment += glm::outerProduct(gradients[v], cage.vertices()[v]);
    }
    report.identities = std::max(report.identities, glm::length(total) * cage.diagonal());
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j)
        report.identities =
            std::max(report.identities, std::fabs(moment[i][j] - (i == j ? 1.0 : 0.0)));
    const double step = 1e-7 * cage.diagonal();
    for (int axis = 0; axis < 3; ++axis) {
      Vec3 e(0.0);
      e[axis] = step;
      coordinates.weights(x + e, plus);
      coordinates.weights(x - e, minus);
      for (std::size_t v = 0; v < n; ++v) {
        const double fd = (plus[v] - minus[v]) / (2.0 * step);
        report.differences =
            std::max(report.differences, std::fabs(fd - gradients[v][axis]) * cage.diagonal());
      }
    }
  }
  return report;
}

/// A random rotation (Rodrigues) of the vertices, then every coordinate rounded by `round` (as
/// an exporter writing 6 decimals or float32 does).
template <class Round>
inline PolygonSoup rotatedAndRounded(PolygonSoup soup, unsigned seed, Round round) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> gauss;
  const Vec3 axis = glm::normalize(Vec3(gauss(rng), gauss(rng), gauss(rng)));
  const double angle = std::uniform_real_distribution<double>(0.0, std::numbers::pi)(rng);
  for (Vec3& p : soup.positions) {
    p = p * std::cos(angle) + glm::cross(axis, p) * std::sin(angle) +
        axis * glm::dot(axis, p) * (1.0 - std::cos(angle));
    p = Vec3(round(p.x), round(p.y), round(p.z));
  }
  return soup;
}

inline double sixDecimals(double x) { return std::round(x * 1e6) / 1e6; }
inline double float32(double x) { return static_cast<double>(static_cast<float>(x)); }

}  // namespace spacewarp::test
