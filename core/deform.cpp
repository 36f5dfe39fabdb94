#include <spacewarp/core/deform.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cstdint>
#include <map>
#include <span>
#include <string>
#include <vector>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>

#include <spacewarp/core/errors.h>

namespace spacewarp {
namespace {

/// The positions moved through the warp. Throws InvalidInput if one is not finite.
std::vector<Vec3> movedPositions(const Warp& warp, const std::vector<Vec3>& positions,
                                 const ProgressCallback& progress) {
  const std::size_t n = positions.size();
  std::vector<Vec3> moved(n);
  // Without a display, one batch; with one, blocks large enough to keep every core busy inside
  // applyBatch, small enough for a responsive display and cancel.
  ProgressTracker tracker(progress, "deform", n);
  const std::span<const Vec3> in(positions);
  forEachBlock(
      n, progress ? std::size_t{1} << 16 : 0, tracker, [&](std::size_t begin, std::size_t count) {
        warp.applyBatch(in.subspan(begin, count), std::span<Vec3>(moved).subspan(begin, count));
      });
  for (std::size_t i = 0; i < moved.size(); ++i) {
    if (!isFinite(moved[i])) {
      throw InvalidInput("the warp sent vertex " + std::to_string(i) + " to a non-finite position");
    }
  }
  return moved;
}

/// The Jacobians at the positions whose `needed` flag is set (the others are left zero), and
/// how many of those are singular.
std::size_t jacobians(const Warp& warp, const std::vector<Vec3>& positions,
                      const std::vector<char>& needed, std::vector<Mat3>& out) {
  out.assign(positions.size(), Mat3(0.0));
  return tbb::parallel_reduce(
      tbb::blocked_range<std::size_t>(0, positions.size(), 1024), std::size_t{0},
      [&](const tbb::blocked_range<std::size_t>& r, std::size_t singular) {
        for (std::size_t i = r.begin(); i != r.end(); ++i) {
          if (!needed[i]) continue;
          out[i] = warp.jacobian(positions[i]);
          if (isSingularJacobian(out[i])) ++singular;
        }
        return singular;
      },
      [](std::size_t a, std::size_t b) { return a + b; });
}

/// The corner normals carried through the Jacobians of their vertices, sharing kept where
/// the results agree (see deform()).
CornerAttribute transformedCornerNormals(const CornerAttribute& normals,
                                         const std::vector<std::uint32_t>& faceIndices,
                                         const std::vector<Mat3>& jacobian) {
  constexpr std::uint32_t kNone = CornerAttribute::kNone;
  const std::size_t corners = normals.indices.size();
  std::vector<Vec3> transformed(corners);
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, corners, 4096),
                    [&](const tbb::blocked_range<std::size_t>& r) {
                      for (std::size_t c = r.begin(); c != r.end(); ++c) {
                        const std::uint32_t k = normals.indices[c];
                        if (k != kNone)
                          transformed[c] =
                              transformNormal(jacobian[faceIndices[c]], normals.values[k]);
                      }
                    });

  // In corner order, so the layout is the same for any thread count.
  using Key = std::array<std::uint64_t, 4>;
  const auto bits = [](const Vec3& v) {
    return std::array<std::uint64_t, 3>{std::bit_cast<std::uint64_t>(v.x),
                                        std::bit_cast<std::uint64_t>(v.y),
                                        std::bit_cast<std::uint64_t>(v.z)};
  };
  CornerAttribute result;
  result.values = normals.values;
  result.indices.resize(corners, kNone);
  std::vector<char> assigned(normals.values.size(), 0);
  std::map<Key, std::uint32_t> splits;  // (original index, new value) -> appended index
  for (std::size_t c = 0; c < corners; ++c) {
    const std::uint32_t k = normals.indices[c];
    if (k == kNone) continue;
    if (!assigned[k]) {
      assigned[k] = 1;
      result.values[k] = transformed[c];
      result.indices[c] = k;
      continue;
    }
    const auto b = bits(transformed[c]);
    if (b == bits(result.values[k])) {
      result.indices[c] = k;
      continue;
    }
    const auto [it, inserted] = splits.try_emplace(
        Key{k, b[0], b[1], b[2]}, static_cast<std::uint32_t>(result.values.size()));
    if (inserted) {
      if (result.values.size() >= kNone)
        throw InvalidInput("too many distinct corner normals for 32-bit indices");
      result.values.push_back(transformed[c]);
    }
    result.indices[c] = it->second;
  }
  return result;
}

}  // namespace

DeformReport deform(const Warp& warp, PointSet& points, const ProgressCallback& progress) {
  points.validate();
  std::vector<Vec3> moved = movedPositions(warp, points.positions, progress);
  DeformReport report;
  if (points.hasNormals()) {
    // No stored Jacobians here: point clouds can be large. The count is an integer sum, the
    // same for any partition.
    std::vector<Vec3> normals(points.normals.size());
    report.singularNormals = tbb::parallel_reduce(
        tbb::blocked_range<std::size_t>(0, normals.size(), 1024), std::size_t{0},
        [&](const tbb::blocked_range<std::size_t>& r, std::size_t singular) {
          for (std::size_t i = r.begin(); i != r.end(); ++i) {
            const Mat3 j = warp.jacobian(points.positions[i]);
            if (isSingularJacobian(j)) ++singular;
            normals[i] = transformNormal(j, points.normals[i]);
          }
          return singular;
        },
        [](std::size_t a, std::size_t b) { return a + b; });
    points.normals = std::move(normals);
  }
  points.positions = std::move(moved);
  return report;
}

DeformReport deform(const Warp& warp, PolygonSoup& soup, const ProgressCallback& progress) {
  soup.validate();
  if (soup.cornerNormals.empty()) return deform(warp, static_cast<PointSet&>(soup), progress);

  // Per-corner normals (validate() excludes per-vertex ones): Jacobians at their vertices only.
  std::vector<Vec3> moved = movedPositions(warp, soup.positions, progress);
  std::vector<char> needed(soup.size(), 0);
  for (std::size_t c = 0; c < soup.faceIndices.size(); ++c)
    if (soup.cornerNormals.indices[c] != CornerAttribute::kNone) needed[soup.faceIndices[c]] = 1;
  std::vector<Mat3> j;
  DeformReport report;
  report.singularNormals = jacobians(warp, soup.positions, needed, j);
  soup.cornerNormals = transformedCornerNormals(soup.cornerNormals, soup.faceIndices, j);
  soup.positions = std::move(moved);
  return report;
}

}  // namespace spacewarp
