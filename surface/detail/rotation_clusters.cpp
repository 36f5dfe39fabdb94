#include <spacewarp/surface/detail/rotation_clusters.h>

#include <functional>
#include <limits>
#include <numeric>
#include <queue>
#include <utility>

namespace spacewarp::detail {

std::vector<std::uint32_t> rotationClusters(const Spokes& spokes, std::size_t count) {
  const std::size_t n = spokes.vertexCount();
  std::vector<std::uint32_t> cluster(n, 0);
  if (count >= n) {
    std::iota(cluster.begin(), cluster.end(), 0u);
    return cluster;
  }
  constexpr double kInf = std::numeric_limits<double>::infinity();
  std::vector<double> distance(n, kInf);
  for (std::size_t i = 0; i < n; ++i)
    if (spokes.offsets[i] == spokes.offsets[i + 1]) distance[i] = 0.0;  // no energy term
  using Entry = std::pair<double, std::uint32_t>;
  std::priority_queue<Entry, std::vector<Entry>, std::greater<>> queue;
  for (std::uint32_t c = 0; c < count; ++c) {
    // The farthest vertex from every seed so far (the lowest index among ties).
    std::size_t seed = 0;
    for (std::size_t i = 1; i < n; ++i)
      if (distance[i] > distance[seed]) seed = i;
    if (!(distance[seed] > 0.0)) break;  // every vertex with spokes is a seed already
    distance[seed] = 0.0;
    cluster[seed] = c;
    queue.push({0.0, static_cast<std::uint32_t>(seed)});
    while (!queue.empty()) {
      const auto [d, i] = queue.top();
      queue.pop();
      if (d > distance[i]) continue;
      for (std::size_t k = spokes.offsets[i]; k < spokes.offsets[i + 1]; ++k) {
        const std::uint32_t j = spokes.neighbor[k];
        const double dj = d + glm::length(spokes.rest[k]);
        if (dj < distance[j]) {
          distance[j] = dj;
          cluster[j] = c;
          queue.push({dj, j});
        }
      }
    }
  }
  return cluster;
}

}  // namespace spacewarp::detail
