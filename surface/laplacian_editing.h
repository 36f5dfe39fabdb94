#pragma once
// Linear surface editing: the free vertices' displacement is harmonic (Laplacian editing,
// Sorkine et al. 2004: Δd = 0, so the differential coordinates δ = Lx are kept) or biharmonic
// (the thin-shell displacement of Botsch and Kobbelt 2004: Δ²d = 0) given the constrained
// vertices' displacements. Factorised once; moving the handles again is a back-substitution.
//
// Linear methods reproduce translations exactly but cannot follow rotations: a rotated handle
// shears and shrinks the free region (use ArapEditor).

#include <array>
#include <cstdint>
#include <memory>
#include <span>
#include <vector>

#include <spacewarp/core/math.h>

namespace spacewarp {

enum class LinearEditMethod {
  Laplacian,    ///< Δd = 0 on the free vertices (membrane: C0 at the handles).
  BiLaplacian,  ///< Δ²d = 0, Δ = M⁻¹L with the mixed Voronoi mass M (thin shell).
};

struct LinearEditOptions {
  LinearEditMethod method = LinearEditMethod::Laplacian;
};

/// Prefactorised linear editing of one mesh with one set of constrained vertices.
/// Connected components with no constrained vertex, and vertices no triangle uses, cannot be
/// placed by the energy: they stay where they are (heldVertices()). Not thread-safe (the
/// factor's workspace); construct one per thread.
class LinearEditor {
 public:
  /// `positions`: n rest vertices (world units); `triangles` index them; `constrained`: the
  /// vertices whose positions solve() is given, in any order, without repeats. Throws
  /// InvalidInput for an empty mesh, no constrained vertex, an index out of range or repeated,
  /// a non-finite position; SolverError if the factorisation fails.
  LinearEditor(std::span<const Vec3> positions,
               std::span<const std::array<std::uint32_t, 3>> triangles,
               std::span<const std::uint32_t> constrained, const LinearEditOptions& options = {});
  ~LinearEditor();
  LinearEditor(LinearEditor&&) noexcept;
  LinearEditor& operator=(LinearEditor&&) noexcept;

  /// All n vertices for the constrained vertices at `targets` (one per constrained vertex, in
  /// the constructor's order, world units). Throws InvalidInput on a wrong count or a
  /// non-finite target.
  std::vector<Vec3> solve(std::span<const Vec3> targets);

  /// Vertices kept at rest because nothing constrains their component (sorted).
  std::span<const std::uint32_t> heldVertices() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace spacewarp
