#pragma once
// The embedded deformation graph of Sumner, Schmid and Pauly, "Embedded deformation for shape
// manipulation" (SIGGRAPH 2007): a sparse set of nodes g_j, each carrying an affine map
// (A_j, t_j), blended over space by the nodes' distance weights. Handle constraints are met
// by Gauss-Newton on E = w_rot E_rot + w_reg E_reg + w_con E_con, and the solved graph is a
// plain `Warp`: x' = Σ_j w_j(x) [A_j (x − g_j) + g_j + t_j].

#include <cstdint>
#include <memory>
#include <span>
#include <utility>
#include <vector>

#include <spacewarp/core/math.h>
#include <spacewarp/core/progress.h>
#include <spacewarp/core/warp.h>

namespace spacewarp {

class ArchiveReader;
class ArchiveWriter;

namespace detail {
struct GraphIndex;   // nodes, KD-tree and lookup grid (nonlinear/detail/graph_index.h)
struct SolverCache;  // normal equations and factor kept between solves (detail/solver_cache.h)
}  // namespace detail

/// How DeformationGraph(positions, options) picks its nodes among the positions.
enum class NodeSampling {
  /// The positions are binned into cubic cells of edge `spacing` (cell (0,0,0) has its corner
  /// at the origin) and each occupied cell gives one node: its input point nearest the
  /// centroid of its input points (ties: the lower index). Nodes come in lexicographic order
  /// of their cells' integer coordinates (x, then y, then z). Two nodes may be closer than
  /// `spacing` across a cell face.
  Voxel,
  /// A maximal Poisson-disk subset of the positions (greedy dart throwing over the input
  /// points): the points are visited in a fixed pseudo-random order (a hash of their index)
  /// and one becomes a node unless a node already lies closer than `spacing`. Hence no two
  /// nodes are closer than `spacing`, and every input point lies within `spacing` of a node
  /// (strictly closer, unless it is a node). Deterministic: the same positions give the same
  /// nodes, listed in ascending input index. Fewer nodes than Voxel for the same spacing,
  /// spread more evenly (677 against 1,000 for 20,000 random points in a 10³ box at spacing 1).
  PoissonDisk,
};

/// How a graph is built.
struct DeformationGraphOptions {
  /// Node sampling spacing (world units); see `sampling` for what it means. Must be > 0 when
  /// nodes are sampled; ignored when the nodes are given explicitly.
  double spacing = 0.0;
  /// Nodes influencing each point: its k nearest (default 4, as in the paper). The weight
  /// cut-off d_max is the distance to the (k+1)-th nearest node, so the graph needs at least
  /// k + 1 nodes.
  int k = 4;
  /// Node sampling scheme (default: voxel grid, the behaviour before the option existed).
  /// Ignored when the nodes are given explicitly.
  NodeSampling sampling = NodeSampling::Voxel;
};

/// Parameters of DeformationGraph::solve(). Defaults are the paper's.
///
/// Units: E_rot is unitless while E_reg and E_con are squared lengths, so the solve measures
/// lengths in units of ℓ = the largest extent of the nodes' bounding box (the translations
/// and residuals are divided by ℓ): the weights are unitless, keep the paper's meaning in a
/// unit-sized scene, and scaling the whole problem (nodes, handles, targets) by s scales the
/// solution exactly by s (same iterations, same warp up to rounding). Before, the same edit
/// failed to converge at scene sizes 1e-6 and 1e6.
struct DeformationGraphSolveOptions {
  double rotationWeight = 1.0;         ///< w_rot: how close each A_j stays to a rotation.
  double regularizationWeight = 10.0;  ///< w_reg: how well neighbouring maps agree.
  double constraintWeight = 100.0;     ///< w_con: how closely handles reach their targets.
  /// Gauss-Newton iterations at most (each may retry with a larger damping, see below).
  int maxIterations = 50;
  /// Stop when an iteration lowers the energy by at most tolerance · E_{k−1} (relative, so
  /// the same for any scale of the scene; the paper's |E_k − E_{k−1}| < tolerance · (1 + E_k)
  /// stops at once in a small scene), or when the energy reaches rounding level (residuals
  /// about 1e-10 of the handles' spread and the edges' lengths, or a few ulps of the largest
  /// coordinate, whichever is larger). 0 runs to the numerical minimum: decreases below
  /// 64 ε · E_{k−1} are rounding and stop the solve too.
  double tolerance = 1e-6;
  /// Told "solve graph" and the fraction of maxIterations done after each iteration, and 1
  /// when they end, converged or not (nothing when the start already meets the stopping
  /// rule); may cancel (Cancelled). Default: none.
  ProgressCallback progress;
};

/// What solve() did.
struct DeformationGraphReport {
  /// energies[0] is the energy of the starting state; energies[i] the energy after
  /// iteration i. Strictly decreasing: a step that would not lower the energy is retried with
  /// a ten times larger Levenberg-Marquardt damping instead.
  std::vector<double> energies;
  int iterations = 0;  ///< Accepted Gauss-Newton steps.
  /// The stopping rule was met (see DeformationGraphSolveOptions::tolerance; a start at
  /// rounding level, such as the rigid fit of a rigid motion, meets it with no iteration), or
  /// no damped step lowered the energy any more (a numerical minimum); false when the
  /// iterations ran out.
  bool converged = false;
  /// The unweighted terms at the final state (E = w_rot·rotation + w_reg·... ), lengths in
  /// units of ℓ (see DeformationGraphSolveOptions), like `energies`.
  double rotationEnergy = 0.0;
  double regularizationEnergy = 0.0;
  double constraintEnergy = 0.0;
  /// Gauss-Newton started from the best rigid fit of the handles to the targets (it had a
  /// lower energy than the maps before the solve), not from those maps.
  bool rigidStart = false;
  /// Connected components of the graph (see DeformationGraph::edges()).
  int componentCount = 0;
  /// Components that no constraint reaches: they stay rigidly in place (A = I, t = 0).
  int unconstrainedComponents = 0;
  /// The nodes of those components, ascending.
  std::vector<std::uint32_t> unconstrainedNodes;
};

/// The k nearest nodes of a point and their normalised weights.
struct NodeWeights {
  std::vector<std::uint32_t> nodes;  ///< k node indices, nearest first (ties: lower index).
  std::vector<double> weights;       ///< k weights, summing to 1.
};

/// A solved (or rest) graph as a `Warp`: x' = Σ_j w_j(x) [A_j (x − g_j) + g_j + t_j] over the
/// k nearest nodes of x, w_j = (1 − |x − g_j| / d_max)² normalised, d_max = |x − g_(k+1)|.
/// Continuous everywhere; smooth except where the set of k nearest nodes changes (the weights
/// are zero there) and at the nodes themselves. The Jacobian is analytic. A snapshot: later
/// solves of the graph do not change it.
class DeformationGraphWarp final : public Warp {
 public:
  DeformationGraphWarp(std::shared_ptr<const detail::GraphIndex> index, std::vector<Mat3> a,
                       std::vector<Vec3> t);
  Vec3 apply(const Vec3& x) const override;
  Mat3 jacobian(const Vec3& x) const override;
  /// Parallel (TBB), allocation-free per point, bit-identical to apply() for any thread count.

