#include <spacewarp/surface/cage_arap.h>

#include <algorithm>
#include <cmath>

#include <tbb/parallel_for.h>
#include <Eigen/Cholesky>

#include <spacewarp/core/binding.h>
#include <spacewarp/core/detail/memory_budget.h>
#include <spacewarp/core/detail/rotation.h>
#include <spacewarp/core/errors.h>
#include <spacewarp/surface/detail/arap_terms.h>
#include <spacewarp/surface/detail/edit_problem.h>
#include <spacewarp/surface/detail/local_global.h>
#include <spacewarp/surface/detail/rotation_clusters.h>

namespace spacewarp {

namespace {

Eigen::Matrix3d transposeOf(const Mat3& m) { return toEigen(glm::transpose(m)); }

}  // namespace

void checkOptions(const CageArapOptions& o) {
  if (!(o.handleWeight > 0.0) || !(o.handleWeight <= 1e6) || o.maxIterations < 0 ||
      o.accelerationWindow < 0 || !(o.relativeTolerance >= 0.0) ||
      !std::isfinite(o.relativeTolerance) || !(o.reachTolerance >= 0.0) ||
      !std::isfinite(o.reachTolerance)) {
    throw InvalidInput(
        "CageArapEditor: handleWeight must be > 0 and at most 1e6, maxIterations and "
        "accelerationWindow >= 0, the tolerances finite and >= 0");
  }
}

// Notation of the header: ΔP = P − P̄ (m × 3), W the model's weights (vertex columns), and per
// term s = (a, b) of a vertex in cluster k the rest vector ē_s = x̄_a − x̄_b and weight w_s. Then
//   cov_k = S̄_k + (Q_kᵀ ΔP)ᵀ             with S̄_k = Σ_s w_s ē_s ē_sᵀ,
//   Q_kᵀ = Σ_s w_s ē_s (W_a − W_b)        (3 × m, the rows 3k..3k+2 of qt),
//   E_arap = 2 c̄ + 2 tr(ΔPᵀ C̄) + tr(ΔPᵀ K ΔP) − 2 Σ_k tr(R_kᵀ cov_k),
//   with c̄ = Σ w |ē|², C̄ = Σ_k Q_k, K = Σ_s w_s (W_a − W_b)ᵀ(W_a − W_b) = Wᵀ A W (A: the
//   terms' system matrix);
// the global step solves (K + λ H + μ I) ΔP = Σ_k Q_k (R_kᵀ − I) + λ W_hᵀ (t − x̄_h) + μ ΔP_prev.
struct CageArapEditor::Impl {
  CageArapOptions options;
  std::size_t m = 0;  // control points
  std::size_t clusters = 0;
  std::vector<Vec3> restControls;
  std::vector<Vec3> restModel;
  Eigen::MatrixXd weights;  // n × m (dense; the subspace's basis)
  std::vector<std::uint32_t> constrained;
  Eigen::MatrixXd qt;             // 3K × m
  std::vector<Mat3> restCov;      // S̄_k
  Eigen::MatrixXd restCross;      // C̄ (m × 3)
  double restSquared = 0.0;       // c̄
  Eigen::MatrixXd stiffness;      // K
  Eigen::MatrixXd handleGram;     // H = W_hᵀ W_h
  Eigen::MatrixXd handleWeights;  // W_h (h × m)
  Eigen::MatrixXd handleRest;     // x̄_h (h × 3)
  double lambda = 0.0, mu = 0.0;
  Eigen::LLT<Eigen::MatrixXd> system;
  double diagonal = 0.0;
  /// Whether every model vertex's weights sum to 1, so that a common translation of the control
  /// points translates the model: the solve then runs in the frame of the handles' mean
  /// displacement, whose energies have no large terms to cancel.
  bool translates = false;

  // Per-iteration state.
  std::vector<Mat3> rotations;

  double localStep(const Eigen::MatrixXd& dp, const Eigen::MatrixXd& targets) {
    const Eigen::MatrixXd mk = qt * dp;  // 3K × 3
    std::vector<double> gain(clusters);
    tbb::parallel_for(std::size_t{0}, clusters, [&](std::size_t k) {
      Mat3 cov = restCov[k];
      for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c) cov[c][r] += mk(3 * Eigen::Index(k) + c, r);
      const Mat3 rot = detail::closestRotationNear(cov, rotations[k]);
      rotations[k] = rot;
      gain[k] = glm::dot(rot[0], cov[0]) + glm::dot(rot[1], cov[1]) + glm::dot(rot[2], cov[2]);
    });
    double trace = 0.0;
    for (double g : gain) trace += g;
    const Eigen::MatrixXd handleResidual = handleRest + handleWeights * dp - targets;
    // Non-negative; below 0 only by the rounding of the expanded sum.
    return std::max(0.0, 2.0 * restSquared + 2.0 * (dp.cwiseProduct(restCross)).sum() +
                             (dp.cwiseProduct(stiffness * dp)).sum() - 2.0 * trace +
                             lambda * handleResidual.squaredNorm());
  }

