#pragma once
// The cage: a closed, consistently and outwardly oriented polygon mesh that controls a
// deformation through cage coordinates (mean-value, Green, harmonic, and the polygon and quad
// coordinates). It keeps its faces as the polygons they were given as, and a triangulation of
// them for the methods that work on triangles.

#include <cstdint>
#include <filesystem>
#include <span>
#include <string>
#include <vector>

#include <glm/vec3.hpp>

#include <spacewarp/core/geometry.h>

namespace spacewarp {
class ArchiveReader;
class ArchiveWriter;
}  // namespace spacewarp

namespace spacewarp {

using Triangle = glm::u32vec3;  ///< Three vertex indices.

/// A cage-relative frame: local = (world − center) / scale. Computations whose round-off would
/// otherwise grow with the distance from the world origin (meshing, assembling, locating) run
/// in it, so their accuracy depends only on the cage's shape, not on where it is or how big.
struct CageFrame {
  /// The center of the cage's bounding box rounded to a multiple of `scale`, world units (0 for
  /// a cage around the origin, whose frame is then an exact scaling).
  Vec3 center{0.0};
  /// The power of two at or above the bounding-box diagonal (a power of two makes the scaling
  /// exact), world units.
  double scale = 1.0;

  Vec3 toLocal(const Vec3& world) const { return (world - center) / scale; }
  Vec3 toWorld(const Vec3& local) const { return local * scale + center; }
};

/// A validated cage. Its faces are the input polygons (triangles, quads, planar or not, and
/// larger polygons), oriented outward: face(f) lists face f's vertices counter-clockwise seen
/// from outside, starting at the vertex the input started it at. The polygons are also
/// triangulated (a fan for faces convex in the plane of their Newell normal, ear clipping
/// otherwise) for the methods that work on triangles; triangleSource() records which face every
/// triangle came from, so results are reproducible. Triangles are oriented like their faces.
/// Validation (closed, manifold, orientable) runs on the triangulation, whose inner diagonals
/// are shared only inside a face.
class Cage {
 public:
  /// Validates and triangulates `soup`; `name` (usually the file) prefixes every message.
  /// Throws InvalidInput naming the element for: fewer than 4 vertices, a non-finite
  /// coordinate, a polygon with fewer than 3 vertices or an index out of range, a vertex used by
  /// no face, a zero-area triangle, an open boundary (names an edge), a non-manifold edge
  /// (more than two triangles), or a non-orientable surface. An inconsistently oriented but
  /// orientable surface is re-oriented (see reorientedCount()), and every component whose
  /// signed volume is negative is flipped so normals point outward.
  explicit Cage(const PolygonSoup& soup, const std::string& name = "cage");

  /// Reads a cage from any supported file (OBJ, OFF, PLY). Throws IoError for unreadable files
  /// and InvalidInput (naming the file) for invalid cages.
  static Cage fromFile(const std::filesystem::path& path);

  std::span<const Vec3> vertices() const { return vertices_; }
  std::span<const Triangle> triangles() const { return triangles_; }
  std::size_t vertexCount() const { return vertices_.size(); }
  std::size_t triangleCount() const { return triangles_.size(); }

  /// The faces: faceCount() polygons of at least 3 vertices, in input order.
  std::size_t faceCount() const { return faceOffsets_.size() - 1; }
  /// The vertex indices of face f, outward (counter-clockwise seen from outside). A face that
  /// was reoriented keeps its first vertex and reverses the rest.
  std::span<const std::uint32_t> face(std::size_t f) const {
    return {faceIndices_.data() + faceOffsets_[f], faceOffsets_[f + 1] - faceOffsets_[f]};
  }
  /// The faces as offsets (faceCount() + 1 entries) into faceIndices().
  std::span<const std::uint32_t> faceOffsets() const { return faceOffsets_; }
  std::span<const std::uint32_t> faceIndices() const { return faceIndices_; }
  /// The largest number of vertices of a face: 3 for a triangle cage, 4 with quads.
  std::size_t maxFaceSize() const { return maxFaceSize_; }

  /// For triangle t, the index of the input polygon (face) it was cut from.
  std::span<const std::uint32_t> triangleSource() const { return triangleSource_; }

  /// How many faces (input polygons) had to be reversed for a consistent outward orientation.
  std::size_t reorientedCount() const { return reorientedCount_; }

  /// The bounding-box diagonal: the length that every tolerance on this cage is relative to.
  double diagonal() const { return diagonal_; }

  /// The enclosed volume (positive: triangles face outward).
  double volume() const { return volume_; }

  /// The name given at construction (usually the file), which prefixes its messages.
  /// Archive (core/archive.h): tag "cage", the name and the input polygons as given; load()
  /// rebuilds the cage through the constructor (same checks, same triangulation).
  void save(ArchiveWriter& out) const;
  static Cage load(ArchiveReader& in);

  const std::string& name() const { return name_; }
  /// The cage-relative frame (bounding-box center, power-of-two scale).
  const CageFrame& frame() const { return frame_; }

  /// Unit outward normal and area of triangle t.
  Vec3 normal(std::size_t t) const;
  double area(std::size_t t) const;

  /// The generalised winding number of the cage at x: the solid angle the cage subtends at x
  /// over 4π (Van Oosterom-Strackee per triangle); 1 inside, 0 outside (on the surface itself
  /// it jumps, and either value may come out).
  double windingNumber(const Vec3& x) const;

  /// True when x is strictly inside the cage (winding number above ½).
  bool contains(const Vec3& x) const { return windingNumber(x) > 0.5; }

  /// The vertices of a posed cage, checked against this (rest) cage: the vertex count must
  /// match, and if the posed soup has polygons they must be the rest polygons. Throws
  /// InvalidInput saying which count differs, or naming a non-finite vertex.
  std::vector<Vec3> posedVertices(const PolygonSoup& posed, const std::string& name) const;
  std::vector<Vec3> posedVerticesFromFile(const std::filesystem::path& path) const;

 private:
  void orientFaces(std::span<const int> triangleFlips);

  std::string name_;
  std::vector<Vec3> vertices_;
  std::vector<Triangle> triangles_;
  std::vector<std::uint32_t> triangleSource_;
  std::vector<std::uint32_t> inputOffsets_, inputIndices_;  // the input polygons, for posed checks
  std::vector<std::uint32_t> faceOffsets_, faceIndices_;    // the same, oriented outward
  std::size_t maxFaceSize_ = 0;
  std::size_t reorientedCount_ = 0;
  double diagonal_ = 0.0;
  double volume_ = 0.0;
  CageFrame frame_;
};

}  // namespace spacewarp