  /// Archive tag "deformation-graph": k, the nodes and the solved state (A_j − I as stored, and
  /// t_j). Neither the handles nor the solve's options are saved: a loaded warp cannot re-solve.
  void save(ArchiveWriter& out) const override;
  /// Rebuilds the node index from the nodes (deterministic: the same neighbours) and takes the
  /// state as stored, after checking k, the counts and that everything is finite.
  static std::shared_ptr<const DeformationGraphWarp> load(ArchiveReader& in);

 protected:
  std::size_t batchGrain() const override;
  UnmappedPoints applyRange(std::span<const Vec3> in, std::span<Vec3> out, std::size_t begin,
                            std::size_t end) const override;
  [[noreturn]] void throwUnmapped(const UnmappedPoints& unmapped,
                                  std::span<const Vec3> in) const override;

 private:
  struct Stored {};  // selects the constructor from stored B_j = A_j − I
  DeformationGraphWarp(std::shared_ptr<const detail::GraphIndex> index, std::vector<Mat3> b,
                       std::vector<Vec3> t, Stored);

  std::shared_ptr<const detail::GraphIndex> index_;
  std::vector<Mat3> a_;
  std::vector<Vec3> t_;
};

/// The deformation graph: nodes, their neighbourhoods, and one affine map per node
/// (the identity until solve() is called).
class DeformationGraph {
 public:
  /// Samples nodes from `positions` (n points, world units: a PointSet's or PolygonSoup's
  /// positions, or the centers of a volume's active voxels) at options.spacing with
  /// options.sampling; edges as edges() says. Throws InvalidInput for empty or non-finite
  /// positions, spacing <= 0 or not finite, k < 1, or k >= the number of nodes.
  DeformationGraph(std::span<const Vec3> positions, const DeformationGraphOptions& options);

