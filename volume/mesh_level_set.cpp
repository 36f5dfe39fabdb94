#include <spacewarp/volume/mesh_level_set.h>

#include <cmath>
#include <string>
#include <vector>

#include <openvdb/tools/MeshToVolume.h>

#include <spacewarp/core/errors.h>

namespace spacewarp {

openvdb::FloatGrid::Ptr meshLevelSet(const PolygonSoup& closed, double voxelSize, float halfWidth) {
  if (!std::isfinite(voxelSize) || !(voxelSize > 0.0))
    throw InvalidInput("meshLevelSet: the voxel size must be finite and > 0, not " +
                       std::to_string(voxelSize));
  if (!std::isfinite(halfWidth) || !(halfWidth > 0.0f))
    throw InvalidInput("meshLevelSet: the half width must be finite and > 0");
  closed.validate();
  openvdb::initialize();
  const auto transform = openvdb::math::Transform::createLinearTransform(voxelSize);
  std::vector<openvdb::Vec3s> points;
  points.reserve(closed.positions.size());
  for (const Vec3& p : closed.positions)
    points.emplace_back(p.x, p.y, p.z);  // world space: meshToLevelSet applies the transform
  std::vector<openvdb::Vec3I> triangles;
  std::vector<openvdb::Vec4I> quads;
  for (std::size_t f = 0; f < closed.polygonCount(); ++f) {
    const auto poly = closed.polygon(f);
    if (poly.size() == 4) {
      quads.emplace_back(poly[0], poly[1], poly[2], poly[3]);
    } else {
      for (std::size_t k = 1; k + 1 < poly.size(); ++k)
        triangles.emplace_back(poly[0], poly[k], poly[k + 1]);
    }
  }
  return openvdb::tools::meshToLevelSet<openvdb::FloatGrid>(*transform, points, triangles, quads,
                                                            halfWidth);
}

}  // namespace spacewarp