  // qt, the rest covariances and sums of the clusters' terms: everything the iterations need of
  // the model's size, folded into 3K × m and m × 3 matrices.
  void foldTerms(const detail::ArapTerms& terms, const std::vector<std::uint32_t>& cluster) {
    // qt's rows 3k..3k+2 = Σ over the terms of the vertices of cluster k of w ē (W_a − W_b):
    // per vertex, its terms' coefficients gathered by model vertex (a few each), then one rank-1
    // update of the cluster's block per model vertex. Memory O(K·m), whatever the model's size.
    qt = Eigen::MatrixXd::Zero(3 * Eigen::Index(clusters), weights.cols());
    restCov.assign(clusters, Mat3(0.0));
    std::vector<std::pair<std::uint32_t, Vec3>> coefficients;
    const auto add = [&](std::uint32_t v, const Vec3& c) {
      for (auto& [u, sum] : coefficients)
        if (u == v) {
          sum += c;
          return;
        }
      coefficients.emplace_back(v, c);
    };
    for (std::size_t i = 0; i < terms.vertexCount(); ++i) {
      coefficients.clear();
      for (std::size_t k = terms.vertexOffsets[i]; k < terms.vertexOffsets[i + 1]; ++k) {
        const detail::ArapElement& e = terms.elements[terms.vertexElements[k]];
        for (int j = 0; j < e.count; ++j) {
          const Vec3 we = e.weight[j] * e.rest[j];
          add(e.a[j], we);
          add(e.b[j], -we);
          restCov[cluster[i]] += glm::outerProduct(we, e.rest[j]);
          restSquared += glm::dot(we, e.rest[j]);
        }
      }
      auto block = qt.middleRows(3 * Eigen::Index(cluster[i]), 3);
      for (const auto& [v, c] : coefficients)
        block.noalias() += Eigen::Vector3d(c.x, c.y, c.z) * weights.row(v);
    }
    restCross = Eigen::MatrixXd::Zero(weights.cols(), 3);
    for (std::size_t c = 0; c < clusters; ++c)
      restCross += qt.middleRows(3 * Eigen::Index(c), 3).transpose();
  }

  // The handles' mean displacement, the origin of the solve's frame (0 when a translation of the
  // controls does not translate the model).
  Eigen::RowVector3d frameShift(const Eigen::MatrixXd& targets) const {
    if (!translates) return Eigen::RowVector3d::Zero();
    return (targets - handleRest).colwise().mean();
  }

  // The m × m matrices of the global step (ARAP stiffness, handle term, ridge), factorised.
  void buildSystem(const detail::ArapTerms& terms, std::span<const Vec3> positions) {
    stiffness = weights.transpose() * (terms.system * weights);
    const auto h = static_cast<Eigen::Index>(constrained.size());
    const auto m = weights.cols();
    handleWeights.resize(h, m);
    handleRest.resize(h, 3);
    for (Eigen::Index r = 0; r < h; ++r) {
      const std::uint32_t v = constrained[static_cast<std::size_t>(r)];
      handleWeights.row(r) = weights.row(v);
      handleRest.row(r) << positions[v].x, positions[v].y, positions[v].z;
    }
    handleGram = handleWeights.transpose() * handleWeights;
    lambda = options.handleWeight * std::max(terms.totalWeight, 1e-300) / double(h);
    Eigen::MatrixXd a = stiffness + lambda * handleGram;
    // A tiny proximal ridge (towards the previous iterate) keeps control points the model does not
    // feel (a lattice point outside its reach) where they are instead of making the system
    // singular, without moving the minimiser.
    mu = 1e-9 * a.trace() / double(m);
    a.diagonal().array() += mu;
    system.compute(a);
    if (system.info() != Eigen::Success) {
      throw SolverError("CageArapEditor: the subspace system is not positive definite");
    }
  }

  // The minimiser for the current rotations, with a proximal term μ |ΔP − current|² (see the
  // constructor): its fixed points are the energy's, and it lowers the energy as the exact step.
  Eigen::MatrixXd globalStep(const Eigen::MatrixXd& targets, const Eigen::MatrixXd& current) const {
    Eigen::MatrixXd z(3 * Eigen::Index(clusters), 3);
    for (std::size_t k = 0; k < clusters; ++k)
      z.block<3, 3>(3 * Eigen::Index(k), 0) =
          transposeOf(rotations[k]) - Eigen::Matrix3d::Identity();
    const Eigen::MatrixXd rhs = qt.transpose() * z +
                                lambda * handleWeights.transpose() * (targets - handleRest) +
                                mu * current;
    return system.solve(rhs);
  }
};

