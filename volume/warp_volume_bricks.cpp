#include <spacewarp/volume/warp_volume_bricks.h>

#include <algorithm>
#include <cstdint>
#include <map>
#include <sstream>
#include <string>
#include <tuple>
#include <type_traits>
#include <utility>

#include <openvdb/io/File.h>
#include <openvdb/io/Stream.h>

#include <spacewarp/core/errors.h>
#include <spacewarp/volume/detail/warp_volume_parts.h>
#include <spacewarp/volume/read_vdb.h>

namespace spacewarp {

namespace {

using openvdb::Coord;
using openvdb::CoordBBox;

std::int32_t floorDiv(std::int32_t a, std::int32_t b) {
  return a >= 0 ? a / b : -((-a + b - 1) / b);
}

Coord scaled(const Coord& a, std::int32_t s) { return {a.x() * s, a.y() * s, a.z() * s}; }

Coord floorDiv(const Coord& a, std::int32_t b) {
  return {floorDiv(a.x(), b), floorDiv(a.y(), b), floorDiv(a.z(), b)};
}

bool coordLess(const Coord& a, const Coord& b) {
  return std::make_tuple(a.x(), a.y(), a.z()) < std::make_tuple(b.x(), b.y(), b.z());
}

struct CoordLess {
  bool operator()(const Coord& a, const Coord& b) const { return coordLess(a, b); }
};

// The bricks' leaves in one grid of type GridT, then the level-set step.
template <typename GridT>
WarpedGrid<openvdb::GridBase> merge(const std::vector<WarpedBrick>& bricks,
                                    const VolumeBrickPlan& plan, double inputBackground,
                                    const WarpVolumeOptions& options) {
  using LeafT = typename GridT::TreeType::LeafNodeType;
  const GridT& first = static_cast<const GridT&>(*bricks.front().grid);
  typename GridT::Ptr grid = first.copyWithNewTree();
  // Statistics of the stream the brick travelled in, not of this grid.
  std::vector<std::string> stale;
  for (auto it = grid->beginMeta(); it != grid->endMeta(); ++it)
    if (it->first.rfind("file_", 0) == 0) stale.push_back(it->first);
  for (const std::string& name : stale) grid->removeMeta(name);
  WarpVolumeReport report = plan.report;
  for (const WarpedBrick& brick : bricks) {
    const auto* g = dynamic_cast<const GridT*>(brick.grid.get());
    if (!g) throw InvalidInput("mergeVolumeBricks: the bricks are grids of different types");
    // Bricks own disjoint leaves and no tiles, so the merged tree is the single-process one.
    for (auto leaf = g->tree().cbeginLeaf(); leaf; ++leaf)
      grid->tree().addLeaf(new LeafT(*leaf.getLeaf()));
    const WarpVolumeReport& r = brick.report;
    report.solvedVoxels += r.solvedVoxels;
    report.inverseFailures += r.inverseFailures;
    report.vectorFailures += r.vectorFailures;
    report.totalNewtonIterations += r.totalNewtonIterations;
    report.maxNewtonIterations = std::max(report.maxNewtonIterations, r.maxNewtonIterations);
    report.massAfter += r.massAfter;
    detail::joinVolumeChange(report, r.minVolumeChange, r.maxVolumeChange);
    report.degenerateVolumeChanges += r.degenerateVolumeChanges;
    report.vectors = r.vectors;
  }
  openvdb::GridBase::Ptr out = grid;
  if constexpr (std::is_floating_point_v<typename GridT::ValueType>) {
    if (grid->getGridClass() == openvdb::GRID_LEVEL_SET)
      detail::redistanceVolume(out, inputBackground, plan.rigid, plan.smallestStretch, options,
                               report);
  }
  report.outputActiveVoxels = static_cast<std::size_t>(out->activeVoxelCount());
  return {out, report};
}

}  // namespace

VolumeBrickPlan planVolumeBricks(const Warp& warp, const openvdb::GridBase& grid,
                                 const WarpVolumeOptions& options,
                                 const VolumeBrickOptions& brickOptions) {
  if (brickOptions.brickSize < 1 || brickOptions.halo < 0) {
    throw InvalidInput("planVolumeBricks: brickSize must be >= 1 and halo >= 0, got " +
                       std::to_string(brickOptions.brickSize) + " and " +
                       std::to_string(brickOptions.halo));
  }
  if (options.cacheSpacing > 0.0) {
    throw InvalidInput("planVolumeBricks: grid '" + grid.getName() +
                       "': cacheSpacing cannot be used when warping in bricks (its lattice "
                       "depends on every cell of the grid)");
  }
  constexpr int kLeaf = 8;  // the leaf edge of every grid type warpVolume() takes
  const int size = (brickOptions.brickSize + kLeaf - 1) / kLeaf * kLeaf;
  const int c = options.seedSpacing;
  VolumeBrickPlan plan;
  const detail::VolumeCellImages images =
      detail::volumeCellImages(warp, grid, options, plan.report);
  plan.rigid = images.rigid;
  plan.smallestStretch = images.smallestStretch;
  // Every brick that a cell's output box meets lists the cell; keys arrive sorted.
  std::map<Coord, VolumeBrick, CoordLess> bricks;
  for (std::size_t i = 0; i < images.keys.size(); ++i) {
    const CoordBBox& box = images.outBoxes[i];
    if (box.empty()) continue;
    const Coord lo = floorDiv(box.min(), size), hi = floorDiv(box.max(), size);
    const Coord& key = images.keys[i];
    const CoordBBox cellBox(scaled(key, c), scaled(key, c) + Coord(c - 1));
    for (int x = lo.x(); x <= hi.x(); ++x)
      for (int y = lo.y(); y <= hi.y(); ++y)
        for (int z = lo.z(); z <= hi.z(); ++z) {
          VolumeBrick& brick = bricks[Coord(x, y, z)];
          if (brick.cells.empty()) {
            const Coord corner = scaled(Coord(x, y, z), size);
            brick.output = CoordBBox(corner, corner + Coord(size - 1));
            brick.input = cellBox;
          }
          brick.cells.push_back(key);
          brick.input.expand(cellBox);
        }
  }
  // The stencil (2 voxels) and the seeds' slack (at most 2 voxels) come on top of the halo.
  const int margin = brickOptions.halo + 4;
  plan.bricks.reserve(bricks.size());
  for (auto& [corner, brick] : bricks) {
    brick.input.expand(margin);
    plan.bricks.push_back(std::move(brick));
  }
  return plan;
}

WarpedBrick warpVolumeBrick(const Warp& warp, const openvdb::GridBase& input,
                            const WarpVolumeOptions& options, const VolumeBrick& brick, bool rigid,
                            bool clipped) {
  detail::VolumePart part;
  part.cellKeys = brick.cells;
  part.outputBox = brick.output;
  part.rigid = rigid;
  if (clipped) part.validInput = brick.input;
  WarpedGrid<openvdb::GridBase> r = detail::warpVolumePart(warp, input, options, part);
  return {r.grid, r.report, part.haloMisses};
}

WarpedGrid<openvdb::GridBase> mergeVolumeBricks(const std::vector<WarpedBrick>& bricks,
                                                const VolumeBrickPlan& plan, double inputBackground,
                                                const WarpVolumeOptions& options) {
  if (bricks.empty() || !bricks.front().grid)
    throw InvalidInput("mergeVolumeBricks: no bricks to merge");
  const openvdb::GridBase& first = *bricks.front().grid;
  if (first.isType<openvdb::FloatGrid>())
    return merge<openvdb::FloatGrid>(bricks, plan, inputBackground, options);
  if (first.isType<openvdb::DoubleGrid>())
    return merge<openvdb::DoubleGrid>(bricks, plan, inputBackground, options);
  if (first.isType<openvdb::Vec3SGrid>())
    return merge<openvdb::Vec3SGrid>(bricks, plan, inputBackground, options);
  throw InvalidInput("mergeVolumeBricks: bricks of type " + first.type() +
                     " (float, double and vec3s grids can be merged)");
}

openvdb::GridBase::Ptr readVdbGridRegion(const std::filesystem::path& path, const std::string& name,
                                         const CoordBBox& region) {
  // Checks the file's header and that every grid's recorded end lies within it first.
  readVdbFile(path, /*headerOnly=*/true);
  try {
    openvdb::io::File file(path.string());
    file.open();
    if (!file.hasGrid(name)) throw IoError(path.string() + ": no grid named '" + name + "'");
    const openvdb::GridBase::ConstPtr meta = file.readGridMetadata(name);
    // The index box one voxel wider, as a world box whose index box holds it.
    const CoordBBox wide = region.expandBy(1);
    openvdb::BBoxd world;
    for (int d = 0; d < 8; ++d) {
      const openvdb::Vec3d corner((d & 1) ? wide.max().x() : wide.min().x(),
                                  (d & 2) ? wide.max().y() : wide.min().y(),
                                  (d & 4) ? wide.max().z() : wide.min().z());
      world.expand(meta->transform().indexToWorld(corner));
    }
    openvdb::GridBase::Ptr grid = file.readGrid(name, world);
    file.close();
    if (!grid) throw IoError(path.string() + ": grid '" + name + "' could not be read");
    return grid;
  } catch (const IoError&) {
    throw;
  } catch (const std::exception& e) {
    throw IoError(path.string() + ": grid '" + name + "' could not be read: " + e.what());
  }
}

std::string gridToBytes(const openvdb::GridBase& grid) {
  std::ostringstream os(std::ios_base::binary);
  // The grid itself, not a copy: Stream::write takes shared pointers it does not keep.
  const openvdb::GridCPtrVec grids{openvdb::GridBase::ConstPtr(&grid, [](const auto*) {})};
  openvdb::io::Stream stream(os);
  stream.setCompression(openvdb::io::COMPRESS_ACTIVE_MASK);  // lossless and cheap; no zip
  stream.write(grids);
  return std::move(os).str();
}

openvdb::GridBase::Ptr gridFromBytes(const std::string& bytes) {
  openvdb::initialize();
  try {
    std::istringstream is(bytes, std::ios_base::binary);
    openvdb::io::Stream stream(is);
    const openvdb::GridPtrVecPtr grids = stream.getGrids();
    if (!grids || grids->size() != 1 || !grids->front())
      throw InvalidInput("gridFromBytes: the bytes do not hold one grid");
    return grids->front();
  } catch (const openvdb::Exception& e) {
    throw InvalidInput(std::string("gridFromBytes: not an OpenVDB grid stream: ") + e.what());
  }
}

}  // namespace spacewarp
