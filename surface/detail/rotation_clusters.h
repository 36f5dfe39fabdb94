#pragma once
// Clusters of vertices that share one rotation in the cage-subspace ARAP energy.

#include <cstdint>
#include <span>
#include <vector>

#include <Eigen/SparseCore>

#include <spacewarp/core/math.h>

namespace spacewarp::detail {

/// `count` clusters grown over the mesh's edges (the off-diagonal entries of `laplacian`, lengths
/// from `rest`): farthest-point seeds, each vertex joining its nearest seed (incremental
/// Dijkstra, so the cost is close to one shortest-path sweep). Every connected part gets a seed
/// before any part gets a second. Returns the cluster of each vertex (0 .. count − 1); vertices
/// without edges join cluster 0. `count` >= the vertex count gives each vertex its own cluster;
/// fewer clusters than requested result when fewer vertices have edges (the returned maximum
/// + 1 is the count).
std::vector<std::uint32_t> rotationClusters(const Eigen::SparseMatrix<double>& laplacian,
                                            std::span<const Vec3> rest, std::size_t count);

}  // namespace spacewarp::detail
