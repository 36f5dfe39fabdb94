#include <spacewarp/core/deform.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cstdint>
#include <iomanip>
#include <map>
#include <span>
#include <sstream>
#include <string>
#include <vector>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>

#include <spacewarp/core/errors.h>
#include <spacewarp/core/inverse.h>

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
  forEachBlock(n, progress ? std::size_t{1} << 16 : 0, tracker,
               [&](std::size_t begin, std::size_t count) {
                 warp.applyBatch(in, moved, begin, begin + count);
               });
  for (std::size_t i = 0; i < moved.size(); ++i) {
    if (!isFinite(moved[i])) {
      throw InvalidInput("the warp sent vertex " + std::to_string(i) + " to a non-finite position");
    }
  }
  return moved;
}

/// The Jacobians jacobianAt(i) of the vertices whose `needed` flag is set (the others are left
/// zero), and how many of those are singular.
template <class JacobianAt>
std::size_t jacobians(std::size_t n, const std::vector<char>& needed, const JacobianAt& jacobianAt,
                      std::vector<Mat3>& out) {
  out.assign(n, Mat3(0.0));
  return tbb::parallel_reduce(
      tbb::blocked_range<std::size_t>(0, n, 1024), std::size_t{0},
      [&](const tbb::blocked_range<std::size_t>& r, std::size_t singular) {
        for (std::size_t i = r.begin(); i != r.end(); ++i) {
          if (!needed[i]) continue;
          out[i] = jacobianAt(i);
          if (isSingularJacobian(out[i])) ++singular;
        }
        return singular;
      },
      [](std::size_t a, std::size_t b) { return a + b; });
}

/// The corner normals carried by carry(J, n) through the Jacobians J of their vertices, sharing
/// kept where the results agree (see deform()).
template <class Carry>
CornerAttribute transformedCornerNormals(const CornerAttribute& normals,
                                         const std::vector<std::uint32_t>& faceIndices,
                                         const std::vector<Mat3>& jacobian, const Carry& carry) {
  constexpr std::uint32_t kNone = CornerAttribute::kNone;
  const std::size_t corners = normals.indices.size();
  std::vector<Vec3> transformed(corners);
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, corners, 4096),
                    [&](const tbb::blocked_range<std::size_t>& r) {
                      for (std::size_t c = r.begin(); c != r.end(); ++c) {
                        const std::uint32_t k = normals.indices[c];
                        if (k != kNone)
                          transformed[c] = carry(jacobian[faceIndices[c]], normals.values[k]);
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

// The per-vertex normals of `points` carried by carry(J_i, n_i), J_i = jacobianAt(i); returns
// how many J_i are singular. No stored Jacobians here: point clouds can be large. The count is
// an integer sum, the same for any partition.
template <class JacobianAt, class Carry>
std::size_t carryVertexNormals(PointSet& points, const JacobianAt& jacobianAt, const Carry& carry) {
  if (!points.hasNormals()) return 0;
  std::vector<Vec3> normals(points.normals.size());
  const std::size_t singular = tbb::parallel_reduce(
      tbb::blocked_range<std::size_t>(0, normals.size(), 1024), std::size_t{0},
      [&](const tbb::blocked_range<std::size_t>& r, std::size_t singular) {
        for (std::size_t i = r.begin(); i != r.end(); ++i) {
          const Mat3 j = jacobianAt(i);
          if (isSingularJacobian(j)) ++singular;
          normals[i] = carry(j, points.normals[i]);
        }
        return singular;
      },
      [](std::size_t a, std::size_t b) { return a + b; });
  points.normals = std::move(normals);
  return singular;
}

// The per-corner normals of `soup` (validate() excludes per-vertex ones) carried the same way,
// with Jacobians at the vertices that have them only.
template <class JacobianAt, class Carry>
std::size_t carryCornerNormals(PolygonSoup& soup, const JacobianAt& jacobianAt,
                               const Carry& carry) {
  std::vector<char> needed(soup.size(), 0);
  for (std::size_t c = 0; c < soup.faceIndices.size(); ++c)
    if (soup.cornerNormals.indices[c] != CornerAttribute::kNone) needed[soup.faceIndices[c]] = 1;
  std::vector<Mat3> j;
  const std::size_t singular = jacobians(soup.size(), needed, jacobianAt, j);
  soup.cornerNormals = transformedCornerNormals(soup.cornerNormals, soup.faceIndices, j, carry);
  return singular;
}

// A normal carried through the warp: J^-T n, normalised.
Vec3 carryForward(const Mat3& j, const Vec3& n) { return transformNormal(j, n); }

// The preimages of `positions` under `warp`, with the solves' counts in `report`. Throws
// SolverError naming the first vertex whose solve did not converge.
std::vector<Vec3> preimages(const Warp& warp, const std::vector<Vec3>& positions,
                            const InverseOptions& options, const ProgressCallback& progress,
                            InverseDeformReport& report) {
  const std::size_t n = positions.size();
  std::vector<InverseResult> results(n);
  inverseBatch(warp, positions, results, options, progress);
  std::vector<Vec3> x(n);
  std::size_t failures = 0, first = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const InverseResult& r = results[i];
    if (!r.converged && failures++ == 0) first = i;
    x[i] = r.x;
    ++(r.closedForm ? report.closedForm : report.iterative);
    if (r.continuationIterations > 0) ++report.continuation;
    report.maxResidual = std::max(report.maxResidual, r.residual);
  }
  if (failures > 0) {
    const InverseResult& r = results[first];
    const Vec3& y = positions[first];
    // The tolerance the solve was held to (inverse()'s scale, recomputed for this one point).
    const double scale = options.lengthScale > 0.0
                             ? options.lengthScale
                             : std::max({maxAbs(y), maxAbs(warp.apply(y) - y), 1e-300});
    std::ostringstream m;
    m << std::setprecision(17) << "the inverse of the warp did not converge at " << failures
      << " of " << n << " vertices; the first is vertex " << first << " at (" << y.x << ", " << y.y
      << ", " << y.z << ")" << std::setprecision(3) << ": residual " << r.residual
      << " > tolerance " << options.tolerance * scale << " (world units) after "
      << r.iterations + r.continuationIterations << " iterations; the warp may fold space or "
      << "flatten it there, so that the point has no preimage or several";
    throw SolverError(m.str());
  }
  return x;
}

}  // namespace

