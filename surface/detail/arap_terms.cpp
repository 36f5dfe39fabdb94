#include <spacewarp/surface/detail/arap_terms.h>

#include <numeric>

#include <spacewarp/surface/detail/edit_problem.h>

namespace spacewarp::detail {

namespace {

// One element per edge of the Laplacian (upper triangle), owned by both end points. A negative
// weight (an edge whose opposite angles sum past 180°) would make the energy unbounded below:
// stretching that edge would lower it, so not even the rest pose is a minimum. It is replaced by
// 1e-3 of its magnitude, which keeps the energy non-negative and the edge in the system.
void addSpokes(ArapTerms& t, std::span<const Vec3> rest, const Eigen::SparseMatrix<double>& l) {
  for (Eigen::Index j = 0; j < l.outerSize(); ++j)
    for (Eigen::SparseMatrix<double>::InnerIterator it(l, j); it; ++it) {
      if (it.row() >= j || it.value() == 0.0) continue;
      ArapElement e;
      e.count = 1;
      e.a[0] = static_cast<std::uint32_t>(it.row());
      e.b[0] = static_cast<std::uint32_t>(j);
      e.weight[0] = -it.value() > 0.0 ? -it.value() : 1e-3 * it.value();
      e.rest[0] = rest[e.a[0]] - rest[e.b[0]];
      e.owner = {e.a[0], e.b[0], 0};
      e.ownerCount = 2;
      t.elements.push_back(e);
    }
}

// One element per triangle that is not degenerate, owned by its corners.
void addSpokesAndRims(ArapTerms& t, std::span<const Vec3> rest,
                      std::span<const std::array<std::uint32_t, 3>> triangles) {
  for (const auto& tri : triangles) {
    const Vec3 p[3] = {rest[tri[0]], rest[tri[1]], rest[tri[2]]};
    if (isDegenerateTriangle(p[0], p[1], p[2])) continue;
    const double twiceArea = glm::length(glm::cross(p[1] - p[0], p[2] - p[0]));
    ArapElement e;
    e.count = 3;
    for (int c = 0; c < 3; ++c) {
      const int j = (c + 1) % 3, m = (c + 2) % 3;
      e.a[c] = tri[j];
      e.b[c] = tri[m];
      e.weight[c] = 0.5 * glm::dot(p[j] - p[c], p[m] - p[c]) / twiceArea;  // cot at c, halved
      e.rest[c] = p[j] - p[m];
    }
    e.owner = tri;
    e.ownerCount = 3;
    t.elements.push_back(e);
  }
}

}  // namespace

ArapTerms makeArapTerms(ArapEnergy energy, std::span<const Vec3> rest,
                        std::span<const std::array<std::uint32_t, 3>> triangles,
                        const Eigen::SparseMatrix<double>& laplacian) {
  ArapTerms t;
  if (energy == ArapEnergy::Spokes) {
    addSpokes(t, rest, laplacian);
  } else {
    addSpokesAndRims(t, rest, triangles);
  }
  const std::size_t n = rest.size();
  t.vertexOffsets.assign(n + 1, 0);
  for (const ArapElement& e : t.elements)
    for (int o = 0; o < e.ownerCount; ++o) ++t.vertexOffsets[e.owner[o] + 1];
  std::partial_sum(t.vertexOffsets.begin(), t.vertexOffsets.end(), t.vertexOffsets.begin());
  t.vertexElements.resize(t.vertexOffsets.back());
  t.vertexEdgeSigns.resize(t.vertexOffsets.back());
  std::vector<std::size_t> fill(t.vertexOffsets.begin(), t.vertexOffsets.end() - 1);
  std::vector<Eigen::Triplet<double>> entries;
  entries.reserve(12 * t.elements.size());
  for (std::size_t i = 0; i < t.elements.size(); ++i) {
    const ArapElement& e = t.elements[i];
    for (int o = 0; o < e.ownerCount; ++o) {
      const std::uint32_t v = e.owner[o];
      std::array<std::int8_t, 3> signs{};
      for (int k = 0; k < e.count; ++k) signs[k] = std::int8_t((e.a[k] == v) - (e.b[k] == v));
      t.vertexEdgeSigns[fill[v]] = signs;
      t.vertexElements[fill[v]++] = static_cast<std::uint32_t>(i);
    }
    double restSquared = 0.0;
    for (int k = 0; k < e.count; ++k) restSquared += e.weight[k] * glm::dot(e.rest[k], e.rest[k]);
    t.restSquared.push_back(restSquared);
    for (int k = 0; k < e.count; ++k) {
      const double w = e.ownerCount * e.weight[k];
      t.totalWeight += w;
      const auto a = static_cast<int>(e.a[k]), b = static_cast<int>(e.b[k]);
      entries.emplace_back(a, a, w);
      entries.emplace_back(b, b, w);
      entries.emplace_back(a, b, -w);
      entries.emplace_back(b, a, -w);
    }
  }
  t.system.resize(static_cast<Eigen::Index>(n), static_cast<Eigen::Index>(n));
  t.system.setFromTriplets(entries.begin(), entries.end());
  return t;
}

}  // namespace spacewarp::detail
