#include <spacewarp/nonlinear/detail/graph_solver.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <utility>

#include <Eigen/LU>
#include <Eigen/SVD>

#include <spacewarp/core/detail/rotation.h>
#include <spacewarp/core/errors.h>
#include <spacewarp/core/progress.h>
#include <spacewarp/nonlinear/detail/graph_problem.h>

namespace spacewarp::detail {

void validateSolve(std::span<const Vec3> handles, std::span<const Vec3> targets,
                   const DeformationGraphSolveOptions& options) {
  if (handles.size() != targets.size()) {
    throw InvalidInput("DeformationGraph::solve: " + std::to_string(handles.size()) +
                       " handles but " + std::to_string(targets.size()) + " targets");
  }
  requireFinite("handles", handles);
  requireFinite("targets", targets, false);  // overflow: see the energy check
  const auto requireWeight = [](const char* name, double w) {
    if (!(w >= 0.0) || !std::isfinite(w)) {
      throw InvalidInput(std::string("DeformationGraph::solve: ") + name + " = " +
                         std::to_string(w) + " must be finite and >= 0");
    }
  };
  requireWeight("rotationWeight", options.rotationWeight);
  requireWeight("regularizationWeight", options.regularizationWeight);
  requireWeight("constraintWeight", options.constraintWeight);
  if (options.maxIterations < 0) {
    throw InvalidInput("DeformationGraph::solve: maxIterations = " +
                       std::to_string(options.maxIterations) + " must be >= 0");
  }
  if (!(options.tolerance >= 0.0) || !std::isfinite(options.tolerance)) {
    throw InvalidInput("DeformationGraph::solve: tolerance must be finite and >= 0");
  }
}

namespace {

// Rounding level: the energy with every residual 1e-10 of its term's scale (the handles'
// spread, the edges' lengths, a unit rotation residual). Nothing is left to solve below it.
// Residuals are computed from coordinates of magnitude up to `reach`, so each carries a
// rounding error of a few ulps of it: far from the origin that, not the scene's size, is the
// floor (a rigid motion 1e7 away would otherwise iterate on rounding noise).
double roundingLevel(const Problem& p, const DeformationGraphSolveOptions& options) {
  const std::size_t handleCount = p.handles.size();
  double scale = options.rotationWeight * 6.0 * double(p.freeNodes.size());
  for (const auto& [j, kk] : p.regEdges) {
    const Vec3 d = p.nodes[kk] - p.nodes[j];
    scale += options.regularizationWeight * glm::dot(d, d);
  }
  Vec3 center(0.0);
  for (const Vec3& h : p.handles) center += h / double(handleCount);
  for (const Vec3& h : p.handles)
    scale += options.constraintWeight * glm::dot(h - center, h - center);
  double reach = 0.0;
  for (const auto* points : {&p.handles, &p.targets})
    for (const Vec3& x : *points)
      reach = std::max({reach, std::abs(x.x), std::abs(x.y), std::abs(x.z)});
  for (std::uint32_t j : p.freeNodes) {
    const Vec3& x = p.nodes[j];
    reach = std::max({reach, std::abs(x.x), std::abs(x.y), std::abs(x.z)});
  }
  const double ulps = 16.0 * std::numeric_limits<double>::epsilon() * reach;
  return 1e-20 * scale + 3.0 * ulps * ulps *
                             (options.constraintWeight * double(handleCount) +
                              options.regularizationWeight * double(p.regEdges.size()));
}

// y = A x for the symmetric A whose lower triangle (diagonal included) `lower` holds. Serial.
void symmetricProduct(const Eigen::SparseMatrix<double>& lower, const Eigen::VectorXd& x,
                      Eigen::VectorXd& y) {
  y.setZero(x.size());
  const int* outer = lower.outerIndexPtr();
  const int* inner = lower.innerIndexPtr();
  const double* value = lower.valuePtr();
  for (Eigen::Index c = 0; c < lower.outerSize(); ++c) {
    const double xc = x[c];
    double yc = 0.0;
    for (int s = outer[c]; s < outer[c + 1]; ++s) {
      const int r = inner[s];
      if (r == c) {
        yc += value[s] * xc;
      } else {
        y[r] += value[s] * xc;
        yc += value[s] * x[r];
      }
    }
    y[c] += yc;
  }
}

// The linear solves of one solve() call. The factor of an earlier iteration's matrix
// preconditions conjugate gradients on the current one: only the rotation blocks and the
// damping change between iterations, so a few iterations usually reach the direct solve's
// accuracy at a fraction of a factorisation. When they do not, the current matrix is
// factorised. Only a factor computed (or found current) during this call is used, so the
// result never depends on earlier solves.
class StepSolver {
 public:
  explicit StepSolver(SolverCache& cache) : cache_(cache) {}

