#pragma once
// Warping OpenVDB voxel grids (level sets, fog volumes, vector fields) with any Warp, by
// backward mapping: every output voxel center y takes the input's value at its preimage
// x = warp⁻¹(y). The preimage is solved for from a seed given by the warp's affine model on
// coarse cells of the input (the warp and its Jacobian at each cell center, the warp at its
// corners; cells where that model is off by more than half a voxel are split): chord steps
// with the cell's Jacobian while they converge fast, then damped Newton. Voxels where that
// fails (a warp that is only C⁰ — piecewise linear, or with kinks — can stall Newton at a kink)
// get a second chance afterwards: continuation from the seeding cell's center along the segment
// to the voxel in steps of at most a voxel, each solved by Newton with the warp's and with
// secant Jacobians (backtracking, then golden-section line search), never stepping more than a
// voxel and keeping the sign of det J, so it follows the cell's sheet of the warp and does not
// jump across a fold.
//
// The output has the input's transform, background, name and metadata. Its active region is
// the forward image of the input's active voxels and tiles: an output voxel is active when
// the preimage of its center lies in an active input voxel (or tile). Candidates come from
// the images of the cells, each widened by twice the measured deviation of the warp from its
// affine model over the cell, so the region is complete for warps that are smooth at the
// scale of a cell. Voxels where the inverse fails are counted, never filled silently.
//
// Vector grids (vec3s) are resampled the same way, and then their vectors follow the warp as
// the grid's openvdb::VecType says (see VectorTransform): a velocity carried by the flow is
// pushed forward by J at the preimage, a gradient by J⁻ᵀ, a position is warped itself.
//
// Level sets are re-distanced after resampling with OpenVDB's own tools (LevelSetTracker by
// default, levelSetRebuild as an option), so the output has a proper narrow band of the
// input's half-width (in voxels); a warp that is rigid over the band (an isometry: Jᵀ J = I
// within 1e-9 at every cell center) keeps the resampled distances, which are then already
// exact, and skips that step. Fog volumes may conserve mass.
//
// Results are bit-identical for any number of threads.

#include <cstddef>
#include <string>

#include <openvdb/openvdb.h>

#include <spacewarp/core/inverse.h>
#include <spacewarp/core/progress.h>
#include <spacewarp/core/warp.h>

namespace spacewarp {

/// How values are read at the (non-integer) preimage of an output voxel.
enum class VolumeSampler {
  Trilinear,    ///< openvdb::tools::BoxSampler: 2³ stencil, C⁰, never overshoots.
  Triquadratic  ///< openvdb::tools::QuadraticSampler: 3³ stencil, smoother, may overshoot.
};

/// How a warped level set gets a proper narrow band of the input's half-width again.
enum class LevelSetRedistance {
  /// openvdb::tools::LevelSetTracker: the band is grown where the warp compresses (by as many
  /// voxels as the smallest singular value of J requires, each new layer normalised), the
  /// Eikonal equation is solved over the band (normCount steps, first-order upwind, TVD-RK1) and
  /// voxels beyond the half-width are trimmed. Fast; moves the surface by a small fraction
  /// of a voxel.
  Normalize,
  /// openvdb::tools::levelSetRebuild: the zero isosurface is meshed and voxelised again,
  /// exact distances to that mesh. Several times slower.
  Rebuild,
  /// None: the resampled values are kept, so the band is widened where the warp stretches and
  /// thinned where it compresses, and values are distances in the input's metric.
  None
};

/// How the values of a vector grid (vec3s) follow the warp, J = Jacobian of the warp at the
/// preimage x of the output voxel (applied in index space for grids whose vectors are in
/// local space, openvdb::GridBase::isInWorldSpace() false).
enum class VectorTransform {
  /// By the grid's openvdb::VecType: VEC_CONTRAVARIANT_RELATIVE (velocities, displacements)
  /// J v; VEC_COVARIANT (gradients) J⁻ᵀ v; VEC_COVARIANT_NORMALIZE (normals) J⁻ᵀ v normalised;
  /// VEC_CONTRAVARIANT_ABSOLUTE (positions) warp(v). VEC_INVARIANT is OpenVDB's default, which
  /// most files keep whatever the field is (velocity fields included), so it is taken as a
  /// field carried by the space: J v. Use Keep for fields that truly do not move (colours).
  Auto,
  /// J v for every vector grid, whatever its VecType (velocities, displacements, tangents).
  Push,
  /// J⁻ᵀ v rescaled to the length of v, for every vector grid: normal-like fields, whose
  /// directions stay perpendicular to warped surfaces and whose lengths (unit normals stay
  /// unit) are kept.
  Normal,
  /// Values resampled only, never transformed (colours and other invariant vectors).
  Keep
};

/// Options of warpVolume().
struct WarpVolumeOptions {
  /// The sampler. Default trilinear (OpenVDB's default for resampling).
  VolumeSampler sampler = VolumeSampler::Trilinear;

