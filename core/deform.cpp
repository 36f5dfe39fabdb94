#include "core/deform.h"

#include <string>
#include <vector>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "core/errors.h"

namespace spacewarp {

void deform(const Warp& warp, PointSet& points) {
  points.validate();
  std::vector<Vec3> moved(points.positions.size());
  warp.applyBatch(points.positions, moved);
  for (std::size_t i = 0; i < moved.size(); ++i) {
    if (!isFinite(moved[i])) {
      throw InvalidInput("the warp sent vertex " + std::to_string(i) +
                         " to a non-finite position");
    }
  }
  if (points.hasNormals()) {
    std::vector<Vec3> normals(points.normals.size());
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, normals.size(), 1024),
                      [&](const tbb::blocked_range<std::size_t>& r) {
                        for (std::size_t i = r.begin(); i != r.end(); ++i)
                          normals[i] = transformNormal(warp, points.positions[i], points.normals[i]);
                      });
    points.normals = std::move(normals);
  }
  points.positions = std::move(moved);
}

void deform(const Warp& warp, PolygonSoup& soup) {
  soup.validate();
  deform(warp, static_cast<PointSet&>(soup));
}

}  // namespace spacewarp
