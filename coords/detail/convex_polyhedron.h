#pragma once
// The convex polyhedron behind a convex cage, shared by the Wachspress and discrete harmonic
// coordinates: the cage's adjacent coplanar faces merged into one planar face each (a
// triangulated box becomes six quads), the face planes, the faces around every vertex, the 2D
// Wachspress coordinates of a face, the nearest surface point, and the row logic both coordinates
// follow (interior closed form, surface coordinates within the snap distance, the outside policy).
// Discrete harmonic coordinates take simplicial polyhedra only, whose faces are triangles, where
// the 2D coordinates of every kind are the barycentric ones.

#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include <spacewarp/coords/cage.h>
#include <spacewarp/coords/convex_cage.h>

namespace spacewarp::detail {

struct ConvexPolyhedron {
  struct Face {
    Vec3 normal{0.0};                   ///< unit, outward
    double offset = 0.0;                ///< normal · p for every p on the face (world units)
    std::vector<std::uint32_t> loop;    ///< the corners, counter-clockwise seen from outside
    std::vector<double> cornerArea;     ///< per corner j: area(v_{j−1}, v_j, v_{j+1}) > 0
    double area = 0.0;                  ///< world units²
    std::vector<std::uint32_t> source;  ///< the cage faces merged into it
  };
  std::vector<Vec3> vertices;  ///< the cage's vertices
  std::vector<Face> faces;
  /// The faces around vertex v, counter-clockwise seen from outside, each once (at least 3):
  /// ring[ringOffsets[v], ringOffsets[v + 1]).
  std::vector<std::uint32_t> ringOffsets, ring;
  double diagonal = 0.0;
  /// The largest distance of a cage face's corner from its polyhedron face's best-fit plane
  /// (world units, at most planarity × diagonal): points outside by no more than this are on the
  /// cage's own (nearly planar) surface, not outside it.
  double flatness = 0.0;
};

/// Merges and checks the faces of `cage`. Throws InvalidInput, prefixed by `method` and the cage's
/// name, for a face that is not planar, a reflex edge (naming its two vertices), a vertex that is
/// not a corner (its faces lie in fewer than 3 planes) or otherwise breaks convexity, or a
/// planarity outside [0, 1e-2]. All lengths are judged against one distance, planarity × the cage
/// diagonal: a face is planar when its corners are that close to its best-fit plane (through the
/// corners' centroid, normal to the Newell normal), and two faces sharing an edge are coplanar
/// (and merge) when turning from one to the other by θ lifts their corner farthest from the edge
/// line (distance d) by d |sin θ| ≤ that distance off the other's plane; an edge turning inward
/// by more is reflex. So a polygon and its triangulation get the same answer. The checks run in
/// cage-relative coordinates (Cage::frame()'s center), so translating a cage does not change
/// them. A nearly planar face is then treated as lying in its best-fit plane.
ConvexPolyhedron buildConvexPolyhedron(const Cage& cage, const char* method, double planarity);

/// Throws InvalidInput unless planarity is in [0, 1e-2].
void checkPlanarity(const char* method, double planarity);

/// Throws InvalidInput, prefixed by `method` and the cage's name, unless every face of `poly`
/// (built from `cage`) is a triangle, naming the first that is not: a cage face that is a polygon,
/// or the coplanar cage faces that merge into one, with its corners.
void checkSimplicial(const ConvexPolyhedron& poly, const Cage& cage, const char* method);

/// The 2D Wachspress coordinates (normalised, one per corner of `face`, into `out`) of y, a point
/// of the face's plane (barycentric on a triangle). Meant for y on the face; false if their sum
/// vanishes at y (which happens only outside the polygon, where they are continued).
bool faceCoordinates(const ConvexPolyhedron::Face& face, std::span<const Vec3> vertices,
                     const Vec3& y, std::span<double> out);

/// The point of the polyhedron's surface nearest to x, its face and its distance (0 on it).
struct SurfacePoint {
  std::size_t face = 0;
  Vec3 point{0.0};
  double distance = 0.0;
};
SurfacePoint nearestSurfacePoint(const ConvexPolyhedron& poly, const Vec3& x);

/// The interior closed form of one coordinate: the normalised row (vertex count entries) of an
/// inside point x whose height below every face plane (offset − normal · x, positive) is given.
using InteriorRow = void (*)(const void* data, const ConvexPolyhedron& poly, const Vec3& x,
                             std::span<const double> heights, std::span<double> row);

/// One row: the interior closed form when x is farther than snapLength (world units) inside every
/// face plane, the surface coordinates of the nearest surface point when it is within snapLength of
/// the surface (or poly.flatness outside it) or outside with NearestPoint. Returns false (row
/// unspecified) for a point outside under Throw.
bool convexRow(const ConvexPolyhedron& poly, const Vec3& x, double snapLength,
               ConvexOutsidePolicy policy, InteriorRow interior, const void* data,
               std::span<double> row);

/// "a, b, c" (vertex or face indices), for messages.
std::string vertexList(std::span<const std::uint32_t> vertices);

/// "(x, y, z)" with every digit, for messages.
std::string pointText(const Vec3& x);

/// The message for `count` of `total` points outside the cage, the first being point `first`
/// at x.
std::string outsideMessage(const char* method, std::size_t count, std::size_t total,
                           std::size_t first, const Vec3& x);

/// Throws InvalidInput unless snapTolerance is in [0, 1e-3].
void checkSnapTolerance(const char* method, double snapTolerance);

}  // namespace spacewarp::detail
