// The OpenVDB baseline of volume_bench.cpp: tools::GridResampler with a non-affine
// transformer (the twist and its closed-form inverse, in index space). Compiled as C++17
// because OpenVDB 10's GridResampler bodies do not satisfy oneTBB's C++20 parallel_reduce
// concepts; it includes no spacewarp header.

#include <cmath>
#include <cstddef>

#include <openvdb/openvdb.h>
#include <openvdb/tools/GridTransformer.h>

namespace {

// x' = o + R(rate * (x - o).z) (x - o), rotation about +z; world = voxel * index.
class TwistTransformer {
 public:
  TwistTransformer(const openvdb::Vec3d& origin, double rate, double voxel)
      : origin_(origin), rate_(rate), voxel_(voxel) {}
  bool isAffine() const { return false; }
  openvdb::Vec3R transform(const openvdb::Vec3R& i) const { return turn(i, rate_); }
  openvdb::Vec3R invTransform(const openvdb::Vec3R& j) const { return turn(j, -rate_); }

 private:
  // The twist keeps the axial coordinate, so the inverse turns back by the same angle.
  openvdb::Vec3R turn(const openvdb::Vec3R& index, double rate) const {
    const openvdb::Vec3d d = index * voxel_ - origin_;
    const double a = rate * d.z();
    const openvdb::Vec3d x(std::cos(a) * d.x() - std::sin(a) * d.y(),
                           std::sin(a) * d.x() + std::cos(a) * d.y(), d.z());
    return (x + origin_) / voxel_;
  }

  openvdb::Vec3d origin_;
  double rate_, voxel_;
};

}  // namespace

/// Twists `grid` (uniform voxels of `voxel`) with OpenVDB's GridResampler; returns the output's
/// active voxel count.
std::size_t openVdbTwistResample(const openvdb::FloatGrid& grid, const openvdb::Vec3d& origin,
                                 double rate, double voxel) {
  auto result = openvdb::FloatGrid::create(grid.background());
  result->setTransform(grid.transform().copy());
  result->setGridClass(openvdb::GRID_LEVEL_SET);
  openvdb::tools::GridResampler resampler;
  resampler.transformGrid<openvdb::tools::BoxSampler>(TwistTransformer(origin, rate, voxel), grid,
                                                      *result);
  return static_cast<std::size_t>(result->activeVoxelCount());
}