  // δ for the damped matrix now in cache.lower; false if it is not positive definite.
  bool solve(const Eigen::VectorXd& rhs, Eigen::VectorXd& delta) {
    if (cache_.factorIsCurrent()) {
      factored_ = true;
      delta = cache_.cholesky.solve(rhs);
    } else if (!(factored_ && refine(rhs, delta))) {
      if (!cache_.factorize()) {
        factored_ = false;
        return false;
      }
      factored_ = true;
      delta = cache_.cholesky.solve(rhs);
    }
    return true;
  }

 private:
  // Preconditioned conjugate gradients from x = 0; false if they do not converge.
  bool refine(const Eigen::VectorXd& b, Eigen::VectorXd& x) {
    constexpr int kMaxCgIterations = 25;
    // Relative residual: an inexact Gauss-Newton step, which the energy test still guards. On
    // the 1,000-node benchmark 1e-4 needs 3 iterations per step where 1e-10 needs 7, changes
    // the final energy by 2e-13 (relative) and no iteration count.
    constexpr double kCgTolerance = 1e-4;
    x.setZero(b.size());
    const double bNorm = b.norm();
    if (!(bNorm > 0.0)) return std::isfinite(bNorm);
    r_ = b;
    z_ = cache_.cholesky.solve(r_);
    d_ = z_;
    double rz = r_.dot(z_);
    for (int i = 0; i < kMaxCgIterations; ++i) {
      symmetricProduct(cache_.lower, d_, ad_);
      const double dad = d_.dot(ad_);
      if (!(dad > 0.0) || !(rz > 0.0)) return false;
      const double alpha = rz / dad;
      x += alpha * d_;
      r_ -= alpha * ad_;
      if (r_.norm() <= kCgTolerance * bNorm) return true;
      z_ = cache_.cholesky.solve(r_);
      const double rzNext = r_.dot(z_);
      d_ = z_ + (rzNext / rz) * d_;
      rz = rzNext;
    }
    return false;
  }

  SolverCache& cache_;
  bool factored_ = false;
  Eigen::VectorXd r_, z_, d_, ad_;  // conjugate gradients' residual, preconditioned, direction
};

// Puts the maps back unless dismissed: an exception leaves them as they were.
struct RestoreOnThrow {
  std::vector<Mat3>& a;
  std::vector<Vec3>& t;
  std::vector<Mat3> savedA;
  std::vector<Vec3> savedT;
  bool dismissed = false;
  ~RestoreOnThrow() {
    if (dismissed) return;
    a.swap(savedA);
    t.swap(savedT);
  }
};

// One solve() call: its stages share the problem, the maps (a, t) and the report.
class GraphSolve {
 public:
  GraphSolve(const GraphIndex& g, const DeformationGraphSolveOptions& options, std::vector<Mat3>& a,
             std::vector<Vec3>& t)
      : g_(g),
        options_(options),
        a_(a),
        t_(t),
        p_{g,
           {},
           {},
           0,
           std::sqrt(options.rotationWeight),
           std::sqrt(options.regularizationWeight),
           std::sqrt(options.constraintWeight),
           {},
           {},
           {},
           {},
           {},
           {}} {}

  DeformationGraphReport run(std::span<const Vec3> handles, std::span<const Vec3> targets,
                             std::unique_ptr<SolverCache>& cache);

