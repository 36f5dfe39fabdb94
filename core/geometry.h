#pragma once
// Geometry containers: point sets and polygon soups. Positions are in world units, double.

#include <cstdint>
#include <initializer_list>
#include <limits>
#include <span>
#include <string>
#include <vector>

#include "core/math.h"

namespace spacewarp {

/// The storage type a per-vertex attribute was read with, so that writing it back to a PLY
/// file keeps its type. Values are held as double, which represents every type exactly.
enum class ScalarType { Int8, UInt8, Int16, UInt16, Int32, UInt32, Float32, Float64 };

/// A named scalar per vertex (PLY "red", "confidence", "label", ...), carried through warps
/// untouched.
struct VertexAttribute {
  std::string name;
  ScalarType type = ScalarType::Float64;
  std::vector<double> values;  ///< One per vertex.
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

/// A polygon soup: vertices (as a PointSet) and polygons of any size, stored compactly.
/// No manifoldness, orientation or connectivity is assumed; duplicate and unreferenced
/// vertices are kept as they are.
struct PolygonSoup : PointSet {
  /// Polygon p has the vertices faceIndices[faceOffsets[p] .. faceOffsets[p + 1]).
  /// faceOffsets always starts with 0 and has polygonCount() + 1 entries.
  std::vector<std::uint32_t> faceOffsets{0};
  std::vector<std::uint32_t> faceIndices;

  std::size_t polygonCount() const { return faceOffsets.size() - 1; }

  /// The vertex indices of polygon p.
  std::span<const std::uint32_t> polygon(std::size_t p) const {
    return {faceIndices.data() + faceOffsets[p], faceOffsets[p + 1] - faceOffsets[p]};
  }

  /// Appends a polygon with the given vertex indices.
  void addPolygon(std::span<const std::uint32_t> vertices) {
    faceIndices.insert(faceIndices.end(), vertices.begin(), vertices.end());
    faceOffsets.push_back(static_cast<std::uint32_t>(faceIndices.size()));
  }
  void addPolygon(std::initializer_list<std::uint32_t> vertices) {
    addPolygon(std::span<const std::uint32_t>(vertices.begin(), vertices.size()));
  }

  /// PointSet::validate() plus: offsets well formed, every polygon has at least 3 vertices
  /// (polygons with fewer are rejected), every index refers to a vertex.
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
