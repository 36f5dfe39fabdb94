#include <spacewarp/nonlinear/detail/node_sampling.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <unordered_map>
#include <utility>

#include <spacewarp/core/errors.h>

namespace spacewarp::detail {

namespace {

using Key = std::array<std::int64_t, 3>;

// The integer cell of x in a grid of edge `spacing` (corner at the origin); throws for points
// whose cell index would not fit.
Key cellKey(const Vec3& x, double spacing, std::size_t i) {
  constexpr double kLimit = 4.0e18;
  Key key;
  for (int a = 0; a < 3; ++a) {
    const double c = std::floor(x[a] / spacing);
    if (!(std::abs(c) < kLimit)) {
      throw InvalidInput("DeformationGraph: positions[" + std::to_string(i) +
                         "] is too far from the origin for spacing " + std::to_string(spacing));
    }
    key[std::size_t(a)] = static_cast<std::int64_t>(c);
  }
  return key;
}

// SplitMix64's finaliser: a fixed, well-mixed permutation of 64-bit integers.
std::uint64_t mix64(std::uint64_t x) {
  x += 0x9e3779b97f4a7c15ull;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ull;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebull;
  return x ^ (x >> 31);
}

struct KeyHash {
  std::size_t operator()(const Key& k) const {
    return std::size_t(
        mix64(std::uint64_t(k[0]) ^ mix64(std::uint64_t(k[1]) ^ mix64(std::uint64_t(k[2])))));
  }
};

// Input points binned by cell, each cell's list in the order the points were added.
using HashGrid = std::unordered_map<Key, std::vector<std::uint32_t>, KeyHash>;

// Whether a point of `grid` lies closer than sqrt(r2) to x, whose cell is `key`: only the 27
// cells around it can hold one when the cells' edge is at least sqrt(r2).
bool coveredByGrid(const HashGrid& grid, std::span<const Vec3> positions, const Vec3& x,
                   const Key& key, double r2) {
  for (std::int64_t dz = -1; dz <= 1; ++dz) {
    for (std::int64_t dy = -1; dy <= 1; ++dy) {
      for (std::int64_t dx = -1; dx <= 1; ++dx) {
        const auto it = grid.find(Key{key[0] + dx, key[1] + dy, key[2] + dz});
        if (it == grid.end()) continue;
        for (std::uint32_t j : it->second) {
          const Vec3 d = x - positions[j];
          if (glm::dot(d, d) < r2) return true;
        }
      }
    }
  }
  return false;
}

}  // namespace

// Sorting (cell, index) pairs groups each cell's points in ascending index, so ties for the
// point nearest the centroid keep the lower index.
std::vector<Vec3> sampleNodesVoxel(std::span<const Vec3> positions, double spacing) {
  std::vector<std::pair<Key, std::uint32_t>> cells(positions.size());
  for (std::size_t i = 0; i < positions.size(); ++i)
    cells[i] = {cellKey(positions[i], spacing, i), static_cast<std::uint32_t>(i)};
  std::sort(cells.begin(), cells.end());
  std::vector<Vec3> nodes;
  using Iter = std::vector<std::pair<Key, std::uint32_t>>::const_iterator;
  for (Iter begin = cells.cbegin(); begin != cells.cend();) {
    const Iter end =
        std::find_if(begin, cells.cend(), [&](const auto& c) { return c.first != begin->first; });
    Vec3 centroid(0.0);
    for (Iter it = begin; it != end; ++it) centroid += positions[it->second];
    centroid /= double(end - begin);
    std::uint32_t best = begin->second;
    double bestD = std::numeric_limits<double>::infinity();
    for (Iter it = begin; it != end; ++it) {
      const Vec3 d = positions[it->second] - centroid;
      if (glm::dot(d, d) < bestD) {
        bestD = glm::dot(d, d);
        best = it->second;
      }
    }
    nodes.push_back(positions[best]);
    begin = end;
  }
  return nodes;
}

// The points are visited in the order of a hash of their index (so that scan-line or sorted
// inputs do not imprint their order on the nodes); the nodes are binned in a hash grid of edge
// `spacing`, so only the 27 cells around a point are searched. Serial; the result depends only
// on the positions.
std::vector<Vec3> sampleNodesPoissonDisk(std::span<const Vec3> positions, double spacing) {
  const std::size_t n = positions.size();
  std::vector<Key> keys(n);
  for (std::size_t i = 0; i < n; ++i) keys[i] = cellKey(positions[i], spacing, i);
  std::vector<std::pair<std::uint64_t, std::uint32_t>> order(n);
  for (std::size_t i = 0; i < n; ++i) order[i] = {mix64(i), static_cast<std::uint32_t>(i)};
  std::sort(order.begin(), order.end());
  const double r2 = spacing * spacing;
  HashGrid grid;
  grid.reserve(n / 4 + 16);
  std::vector<std::uint32_t> chosen;
  for (const auto& [hash, i] : order) {
    if (coveredByGrid(grid, positions, positions[i], keys[i], r2)) continue;
    grid[keys[i]].push_back(i);
    chosen.push_back(i);
  }
  std::sort(chosen.begin(), chosen.end());
  std::vector<Vec3> nodes;
  nodes.reserve(chosen.size());
  for (std::uint32_t i : chosen) nodes.push_back(positions[i]);
  return nodes;
}

}  // namespace spacewarp::detail
