#pragma once
// Geometry containers: point sets and polygon soups. Positions are in world units, double.

#include <cstdint>
#include <initializer_list>
#include <limits>
#include <span>
#include <string>
#include <vector>

#include <spacewarp/core/math.h>

namespace spacewarp {

/// The storage type a per-vertex attribute was read with, so that writing it back to a PLY
/// file keeps its type. Values are held as double, which represents every type exactly.
enum class ScalarType { Int8, UInt8, Int16, UInt16, Int32, UInt32, Float32, Float64 };

/// A named scalar per element (PLY "red", "confidence", "label", ... per vertex, or
/// "material_index" per face), carried through warps untouched.
struct ScalarAttribute {
  std::string name;
  ScalarType type = ScalarType::Float64;
  std::vector<double> values;  ///< One per element (vertex or polygon).
};
using VertexAttribute = ScalarAttribute;

/// Values attached to polygon corners through an index of their own, as OBJ's `vt` and `vn`
/// are: corner c (the vertex faceIndices[c]) has the value values[indices[c]], or none when
/// indices[c] == kNone. A value may be shared by any number of corners.
struct CornerAttribute {
  static constexpr std::uint32_t kNone = std::numeric_limits<std::uint32_t>::max();
  std::vector<Vec3> values;
  std::vector<std::uint32_t> indices;  ///< Empty (no corner has a value), or one per corner.

  bool empty() const { return indices.empty(); }
};

/// Points with optional unit normals and other per-point attributes.
/// Invariant (checked by validate()): normals is empty or has one entry per position, and
/// every attribute has one value per position.
struct PointSet {
  std::vector<Vec3> positions;  ///< n points, world units.
  std::vector<Vec3> normals;    ///< empty, or n unit vectors.
  std::vector<VertexAttribute> attributes;

  std::size_t size() const { return positions.size(); }
  bool hasNormals() const { return !normals.empty(); }

  /// Throws InvalidInput naming the offending element if the invariant does not hold or a
  /// position or normal is not finite.
  void validate() const;
};

/// A line of an OBJ file that names the polygons after it (`o`, `g`, `s`, `usemtl`, `mtllib`),
/// kept verbatim so that writing OBJ again keeps the groups and materials.
struct ObjStatement {
  std::uint32_t polygon = 0;  ///< The polygon it precedes (polygonCount(): after the last).
  std::string text;           ///< The line without comment and line end, e.g. "usemtl red".
};

/// A polygon soup: vertices (as a PointSet) and polygons of any size, stored compactly, with
/// optional per-polygon and per-corner attributes. No manifoldness, orientation or
/// connectivity is assumed; duplicate and unreferenced vertices are kept as they are.
struct PolygonSoup : PointSet {
  /// Polygon p has the vertices faceIndices[faceOffsets[p] .. faceOffsets[p + 1]).
  /// faceOffsets always starts with 0 and has polygonCount() + 1 entries.
  std::vector<std::uint32_t> faceOffsets{0};
  std::vector<std::uint32_t> faceIndices;

  /// Scalars per polygon (PLY face properties), carried through warps untouched.
  std::vector<ScalarAttribute> faceAttributes;
  /// Normals per corner (OBJ `f v//n` where a vertex has several normals: creases, flat
  /// shading); transformed by deform() at the corner's vertex. A soup has normals per vertex
  /// (PointSet::normals) or per corner, not both.
  CornerAttribute cornerNormals;
  /// Texture coordinates (u, v, w) per corner (OBJ `vt`), carried through warps untouched.
  CornerAttribute texcoords;
  /// How many of u, v, w the texture coordinates have (1 to 3), so they are written back as
  /// read; the components past it are 0.
  int texcoordDimension = 2;
  /// OBJ groups, objects, smoothing groups and materials, in file order (other formats drop
  /// them).
  std::vector<ObjStatement> objStatements;
  /// What the reader read through but does not keep, one short phrase per kind, in file order
  /// ("OBJ line elements (l)", "PLY element 'edge'"): for a warning that they are not in the
  /// output. Empty for a soup made in memory; never written.
  std::vector<std::string> notKept;

  std::size_t polygonCount() const { return faceOffsets.size() - 1; }

  /// The vertex indices of polygon p.
  std::span<const std::uint32_t> polygon(std::size_t p) const {
    return {faceIndices.data() + faceOffsets[p], faceOffsets[p + 1] - faceOffsets[p]};
  }

  /// Appends a polygon with the given vertex indices (face and corner attributes are not
  /// extended).
  void addPolygon(std::span<const std::uint32_t> vertices) {
    faceIndices.insert(faceIndices.end(), vertices.begin(), vertices.end());
    faceOffsets.push_back(static_cast<std::uint32_t>(faceIndices.size()));
  }
  void addPolygon(std::initializer_list<std::uint32_t> vertices) {
    addPolygon(std::span<const std::uint32_t>(vertices.begin(), vertices.size()));
  }

  /// Whether any corner has a normal or texture coordinate.
  bool hasCornerAttributes() const { return !cornerNormals.empty() || !texcoords.empty(); }

  /// PointSet::validate() plus: offsets well formed, every polygon has at least 3 vertices
  /// (polygons with fewer are rejected), every index refers to a vertex, every face attribute
  /// has one value per polygon, every corner attribute has no indices or one per corner, each
  /// kNone or referring to a value, with finite values; normals not both per vertex and per
  /// corner; texcoordDimension in 1..3; OBJ statements in polygon order, each on one line.
  void validate() const;
};

/// Axis-aligned bounding box of a set of positions. Empty input gives min > max.
struct BoundingBox {
  Vec3 min{std::numeric_limits<double>::infinity()};
  Vec3 max{-std::numeric_limits<double>::infinity()};

  bool empty() const { return min.x > max.x; }
  Vec3 extent() const { return empty() ? Vec3(0.0) : max - min; }
  double diagonal() const { return glm::length(extent()); }
};
BoundingBox boundingBox(std::span<const Vec3> positions);

}  // namespace spacewarp
