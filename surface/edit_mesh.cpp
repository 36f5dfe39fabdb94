#include <spacewarp/surface/edit_mesh.h>

#include <string>
#include <utility>

#include <spacewarp/core/detail/rotation.h>
#include <spacewarp/core/errors.h>

namespace spacewarp {

namespace {

// Area-weighted normals of the soup's vertices over its own polygons (fanned) at `positions`:
// copies of a vertex that welding joined keep their own polygons' normals, so a flat-shaded soup
// stays flat.
std::vector<Vec3> areaWeightedNormals(const PolygonSoup& soup, std::span<const Vec3> positions) {
  std::vector<Vec3> sum(positions.size(), Vec3(0.0));
  for (std::size_t p = 0; p < soup.polygonCount(); ++p) {
    const auto polygon = soup.polygon(p);
    for (std::size_t c = 1; c + 1 < polygon.size(); ++c) {
      const Vec3& a = positions[polygon[0]];
      const Vec3 n = glm::cross(positions[polygon[c]] - a, positions[polygon[c + 1]] - a);
      for (const std::uint32_t v : {polygon[0], polygon[c], polygon[c + 1]}) sum[v] += n;
    }
  }
  return sum;
}

// Per-vertex normals recomputed at the edited positions, each keeping the side of the input's
// normal (the same recomputation at rest tells which side the input chose). Vertices without
// area keep their normal.
void recomputeVertexNormals(PolygonSoup& soup, std::span<const Vec3> rest) {
  const std::vector<Vec3> before = areaWeightedNormals(soup, rest);
  const std::vector<Vec3> now = areaWeightedNormals(soup, soup.positions);
  for (std::size_t v = 0; v < soup.normals.size(); ++v) {
    const double length = glm::length(now[v]);
    if (!(length > 0.0)) continue;
    const double side = glm::dot(before[v], soup.normals[v]) < 0.0 ? -1.0 : 1.0;
    soup.normals[v] = side * now[v] / length;
  }
}

// The rotation of each soup polygon from rest to edited: the closest rotation to the
// covariance of its triangles' edges, plus its normal's direction (weighted like the edges),
// which fixes the rotation about the polygon's plane. The identity for dropped polygons.
std::vector<Mat3> polygonRotations(const PolygonSoup& soup, const SurfaceMesh& mesh,
                                   std::span<const Vec3> edited) {
  const std::size_t polygons = soup.polygonCount();
  std::vector<Mat3> covariance(polygons, Mat3(0.0));
  std::vector<Vec3> restNormal(polygons, Vec3(0.0)), editedNormal(polygons, Vec3(0.0));
  std::vector<double> scale(polygons, 0.0);
  const std::span<const Vec3> rest = mesh.positions;
  for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
    const auto& tri = mesh.triangles[t];
    const std::uint32_t p = mesh.triangleToPolygon[t];
    for (int k = 0; k < 3; ++k) {
      const Vec3 r = rest[tri[(k + 1) % 3]] - rest[tri[k]];
      const Vec3 e = edited[tri[(k + 1) % 3]] - edited[tri[k]];
      covariance[p] += glm::outerProduct(e, r);
      scale[p] += glm::dot(r, r);
    }
    restNormal[p] += glm::cross(rest[tri[1]] - rest[tri[0]], rest[tri[2]] - rest[tri[0]]);
    editedNormal[p] += glm::cross(edited[tri[1]] - edited[tri[0]], edited[tri[2]] - edited[tri[0]]);
  }
  std::vector<Mat3> rotation(polygons, Mat3(1.0));
  for (std::size_t p = 0; p < polygons; ++p) {
    if (!(scale[p] > 0.0)) continue;
    const double r = glm::length(restNormal[p]), e = glm::length(editedNormal[p]);
    Mat3 b = covariance[p];
    if (r > 0.0 && e > 0.0)
      b += scale[p] * glm::outerProduct(editedNormal[p] / e, restNormal[p] / r);
    rotation[p] = detail::closestRotation(b);
  }
  return rotation;
}

// Corner normals rotated by their polygon's rotation; a normal shared by several corners
// becomes the normalised sum of its rotations. Normals no corner uses are kept.
void rotateCornerNormals(PolygonSoup& soup, const SurfaceMesh& mesh, std::span<const Vec3> edited) {
  CornerAttribute& normals = soup.cornerNormals;
  if (normals.indices.empty()) return;
  const std::vector<Mat3> rotation = polygonRotations(soup, mesh, edited);
  std::vector<Vec3> sum(normals.values.size(), Vec3(0.0));
  for (std::size_t p = 0; p < soup.polygonCount(); ++p)
    for (std::uint32_t c = soup.faceOffsets[p]; c < soup.faceOffsets[p + 1]; ++c)
      if (const std::uint32_t k = normals.indices[c]; k != CornerAttribute::kNone)
        sum[k] += rotation[p] * normals.values[k];
  for (std::size_t k = 0; k < sum.size(); ++k)
    if (const double length = glm::length(sum[k]); length > 0.0)
      normals.values[k] = sum[k] / length;
}

}  // namespace

SurfaceEdit editMesh(const SurfaceMesh& mesh, const VertexConstraints& c,
                     const SurfaceEditOptions& options, const ProgressCallback& progress) {
  SurfaceEdit out;
  switch (options.method) {
    case SurfaceEditMethod::Laplacian:
    case SurfaceEditMethod::BiLaplacian: {
      LinearEditOptions linear;
      linear.method = options.method == SurfaceEditMethod::Laplacian
                          ? LinearEditMethod::Laplacian
                          : LinearEditMethod::BiLaplacian;
      LinearEditor editor(mesh.positions, mesh.triangles, c.vertices, linear);
      const auto held = editor.heldVertices();
      out.heldVertices.assign(held.begin(), held.end());
      out.positions = editor.solve(c.targets);
      break;
    }
    case SurfaceEditMethod::Arap: {
      ArapEditor editor(mesh.positions, mesh.triangles, c.vertices, options.arap);
      const auto held = editor.heldVertices();
      out.heldVertices.assign(held.begin(), held.end());
      ArapResult result = editor.solve(c.targets, progress);
      out.positions = std::move(result.positions);
      out.arapReport = std::move(result.report);
      break;
    }
    case SurfaceEditMethod::CageArap: {
      if (!options.coordinates) {
        throw InvalidInput(
            "editMesh: the cage-subspace method needs coordinates (a cage's or a "
            "lattice's)");
      }
      CageArapEditor editor(mesh.positions, mesh.triangles, options.coordinates, c.vertices,
                            options.cageArap, progress);
      out.clusterCount = editor.clusterCount();
      CageArapResult result = editor.solve(c.targets, progress);
      out.positions = std::move(result.positions);
      out.controlPoints = std::move(result.controlPoints);
      out.cageArapReport = std::move(result.report);
      break;
    }
  }
  for (std::size_t v = 0; v < out.positions.size(); ++v)
    if (!isFinite(out.positions[v])) {
      throw SolverError("editMesh: the edit sent mesh vertex " + std::to_string(v) +
                        " to a non-finite position");
    }
  return out;
}

void applyEdit(PolygonSoup& soup, const SurfaceMesh& mesh, std::span<const Vec3> edited) {
  const std::vector<Vec3> rest = std::exchange(soup.positions, mesh.toSoupPositions(edited));
  if (soup.hasNormals()) recomputeVertexNormals(soup, rest);
  rotateCornerNormals(soup, mesh, edited);
}

}  // namespace spacewarp
