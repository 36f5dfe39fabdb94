#pragma once
// The cotangent Laplacian and the lumped mass matrix of a triangle mesh: the discrete
// Laplace-Beltrami operator Δ ≈ -M⁻¹ L of every surface method.

#include <array>
#include <cstdint>
#include <span>

#include <Eigen/SparseCore>

#include <spacewarp/core/math.h>

namespace spacewarp {

/// The cotangent stiffness matrix L (n × n, symmetric positive semi-definite, rows summing to
/// 0): L_ij = -(cot α_ij + cot β_ij) / 2 for an edge ij with opposite angles α, β (one of them
/// on a boundary edge), L_ii = -Σ_j L_ij. Dimensionless (invariant under scaling).
/// Safeguards: a triangle whose area is below 1e-12 of its longest edge squared contributes
/// nothing (its cotangents are unbounded); an obtuse angle gives a negative weight, as the
/// operator's convergence needs (clamping them breaks linear precision).
/// `positions`: n vertices, world units; `triangles`: indices into them. Throws InvalidInput if
/// an index is out of range or a position used is not finite.
Eigen::SparseMatrix<double> cotanLaplacian(std::span<const Vec3> positions,
                                           std::span<const std::array<std::uint32_t, 3>> triangles);

/// The lumped (diagonal) mass matrix: the mixed Voronoi area of each vertex (Meyer et al.
/// 2003): a triangle's Voronoi region for its vertices when it is not obtuse, and half its
/// area to the obtuse corner, a quarter to the others when it is, so the areas stay positive
/// and sum to the surface area. World units squared. Vertices with no area (isolated, or only
/// degenerate triangles) get the smallest positive mass of the mesh so that M is invertible.
Eigen::VectorXd massMatrixDiagonal(std::span<const Vec3> positions,
                                   std::span<const std::array<std::uint32_t, 3>> triangles);

}  // namespace spacewarp