CageArapEditor::CageArapEditor(std::span<const Vec3> positions,
                               std::span<const std::array<std::uint32_t, 3>> triangles,
                               std::shared_ptr<const Coordinates> coordinates,
                               std::span<const std::uint32_t> constrained,
                               const CageArapOptions& options, const ProgressCallback& progress)
    : impl_(std::make_unique<Impl>()) {
  const std::string caller = "CageArapEditor";
  if (!coordinates) throw InvalidInput(caller + ": no coordinates");
  checkOptions(options);
  auto& im = *impl_;
  im.options = options;
  const detail::EditProblem problem =
      detail::makeEditProblem(positions, triangles, constrained, caller);
  im.diagonal = problem.diagonal;
  im.restModel.assign(positions.begin(), positions.end());
  im.constrained.assign(constrained.begin(), constrained.end());
  im.m = coordinates->controlPointCount();
  const auto rest = coordinates->restControlPoints();
  im.restControls.assign(rest.begin(), rest.end());
  const auto n = static_cast<Eigen::Index>(positions.size());
  const auto m = static_cast<Eigen::Index>(im.m);
  std::size_t k = options.rotationClusters;
  if (k == 0) k = std::max<std::size_t>(64, 4 * im.m);
  k = std::min<std::size_t>(k, positions.size());
  // The binding and its vertex block (n × columns, n × m), qt (3K × m), the m × m matrices, the
  // ARAP terms (one element of about 150 bytes per triangle).
  const double columns = double(coordinates->columnCount());
  detail::checkMemory(8.0 * (double(n) * (columns + double(m)) + 3.0 * double(k) * double(m) +
                             4.0 * double(m) * double(m)) +
                          400.0 * double(n),
                      caller + ": " + std::to_string(n) + " model vertices × " + std::to_string(m) +
                          " control points (" + std::to_string(k) + " rotation clusters)");
  {
    const Binding binding(coordinates, positions, progress);
    im.weights = binding.isSparse() ? Eigen::MatrixXd(binding.sparse()).leftCols(m)
                                    : Eigen::MatrixXd(binding.dense().leftCols(m));
  }
  im.translates = ((im.weights.rowwise().sum().array() - 1.0).abs() <= 1e-9).all();
  ProgressTracker tracker(progress, "subspace", 3);
  const detail::ArapTerms terms =
      detail::makeArapTerms(options.energy, positions, triangles, problem.laplacian);
  const auto cluster = detail::rotationClusters(problem.laplacian, positions, k);
  im.clusters = 0;
  for (std::uint32_t c : cluster) im.clusters = std::max<std::size_t>(im.clusters, c + 1);
  im.rotations.assign(im.clusters, Mat3(1.0));
  tracker.advance();

  im.foldTerms(terms, cluster);
  tracker.advance();

  im.buildSystem(terms, positions);
  tracker.finish();
}

CageArapEditor::~CageArapEditor() = default;
CageArapEditor::CageArapEditor(CageArapEditor&&) noexcept = default;
CageArapEditor& CageArapEditor::operator=(CageArapEditor&&) noexcept = default;

std::size_t CageArapEditor::clusterCount() const { return impl_->clusters; }

namespace {

Eigen::MatrixXd targetMatrix(std::span<const Vec3> targets, std::size_t expected,
                             const std::string& caller) {
  if (targets.size() != expected) {
    throw InvalidInput(caller + ": " + std::to_string(targets.size()) + " targets for " +
                       std::to_string(expected) + " constrained vertices");
  }
  for (std::size_t k = 0; k < targets.size(); ++k)
    if (!isFinite(targets[k])) {
      throw InvalidInput(caller + ": target " + std::to_string(k) + " is not finite");
    }
  return detail::toMatrix(targets);
}

}  // namespace

