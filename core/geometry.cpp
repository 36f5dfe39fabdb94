#include <spacewarp/core/geometry.h>

#include <string>

#include <spacewarp/core/errors.h>

namespace spacewarp {
namespace {

void validateCornerAttribute(const CornerAttribute& attribute, const char* what,
                             std::size_t cornerCount) {
  if (!attribute.indices.empty() && attribute.indices.size() != cornerCount) {
    throw InvalidInput(std::string(what) + ": " + std::to_string(attribute.indices.size()) +
                       " corner indices for " + std::to_string(cornerCount) + " corners");
  }
  for (std::size_t c = 0; c < attribute.indices.size(); ++c) {
    const std::uint32_t k = attribute.indices[c];
    if (k != CornerAttribute::kNone && k >= attribute.values.size()) {
      throw InvalidInput(std::string(what) + ": corner " + std::to_string(c) + " refers to value " +
                         std::to_string(k) + " but there are only " +
                         std::to_string(attribute.values.size()));
    }
  }
  for (std::size_t k = 0; k < attribute.values.size(); ++k) {
    if (!isFinite(attribute.values[k]))
      throw InvalidInput(std::string(what) + ": value " + std::to_string(k) + " is not finite");
  }
}

}  // namespace

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
    // Offsets that overshoot the index array and come back (only the last is checked above).
    if (faceOffsets[p + 1] > faceIndices.size())
      throw InvalidInput("polygon " + std::to_string(p) + " ends past the face index array");
    for (std::uint32_t v : polygon(p)) {
      if (v >= positions.size()) {
        throw InvalidInput("polygon " + std::to_string(p) + " refers to vertex " +
                           std::to_string(v) + " but there are only " +
                           std::to_string(positions.size()) + " vertices");
      }
    }
  }
  for (const ScalarAttribute& a : faceAttributes) {
    if (a.values.size() != polygonCount()) {
      throw InvalidInput("face attribute '" + a.name + "' has " + std::to_string(a.values.size()) +
                         " values for " + std::to_string(polygonCount()) + " polygons");
    }
  }
  validateCornerAttribute(cornerNormals, "corner normals", faceIndices.size());
  validateCornerAttribute(texcoords, "texture coordinates", faceIndices.size());
  if (hasNormals() && !cornerNormals.empty())
    throw InvalidInput("polygon soup has normals both per vertex and per corner");
  for (std::size_t k = 0; k < objStatements.size(); ++k) {
    const ObjStatement& statement = objStatements[k];
    if (statement.polygon > polygonCount() ||
        (k > 0 && statement.polygon < objStatements[k - 1].polygon)) {
      throw InvalidInput("OBJ statement " + std::to_string(k) + " precedes polygon " +
                         std::to_string(statement.polygon) +
                         ", out of order or past the last polygon");
    }
    if (statement.text.empty() || statement.text.find_first_of("\r\n") != std::string::npos)
      throw InvalidInput("OBJ statement " + std::to_string(k) + " is empty or not one line");
  }
  if (texcoordDimension < 1 || texcoordDimension > 3) {
    throw InvalidInput("texture coordinate dimension " + std::to_string(texcoordDimension) +
                       " is not 1, 2 or 3");
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
