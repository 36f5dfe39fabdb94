#pragma once
// Clusters of vertices that share one rotation in the cage-subspace ARAP energy.

#include <cstdint>
#include <vector>

#include <spacewarp/surface/detail/spokes.h>

namespace spacewarp::detail {

/// `count` clusters grown over the spoke graph (edge lengths as distances): farthest-point
/// seeds, each vertex joining its nearest seed (incremental Dijkstra, so the cost is close to
/// one shortest-path sweep). Every connected part gets a seed before any part gets a second.
/// Returns the cluster of each vertex (0 .. count − 1); vertices without spokes join cluster 0.
/// `count` >= the vertex count gives each vertex its own cluster; fewer clusters than
/// requested result when fewer vertices have spokes (the returned maximum + 1 is the count).
std::vector<std::uint32_t> rotationClusters(const Spokes& spokes, std::size_t count);

}  // namespace spacewarp::detail
