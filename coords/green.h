#pragma once
// Green coordinates of a triangle cage: Lipman, Levin, Cohen-Or, "Green Coordinates",
// SIGGRAPH 2008.
//
// A point x is written as a combination of the cage vertices v_i and the outward unit face
// normals n_j,
//
//     x = Σ_i φ_i(x) v_i + Σ_j ψ_j(x) n_j,
//
// where, by Green's third identity with G(ξ, x) = −1 / (4π |ξ − x|),
//
//     φ_i(x) = ∫_∂cage Γ_i(ξ) ∂G/∂n(ξ, x) dσ   (Γ_i: the piecewise-linear hat of vertex i)
//     ψ_j(x) = −∫_{t_j} G(ξ, x) dσ = (1/4π) ∫_{t_j} dσ / |ξ − x|   (always ≥ 0).
//
// A posed cage moves x to Σ φ_i v'_i + Σ ψ_j s_j n'_j, with n'_j the posed unit normal and s_j
// the paper's stretch factor of triangle j (see columnControls()). Inside the cage the map is
// harmonic, reproduces similarities exactly (outside too, through the extension below) and is
// quasi-conformal. Green coordinates do not interpolate: a cage vertex does not map to its posed
// position in general.
//
// Which formula a point gets depends on where it is (see locate()):
//
// - Inside (winding number > 1/2, farther than surfaceTolerance from the surface): the closed
//   form integrals above. Σ φ_i = 1 there (∫ ∂G/∂n over a closed surface is the winding number).
// - On the surface (within options().surfaceTolerance × cage().diagonal() of it): the limit from
//   inside, φ_in(x0) = φ_pv(x0) + (1 − σ(x0)) Γ(x0), where φ_pv is the principal value (the
//   triangles that touch x0 contribute no double layer), σ(x0) the principal-value winding number
//   (1/2 on a face, the interior solid-angle fraction on an edge or at a vertex) and Γ(x0) the hat
//   values at x0; ψ is continuous across the surface and taken as it is. This is exact on faces,
//   edges and vertices alike, continuous with the interior values and equal to the exterior
//   extension below at points on the face that extends them. Σ φ_i = 1 there too.
// - Outside: the paper's analytic extension through one face t_j. The raw integrals of an outside
//   point reproduce 0 (Σφ_i v_i + Σψ_j n_j = 0, Σφ_i = 0); writing x = Σ_{k∈t_j} α_k v_k + β n_j
//   (α: barycentric coordinates of the projection of x onto the plane of t_j, β: the signed
//   distance of x from that plane, positive outside), α_k is added to φ_k and β to ψ_j. The result
//   reproduces x at rest, Σφ_i = 1 again, and across the interior of t_j it is the analytic
//   continuation of the interior coordinates (continuous, with continuous derivatives).
//   The face t_j is the triangle that contains the point of the cage surface nearest to x
//   (ties, which occur when that point is on an edge or a vertex, go to the triangle whose plane
//   x is farthest in front of, i.e. the largest β, then to the lowest triangle index). The
//   extension is a continuation through that one face even where x is far from it or its
//   nearest point is on an edge or a vertex: two outside points close to each other whose
//   nearest triangles differ (on either side of the medial surface of the exterior, e.g. the
//   bisector plane outside a convex edge) are extended through different faces and generally
//   get different coordinates. The outside map is therefore piecewise analytic and discontinuous
//   across that medial surface; it is continuous across the cage surface.
//
// Evaluation is a closed form per triangle, equivalent to the paper's GCTriInt (no quadrature):
// per point, one square root per cage vertex, one logarithm per cage edge and one arctangent per
// triangle, all in double precision and arranged to stay accurate for points in or near the plane
// of a triangle, on the line of an edge, above a vertex and close to edges and vertices (the solid
// angle uses a cancellation-free form of Van Oosterom and Strackee's formula, shared between the
// two triangles of an edge). At rest Σφ_i v_i + Σψ_j n_j reproduces x to about 1e-13 of the
// diagonal for cages near the origin. Points are evaluated four at a time in SIMD lanes (an
// x86-64-v3 build is chosen at run time where the CPU has it), with the kernel's own logarithm
// and arctangent (within 1.5 ulp; see coords/detail/green_kernels.h); weights()
// and locate() run one point through the same code, so every row is bit-identical whichever
// call or thread computes it. That makes weights() of a single point cost about as much as
// weightsBatch() of four: evaluate many points with weightsBatch(). The nearest triangle (outside
// and near-surface points only) is found by brute force over all triangles (cages have ~10-1000
// triangles).