DeformReport deform(const Warp& warp, PointSet& points, const ProgressCallback& progress) {
  points.validate();
  std::vector<Vec3> moved = movedPositions(warp, points.positions, progress);
  DeformReport report;
  report.singularNormals = carryVertexNormals(
      points, [&](std::size_t i) { return warp.jacobian(points.positions[i]); }, carryForward);
  points.positions = std::move(moved);
  return report;
}

DeformReport deform(const Warp& warp, PolygonSoup& soup, const ProgressCallback& progress) {
  soup.validate();
  if (soup.cornerNormals.empty()) return deform(warp, static_cast<PointSet&>(soup), progress);
  std::vector<Vec3> moved = movedPositions(warp, soup.positions, progress);
  DeformReport report;
  report.singularNormals = carryCornerNormals(
      soup, [&](std::size_t i) { return warp.jacobian(soup.positions[i]); }, carryForward);
  soup.positions = std::move(moved);
  return report;
}

InverseDeformReport deformInverse(const Warp& warp, PointSet& points, const InverseOptions& options,
                                  const ProgressCallback& progress) {
  points.validate();
  InverseDeformReport report;
  std::vector<Vec3> x = preimages(warp, points.positions, options, progress, report);
  report.singularNormals = carryVertexNormals(
      points, [&](std::size_t i) { return warp.jacobian(x[i]); }, transformNormalByInverse);
  points.positions = std::move(x);
  return report;
}

InverseDeformReport deformInverse(const Warp& warp, PolygonSoup& soup,
                                  const InverseOptions& options, const ProgressCallback& progress) {
  soup.validate();
  if (soup.cornerNormals.empty())
    return deformInverse(warp, static_cast<PointSet&>(soup), options, progress);
  InverseDeformReport report;
  std::vector<Vec3> x = preimages(warp, soup.positions, options, progress, report);
  report.singularNormals = carryCornerNormals(
      soup, [&](std::size_t i) { return warp.jacobian(x[i]); }, transformNormalByInverse);
  soup.positions = std::move(x);
  return report;
}

}  // namespace spacewarp
