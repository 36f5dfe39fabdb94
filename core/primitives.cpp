#include <spacewarp/core/primitives.h>

#include <array>
#include <cmath>
#include <map>
#include <random>
#include <set>
#include <string>

#include <spacewarp/core/errors.h>

namespace spacewarp {

namespace {

void checkBox(const Vec3& min, const Vec3& max) {
  if (!isFinite(min) || !isFinite(max) || !(min.x < max.x && min.y < max.y && min.z < max.z))
    throw InvalidInput("box: min must be finite and strictly below max on every axis");
}

}  // namespace

PolygonSoup makeBoxSurface(const Vec3& min, const Vec3& max, const glm::ivec3& divisions) {
  checkBox(min, max);
  if (divisions.x < 1 || divisions.y < 1 || divisions.z < 1)
    throw InvalidInput("box: every division count must be at least 1");

  PolygonSoup soup;
  // Vertices live on the integer lattice (i, j, k) in [0, divisions]; a map shares them
  // between the six faces.
  std::map<std::array<int, 3>, std::uint32_t> index;
  auto vertex = [&](std::array<int, 3> ijk) {
    auto [it, inserted] = index.try_emplace(ijk, static_cast<std::uint32_t>(soup.positions.size()));
    if (inserted) {
      Vec3 p;
      for (int a = 0; a < 3; ++a)
        p[a] = ijk[a] == divisions[a]
                   ? max[a]
                   : min[a] + (max[a] - min[a]) * ijk[a] / static_cast<double>(divisions[a]);
      soup.positions.push_back(p);
      soup.normals.push_back(Vec3(0.0));
    }
    return it->second;
  };

  for (int axis = 0; axis < 3; ++axis) {
    const int u = (axis + 1) % 3, v = (axis + 2) % 3;  // (u, v, axis) is right-handed
    for (int side = 0; side < 2; ++side) {
      Vec3 normal(0.0);
      normal[axis] = side ? 1.0 : -1.0;
      for (int i = 0; i < divisions[u]; ++i) {
        for (int j = 0; j < divisions[v]; ++j) {
          std::array<std::array<int, 3>, 4> corners;
          const int du[4] = {0, 1, 1, 0}, dv[4] = {0, 0, 1, 1};
          for (int c = 0; c < 4; ++c) {
            corners[c][axis] = side ? divisions[axis] : 0;
            corners[c][u] = i + du[c];
            corners[c][v] = j + dv[c];
          }
          std::array<std::uint32_t, 4> quad;
          for (int c = 0; c < 4; ++c) quad[c] = vertex(corners[c]);
          if (!side) std::swap(quad[1], quad[3]);  // keep the low face outward
          soup.addPolygon({quad[0], quad[1], quad[2], quad[3]});
          for (std::uint32_t q : quad) soup.normals[q] += normal;
        }
      }
    }
  }
  for (Vec3& n : soup.normals) n = glm::normalize(n);
  return soup;
}

PolygonSoup makeBlocksSurface(std::span<const glm::ivec3> cells, const Vec3& origin,
                              double cellSize) {
  if (cells.empty()) throw InvalidInput("blocks: no cells");
  if (!isFinite(origin) || !std::isfinite(cellSize) || !(cellSize > 0.0))
    throw InvalidInput("blocks: the origin and cell size must be finite, the cell size > 0");
  std::set<std::array<int, 3>> occupied;
  for (const glm::ivec3& c : cells) occupied.insert({c.x, c.y, c.z});
  PolygonSoup soup;
  std::map<std::array<int, 3>, std::uint32_t> index;
  auto vertex = [&](const std::array<int, 3>& ijk) {
    auto [it, inserted] = index.try_emplace(ijk, static_cast<std::uint32_t>(soup.positions.size()));
    if (inserted) soup.positions.push_back(origin + Vec3(ijk[0], ijk[1], ijk[2]) * cellSize);
    return it->second;
  };
  for (const std::array<int, 3>& cell : occupied) {
    for (int axis = 0; axis < 3; ++axis) {
      const int u = (axis + 1) % 3, v = (axis + 2) % 3;  // (u, v, axis) is right-handed
      for (int side = 0; side < 2; ++side) {
        std::array<int, 3> next = cell;
        next[axis] += side ? 1 : -1;
        if (occupied.count(next)) continue;  // an inner face
        std::array<std::uint32_t, 4> quad;
        const int du[4] = {0, 1, 1, 0}, dv[4] = {0, 0, 1, 1};
        for (int c = 0; c < 4; ++c) {
          std::array<int, 3> corner = cell;
          corner[axis] += side;
          corner[u] += du[c];
          corner[v] += dv[c];
          quad[c] = vertex(corner);
        }
        if (!side) std::swap(quad[1], quad[3]);  // keep the low face outward
        soup.addPolygon({quad[0], quad[1], quad[2], quad[3]});
      }
    }
  }
  return soup;
}

PointSet makeRandomPoints(const Vec3& min, const Vec3& max, std::size_t n, std::uint64_t seed) {
  checkBox(min, max);
  std::mt19937_64 rng(seed);
  // Bits to [0, 1) by hand: std::uniform_real_distribution is not portable across libraries.
  auto unit = [&] { return static_cast<double>(rng() >> 11) * 0x1.0p-53; };
  PointSet points;
  points.positions.resize(n);
  VertexAttribute index{"index", ScalarType::UInt32, std::vector<double>(n)};
  for (std::size_t i = 0; i < n; ++i) {
    for (int a = 0; a < 3; ++a) points.positions[i][a] = min[a] + (max[a] - min[a]) * unit();
    index.values[i] = static_cast<double>(i);
  }
  points.attributes.push_back(std::move(index));
  return points;
}

}  // namespace spacewarp