#include <cstddef>
#include <memory>
#include <span>

#include <spacewarp/coords/cage.h>
#include <spacewarp/core/coordinates.h>

namespace spacewarp {

/// Options of GreenCoordinates.
struct GreenOptions {
  /// Points closer than surfaceTolerance × cage.diagonal() to the cage surface are surface
  /// points: they get the interior limit of the coordinates (see the file comment). The interior
  /// and exterior formulas stay accurate to round-off arbitrarily close to the surface; the
  /// surface formula is needed only on an edge or at a vertex, where they are singular (points at
  /// distance exactly 0 always get it, even with a tolerance of 0). The tolerance catches points
  /// that are on the surface up to round-off; treating a point at distance δ as a surface point
  /// changes its coordinates by O(δ log δ) relative. Must be in [0, 1e-3] (as
  /// MeanValueOptions::snapTolerance).
  double surfaceTolerance = 1e-14;
};

/// Green coordinates with respect to a cage. Columns: the V vertex coordinates φ_i first, then
/// the F face coordinates ψ_j (columnCount() = V + F; columnName() gives "v<i>" and "f<j>").
/// Every method is const and thread-safe.
class GreenCoordinates final : public Coordinates {
 public:
  /// Where a point is with respect to the cage, as weights() sees it.
  enum class Region { Inside, Surface, Outside };

  struct Location {
    Region region = Region::Inside;
    /// The triangle that contains the point of the cage surface nearest to x (the triangle an
    /// outside point is extended through).
    std::size_t triangle = 0;
    /// The distance from x to the cage surface (world units).
    double distance = 0.0;
    /// The generalised winding number of the cage around x (solid angle sum / 4π): 1 inside,
    /// 0 outside, computed with the principal value (about 1/2) on the surface.
    double windingNumber = 0.0;
  };

  /// Precomputes the per-triangle rest data of `cage`, which is shared, not copied. Throws
  /// InvalidInput if `cage` is null or options.surfaceTolerance is negative or not finite.
  explicit GreenCoordinates(std::shared_ptr<const Cage> cage, GreenOptions options = {});
  ~GreenCoordinates() override;

  const Cage& cage() const { return *cage_; }
  const GreenOptions& options() const { return options_; }

  /// V, the cage vertex count.
  std::size_t controlPointCount() const override;
  /// The rest cage vertices (V entries, world units).
  std::span<const Vec3> restControlPoints() const override;
  /// V + F.
  std::size_t columnCount() const override;

  /// The Green coordinates of x: row[i] = φ_i(x) for the V vertices, then row[V + j] = ψ_j(x)
  /// for the F triangles (ψ in world units, φ unitless). Throws InvalidInput if x is not finite
  /// or row.size() != columnCount().
  void weights(const Vec3& x, std::span<double> row) const override;

  /// The column controls of a posed cage (V posed vertices, same order as the rest cage): the
  /// posed vertices, then for every triangle j the posed unit normal n'_j times the stretch factor
  ///     s_j = sqrt(|u'|²|v|² − 2 (u'·v')(u·v) + |v'|²|u|²) / (√8 · area_j),
  /// with u, v the rest edge vectors v_b − v_a, v_c − v_a of the triangle and u', v' the posed
  /// ones. At rest s_j = 1; for a similarity with scale k, s_j = k. A posed triangle of zero area
  /// has no normal and gets the zero vector. Throws InvalidInput if `posed` has the wrong size or
  /// a non-finite point, or `out` does not have columnCount() entries.
  void columnControls(std::span<const Vec3> posed, std::span<Vec3> out) const override;

  /// Where x is: inside, on the surface (within the tolerance) or outside, its nearest triangle,
  /// its distance to the surface and the winding number. Throws InvalidInput if x is not finite.
  Location locate(const Vec3& x) const;

  /// Archive (core/archive.h): tag "green", the cage and the options.
  void save(ArchiveWriter& out) const override;
  static std::shared_ptr<const GreenCoordinates> load(ArchiveReader& in);

 protected:
  /// Four points at a time (eight on x86-64-v4) through the same kernels as weights():
  /// bit-identical rows.
  std::size_t batchGrain() const override;
  UnmappedPoints weightsRange(std::span<const Vec3> points, std::span<double> rows,
                              std::size_t begin, std::size_t end) const override;

 private:
  struct Impl;
  std::shared_ptr<const Cage> cage_;
  GreenOptions options_;
  std::unique_ptr<const Impl> impl_;
};

}  // namespace spacewarp
