#pragma once
// As-rigid-as-possible surface editing (Sorkine and Alexa 2007): one rotation per vertex,
// cotangent weights, hard positional constraints.
//
//   E(x, R) = Σ_i Σ_{(a,b) ∈ T(i)} w_ab ‖(x_a − x_b) − R_i (x̄_a − x̄_b)‖²
//
// with T(i) the edges of the triangles around vertex i ("spokes and rims", Chao et al. 2010:
// the default) or its one-ring edges only ("spokes", the paper's). With spokes, the negative
// cotangent weights of obtuse triangles would make the energy unbounded below (on the
// armadillo, where 11% of its weights are negative, single edges stretch 38-fold even with
// every handle at rest, as libigl's spokes energy does): they are replaced by 1e-3 of their
// magnitude. With rims each triangle's terms are its Dirichlet energy, never negative, and the
// cotangent weights are used as they are.
//
// minimised by alternating the local step (each R_i the rotation of the polar decomposition
// of its edge covariance, reflections excluded) and the global step (a Laplace solve with the
// factor kept from construction). Each step minimises E over its variables, so the energy
// never increases.

#include <array>
#include <cstdint>
#include <memory>
#include <span>
#include <vector>

#include <spacewarp/core/math.h>
#include <spacewarp/core/progress.h>

namespace spacewarp {

/// The edges each vertex's rotation acts on.
enum class ArapEnergy {
  SpokesAndRims,  ///< the edges of the triangles around the vertex (bounded below; default)
  Spokes,         ///< the vertex's one-ring edges (Sorkine and Alexa 2007)
};

struct ArapOptions {
  /// The energy's edge sets (default SpokesAndRims).
  ArapEnergy energy = ArapEnergy::SpokesAndRims;
  /// At most this many local/global iterations per solve (default 200: with acceleration a
  /// 90° bend of a 10k-vertex bar converges to 1e-6 in about 130).
  int maxIterations = 200;
  /// Stop when an iteration lowers the energy by less than this fraction of it (default 1e-6);
  /// 0 runs maxIterations.
  double relativeTolerance = 1e-6;
  /// Anderson acceleration over this many previous iterations (default 5; 0: the plain
  /// local/global iteration). An accelerated iterate is kept only when it lowers the energy, so
  /// the energy still never increases; the fixed points are the plain iteration's.
  int accelerationWindow = 5;
};

/// What one ARAP solve did.
struct ArapReport {
  /// The energy of the start and after each iteration (iterations + 1 entries, non-increasing),
  /// in world units squared.
  std::vector<double> energies;
  int iterations = 0;
  /// Whether the relative decrease fell below relativeTolerance (or the energy reached 0)
  /// before maxIterations.
  bool converged = false;
  /// Whether the solve started from the handles' common rigid motion (it had lower energy
  /// than the Laplacian-editing start): then a common rigid motion of all handles is
  /// reproduced exactly.
  bool startedRigid = false;
};

/// The result of a solve: all n vertices (world units) and the report.
struct ArapResult {
  std::vector<Vec3> positions;
  ArapReport report;
};

/// Prefactorised ARAP editing of one mesh with one set of constrained vertices. Components no
/// constrained vertex reaches, and isolated vertices, stay at rest (heldVertices()). Not
/// thread-safe; construct one per thread.
class ArapEditor {
 public:
  /// Same arguments and errors as LinearEditor's constructor.
  ArapEditor(std::span<const Vec3> positions,
             std::span<const std::array<std::uint32_t, 3>> triangles,
             std::span<const std::uint32_t> constrained, const ArapOptions& options = {});
  ~ArapEditor();
  ArapEditor(ArapEditor&&) noexcept;
  ArapEditor& operator=(ArapEditor&&) noexcept;

  /// Solves for the constrained vertices at `targets` (one per constrained vertex, in the
  /// constructor's order), starting from the Laplacian-editing solution or the handles' rigid
  /// motion (whichever has the lower energy). Throws InvalidInput on a wrong count or a
  /// non-finite target. Reports the stage "arap" (one step per iteration); a cancel throws
  /// Cancelled.
  ArapResult solve(std::span<const Vec3> targets, const ProgressCallback& progress = {});

  /// Continues from `start` (n vertices, e.g. the previous frame's result), the constrained
  /// vertices set to `targets` first.
  ArapResult solveFrom(std::span<const Vec3> start, std::span<const Vec3> targets,
                       const ProgressCallback& progress = {});

  /// The ARAP energy of `positions` (n vertices) with its optimal rotations.
  double energy(std::span<const Vec3> positions) const;

  std::span<const std::uint32_t> heldVertices() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace spacewarp