  /// Fog volumes (every grid that is not a level set) only: scale each sampled density by
  /// 1 / |det J(x)|, J the Jacobian of the forward warp at the preimage x, so that the total
  /// Σ value × voxel volume is preserved. Default off: values are carried unchanged. Ignored
  /// for level sets and vector grids.
  bool conserveMass = false;

  /// Level sets only: how the narrow band is re-distanced after resampling (skipped when the
  /// warp is rigid over the band). Default Normalize.
  LevelSetRedistance redistance = LevelSetRedistance::Normalize;

  /// Vector grids only: how their vectors follow the warp. Default Auto (the grid's VecType;
  /// J v when it says nothing).
  VectorTransform vectors = VectorTransform::Auto;

  /// LevelSetRedistance::Normalize: Eikonal steps over the band (and per grown layer). The
  /// resampled values are first divided by |J⁻ᵀ ∇φ| / |∇φ| (J of the seeding cell), which
  /// makes them distances to first order, so one step (the default) suffices for smooth warps.
  int normCount = 1;

  /// The inverse solve of each output voxel (core/inverse.h), seeded by the voxel's cell:
  /// `maxIterations` chord and Newton steps at most in the first solve (default here 20; a
  /// smooth warp typically needs 1–3), the continuation fallback for voxels where it fails (see
  /// the top of this file) with its budget of 32 times that; converged when |warp(x) - y| <=
  /// `tolerance` × voxel size (voxel size = cube root of the voxel volume; default here 1e-4
  /// voxels, far below the sampling error). `lengthScale` is ignored: warpVolume() sets it to
  /// the voxel size, which is also the continuation's step. `continuation` is honoured (default
  /// on): off, voxels where the first solve fails are counted as inverse failures.
  /// `closedForm` is not used: every voxel is solved from its seed, whatever the warp.
  InverseOptions inverse{.maxIterations = 20, .tolerance = 1e-4};

  /// Edge of the coarse seeding cells, in input voxels (≥ 1). The warp and its Jacobian are
  /// evaluated once per cell to seed Newton and bound the output region. Default 4.
  int seedSpacing = 4;

  /// When > 0, the warp is replaced by the trilinear interpolant of its displacement sampled
  /// on a lattice of this spacing (input voxels) over the input's active region (outside it
  /// the exact warp is used), which pays off for expensive warps (cage coordinates, RBFs).
  /// Error bound: the interpolated position is within (h²/8)(M_x + M_y + M_z) of the warp's,
  /// h the spacing in world units and M_a the largest |∂²w/∂a²| along the lattice axes over
  /// the region (the standard bound for trilinear interpolation; e.g. a twist of rate θ about
  /// z: h² θ² r / 8 at distance r from the axis). The field is also compared with the warp at
  /// every lattice-cell center and the largest deviation is reported as
  /// WarpVolumeReport::cacheError (world units). Sampled values then move by at most about
  /// cacheError × |∇value| × |J⁻¹|. Default 0: the exact warp.
  double cacheSpacing = 0.0;

  /// Bound on the output voxels whose preimage may be solved for (the sum over the seeding
  /// cells of the voxels in the box around each cell's image), checked before any of them is
  /// allocated. A warp that is not smooth at the scale of a voxel (e.g. a twist far from its
  /// axis, where one voxel's corners land millions of voxels apart) would otherwise make the
  /// cost follow the extent of those images rather than the active voxels; beyond the bound
  /// warpVolume() throws InvalidInput naming the grid, where the warp stretches most and by
  /// how much. Default 2^30 (about 4 GB of float output at most).
  double maxCandidateVoxels = 1073741824.0;