CageArapResult CageArapEditor::solve(std::span<const Vec3> targets,
                                     const ProgressCallback& progress) {
  auto& im = *impl_;
  const Eigen::MatrixXd t = targetMatrix(targets, im.constrained.size(), "CageArapEditor::solve");
  // Both starts are compared in the frame of solveFrom (see there).
  const Eigen::RowVector3d shift = im.frameShift(t);
  const Eigen::MatrixXd shifted = t.rowwise() - shift;
  // Start 1: the rotation-free (linear) solution, its proximal term towards the rest pose
  // carried by the handles' mean displacement (0 in this frame).
  std::fill(im.rotations.begin(), im.rotations.end(), Mat3(1.0));
  const Eigen::MatrixXd linear =
      im.globalStep(shifted, Eigen::MatrixXd::Zero(Eigen::Index(im.m), 3));
  // Start 2: the handles' common rigid motion applied to the cage.
  std::vector<Vec3> handleRest;
  for (std::uint32_t v : im.constrained) handleRest.push_back(im.restModel[v]);
  const auto fit = detail::rigidFit(handleRest, targets);
  std::vector<Vec3> rigid(im.m);
  for (std::size_t c = 0; c < im.m; ++c) rigid[c] = fit.r * im.restControls[c] + fit.shift;
  Eigen::MatrixXd rigidDp = detail::toMatrix(rigid) - detail::toMatrix(im.restControls);
  rigidDp.rowwise() -= shift;
  const bool startRigid = im.localStep(rigidDp, shifted) < im.localStep(linear, shifted);
  std::vector<Vec3> start(im.m);
  for (std::size_t c = 0; c < im.m; ++c) {
    const Eigen::RowVector3d row =
        (startRigid ? rigidDp : linear).row(static_cast<Eigen::Index>(c)) + shift;
    start[c] = im.restControls[c] + Vec3(row(0), row(1), row(2));
  }
  CageArapResult result = solveFrom(start, targets, progress);
  result.report.startedRigid = startRigid;
  return result;
}

CageArapResult CageArapEditor::solveFrom(std::span<const Vec3> startControlPoints,
                                         std::span<const Vec3> targets,
                                         const ProgressCallback& progress) {
  auto& im = *impl_;
  const std::string caller = "CageArapEditor::solveFrom";
  const Eigen::MatrixXd t = targetMatrix(targets, im.constrained.size(), caller);
  if (startControlPoints.size() != im.m) {
    throw InvalidInput(caller + ": " + std::to_string(startControlPoints.size()) +
                       " control points for " + std::to_string(im.m));
  }
  for (std::size_t c = 0; c < im.m; ++c)
    if (!isFinite(startControlPoints[c])) {
      throw InvalidInput(caller + ": control point " + std::to_string(c) + " is not finite");
    }
  // In the frame of the handles' mean displacement c (when a common translation of the controls
  // translates the model): ΔP' = ΔP − c and t' = t − c give the same energies, without the
  // large terms of a far translation that the expanded energy would cancel (and whose rounding
  // would set its floor).
  const Eigen::RowVector3d shift = im.frameShift(t);
  const Eigen::MatrixXd shifted = t.rowwise() - shift;
  Eigen::MatrixXd dp = detail::toMatrix(startControlPoints) - detail::toMatrix(im.restControls);
  dp.rowwise() -= shift;
  CageArapResult result;
  CageArapReport& report = result.report;
  ProgressTracker tracker(progress, "cage-arap",
                          static_cast<std::size_t>(im.options.maxIterations));
  detail::LocalGlobalOptions o;
  o.maxIterations = im.options.maxIterations;
  o.relativeTolerance = im.options.relativeTolerance;
  o.accelerationWindow = im.options.accelerationWindow;
  // Rounding level of the expanded energy: a few ulps of its largest terms.
  o.floor = 1e-13 * (2.0 * im.restSquared + im.lambda * (im.handleRest - shifted).squaredNorm());
  std::vector<Mat3> keep;
  detail::LocalGlobalReport r = detail::minimiseLocalGlobal(
      dp, im.localStep(dp, shifted), o, tracker,
      [&](const Eigen::MatrixXd& x) { return im.localStep(x, shifted); },
      [&](const Eigen::MatrixXd& x) { return im.globalStep(shifted, x); },
      [&] { keep = im.rotations; }, [&] { im.rotations = keep; },
      [](Eigen::MatrixXd& x) { return x.reshaped(); });
  report.energies = std::move(r.energies);
  report.iterations = r.iterations;
  report.converged = r.converged;
  Eigen::MatrixXd x = detail::toMatrix(im.restModel) + im.weights * dp;
  x.rowwise() += shift;
  dp.rowwise() += shift;
  result.positions.resize(im.restModel.size());
  for (std::size_t v = 0; v < result.positions.size(); ++v) {
    const auto r = static_cast<Eigen::Index>(v);
    result.positions[v] = Vec3(x(r, 0), x(r, 1), x(r, 2));
  }
  result.controlPoints.resize(im.m);
  for (std::size_t c = 0; c < im.m; ++c) {
    const auto r = static_cast<Eigen::Index>(c);
    result.controlPoints[c] = im.restControls[c] + Vec3(dp(r, 0), dp(r, 1), dp(r, 2));
  }
  const double reach = im.options.reachTolerance * im.diagonal;
  for (std::size_t k = 0; k < im.constrained.size(); ++k) {
    const double d = glm::length(result.positions[im.constrained[k]] - targets[k]);
    report.handleResiduals.push_back(d);
    report.maxResidual = std::max(report.maxResidual, d);
    if (d > reach) report.unreached.push_back(im.constrained[k]);
  }
  return result;
}

}  // namespace spacewarp
