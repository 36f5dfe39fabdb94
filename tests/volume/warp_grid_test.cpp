// Tests of volume/warp_grid.h: grids of any type are dispatched to the right warper or
// rejected by name.

#include <spacewarp/volume/warp_grid.h>

#include <string>

#include <gtest/gtest.h>

#include <spacewarp/core/errors.h>
#include <spacewarp/core/twist.h>
#include "volume/volume_test_util.h"

namespace spacewarp {
namespace {

TEST(WarpGrid, DispatchesByTypeAndRejectsUnsupportedGridsByName) {
  openvdb::initialize();
  const auto fog = test::makeGaussianFog(Vec3(0.0), 0.5, 0.2);
  const TwistWarp twist(TwistOptions{});
  const auto warped = warpGrid(twist, *fog);
  ASSERT_TRUE(warped.grid);
  EXPECT_TRUE(warped.grid->isType<openvdb::FloatGrid>());
  EXPECT_EQ(warped.report.outputActiveVoxels, static_cast<std::size_t>(fog->activeVoxelCount()));

  auto mask = openvdb::BoolGrid::create(false);
  mask->setName("occupancy");
  EXPECT_FALSE(isWarpableGrid(*mask));
  try {
    warpGrid(twist, *mask);
    ADD_FAILURE() << "no exception";
  } catch (const InvalidInput& e) {
    EXPECT_NE(std::string(e.what()).find("occupancy"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace spacewarp