 private:
  std::vector<char> setUp(std::span<const Vec3> handles, std::span<const Vec3> targets);
  void chooseUnknowns(const std::vector<char>& reached);
  void startRigidly(std::span<const Vec3> handles, std::span<const Vec3> targets);
  void requireFiniteEnergy() const;
  void iterate(SolverCache& cache);
  bool dampedStep(SolverCache& cache, StepSolver& solver, const Eigen::VectorXd& rhs,
                  const Eigen::VectorXd& diag, double& next);
  void finish();

  // The weighted energy at (a, t); the unweighted terms go to eRot_, eReg_, eCon_, and −Jᵀf
  // to `gradient` if given.
  double energyOf(const std::vector<Mat3>& a, const std::vector<Vec3>& t, double* gradient) {
    p_.evaluate(a, t, eRot_, eReg_, eCon_, gradient);
    return options_.rotationWeight * eRot_ + options_.regularizationWeight * eReg_ +
           options_.constraintWeight * eCon_;
  }

  const GraphIndex& g_;
  const DeformationGraphSolveOptions& options_;
  std::vector<Mat3>& a_;
  std::vector<Vec3>& t_;
  Problem p_;
  DeformationGraphReport report_;
  RigidFit fit_;
  double energy_ = 0.0;
  double eRot_ = 0.0, eReg_ = 0.0, eCon_ = 0.0;
  double negligible_ = 0.0;  // roundingLevel()
  // Levenberg-Marquardt state: the damping (relative to the mean diagonal; < 0 before the
  // first iteration), whether any damped matrix was factorised, the trial step and maps.
  double lambda_ = -1.0;
  bool anyFactor_ = false;
  Eigen::VectorXd delta_;
  std::vector<Mat3> a2_;
  std::vector<Vec3> t2_;
};

DeformationGraphReport GraphSolve::run(std::span<const Vec3> handles, std::span<const Vec3> targets,
                                       std::unique_ptr<SolverCache>& cache) {
  chooseUnknowns(setUp(handles, targets));
  // The maps are solved with translations in units of g.unit; an exception leaves them as
  // they are now.
  RestoreOnThrow restore{a_, t_, a_, t_};
  for (std::uint32_t j : p_.freeNodes) t_[j] /= g_.unit;
  startRigidly(handles, targets);
  requireFiniteEnergy();
  report_.energies.push_back(energy_);
  negligible_ = roundingLevel(p_, options_);
  if (p_.unknowns == 0 || energy_ <= negligible_) {
    report_.converged = true;
  } else {
    // CHOLMOD's supernodal Cholesky (dense BLAS kernels on the supernodes): the fill of a 3D
    // graph makes the factor several times denser than JᵀJ, where a simplicial factorisation
    // crawls. JᵀJ is written straight into a fixed pattern kept in the cache with its constant
    // part and symbolic analysis; per iteration only the nodes' diagonal blocks are rewritten.
    if (!cache) cache = std::make_unique<SolverCache>();
    if (!cache->matches(p_)) cache->build(p_);
    iterate(*cache);
  }
  finish();
  restore.dismissed = true;
  return std::move(report_);
}

// Scales nodes, handles and targets to units of g.unit and binds each handle to its k nearest
// nodes. Returns, per component of the graph, whether a handle reaches it.
std::vector<char> GraphSolve::setUp(std::span<const Vec3> handles, std::span<const Vec3> targets) {
  const int k = g_.k;
  const std::size_t m = g_.nodes.size();
  const double unit = g_.unit;
  p_.nodes.resize(m);
  for (std::size_t j = 0; j < m; ++j) p_.nodes[j] = g_.nodes[j] / unit;
  p_.handles.resize(handles.size());
  p_.targets.resize(targets.size());
  for (std::size_t l = 0; l < handles.size(); ++l) {
    p_.handles[l] = handles[l] / unit;
    p_.targets[l] = targets[l] / unit;
  }
  p_.hNodes.resize(handles.size() * k);
  p_.hWeights.resize(handles.size() * k);
  std::vector<char> reached(std::size_t(g_.componentCount), 0);
  Scratch s(k);
  for (std::size_t l = 0; l < handles.size(); ++l) {
    g_.nearest(handles[l], s.idx(), s.d2());
    weightsOf(k, s.d2(), s.w());
    for (int i = 0; i < k; ++i) {
      p_.hNodes[l * k + i] = s.idx()[i];
      p_.hWeights[l * k + i] = s.w()[i];
      reached[g_.component[s.idx()[i]]] = 1;
    }
  }
  return reached;
}

// The nodes of reached components are free (12 unknowns each) and regularised along their
// edges; the others are pinned at rest and reported.
void GraphSolve::chooseUnknowns(const std::vector<char>& reached) {
  report_.componentCount = g_.componentCount;
  for (int c = 0; c < g_.componentCount; ++c) report_.unconstrainedComponents += reached[c] ? 0 : 1;
  const std::size_t m = g_.nodes.size();
  p_.var.assign(m, -1);
  for (std::uint32_t j = 0; j < m; ++j) {
    if (reached[g_.component[j]]) {
      p_.var[j] = p_.unknowns;
      p_.unknowns += 12;
      p_.freeNodes.push_back(j);
    } else {
      report_.unconstrainedNodes.push_back(j);
      a_[j] = Mat3(1.0);  // pinned: rigidly in place
      t_[j] = Vec3(0.0);
    }
  }
  for (std::uint32_t j : p_.freeNodes) {
    for (std::uint32_t e = g_.adjacencyOffsets[j]; e < g_.adjacencyOffsets[j + 1]; ++e)
      p_.regEdges.emplace_back(j, g_.adjacency[e]);
  }
}

// Starts from the best rigid fit of the handles to the targets when it beats the current
// maps. Gauss-Newton then runs in the fit's frame (targets mapped back by its inverse, the fit
// itself being the identity there): every term is invariant under a rigid change of frame, so
// any rigid motion of the handles is met at iteration 0, and the start is the rest state,
// whose kept factor serves while only the targets move.
void GraphSolve::startRigidly(std::span<const Vec3> handles, std::span<const Vec3> targets) {
  const double unit = g_.unit;
  energy_ = energyOf(a_, t_, nullptr);
  fit_ = rigidFit(handles, targets);
  if (p_.unknowns == 0) return;
  const Mat3 rt = glm::transpose(fit_.r);
  for (std::size_t l = 0; l < handles.size(); ++l)
    p_.targets[l] = rt * (targets[l] - fit_.shift) / unit;
  std::vector<Mat3> a0(a_);
  std::vector<Vec3> t0(t_);
  for (std::uint32_t j : p_.freeNodes) {
    a0[j] = Mat3(1.0);
    t0[j] = Vec3(0.0);
  }
  const double rigid = energyOf(a0, t0, nullptr);
  if (rigid < energy_) {
    a_.swap(a0);
    t_.swap(t0);
    energy_ = rigid;
    report_.rigidStart = true;
  } else {
    for (std::size_t l = 0; l < targets.size(); ++l) p_.targets[l] = targets[l] / unit;
  }
}

// eRot_, eReg_, eCon_ are those of the start evaluated last (the rigid fit, if any).
void GraphSolve::requireFiniteEnergy() const {
  if (std::isfinite(energy_)) return;
  const char* term = !std::isfinite(options_.constraintWeight * eCon_)       ? "constraint"
                     : !std::isfinite(options_.regularizationWeight * eReg_) ? "regulariser"
                                                                             : "rotation";
  throw SolverError(std::string("DeformationGraph::solve: the energy overflows (its ") + term +
                    " term is not finite): the targets are too far from the handles, or the "
                    "weights too large, for double precision");
}

// Levenberg-Marquardt: each iteration takes the first damped Gauss-Newton step that lowers the
// energy, then relaxes the damping; it stops at the tolerance, at rounding level, or when no
// step lowers the energy (a numerical minimum).
void GraphSolve::iterate(SolverCache& cache) {
  StepSolver solver(cache);
  Eigen::VectorXd rhs(p_.unknowns), diag;
  a2_ = a_;
  t2_ = t_;
  ProgressTracker tracker(options_.progress, "solve graph",
                          static_cast<std::size_t>(options_.maxIterations));
  for (int iter = 0; iter < options_.maxIterations; ++iter) {
    tracker.check();
    energyOf(a_, t_, rhs.data());  // −Jᵀf at the current state
    cache.assemble(p_, a_, diag);
    if (lambda_ < 0.0) lambda_ = 1e-9;
    double next = energy_;
    if (!dampedStep(cache, solver, rhs, diag, next)) {
      if (!anyFactor_)
        throw SolverError("DeformationGraph::solve: the normal equations are singular");
      // No step lowers the energy: a (numerical) minimum.
      report_.converged = true;
      break;
    }
    a_.swap(a2_);
    t_.swap(t2_);
    a2_ = a_;
    t2_ = t_;
    const double previous = energy_;
    energy_ = next;
    report_.energies.push_back(energy_);
    report_.iterations = iter + 1;
    tracker.advance();
    lambda_ = std::max(lambda_ / 10.0, 1e-12);
    // A relative decrease of a few ulps is rounding in the energy's sum, not progress.
    constexpr double kRoundingDecrease = 64.0 * std::numeric_limits<double>::epsilon();
    if (previous - energy_ <= std::max(options_.tolerance, kRoundingDecrease) * previous ||
        energy_ <= negligible_) {
      report_.converged = true;
      break;
    }
  }
  tracker.finish();
}

// Tries steps with a ten times larger damping each until one lowers the energy: true with the
// trial maps in a2_, t2_ and their energy in `next`; false once the damping exceeds 1e12.
bool GraphSolve::dampedStep(SolverCache& cache, StepSolver& solver, const Eigen::VectorXd& rhs,
                            const Eigen::VectorXd& diag, double& next) {
  constexpr double kMaxLambda = 1e12;
  const double meanDiag = std::max(diag.mean(), 1e-300);
  while (lambda_ <= kMaxLambda) {
    cache.damp(diag, lambda_ * meanDiag);
    if (!solver.solve(rhs, delta_)) {
      lambda_ *= 10.0;
      continue;
    }
    anyFactor_ = true;
    for (std::uint32_t j : p_.freeNodes) {
      const int v = p_.var[j];
      for (int c = 0; c < 3; ++c)
        for (int r = 0; r < 3; ++r) a2_[j][c][r] = a_[j][c][r] + delta_[v + 3 * c + r];
      for (int r = 0; r < 3; ++r) t2_[j][r] = t_[j][r] + delta_[v + 9 + r];
    }
    next = energyOf(a2_, t2_, nullptr);
    if (next < energy_) return true;  // strictly: an unchanged energy is no progress (nor NaN)
    lambda_ *= 10.0;
  }
  return false;
}

// The final terms, and the maps back to world units (and frame).
void GraphSolve::finish() {
  // The terms are invariant under the fit's rigid change of frame: evaluated in it.
  energyOf(a_, t_, nullptr);
  report_.rotationEnergy = eRot_;
  report_.regularizationEnergy = eReg_;
  report_.constraintEnergy = eCon_;
  for (std::uint32_t j : p_.freeNodes) {
    t_[j] *= g_.unit;
    if (report_.rigidStart) {
      t_[j] = fit_.r * (g_.nodes[j] + t_[j]) + fit_.shift - g_.nodes[j];
      a_[j] = fit_.r * a_[j];
    }
  }
}

}  // namespace

DeformationGraphReport solveGraph(const GraphIndex& g, std::span<const Vec3> handles,
                                  std::span<const Vec3> targets,
                                  const DeformationGraphSolveOptions& options, std::vector<Mat3>& a,
                                  std::vector<Vec3>& t, std::unique_ptr<SolverCache>& cache) {
  return GraphSolve(g, options, a, t).run(handles, targets, cache);
}

}  // namespace spacewarp::detail
