#pragma once
// What every surface editor sets up the same way: the checked mesh, which vertices are free,
// constrained or held at rest, and the cotangent Laplacian split into its free and fixed blocks.

#include <array>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/SparseCore>

#include <spacewarp/core/math.h>

namespace spacewarp::detail {

/// Whether the triangle is too thin for its cotangents to mean anything: twice its area at most
/// 1e-12 of its longest edge squared. Such triangles are left out of the Laplacian.
bool isDegenerateTriangle(const Vec3& a, const Vec3& b, const Vec3& c);

/// The connected component of every vertex through the triangles (those that are not
/// degenerate only, when `skipDegenerate`), numbered from 0 in order of their lowest vertex;
/// vertices in no such triangle get a component each, after those. `count` receives the number
/// of components that have a triangle.
std::vector<std::uint32_t> vertexComponents(std::span<const Vec3> positions,
                                            std::span<const std::array<std::uint32_t, 3>> triangles,
                                            std::size_t& count, bool skipDegenerate = false);

/// The partition of the vertices of an edit. Fixed vertices are the constrained ones (first, in
/// the caller's order) and the held ones (after them, sorted).
struct EditProblem {
  std::vector<Vec3> rest;
  std::vector<std::array<std::uint32_t, 3>> triangles;
  std::vector<std::uint32_t> constrained;
  std::vector<std::uint32_t> held;
  std::vector<std::uint32_t> freeVertices;
  /// slot[v] >= 0: index among the free vertices; otherwise -(index among the fixed) - 1.
  std::vector<std::int64_t> slot;
  Eigen::SparseMatrix<double> laplacian;  ///< n × n cotangent Laplacian (full, symmetric)
  double diagonal = 0.0;                  ///< of the rest bounding box

  std::size_t fixedCount() const { return constrained.size() + held.size(); }

  /// The lower triangle of M's free block and M's free × fixed block.
  Eigen::SparseMatrix<double> freeBlockLower(const Eigen::SparseMatrix<double>& m) const;
  Eigen::SparseMatrix<double> freeFixedBlock(const Eigen::SparseMatrix<double>& m) const;

  /// Fixed positions (fixedCount() × 3): `targets` for the constrained vertices, the rest
  /// positions for the held ones. Throws InvalidInput (naming `caller`) on a wrong count or a
  /// non-finite target.
  Eigen::MatrixXd fixedPositions(std::span<const Vec3> targets, const std::string& caller) const;

  /// All n positions from the free block's solution (free × 3) and the fixed positions.
  std::vector<Vec3> assemble(const Eigen::MatrixXd& freePositions,
                             const Eigen::MatrixXd& fixed) const;
};

/// Throws InvalidInput (naming `caller`) unless the box of `positions` spans less than 1e100 world
/// units and every coordinate is below 1e100 in magnitude: the surface methods square lengths.
void checkSurfaceScale(std::span<const Vec3> positions, const std::string& caller);

/// Checks the mesh and the constrained vertices (InvalidInput naming `caller` and the index at
/// fault), builds the Laplacian and the partition.
EditProblem makeEditProblem(std::span<const Vec3> positions,
                            std::span<const std::array<std::uint32_t, 3>> triangles,
                            std::span<const std::uint32_t> constrained, const std::string& caller);

/// Rows of positions as an n × 3 matrix, and back.
Eigen::MatrixXd toMatrix(std::span<const Vec3> points);

}  // namespace spacewarp::detail
