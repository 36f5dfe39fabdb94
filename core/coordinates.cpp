#include <spacewarp/core/coordinates.h>

#include <string>

#include <spacewarp/core/coordinate_warp.h>
#include <spacewarp/core/detail/batch.h>
#include <spacewarp/core/errors.h>

namespace spacewarp {

std::string Coordinates::columnName(std::size_t c) const {
  const std::size_t n = controlPointCount();
  // Built by append: GCC 12 warns (-Wrestrict, falsely) on "literal" + std::string.
  std::string name(1, c < n ? 'v' : 'f');
  name += std::to_string(c < n ? c : c - n);
  return name;
}

void Coordinates::checkWeightsArguments(const Vec3& x, std::size_t rowSize) const {
  if (!isFinite(x)) throw InvalidInput("coordinates: the query point is not finite");
  if (rowSize != columnCount()) {
    throw InvalidInput("coordinates: the weight row has " + std::to_string(rowSize) +
                       " entries but there are " + std::to_string(columnCount()) + " columns");
  }
}

void Coordinates::weightsBatch(std::span<const Vec3> points, std::span<double> rows) const {
  weightsBatch(points, 0, points.size(), rows);
}

void Coordinates::weightsBatch(std::span<const Vec3> points, std::size_t begin, std::size_t end,
                               std::span<double> rows) const {
  if (begin > end || end > points.size()) {
    throw InvalidInput("coordinates: the block [" + std::to_string(begin) + ", " +
                       std::to_string(end) + ") is not within the " +
                       std::to_string(points.size()) + " points");
  }
  const std::size_t m = columnCount(), n = end - begin;
  if (rows.size() != n * m) {
    throw InvalidInput("coordinates: " + std::to_string(n) + " points need " +
                       std::to_string(n * m) + " weights but the output has " +
                       std::to_string(rows.size()));
  }
  for (std::size_t i = begin; i < end; ++i) {
    if (!isFinite(points[i]))
      throw InvalidInput("coordinates: point " + std::to_string(i) + " is not finite");
  }
  const std::span<const Vec3> block = points.subspan(begin, n);
  UnmappedPoints unmapped = detail::forEachRange(
      n, batchGrain(),
      [&](std::size_t b, std::size_t e) { return weightsRange(block, rows, b, e); });
  if (unmapped.count == 0) return;
  unmapped.first += begin;  // the caller's index, not the block's
  throwUnmapped(unmapped, points);
}

UnmappedPoints Coordinates::weightsRange(std::span<const Vec3> points, std::span<double> rows,
                                         std::size_t begin, std::size_t end) const {
  const std::size_t m = columnCount();
  for (std::size_t i = begin; i != end; ++i) weights(points[i], rows.subspan(i * m, m));
  return {};
}

void Coordinates::throwUnmapped(const UnmappedPoints& unmapped,
                                std::span<const Vec3> points) const {
  throw InvalidInput(
      "coordinates: " + std::to_string(unmapped.count) + " of " + std::to_string(points.size()) +
      " points have no weights (the first is point " + std::to_string(unmapped.first) + ")");
}

std::size_t Coordinates::sparseWeights(const Vec3& x, std::span<SparseWeight> out) const {
  std::vector<double> row(columnCount());
  weights(x, row);
  std::size_t count = 0;
  for (std::size_t c = 0; c < row.size(); ++c) {
    if (row[c] == 0.0) continue;
    if (count == out.size())
      throw InvalidInput("coordinates: more non-zero weights than the sparse row holds");
    out[count++] = {static_cast<std::uint32_t>(c), row[c]};
  }
  return count;
}

void Coordinates::columnControls(std::span<const Vec3> posed, std::span<Vec3> out) const {
  if (posed.size() != controlPointCount()) {
    throw InvalidInput("coordinates: " + std::to_string(posed.size()) +
                       " posed control points given, " + std::to_string(controlPointCount()) +
                       " expected");
  }
  if (out.size() != columnCount())
    throw InvalidInput("coordinates: the column-control output has the wrong size");
  for (std::size_t i = 0; i < posed.size(); ++i) {
    if (!isFinite(posed[i]))
      throw InvalidInput("posed control point " + std::to_string(i) + " is not finite");
    out[i] = posed[i];
  }
}

bool Coordinates::weightGradients(const Vec3&, std::span<Vec3>) const { return false; }

std::shared_ptr<const Warp> Coordinates::makeWarpFor(std::shared_ptr<const Coordinates> self,
                                                     std::span<const Vec3> posed) const {
  return std::make_shared<CoordinateWarp>(std::move(self), posed);
}

std::shared_ptr<const Warp> makeWarp(std::shared_ptr<const Coordinates> coordinates,
                                     std::span<const Vec3> posed) {
  if (!coordinates) throw InvalidInput("makeWarp: the coordinates are null");
  const Coordinates& c = *coordinates;
  return c.makeWarpFor(std::move(coordinates), posed);
}

}  // namespace spacewarp