  /// Explicit nodes (world units). Edges as edges() says, over the points of `positions`;
  /// when `positions` is empty the nodes themselves are used. Throws
  /// InvalidInput as above (options.spacing is ignored).
  DeformationGraph(std::span<const Vec3> nodes, std::span<const Vec3> positions,
                   const DeformationGraphOptions& options);

  ~DeformationGraph();
  DeformationGraph(DeformationGraph&&) noexcept;
  DeformationGraph& operator=(DeformationGraph&&) noexcept;

  std::size_t nodeCount() const;
  std::span<const Vec3> nodes() const;
  int k() const;
  /// Undirected edges (i < j), sorted: nodes that influence a common position, and each node
  /// with every node within its own cut-off distance d_(k+1) (ties included, so a regular
  /// grid of nodes is connected for any k).
  const std::vector<std::pair<std::uint32_t, std::uint32_t>>& edges() const;
  /// The k nearest nodes of x and their weights (throws InvalidInput if x is not finite).
  NodeWeights weights(const Vec3& x) const;

  /// Moves each handles[l] (any point of space, world units) towards targets[l] by
  /// Gauss-Newton from the current maps (the identity at first) or, when its energy is lower,
  /// from the best rigid fit of the handles to the targets (every map the same rotation), so
  /// a rigid motion of all handles is reproduced exactly everywhere. Components of the graph
  /// that no handle's nodes reach keep A = I, t = 0 and are listed in the report. Throws
  /// InvalidInput for mismatched sizes, non-finite points, handles beyond ±1e150 or invalid
  /// options; SolverError if the energy overflows (targets too far for double precision) or
  /// the normal equations cannot be factorised (OutOfMemory, a SolverError, when CHOLMOD runs
  /// out of memory).
  ///
  /// The result is bit-identical for any TBB or BLAS thread count: the assembly is serial and
  /// the sparse Cholesky runs its BLAS single-threaded (OpenBLAS's process-wide thread count
  /// is set to 1 during each factorisation and triangular solve and restored after it; those
  /// of concurrent solve() calls on different graphs are serialised by a process-wide lock).
  ///
  /// Cost: the normal equations' sparsity pattern, their constant (regulariser and
  /// constraint) part, the Cholesky analysis and the last numeric factor are kept between
  /// calls while the handles, their nodes and w_reg, w_con stay the same; so a solve from the
  /// rest state with the same handles (only the targets moved) starts from the kept factor
  /// instead of factorising again. The first solve with new handles pays the analysis and a
  /// factorisation (about 0.2-0.4 s for 1,000 nodes). Results never depend on what was kept.
  DeformationGraphReport solve(std::span<const Vec3> handles, std::span<const Vec3> targets,
                               const DeformationGraphSolveOptions& options = {});

  /// Back to the rest state (A = I, t = 0).
  void reset();

  std::span<const Mat3> affineMaps() const { return a_; }    ///< A_j, one per node.
  std::span<const Vec3> translations() const { return t_; }  ///< t_j (world units).

  /// A snapshot of the current state as a Warp.
  DeformationGraphWarp warp() const;

 private:
  std::shared_ptr<const detail::GraphIndex> index_;
  std::vector<Mat3> a_;
  std::vector<Vec3> t_;
  /// Kept between solve() calls with the same handles and weights: the normal equations'
  /// pattern and constant part, the Cholesky analysis and the last numeric factor.
  std::unique_ptr<detail::SolverCache> cache_;
};

}  // namespace spacewarp
