#include <spacewarp/surface/handles.h>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <string>

#include <spacewarp/core/errors.h>
#include <spacewarp/core/geometry.h>

namespace spacewarp {

namespace {

std::string regionName(std::size_t r) { return "handle region " + std::to_string(r); }

void checkMatrix(const Mat4& m, std::size_t r) {
  for (int c = 0; c < 4; ++c)
    for (int row = 0; row < 4; ++row)
      if (!std::isfinite(m[c][row])) {
        throw InvalidInput("resolveHandles: " + regionName(r) + ": the matrix is not finite");
      }
  if (m[0][3] != 0.0 || m[1][3] != 0.0 || m[2][3] != 0.0 || m[3][3] != 1.0) {
    throw InvalidInput("resolveHandles: " + regionName(r) +
                       ": the matrix is not affine (its last row must be 0 0 0 1)");
  }
}

// Sorts by vertex and merges repeats, which must agree to `tolerance`; `describe` names an
// entry for the message.
template <class Describe>
VertexConstraints sortAndMerge(std::vector<std::uint32_t> vertices, std::vector<Vec3> targets,
                               double tolerance, const Describe& describe) {
  std::vector<std::size_t> order(vertices.size());
  std::iota(order.begin(), order.end(), std::size_t{0});
  std::stable_sort(order.begin(), order.end(),
                   [&](std::size_t a, std::size_t b) { return vertices[a] < vertices[b]; });
  VertexConstraints out;
  std::size_t last = 0;
  for (std::size_t k : order) {
    if (!out.vertices.empty() && out.vertices.back() == vertices[k]) {
      if (glm::length(out.targets.back() - targets[k]) > tolerance) {
        throw InvalidInput("conflicting targets: " + describe(last) + " and " + describe(k) +
                           " move vertex " + std::to_string(vertices[k]) + " to different places");
      }
      continue;
    }
    out.vertices.push_back(vertices[k]);
    out.targets.push_back(targets[k]);
    last = k;
  }
  return out;
}

}  // namespace

VertexConstraints resolveHandles(std::span<const HandleRegion> regions,
                                 std::span<const Vec3> rest) {
  std::vector<std::uint32_t> vertices;
  std::vector<Vec3> targets;
  std::vector<std::size_t> regionOf;
  for (std::size_t r = 0; r < regions.size(); ++r) {
    const HandleRegion& region = regions[r];
    if (region.vertices.empty()) {
      throw InvalidInput("resolveHandles: " + regionName(r) + " has no vertices");
    }
    if (region.matrix) {
      checkMatrix(*region.matrix, r);
    } else if (region.targets.size() != region.vertices.size()) {
      throw InvalidInput("resolveHandles: " + regionName(r) + " has " +
                         std::to_string(region.vertices.size()) + " vertices but " +
                         std::to_string(region.targets.size()) + " targets");
    }
    for (std::size_t k = 0; k < region.vertices.size(); ++k) {
      const std::uint32_t v = region.vertices[k];
      if (v >= rest.size()) {
        throw InvalidInput("resolveHandles: " + regionName(r) + ", vertex entry " +
                           std::to_string(k) + ": index " + std::to_string(v) +
                           " is out of range (the model has " + std::to_string(rest.size()) +
                           " vertices)");
      }
      Vec3 t;
      if (region.matrix) {
        t = Vec3(*region.matrix * glm::dvec4(rest[v], 1.0));
      } else {
        t = region.targets[k];
        if (!isFinite(t)) {
          throw InvalidInput("resolveHandles: " + regionName(r) + ", target entry " +
                             std::to_string(k) + " is not finite");
        }
      }
      vertices.push_back(v);
      targets.push_back(t);
      regionOf.push_back(r);
    }
  }
  const double tolerance = 1e-9 * boundingBox(rest).diagonal();
  try {
    return sortAndMerge(std::move(vertices), std::move(targets), tolerance,
                        [&](std::size_t k) { return regionName(regionOf[k]); });
  } catch (const InvalidInput& e) {
    throw InvalidInput(std::string("resolveHandles: ") + e.what());
  }
}

VertexConstraints mapConstraints(const VertexConstraints& constraints,
                                 std::span<const std::uint32_t> vertexMap, double tolerance) {
  std::vector<std::uint32_t> mapped;
  mapped.reserve(constraints.vertices.size());
  for (std::uint32_t v : constraints.vertices) {
    if (v >= vertexMap.size()) {
      throw InvalidInput("mapConstraints: vertex " + std::to_string(v) + " is out of range");
    }
    mapped.push_back(vertexMap[v]);
  }
  try {
    return sortAndMerge(std::move(mapped), constraints.targets, tolerance, [&](std::size_t k) {
      return "input vertex " + std::to_string(constraints.vertices[k]);
    });
  } catch (const InvalidInput& e) {
    throw InvalidInput(std::string("mapConstraints: ") + e.what() + " (they were welded into one)");
  }
}

}  // namespace spacewarp
