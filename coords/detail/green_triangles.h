#pragma once
// The raw Green terms of a set of triangles (closed or not), computed by GreenCoordinates'
// kernels: for coordinates whose cages mix triangles with other faces (QuadGreenCoordinates).
// Not API.

#include <cstddef>
#include <limits>
#include <memory>
#include <span>

#include <spacewarp/coords/cage.h>

namespace spacewarp::detail {

struct GreenData;

/// The integrals of coords/green.h over a set of triangles of a cage, without the exterior
/// extension or the surface limit (which need the whole cage), bit for bit as
/// GreenCoordinates computes them.
class GreenTriangleTerms {
 public:
  /// What evaluate() reports of a point besides its row.
  struct Point {
    /// Σ Ω over the triangles (steradians); triangles within the tolerance of the point add
    /// their principal value, 0.
    double solidAngle = 0.0;
    /// The squared distance to the nearest triangle (world units²), ∞ without triangles.
    double dist2 = std::numeric_limits<double>::infinity();
    /// The nearest triangle (ties as GreenCoordinates::locate), the signed distance of the point
    /// from its plane (outside positive) and the barycentric coordinates of the projection.
    std::size_t triangle = 0;
    double beta = 0.0;
    double bary[3] = {0.0, 0.0, 0.0};
    /// Whether the point is within the tolerance of a triangle.
    bool surface = false;
  };

  /// `vertices`: every vertex of the cage (world units); `triangles` index them, outward.
  /// surfaceTolerance: world units.
  GreenTriangleTerms(std::span<const Vec3> vertices, std::span<const Triangle> triangles,
                     double surfaceTolerance);
  ~GreenTriangleTerms();
  GreenTriangleTerms(const GreenTriangleTerms&) = delete;
  GreenTriangleTerms& operator=(const GreenTriangleTerms&) = delete;

  /// Points evaluated together (the SIMD lanes of this machine: 4 or 8).
  std::size_t lanes() const;

  /// The terms of count ≤ lanes() points: row l (at rows + l · stride) gets φ (one entry per
  /// vertex, 1/4π ∫ Γ_i ∂G/∂n) then ψ (one per triangle, 1/4π ∫ 1/|ξ − x|); info[l] the rest.
  void evaluate(const Vec3* points, std::size_t count, double* rows, std::size_t stride,
                Point* info) const;

 private:
  std::unique_ptr<const GreenData> data_;
};

}  // namespace spacewarp::detail
