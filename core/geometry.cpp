#include "core/geometry.h"

#include <string>

#include "core/errors.h"

namespace spacewarp {

void PointSet::validate() const {
  const std::size_t n = positions.size();
  for (std::size_t i = 0; i < n; ++i) {
    if (!isFinite(positions[i]))
      throw InvalidInput("vertex " + std::to_string(i) + " has a non-finite coordinate");
  }
  if (!normals.empty() && normals.size() != n) {
    throw InvalidInput("point set has " + std::to_string(n) + " positions but " +
                       std::to_string(normals.size()) + " normals");
  }
  for (std::size_t i = 0; i < normals.size(); ++i) {
    if (!isFinite(normals[i]))
      throw InvalidInput("normal " + std::to_string(i) + " has a non-finite component");
  }
  for (const VertexAttribute& a : attributes) {
    if (a.values.size() != n) {
      throw InvalidInput("attribute '" + a.name + "' has " + std::to_string(a.values.size()) +
                         " values for " + std::to_string(n) + " vertices");
    }
  }
}

void PolygonSoup::validate() const {
  PointSet::validate();
  if (faceOffsets.empty() || faceOffsets.front() != 0 || faceOffsets.back() != faceIndices.size())
    throw InvalidInput("polygon soup: face offsets do not match the face index array");
  for (std::size_t p = 0; p < polygonCount(); ++p) {
    if (faceOffsets[p + 1] < faceOffsets[p] || faceOffsets[p + 1] - faceOffsets[p] < 3) {
      throw InvalidInput("polygon " + std::to_string(p) + " has fewer than 3 vertices");
    }
    for (std::uint32_t v : polygon(p)) {
      if (v >= positions.size()) {
        throw InvalidInput("polygon " + std::to_string(p) + " refers to vertex " +
                           std::to_string(v) + " but there are only " +
                           std::to_string(positions.size()) + " vertices");
      }
    }
  }
}

BoundingBox boundingBox(std::span<const Vec3> positions) {
  BoundingBox box;
  for (const Vec3& p : positions) {
    box.min = glm::min(box.min, p);
    box.max = glm::max(box.max, p);
  }
  return box;
}

}  // namespace spacewarp
