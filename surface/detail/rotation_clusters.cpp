#include <spacewarp/surface/detail/rotation_clusters.h>

#include <functional>
#include <limits>
#include <numeric>
#include <queue>
#include <utility>

namespace spacewarp::detail {

std::vector<std::uint32_t> rotationClusters(const Eigen::SparseMatrix<double>& laplacian,
                                            std::span<const Vec3> rest, std::size_t count) {
  const std::size_t n = rest.size();
  std::vector<std::uint32_t> cluster(n, 0);
  if (count >= n) {
    std::iota(cluster.begin(), cluster.end(), 0u);
    return cluster;
  }
  constexpr double kInf = std::numeric_limits<double>::infinity();
  std::vector<double> distance(n, kInf);
  for (std::size_t i = 0; i < n; ++i)
    if (laplacian.col(static_cast<Eigen::Index>(i)).nonZeros() <= 1) distance[i] = 0.0;  // no edge
  using Entry = std::pair<double, std::uint32_t>;
  std::priority_queue<Entry, std::vector<Entry>, std::greater<>> queue;
  for (std::uint32_t c = 0; c < count; ++c) {
    // The farthest vertex from every seed so far (the lowest index among ties).
    std::size_t seed = 0;
    for (std::size_t i = 1; i < n; ++i)
      if (distance[i] > distance[seed]) seed = i;
    if (!(distance[seed] > 0.0)) break;  // every vertex with edges is a seed already
    distance[seed] = 0.0;
    cluster[seed] = c;
    queue.push({0.0, static_cast<std::uint32_t>(seed)});
    while (!queue.empty()) {
      const auto [d, i] = queue.top();
      queue.pop();
      if (d > distance[i]) continue;
      for (Eigen::SparseMatrix<double>::InnerIterator it(laplacian, i); it; ++it) {
        const auto j = static_cast<std::uint32_t>(it.row());
        if (j == i) continue;
        const double dj = d + glm::length(rest[i] - rest[j]);
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
