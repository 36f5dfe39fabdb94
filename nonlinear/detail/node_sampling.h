#pragma once
// How DeformationGraph(positions, options) picks its nodes among the positions: the two
// NodeSampling schemes (see nonlinear/deformation_graph.h for what each guarantees). Both are
// deterministic functions of the positions; both throw InvalidInput for a position whose grid
// cell index (floor(x / spacing)) would not fit in 64 bits.

#include <span>
#include <vector>

#include <spacewarp/core/math.h>

namespace spacewarp::detail {

// NodeSampling::Voxel: one node per occupied cell of edge `spacing`, the cell's point nearest
// its centroid; nodes in lexicographic order of their cells.
std::vector<Vec3> sampleNodesVoxel(std::span<const Vec3> positions, double spacing);

// NodeSampling::PoissonDisk: a maximal subset with no two points closer than `spacing`, by
// greedy dart throwing in a hashed order; nodes in ascending input index.
std::vector<Vec3> sampleNodesPoissonDisk(std::span<const Vec3> positions, double spacing);

}  // namespace spacewarp::detail
