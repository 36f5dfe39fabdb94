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

}  // namespace

WarpedGrid<openvdb::points::PointDataGrid> warpPoints(const Warp& warp,
                                                      const openvdb::points::PointDataGrid& grid,
                                                      const WarpVolumeOptions& options) {
  openvdb::points::PointDataGrid::Ptr out = grid.deepCopy();
  WarpedGrid<openvdb::points::PointDataGrid> result;
  result.report.points = static_cast<std::size_t>(openvdb::points::pointCount(out->tree()));
  ProgressTracker tracker(options.progress, "warp volume", out->tree().leafCount());
  WarpDeformer deformer(warp, tracker);
  openvdb::points::movePoints(*out, deformer);
  tracker.finish();
  result.grid = out;
  return result;
}

}  // namespace spacewarp
