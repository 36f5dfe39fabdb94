#include "core/deform.h"

#include <algorithm>
#include <span>
#include <string>
#include <vector>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "core/errors.h"

namespace spacewarp {

void deform(const Warp& warp, PointSet& points, const ProgressCallback& progress) {
  points.validate();
  const std::size_t n = points.positions.size();
  std::vector<Vec3> moved(n);
  if (!progress) {
    warp.applyBatch(points.positions, moved);
  } else {
    // Blocks large enough to keep every core busy inside applyBatch, small enough for a
    // responsive display and cancel.
    constexpr std::size_t kBlock = std::size_t{1} << 16;
    ProgressTracker tracker(progress, "deform", n);
    const std::span<const Vec3> in(points.positions);
    for (std::size_t begin = 0; begin < n; begin += kBlock) {
      const std::size_t count = std::min(kBlock, n - begin);
      warp.applyBatch(in.subspan(begin, count), std::span<Vec3>(moved).subspan(begin, count));
      tracker.advance(count);
    }
    tracker.finish();
  }
  for (std::size_t i = 0; i < moved.size(); ++i) {
    if (!isFinite(moved[i])) {
      throw InvalidInput("the warp sent vertex " + std::to_string(i) + " to a non-finite position");
    }
  }
  if (points.hasNormals()) {
    std::vector<Vec3> normals(points.normals.size());
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, normals.size(), 1024),
                      [&](const tbb::blocked_range<std::size_t>& r) {
                        for (std::size_t i = r.begin(); i != r.end(); ++i)
                          normals[i] =
                              transformNormal(warp, points.positions[i], points.normals[i]);
                      });
    points.normals = std::move(normals);
  }
  points.positions = std::move(moved);
}

void deform(const Warp& warp, PolygonSoup& soup, const ProgressCallback& progress) {
  soup.validate();
  deform(warp, static_cast<PointSet&>(soup), progress);
}

}  // namespace spacewarp
