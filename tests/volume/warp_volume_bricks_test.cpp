#include <spacewarp/volume/warp_volume_bricks.h>

#include <vector>

#include <gtest/gtest.h>

#include <spacewarp/core/errors.h>
#include <spacewarp/core/twist.h>

#include "volume/volume_test_util.h"

namespace spacewarp {
namespace {

// Plan, every brick from the whole grid (or a clipped copy), the merge: the bricked result.
template <typename GridT>
typename GridT::Ptr bricked(const Warp& warp, const GridT& grid, const WarpVolumeOptions& options,
                            int brickSize, std::size_t* brickCount = nullptr) {
  const VolumeBrickPlan plan = planVolumeBricks(warp, grid, options, {.brickSize = brickSize});
  if (brickCount) *brickCount = plan.bricks.size();
  std::vector<WarpedBrick> bricks;
  for (const VolumeBrick& brick : plan.bricks) {
    // A clipped copy of the input stands for a worker's clipped read.
    typename GridT::Ptr clipped = grid.deepCopy();
    clipped->clip(brick.input);
    bricks.push_back(warpVolumeBrick(warp, *clipped, options, brick, plan.rigid, true));
    EXPECT_EQ(bricks.back().haloMisses, 0u);
  }
  auto merged = mergeVolumeBricks(bricks, plan, double(grid.background()), options);
  return openvdb::gridPtrCast<GridT>(merged.grid);
}

TEST(WarpVolumeBricks, LevelSetEqualsTheSingleProcessWarpBitForBit) {
  const auto sphere = test::makeSphere(1.0, Vec3(0.1, -0.05, 0.2), 1.0 / 12);
  for (const double rate : {0.3, 4.0}) {                // smooth, and strongly non-rigid
    const TwistWarp twist(TwistOptions{.rate = rate});  // about z
    const auto single = warpVolume(twist, *sphere).grid;
    std::size_t count = 0;
    const auto merged = bricked(twist, *sphere, {}, 16, &count);
    EXPECT_GT(count, 12u);
    ASSERT_TRUE(merged);
    EXPECT_GT(single->activeVoxelCount(), 0u);
    EXPECT_TRUE(test::bitIdentical(*single, *merged)) << "rate " << rate;
    EXPECT_EQ(merged->getGridClass(), openvdb::GRID_LEVEL_SET);
  }
}

TEST(WarpVolumeBricks, FogVolumeEqualsTheSingleProcessWarpWithConservedMass) {
  const auto fog = test::makeGaussianFog(Vec3(0.0, 0.1, 0.0), 0.4, 1.0 / 16);
  WarpVolumeOptions options;
  options.conserveMass = true;
  const TwistWarp twist(TwistOptions{.rate = 2.0});  // about z
  const auto single = warpVolume(twist, *fog, options);
  const auto merged = bricked(twist, *fog, options, 8);
  EXPECT_TRUE(test::bitIdentical(*single.grid, *merged));
}

TEST(WarpVolumeBricks, RefusesTheCacheAndBadSizes) {
  const auto sphere = test::makeSphere(1.0, Vec3(0.0), 0.1);
  const TwistWarp twist(TwistOptions{.rate = 1.0});  // about z
  WarpVolumeOptions cached;
  cached.cacheSpacing = 2.0;
  EXPECT_THROW(planVolumeBricks(twist, *sphere, cached), InvalidInput);
  EXPECT_THROW(planVolumeBricks(twist, *sphere, {}, {.brickSize = 0}), InvalidInput);
  EXPECT_THROW(mergeVolumeBricks({}, {}, 0.0, {}), InvalidInput);
}

}  // namespace
}  // namespace spacewarp
