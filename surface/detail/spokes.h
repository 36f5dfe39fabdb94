#pragma once
// The one-ring edges ("spokes") of every vertex with their cotangent weights and rest vectors:
// the terms of the surface ARAP energy, shared by ArapEditor and CageArapEditor.

#include <cstdint>
#include <span>
#include <vector>

#include <Eigen/SparseCore>

#include <spacewarp/core/math.h>

namespace spacewarp::detail {

/// Spoke s of vertex i (offsets[i] <= s < offsets[i + 1]) is the edge i -> neighbor[s] with
/// weight w[s] = −L_ij and rest vector rest[s] = x̄_i − x̄_j.
struct Spokes {
  std::vector<std::size_t> offsets;
  std::vector<std::uint32_t> neighbor;
  std::vector<double> weight;
  std::vector<Vec3> rest;

  std::size_t vertexCount() const { return offsets.size() - 1; }
};

/// The spokes of the symmetric Laplacian `laplacian` (n × n) on the rest positions (n).
Spokes makeSpokes(const Eigen::SparseMatrix<double>& laplacian, std::span<const Vec3> rest);

}  // namespace spacewarp::detail
