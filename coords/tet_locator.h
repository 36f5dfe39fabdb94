#pragma once
// Point location in a tetrahedral mesh through a uniform grid: every cell lists the tets whose
// bounding boxes overlap it, so a query tests only the tets of its own cell (never all tets).

#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include <spacewarp/core/geometry.h>
#include <spacewarp/core/math.h>

namespace spacewarp {

/// Whether the tet with corners p0..p3 is flat: its volume is not positive, or is within the
/// round-off of its corners' coordinates (det[p1 − p0, p2 − p0, p3 − p0] ≤ 64 ε L² (L + c), L
/// its longest edge, c its largest corner coordinate in magnitude). Its orientation and any
/// barycentric coordinates in it are then round-off. TetGen leaves such tets between Steiner
/// points that it rounded off a slanted cage face; they have no volume to hold a point.
bool isFlatTet(const Vec3& p0, const Vec3& p1, const Vec3& p2, const Vec3& p3);

/// Finds the tet that contains a point and the point's barycentric coordinates in it. Built
/// once (O(tets)), then const and thread-safe. Results do not depend on the thread count.
class TetLocator {
 public:
  /// Where a point is.
  struct Hit {
    bool found = false;  ///< false: the point is in no tet (outside the mesh)
    std::uint32_t tet = 0;
    /// Barycentric coordinates of the point in `tet` (≥ 0, summing to 1 up to round-off).
    std::array<double, 4> barycentric{};
  };

  /// `vertices` (any length unit; HarmonicCoordinates passes its cage's frame so that the
  /// round-off does not depend on where the mesh is) and positively oriented `tets` are copied
  /// where needed; a flat tet (isFlatTet) is never found. `tolerance` is how far (in barycentric
  /// units, relative to the tet's size) a point may lie outside its nearest tet and still be found
  /// in it, with its barycentric coordinates clamped to ≥ 0 and renormalised: it catches points on
  /// the mesh boundary up to round-off. `slack` (in the vertices' unit, ≥ 0) widens that by an
  /// absolute distance: the round-off of the query points themselves, which for points given in
  /// world units far from the origin can exceed the relative tolerance.
  TetLocator(std::span<const Vec3> vertices, std::span<const std::array<std::uint32_t, 4>> tets,
             double tolerance = 1e-10, double slack = 0.0);

  /// The tet that contains x: the first tet of x's grid cell (in tet order) whose barycentric
  /// coordinates of x are all ≥ 0, failing that the cell's tet where the smallest one is
  /// largest if it is ≥ −tolerance − slack · |∇ of that coordinate|.
  Hit locate(const Vec3& x) const;

  /// The gradients of the four barycentric coordinate functions of tet t (per unit of the
  /// vertices).
  std::array<Vec3, 4> barycentricGradients(std::uint32_t t) const;

  std::size_t cellCount() const { return cellStart_.size() - 1; }
  /// The mean number of tets a cell lists (the cost of a query, in tests).
  double meanCellSize() const;

 private:
  // Construction stages: the grid over the tets' box, then the tets of every cell.
  void placeGrid(const BoundingBox& box, std::size_t tetCount);
  void fillCells(std::span<const Vec3> vertices,
                 std::span<const std::array<std::uint32_t, 4>> tets);
  std::size_t cellOf(const Vec3& x) const;
  std::array<std::size_t, 3> cellCoords(const Vec3& x) const;

  double tolerance_, slack_;
  Vec3 lo_{0.0}, inverseCell_{0.0};
  std::array<std::size_t, 3> dims_{1, 1, 1};
  std::vector<std::uint32_t> cellStart_;  // CSR over cells
  std::vector<std::uint32_t> cellTets_;
  // Per tet: corner 0 and the inverse of [p1 − p0, p2 − p0, p3 − p0] (row-major), 12 doubles.
  std::vector<double> frames_;
};

}  // namespace spacewarp
