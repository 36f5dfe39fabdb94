#include <spacewarp/volume/warp_grid.h>

#include <spacewarp/core/errors.h>
#include <spacewarp/volume/warp_points.h>

namespace spacewarp {

namespace {

template <typename GridT>
WarpedGrid<openvdb::GridBase> erase(WarpedGrid<GridT>&& warped) {
  return {warped.grid, warped.report};
}

}  // namespace

bool isWarpableGrid(const openvdb::GridBase& grid) {
  return grid.isType<openvdb::FloatGrid>() || grid.isType<openvdb::DoubleGrid>() ||
         grid.isType<openvdb::Vec3SGrid>() || grid.isType<openvdb::points::PointDataGrid>();
}

bool isFogVolume(const openvdb::GridBase& grid) {
  return (grid.isType<openvdb::FloatGrid>() || grid.isType<openvdb::DoubleGrid>()) &&
         grid.getGridClass() != openvdb::GRID_LEVEL_SET;
}

void checkWarpableGrids(const openvdb::GridPtrVec& grids, const std::string& where) {
  std::string found;
  std::size_t supported = 0;
  for (const openvdb::GridBase::Ptr& grid : grids) {
    if (isWarpableGrid(*grid)) ++supported;
    // Appended piece by piece: GCC 12 warns falsely (-Wrestrict) about "'" + std::string.
    found.append(found.empty() ? "'" : ", '").append(grid->getName()).append("' (");
    found.append(grid->type()).append(")");
  }
  if (supported == 0) {
    throw InvalidInput(where +
                       ": no supported grid (float, double, vec3s or point data grids); found " +
                       (found.empty() ? std::string("no grids") : found));
  }
}

WarpedGrid<openvdb::GridBase> warpGrid(const Warp& warp, const openvdb::GridBase& grid,
                                       const WarpVolumeOptions& options) {
  if (const auto* g = dynamic_cast<const openvdb::FloatGrid*>(&grid))
    return erase(warpVolume(warp, *g, options));
  if (const auto* g = dynamic_cast<const openvdb::DoubleGrid*>(&grid))
    return erase(warpVolume(warp, *g, options));
  if (const auto* g = dynamic_cast<const openvdb::Vec3SGrid*>(&grid))
    return erase(warpVolume(warp, *g, options));
  if (const auto* g = dynamic_cast<const openvdb::points::PointDataGrid*>(&grid))
    return erase(warpPoints(warp, *g, options));
  throw InvalidInput("warpGrid: grid '" + grid.getName() + "' has the unsupported type " +
                     grid.type() + " (supported: float, double, vec3s and point data grids)");
}

}  // namespace spacewarp
