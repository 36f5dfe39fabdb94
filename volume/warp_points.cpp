#include <spacewarp/volume/warp_points.h>

#include <sstream>
#include <string>

#include <openvdb/points/PointCount.h>
#include <openvdb/points/PointMove.h>

#include <spacewarp/core/errors.h>

namespace spacewarp {

namespace {

// The deformer movePoints() calls: world-space positions in, warped positions out. Copies
// share the tracker; reset() is called once per leaf.
class WarpDeformer {
 public:
  WarpDeformer(const Warp& warp, ProgressTracker& tracker) : warp_(&warp), tracker_(&tracker) {}

  template <typename LeafT>
  void reset(const LeafT&, std::size_t = 0) {
    tracker_->advance();
  }

  template <typename IterT>
  void apply(openvdb::Vec3d& position, const IterT&) const {
    const Vec3 y = warp_->apply(Vec3(position[0], position[1], position[2]));
    if (!isFinite(y)) {
      std::ostringstream s;
      s << "warpPoints: the warp of the point at (" << position[0] << ", " << position[1] << ", "
        << position[2] << ") is not finite";
      throw InvalidInput(s.str());
    }
    position = openvdb::Vec3d(y.x, y.y, y.z);
  }

 private:
  const Warp* warp_;
  ProgressTracker* tracker_;
};

/// Every leaf must hold positions: movePoints reads "P" from each one.
void requirePositions(const openvdb::points::PointDataGrid& grid) {
  for (auto leaf = grid.tree().cbeginLeaf(); leaf; ++leaf) {
    if (leaf->attributeSet().find("P") == openvdb::points::AttributeSet::INVALID_POS) {
      const openvdb::Coord o = leaf->origin();
      throw InvalidInput("warpPoints: grid '" + printable(grid.getName()) + "': the leaf at (" +
                         std::to_string(o.x()) + ", " + std::to_string(o.y()) + ", " +
                         std::to_string(o.z()) + ") has no position attribute 'P'");
    }
  }
}

}  // namespace

WarpedGrid<openvdb::points::PointDataGrid> warpPoints(const Warp& warp,
                                                      const openvdb::points::PointDataGrid& grid,
                                                      const WarpVolumeOptions& options) {
  requirePositions(grid);
  openvdb::points::PointDataGrid::Ptr out = grid.deepCopy();
  WarpedGrid<openvdb::points::PointDataGrid> result;
  result.report.points = static_cast<std::size_t>(openvdb::points::pointCount(out->tree()));
  ProgressTracker tracker(options.progress, "warp volume", out->tree().leafCount());
  WarpDeformer deformer(warp, tracker);
  try {
    openvdb::points::movePoints(*out, deformer);
  } catch (const openvdb::Exception& e) {
    // Attributes that a corrupt file left inconsistent (types, sizes): the grid's fault.
    throw InvalidInput("warpPoints: grid '" + printable(grid.getName()) +
                       "': OpenVDB cannot move its points: " + printable(e.what()));
  }
  tracker.finish();
  result.grid = out;
  return result;
}

}  // namespace spacewarp
