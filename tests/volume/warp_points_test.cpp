// Tests of volume/warp_points.h: points move to warp(p) with their attributes.

#include <spacewarp/volume/warp_points.h>

#include <random>
#include <string>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <openvdb/points/PointConversion.h>
#include <openvdb/points/PointCount.h>

#include <spacewarp/core/errors.h>
#include <spacewarp/core/twist.h>
#include "volume/volume_test_util.h"

namespace spacewarp {
namespace {

using openvdb::points::PointDataGrid;

struct PointWithId {
  Vec3 p;
  int id;
};

// Every point of the grid (world units) with its "id" attribute.
std::vector<PointWithId> readPoints(const PointDataGrid& grid) {
  std::vector<PointWithId> out;
  for (auto leaf = grid.tree().cbeginLeaf(); leaf; ++leaf) {
    openvdb::points::AttributeHandle<openvdb::Vec3f> position(leaf->constAttributeArray("P"));
    openvdb::points::AttributeHandle<int> id(leaf->constAttributeArray("id"));
    for (auto idx = leaf->beginIndexOn(); idx; ++idx) {
      const openvdb::Vec3d w =
          grid.transform().indexToWorld(position.get(*idx) + idx.getCoord().asVec3d());
      out.push_back({Vec3(w[0], w[1], w[2]), id.get(*idx)});
    }
  }
  return out;
}

PointDataGrid::Ptr makePoints(const std::vector<openvdb::Vec3R>& positions, double voxelSize) {
  return test::makePointGrid(positions, voxelSize);
}

TEST(WarpPoints, MovedPositionsAreTheWarpOfTheOldOnes) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-2.0, 2.0);
  std::vector<openvdb::Vec3R> positions(500);
  for (auto& p : positions) p = openvdb::Vec3R(u(rng), u(rng), u(rng));
  const PointDataGrid::Ptr grid = makePoints(positions, 0.25);
  TwistOptions params;
  params.rate = 0.7;
  params.origin = Vec3(0.3, 0.0, 0.0);
  const TwistWarp twist(params);

  const auto warped = warpPoints(twist, *grid);
  EXPECT_EQ(warped.report.points, positions.size());
  EXPECT_EQ(warped.grid->getName(), "points");
  const std::vector<PointWithId> moved = readPoints(*warped.grid);
  ASSERT_EQ(moved.size(), positions.size());
  for (const PointWithId& m : moved) {
    const openvdb::Vec3R& old = positions[static_cast<std::size_t>(m.id)];
    const Vec3 expected = twist.apply(Vec3(old[0], old[1], old[2]));
    // Positions are stored as float offsets within a voxel.
    EXPECT_NEAR(glm::length(m.p - expected), 0.0, 1e-6) << m.id;
  }
  // The input is untouched.
  EXPECT_EQ(readPoints(*grid).size(), positions.size());
}

// A grid read from a corrupt file may have leaves without positions: refused naming the grid,
// not OpenVDB's LookupError from inside movePoints (found by fuzz_vdb).
TEST(WarpPoints, ALeafWithoutPositionsIsRefusedNamingTheGrid) {
  const PointDataGrid::Ptr grid = makePoints({{0.1, 0.1, 0.1}, {3.0, 3.0, 3.0}}, 0.25);
  auto leaf = grid->tree().beginLeaf();
  ASSERT_TRUE(leaf);
  const auto& descriptor = leaf->attributeSet().descriptor();
  const std::vector<std::size_t> position{descriptor.find("P")};
  auto without = descriptor.duplicateDrop(position);
  leaf->dropAttributes(position, descriptor, without);
  ASSERT_EQ(leaf->attributeSet().find("P"), openvdb::points::AttributeSet::INVALID_POS);
  try {
    warpPoints(TwistWarp(TwistOptions{}), *grid);
    FAIL() << "no InvalidInput";
  } catch (const InvalidInput& e) {
    EXPECT_THAT(e.what(), ::testing::HasSubstr("grid 'points': the leaf at ("));
    EXPECT_THAT(e.what(), ::testing::HasSubstr("has no position attribute 'P'"));
  }
}

}  // namespace
}  // namespace spacewarp
