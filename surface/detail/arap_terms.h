#pragma once
// The terms of an ARAP energy, Σ_i Σ_{(a,b) ∈ T(i)} w_ab ‖(x_a − x_b) − R_i (x̄_a − x̄_b)‖², for
// either choice of the edge set T(i) of vertex i's rotation: its one-ring edges ("spokes",
// Sorkine and Alexa 2007) or the edges of its incident triangles ("spokes and rims", Chao et
// al. 2010). Shared by ArapEditor and CageArapEditor.
//
// Both are sums over elements whose edges every owner's rotation acts on alike: an edge owned by
// its two end points (spokes), a triangle's three edges owned by its three corners (spokes and
// rims). Per-element sums are then formed once, not once per owner.

#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include <Eigen/SparseCore>

#include <spacewarp/core/math.h>
#include <spacewarp/surface/arap.h>

namespace spacewarp::detail {

struct ArapElement {
  int count = 0;                     ///< edges, and owners: 1 and 2 (spokes), 3 and 3 (rims)
  std::array<std::uint32_t, 3> a{};  ///< edge k runs from a[k] to b[k]
  std::array<std::uint32_t, 3> b{};
  std::array<double, 3> weight{};
  std::array<Vec3, 3> rest{};            ///< x̄_a − x̄_b
  std::array<std::uint32_t, 3> owner{};  ///< the vertices whose rotations act on the edges
  int ownerCount = 0;
};

struct ArapTerms {
  std::vector<ArapElement> elements;
  /// The elements of vertex v (it owns them, and they are the ones touching it):
  /// vertexElements[vertexOffsets[v] .. vertexOffsets[v + 1]).
  std::vector<std::size_t> vertexOffsets;
  std::vector<std::uint32_t> vertexElements;
  /// Parallel to vertexElements: for each edge k of the element, +1 if v is its a, −1 if its b,
  /// 0 if neither (the rim of a triangle seen from the opposite corner).
  std::vector<std::array<std::int8_t, 3>> vertexEdgeSigns;
  /// Σ_e Σ_owners Σ_edges w (δ_a − δ_b)(δ_a − δ_b)ᵀ (n × n), the quadratic part: the global step
  /// solves system x = rhs(R). 2L for spokes, 3L for spokes and rims.
  Eigen::SparseMatrix<double> system;
  /// Σ_i Σ_{T(i)} w: the sum of the energy's edge weights.
  double totalWeight = 0.0;
  /// Per element: Σ_edges w |ē|², the constant part of each owner's energy.
  std::vector<double> restSquared;

  std::size_t vertexCount() const { return vertexOffsets.size() - 1; }
};

/// The terms of `energy` for the mesh (n rest positions, triangles) with cotangent Laplacian
/// `laplacian` (its off-diagonal entries are the spokes' weights; the rims' weights are the
/// cotangents of each triangle, half each, degenerate triangles left out as in the Laplacian).
ArapTerms makeArapTerms(ArapEnergy energy, std::span<const Vec3> rest,
                        std::span<const std::array<std::uint32_t, 3>> triangles,
                        const Eigen::SparseMatrix<double>& laplacian);

/// Σ_edges w (x_a − x_b) ē̅ᵀ of one element: its share of each owner's covariance.
inline Mat3 elementCovariance(const ArapElement& e, std::span<const Vec3> x) {
  Mat3 c(0.0);
  for (int k = 0; k < e.count; ++k)
    c += glm::outerProduct(e.weight[k] * (x[e.a[k]] - x[e.b[k]]), e.rest[k]);
  return c;
}

}  // namespace spacewarp::detail
