#pragma once
// Shared inputs and comparisons of the volume suites: small grids (a few 10k voxels) so the
// suites stay fast.

#include <cmath>
#include <functional>
#include <vector>

#include <gtest/gtest.h>
#include <openvdb/openvdb.h>
#include <openvdb/points/PointConversion.h>
#include <openvdb/tools/LevelSetSphere.h>
#include <openvdb/tools/PointIndexGrid.h>

#include <spacewarp/core/math.h>
#include <spacewarp/core/warp.h>

namespace spacewarp::test {

/// A Gaussian density exp(-|x - center|² / sigma²) (world units) on voxels of `voxelSize`,
/// active where it exceeds 1e-6.
inline openvdb::FloatGrid::Ptr makeGaussianFog(const Vec3& center, double sigma, double voxelSize) {
  openvdb::initialize();
  auto grid = openvdb::FloatGrid::create(0.0f);
  grid->setTransform(openvdb::math::Transform::createLinearTransform(voxelSize));
  grid->setGridClass(openvdb::GRID_FOG_VOLUME);
  grid->setName("density");
  const double reach = sigma * std::sqrt(std::log(1e6));
  auto acc = grid->getAccessor();
  const int lo[3] = {static_cast<int>(std::floor((center.x - reach) / voxelSize)),
                     static_cast<int>(std::floor((center.y - reach) / voxelSize)),
                     static_cast<int>(std::floor((center.z - reach) / voxelSize))};
  const int hi[3] = {static_cast<int>(std::ceil((center.x + reach) / voxelSize)),
                     static_cast<int>(std::ceil((center.y + reach) / voxelSize)),
                     static_cast<int>(std::ceil((center.z + reach) / voxelSize))};
  for (int i = lo[0]; i <= hi[0]; ++i)
    for (int j = lo[1]; j <= hi[1]; ++j)
      for (int k = lo[2]; k <= hi[2]; ++k) {
        const Vec3 p = Vec3(i, j, k) * voxelSize - center;
        const double v = std::exp(-glm::dot(p, p) / (sigma * sigma));
        if (v > 1e-6) acc.setValue(openvdb::Coord(i, j, k), static_cast<float>(v));
      }
  return grid;
}

/// openvdb::tools::createLevelSetSphere with a name.
inline openvdb::FloatGrid::Ptr makeSphere(double radius, const Vec3& center, double voxelSize,
                                          double halfWidth = 3.0) {
  openvdb::initialize();
  auto grid = openvdb::tools::createLevelSetSphere<openvdb::FloatGrid>(
      static_cast<float>(radius), openvdb::Vec3f(float(center.x), float(center.y), float(center.z)),
      static_cast<float>(voxelSize), static_cast<float>(halfWidth));
  grid->setName("sphere");
  return grid;
}

/// A point data grid "points" of `positions` (world units) on voxels of `voxelSize`, with an
/// integer attribute "id" holding each point's index in `positions`.
inline openvdb::points::PointDataGrid::Ptr makePointGrid(
    const std::vector<openvdb::Vec3R>& positions, double voxelSize) {
  openvdb::initialize();
  const auto xform = openvdb::math::Transform::createLinearTransform(voxelSize);
  const openvdb::points::PointAttributeVector<openvdb::Vec3R> wrapper(positions);
  auto index =
      openvdb::tools::createPointIndexGrid<openvdb::tools::PointIndexGrid>(wrapper, *xform);
  auto grid =
      openvdb::points::createPointDataGrid<openvdb::points::NullCodec,
                                           openvdb::points::PointDataGrid>(*index, wrapper, *xform);
  openvdb::points::appendAttribute<int>(grid->tree(), "id");
  std::vector<int> ids(positions.size());
  for (std::size_t i = 0; i < ids.size(); ++i) ids[i] = static_cast<int>(i);
  openvdb::points::populateAttribute(grid->tree(), index->tree(), "id",
                                     openvdb::points::PointAttributeVector<int>(ids));
  grid->setName("points");
  return grid;
}

/// The world position of a voxel center.
inline Vec3 worldOf(const openvdb::GridBase& grid, const openvdb::Coord& ijk) {
  const openvdb::Vec3d w = grid.indexToWorld(ijk);
  return {w[0], w[1], w[2]};
}

/// True when both grids have the same active voxels and bit-identical values there.
template <typename GridT>
bool bitIdentical(const GridT& a, const GridT& b) {
  if (a.activeVoxelCount() != b.activeVoxelCount()) return false;
  auto acc = b.getConstAccessor();
  for (auto it = a.cbeginValueOn(); it; ++it) {
    if (!it.isVoxelValue()) return false;
    typename GridT::ValueType v;
    if (!acc.probeValue(it.getCoord(), v)) return false;
    if (std::memcmp(&v, &*it, sizeof v) != 0) return false;
  }
  return true;
}

/// A warp given by a function, with the default (finite-difference) Jacobian.
class FunctionWarp final : public Warp {
 public:
  explicit FunctionWarp(std::function<Vec3(const Vec3&)> f) : f_(std::move(f)) {}
  Vec3 apply(const Vec3& x) const override { return f_(x); }

 private:
  std::function<Vec3(const Vec3&)> f_;
};

}  // namespace spacewarp::test