  /// Receives stage "warp volume" with the fraction of output blocks done; returning false
  /// cancels (the function then throws Cancelled). Default none.
  ProgressCallback progress;
};

/// What warpVolume() did. Counts are voxels (an active tile counts its voxels).
struct WarpVolumeReport {
  std::size_t inputActiveVoxels = 0;
  std::size_t outputActiveVoxels = 0;
  /// Output voxels whose preimage was solved for (the candidates of the output region).
  std::size_t solvedVoxels = 0;
  /// Candidates whose preimage was not found: Newton did not converge (ran out of iterations,
  /// singular Jacobian, stalled) and neither did the second chance, which fails where its
  /// path from the seeding cell meets a fold (det J changes sign), or, with conserveMass,
  /// det J = 0 at the preimage. They are left inactive at the background value; a non-zero
  /// count means the warp folds space or is not invertible there, and those voxels are
  /// missing from the output.
  std::size_t inverseFailures = 0;
  /// Active input voxels whose image could not be located: the warp (or, with `cacheSpacing`,
  /// its cache) is not finite there or its Jacobian is singular at the center of every
  /// seeding cell that holds them. Their image is missing from the output.
  std::size_t unmappedVoxels = 0;
  /// The most chord or Newton steps any voxel needed, and the total over all voxels (both
  /// include the second chance's steps).
  int maxNewtonIterations = 0;
  std::size_t totalNewtonIterations = 0;
  /// Σ value × voxel volume over the active voxels and tiles before and after (scalar
  /// grids that are not level sets; 0 otherwise). World units³ × value units.
  double massBefore = 0.0;
  double massAfter = 0.0;
  /// With conserveMass: the smallest and largest local volume change |det J| at the preimages
  /// of the output voxels, by which their densities were divided (0 and 0 when none was). Far
  /// from 1 (hasExtremeVolumeChange) the total is not conserved in practice: where the warp
  /// squeezes space well below the voxel size the output voxels sample a sheet of density
  /// divided by a tiny |det J|, and the mass after can be orders of magnitude off.
  double minVolumeChange = 0.0;
  double maxVolumeChange = 0.0;
  /// With conserveMass: output voxels left inactive because |det J| at their preimage is 0 or
  /// not finite (also counted in inverseFailures).
  std::size_t degenerateVolumeChanges = 0;
  /// Level sets: the half-width of the narrow band in voxels (input's = output's), and
  /// whether the band was rebuilt.
  double halfWidth = 0.0;
  bool redistanced = false;
  /// Layers grown before re-distancing (LevelSetRedistance::Normalize, compressive warps).
  int bandLayersAdded = 0;
  /// Largest deviation of the cached displacement field from the warp at the cache-cell
  /// centers (world units); 0 without cacheSpacing.
  double cacheError = 0.0;
  /// Vector grids: what was done to the vectors ("J v", "J^-T v", "J^-T v normalised",
  /// "J^-T v, length kept", "warp(v)" or "unchanged"); empty for other grids.
  std::string vectors;
  /// Voxels left inactive because their vector could not be transformed (J singular at the
  /// preimage for J⁻ᵀ, or a non-finite result).
  std::size_t vectorFailures = 0;
  /// Point data grids (warpPoints): the points moved.
  std::size_t points = 0;
};

/// Whether conserveMass met volume changes too extreme for the resampled total to be
/// trusted: |det J| below 1e-3 or above 1e3 (a thousandfold, e.g. a tenfold squeeze along
/// every axis) somewhere, or 0 or not finite (degenerateVolumeChanges).
inline bool hasExtremeVolumeChange(const WarpVolumeReport& report) {
  return report.degenerateVolumeChanges > 0 ||
         (report.maxVolumeChange > 0.0 &&
          (report.minVolumeChange < 1e-3 || report.maxVolumeChange > 1e3));
}

/// A warped grid and its report.
template <typename GridT>
struct WarpedGrid {
  typename GridT::Ptr grid;
  WarpVolumeReport report;
};

/// Warps a float, double or float-vector grid (vectors transformed as options.vectors says).
/// Throws InvalidInput naming the grid if its transform is not linear (frustum maps), if a
/// level set's voxels are not cubes, if the output would exceed options.maxCandidateVoxels,
/// or for invalid options; Cancelled if progress asks.
WarpedGrid<openvdb::FloatGrid> warpVolume(const Warp& warp, const openvdb::FloatGrid& grid,
                                          const WarpVolumeOptions& options = {});
WarpedGrid<openvdb::DoubleGrid> warpVolume(const Warp& warp, const openvdb::DoubleGrid& grid,
                                           const WarpVolumeOptions& options = {});
WarpedGrid<openvdb::Vec3SGrid> warpVolume(const Warp& warp, const openvdb::Vec3SGrid& grid,
                                          const WarpVolumeOptions& options = {});

}  // namespace spacewarp
