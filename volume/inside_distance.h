#pragma once
// Distances measured inside a model: for each handle, the length of the shortest path from the
// handle to a point that stays inside a closed polygon soup (a geodesic distance in the solid),
// for MLS weights that do not reach across empty space (Zhu & Gortler, "3D deformation using
// moving least squares", Harvard TR-10-07, 2007, section 5).

#include <array>
#include <cstddef>
#include <memory>
#include <span>
#include <vector>

#include <spacewarp/core/geometry.h>
#include <spacewarp/core/handle_distances.h>

namespace spacewarp {

class ArchiveReader;
class ArchiveWriter;

/// Options of InsideDistances.
struct InsideDistanceOptions {
  /// Voxel edge of the distance grids, world units; finite, >= 0. Default 0: the model's
  /// bounding-box diagonal / 128, which resolves parts and gaps a few hundredths of the model's
  /// size wide in about 1–4 MB per handle for compact models. Parts thinner than about two voxels
  /// and gaps narrower than about four need a smaller voxel.
  double voxelSize = 0.0;
};

/// The distances from n handles to any point, measured inside a closed model.
///
/// Precompute: the model's signed distance on a dense grid of voxel edge h spanning its bounding
/// box plus 4 voxels (OpenVDB's tools::meshToLevelSet, volume/mesh_level_set.h); then per handle
/// a fast-marching solution of |∇d| = 1 (Sethian's second-order upwind scheme where two known
/// voxels line up, first order elsewhere) from exact Euclidean distances in a ball of 4 h around
/// the handle, over the voxels inside the model (φ < 0) only. A voxel outside takes the distance
/// of its nearest inside voxel, extrapolated linearly along the distance's gradient there for
/// the first 2 h and growing with the way out beyond: never a path through empty space or along
/// the outside of the surface, so one part's distances do not undercut another's at its surface
/// and concave corners are not cut. Handles are marched in parallel (TBB), each on its own, so
/// the result does not depend on the thread count.
///
/// Evaluation: trilinear interpolation of each handle's grid (stored as float), blended within
/// 1–2 h of the handle into the exact |x − p_i| (a C¹ smoothstep in the distance) so that
/// d_i(p_i) = 0 exactly and MLS interpolates its handles. Outside the grid, d_i(x) = d_i(c) +
/// |x − c| with c the nearest point of the grid's box. So every point has a distance, and soups,
/// point clouds and volumes that touch or leave the model are all mapped. d_i is continuous
/// except midway between two parts across a gap (where the nearest inside voxel changes part:
/// one steep cell; MLS through it is continuous but stretched, a Jacobian of about 10 across a
/// 1-unit gap at h = 0.05, and on the mid-plane the gradient is one side's); |∇d_i| ≈ 1 inside
/// and up to 2 outside. A component of the model that no handle's inside path reaches is
/// treated as outside: its distances are extrapolated from the nearest reached part, so it moves
/// with those handles (a handle placed in it, target equal to itself, holds it). The gradient is
/// that of the interpolation: exact within a voxel, discontinuous across voxel faces, so a Jacobian
/// built on it jumps by O(h)-relative amounts between voxels.
///
/// Accuracy (measured, tests/volume/inside_distance_test.cpp): inside a convex box within 0.16 h
/// of the Euclidean distance; around the reflex corner of an L within 0.06 h of the shortest
/// path. Parts thinner than about 2 h are lost, gaps narrower than about 4 h (the seed ball) may
/// be bridged near a handle: choose h below a quarter of the thinnest part and gap.
///
/// Cost: n × (grid voxels) × 4 bytes, plus about 40 bytes per voxel while building and 25 per
/// voxel per marching thread; checked against the available memory before allocating
/// (InvalidInput naming the voxel size). Marching is O(N log N) per handle for N grid voxels;
/// evaluation reads 8 values per handle per point. Measured (bench/nonlinear_bench_mls_inside.cpp):
/// 16 handles, 265k voxels, 1.1 s on 2 loaded cores; MLS applies at about 0.9× the Euclidean
/// speed.
class InsideDistances final : public HandleDistances {
 public:
  /// `model`: a closed polygon soup (world units); `handles`: n >= 1 points, world units, each
  /// inside the model or within 2 voxels outside its surface. Throws InvalidInput naming the
  /// problem for: an empty or invalid model, one with boundary edges (not closed: edges used by
  /// an odd number of polygons, vertices matched by position), one that encloses no voxel
  /// (thinner than a voxel), a non-finite or negative voxel size, no handles, a non-finite handle,
  /// a handle outside the model (naming its index and how far out it is), or a grid too large for
  /// the memory.
  InsideDistances(const PolygonSoup& model, std::vector<Vec3> handles,
                  const InsideDistanceOptions& options = {});

  std::span<const Vec3> handles() const override { return handles_; }
  void distances(const Vec3& x, std::span<double> distances) const override;
  void distancesAndGradients(const Vec3& x, std::span<double> distances,
                             std::span<Vec3> gradients) const override;

  /// The voxel edge h used, world units.
  double voxelSize() const { return h_; }
  /// The grid's voxel counts along x, y, z.
  std::array<int, 3> gridSize() const { return dims_; }

  /// Archive tag "inside-distances": the handles, the grid (voxel size, origin, counts) and the
  /// marched distances as the floats they are (4 bytes per voxel and handle).
  void save(ArchiveWriter& out) const override;
  /// Takes the marched grids as stored, without the model and without marching again, after
  /// checking the handles, the grid and that the value count is counts × handles (all before
  /// allocating them) and every value finite and >= 0.
  static std::shared_ptr<const InsideDistances> load(ArchiveReader& in);

 private:
  InsideDistances() = default;  // for load()

  template <bool Gradients>
  void evaluate(const Vec3& x, double* d, Vec3* g) const;

  std::vector<Vec3> handles_;
  double h_ = 0.0;
  Vec3 origin_{0.0};  // world position of grid voxel (0, 0, 0)
  std::array<int, 3> dims_{0, 0, 0};
  std::vector<float> values_;  // voxel-major: values_[voxel × n + handle]
};

}  // namespace spacewarp
