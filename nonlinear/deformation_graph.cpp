#include <spacewarp/nonlinear/deformation_graph.h>

// The public face of the deformation graph: the graph's construction and accessors and its
// Warp view. The work lives in nonlinear/detail/: node sampling (node_sampling.h), the node
// index with its weights and topology (graph_index.h), the solve's problem (graph_problem.h)
// and normal equations (solver_cache.h). The Levenberg-Marquardt loop is solve() below.

#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>
#include <string>
#include <utility>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <Eigen/LU>
#include <Eigen/SVD>

#include <spacewarp/core/errors.h>
#include <spacewarp/nonlinear/detail/graph_index.h>
#include <spacewarp/nonlinear/detail/graph_problem.h>
#include <spacewarp/nonlinear/detail/node_sampling.h>
#include <spacewarp/nonlinear/detail/solver_cache.h>

namespace spacewarp {

namespace {

using detail::describePoint;
using detail::GraphIndex;
using detail::kMaxCoordinate;
using detail::requireFinite;
using detail::requireK;
using detail::Scratch;
using detail::throwOutOfReach;
using detail::warpPoint;
using detail::weightsOf;

// The rigid motion x -> r x + shift that best maps the handles onto their targets in the
// least-squares sense (Kabsch: the rotation from the SVD of the cross-covariance, a reflection
// turned into a rotation). The identity for no handles; for collinear handles r is one of the
// rotations that fit equally well.
struct RigidFit {
  Mat3 r{1.0};
  Vec3 shift{0.0};
};

RigidFit rigidFit(std::span<const Vec3> handles, std::span<const Vec3> targets) {
  RigidFit fit;
  if (handles.empty()) return fit;
  Vec3 ch(0.0), ct(0.0);
  for (std::size_t l = 0; l < handles.size(); ++l) {
    ch += handles[l];
    ct += targets[l];
  }
  ch /= double(handles.size());
  ct /= double(handles.size());
  Eigen::Matrix3d h = Eigen::Matrix3d::Zero();
  for (std::size_t l = 0; l < handles.size(); ++l)
    h += toEigen(handles[l] - ch) * toEigen(targets[l] - ct).transpose();
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(h, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d d = Eigen::Matrix3d::Identity();
  d(2, 2) = (svd.matrixV() * svd.matrixU().transpose()).determinant() < 0.0 ? -1.0 : 1.0;
  fit.r = toMat3(svd.matrixV() * d * svd.matrixU().transpose());
  fit.shift = ct - fit.r * ch;
  return fit;
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

}  // namespace

// ---------------------------------------------------------------------------------------------

DeformationGraphWarp::DeformationGraphWarp(std::shared_ptr<const detail::GraphIndex> index,
                                           std::vector<Mat3> a, std::vector<Vec3> t)
    : index_(std::move(index)), a_(std::move(a)), t_(std::move(t)) {
  for (Mat3& m : a_) m -= Mat3(1.0);  // stored as B = A − I
}

Vec3 DeformationGraphWarp::apply(const Vec3& x) const {
  Scratch s(index_->k);
  try {
    return warpPoint(*index_, a_.data(), t_.data(), x, s);
  } catch (const detail::PointOutOfReach&) {
    throwOutOfReach("the point " + describePoint(x));
  }
}

Mat3 DeformationGraphWarp::jacobian(const Vec3& x) const {
  const GraphIndex& g = *index_;
  const int k = g.k;
  Scratch s(k);
  std::uint32_t* idx = s.idx();
  double* d2 = s.d2();
  try {
    g.nearest(x, idx, d2);
  } catch (const detail::PointOutOfReach&) {
    throwOutOfReach("the point " + describePoint(x));
  }
  // Unnormalised weights u_i = (1 − d_i / d_max)² and their gradients.
  const double dMax = std::sqrt(d2[k]);
  if (!(dMax > 0.0)) return Warp::jacobian(x);  // k + 1 coincident nodes: no analytic form
  const Vec3 gradDMax = (x - g.nodes[idx[k]]) / dMax;
  std::vector<double> u(std::size_t(k), 0.0);
  std::vector<Vec3> gradU(std::size_t(k), Vec3(0.0));
  double sum = 0.0;
  Vec3 gradSum(0.0);
  for (int i = 0; i < k; ++i) {
    const double d = std::sqrt(d2[i]);
    const double sI = 1.0 - d / dMax;
    u[i] = sI * sI;
    // d(d / d_max) = ∇d / d_max − d ∇d_max / d_max²; ∇d = (x − g) / d (zero at the node).
    const Vec3 gradD = d > 0.0 ? (x - g.nodes[idx[i]]) / d : Vec3(0.0);
    gradU[i] = -2.0 * sI * (gradD / dMax - d * gradDMax / (dMax * dMax));
    sum += u[i];
    gradSum += gradU[i];
  }
  if (!(sum > 0.0)) return Warp::jacobian(x);
  Mat3 j(1.0);
  for (int i = 0; i < k; ++i) {
    const std::uint32_t n = idx[i];
    const double w = u[i] / sum;
    const Vec3 gradW = (gradU[i] - w * gradSum) / sum;
    const Vec3 q = a_[n] * (x - g.nodes[n]) + t_[n];
    j += w * a_[n] + glm::outerProduct(q, gradW);
  }
  return j;
}

void DeformationGraphWarp::applyBatch(std::span<const Vec3> in, std::span<Vec3> out) const {
  if (in.size() != out.size()) {
    throw InvalidInput("DeformationGraphWarp::applyBatch: input has " + std::to_string(in.size()) +
                       " points but output has " + std::to_string(out.size()));
  }
  const GraphIndex* g = index_.get();
  const Mat3* b = a_.data();
  const Vec3* t = t_.data();
  const Vec3* src = in.data();
  Vec3* dst = out.data();
  // The lowest point out of reach, whatever the thread count (each range stops at its first).
  std::atomic<std::size_t> firstOutOfReach{in.size()};
  tbb::parallel_for(
      tbb::blocked_range<std::size_t>(0, in.size(), 2048),
      [g, b, t, src, dst, &firstOutOfReach](const tbb::blocked_range<std::size_t>& r) {
        Scratch s(g->k);
        std::size_t i = r.begin();
        try {
          for (; i != r.end(); ++i) dst[i] = warpPoint(*g, b, t, src[i], s);
        } catch (const detail::PointOutOfReach&) {
          std::size_t seen = firstOutOfReach.load();
          while (i < seen && !firstOutOfReach.compare_exchange_weak(seen, i)) {
          }
        }
      });
  const std::size_t bad = firstOutOfReach.load();
  if (bad < in.size())
    throwOutOfReach("point " + std::to_string(bad) + " " + describePoint(in[bad]));
}

// ---------------------------------------------------------------------------------------------

DeformationGraph::DeformationGraph(std::span<const Vec3> positions,
                                   const DeformationGraphOptions& options) {
  if (positions.empty()) throw InvalidInput("DeformationGraph: no positions to sample nodes from");
  if (!(options.spacing > 0.0) || !(options.spacing <= kMaxCoordinate)) {
    throw InvalidInput("DeformationGraph: spacing = " + std::to_string(options.spacing) +
                       " must be > 0 and at most 1e150");
  }
  if (options.k < 1)
    throw InvalidInput("DeformationGraph: k = " + std::to_string(options.k) + " must be >= 1");
  requireFinite("positions", positions);
  std::vector<Vec3> nodes = options.sampling == NodeSampling::PoissonDisk
                                ? detail::sampleNodesPoissonDisk(positions, options.spacing)
                                : detail::sampleNodesVoxel(positions, options.spacing);
  requireK(options.k, nodes.size());
  auto index = std::make_shared<detail::GraphIndex>(std::move(nodes), options.k);
  detail::buildTopology(*index, positions);
  index_ = std::move(index);
  reset();
}

DeformationGraph::DeformationGraph(std::span<const Vec3> nodes, std::span<const Vec3> positions,
                                   const DeformationGraphOptions& options) {
  if (nodes.empty()) throw InvalidInput("DeformationGraph: no nodes");
  requireFinite("nodes", nodes);
  requireFinite("positions", positions);
  requireK(options.k, nodes.size());
  auto index = std::make_shared<detail::GraphIndex>(std::vector<Vec3>(nodes.begin(), nodes.end()),
                                                    options.k);
  detail::buildTopology(*index, positions.empty() ? nodes : positions);
  index_ = std::move(index);
  reset();
}

DeformationGraph::~DeformationGraph() = default;
DeformationGraph::DeformationGraph(DeformationGraph&&) noexcept = default;
DeformationGraph& DeformationGraph::operator=(DeformationGraph&&) noexcept = default;

std::size_t DeformationGraph::nodeCount() const { return index_->nodes.size(); }
std::span<const Vec3> DeformationGraph::nodes() const { return index_->nodes; }
int DeformationGraph::k() const { return index_->k; }
const std::vector<std::pair<std::uint32_t, std::uint32_t>>& DeformationGraph::edges() const {
  return index_->edges;
}

NodeWeights DeformationGraph::weights(const Vec3& x) const {
  if (!isFinite(x)) throw InvalidInput("DeformationGraph::weights: the point is not finite");
  const int k = index_->k;
  Scratch s(k);
  try {
    index_->nearest(x, s.idx(), s.d2());
  } catch (const detail::PointOutOfReach&) {
    throwOutOfReach("the point " + describePoint(x));
  }
  weightsOf(k, s.d2(), s.w());
  NodeWeights out;
  out.nodes.assign(s.idx(), s.idx() + k);
  out.weights.assign(s.w(), s.w() + k);
  return out;
}

void DeformationGraph::reset() {
  a_.assign(index_->nodes.size(), Mat3(1.0));
  t_.assign(index_->nodes.size(), Vec3(0.0));
}

DeformationGraphWarp DeformationGraph::warp() const { return {index_, a_, t_}; }

DeformationGraphReport DeformationGraph::solve(std::span<const Vec3> handles,
                                               std::span<const Vec3> targets,
                                               const DeformationGraphSolveOptions& options) {
  const GraphIndex& g = *index_;
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

  const int k = g.k;
  const std::size_t m = g.nodes.size();
  detail::Problem p{g,
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
                    {}};
  const double unit = g.unit;
  p.nodes.resize(m);
  for (std::size_t j = 0; j < m; ++j) p.nodes[j] = g.nodes[j] / unit;
  p.handles.resize(handles.size());
  p.targets.resize(targets.size());
  for (std::size_t l = 0; l < handles.size(); ++l) {
    p.handles[l] = handles[l] / unit;
    p.targets[l] = targets[l] / unit;
  }
  p.hNodes.resize(handles.size() * k);
  p.hWeights.resize(handles.size() * k);
  std::vector<char> reached(std::size_t(g.componentCount), 0);
  {
    Scratch s(k);
    for (std::size_t l = 0; l < handles.size(); ++l) {
      g.nearest(handles[l], s.idx(), s.d2());
      weightsOf(k, s.d2(), s.w());
      for (int i = 0; i < k; ++i) {
        p.hNodes[l * k + i] = s.idx()[i];
        p.hWeights[l * k + i] = s.w()[i];
        reached[g.component[s.idx()[i]]] = 1;
      }
    }
  }

  DeformationGraphReport report;
  report.componentCount = g.componentCount;
  for (int c = 0; c < g.componentCount; ++c) report.unconstrainedComponents += reached[c] ? 0 : 1;
  p.var.assign(m, -1);
  for (std::uint32_t j = 0; j < m; ++j) {
    if (reached[g.component[j]]) {
      p.var[j] = p.unknowns;
      p.unknowns += 12;
      p.freeNodes.push_back(j);
    } else {
      report.unconstrainedNodes.push_back(j);
      a_[j] = Mat3(1.0);  // pinned: rigidly in place
      t_[j] = Vec3(0.0);
    }
  }
  for (std::uint32_t j : p.freeNodes) {
    for (std::uint32_t e = g.adjacencyOffsets[j]; e < g.adjacencyOffsets[j + 1]; ++e)
      p.regEdges.emplace_back(j, g.adjacency[e]);
  }
  // The maps are solved with translations in units of g.unit; an exception leaves the graph
  // as it was.
  struct Restore {
    DeformationGraph& graph;
    std::vector<Mat3> a;
    std::vector<Vec3> t;
    bool done = false;
    ~Restore() {
      if (done) return;
      graph.a_.swap(a);
      graph.t_.swap(t);
    }
  } restore{*this, a_, t_};
  for (std::uint32_t j : p.freeNodes) t_[j] /= unit;

  const int n = p.unknowns;
  Eigen::VectorXd rhs(n);
  double eRot = 0.0, eReg = 0.0, eCon = 0.0;
  const auto energyOf = [&](const std::vector<Mat3>& a, const std::vector<Vec3>& t,
                            double* gradient) {
    p.evaluate(a, t, eRot, eReg, eCon, gradient);
    return options.rotationWeight * eRot + options.regularizationWeight * eReg +
           options.constraintWeight * eCon;
  };
  double energy = energyOf(a_, t_, nullptr);
  // Start from the best rigid fit of the handles to the targets when it beats the current
  // maps. Gauss-Newton then runs in the fit's frame (targets mapped back by its inverse, the
  // fit itself being the identity there): every term is invariant under a rigid change of
  // frame, so any rigid motion of the handles is met at iteration 0, and the start is the rest
  // state, whose kept factor serves while only the targets move.
  const RigidFit fit = rigidFit(handles, targets);
  const Mat3 rt = glm::transpose(fit.r);
  if (n > 0) {
    for (std::size_t l = 0; l < handles.size(); ++l)
      p.targets[l] = rt * (targets[l] - fit.shift) / unit;
    std::vector<Mat3> a0(a_);
    std::vector<Vec3> t0(t_);
    for (std::uint32_t j : p.freeNodes) {
      a0[j] = Mat3(1.0);
      t0[j] = Vec3(0.0);
    }
    const double rigid = energyOf(a0, t0, nullptr);
    if (rigid < energy) {
      a_.swap(a0);
      t_.swap(t0);
      energy = rigid;
      report.rigidStart = true;
    } else {
      for (std::size_t l = 0; l < targets.size(); ++l) p.targets[l] = targets[l] / unit;
    }
  }
  if (!std::isfinite(energy)) {
    // eRot, eReg, eCon are those of the start evaluated last (the rigid fit, if any).
    const char* term = !std::isfinite(options.constraintWeight * eCon)       ? "constraint"
                       : !std::isfinite(options.regularizationWeight * eReg) ? "regulariser"
                                                                             : "rotation";
    throw SolverError(std::string("DeformationGraph::solve: the energy overflows (its ") + term +
                      " term is not finite): the targets are too far from the handles, or the "
                      "weights too large, for double precision");
  }
  report.energies.push_back(energy);
  const auto finish = [&] {
    // The terms are invariant under the fit's rigid change of frame: evaluated in it.
    energyOf(a_, t_, nullptr);
    report.rotationEnergy = eRot;
    report.regularizationEnergy = eReg;
    report.constraintEnergy = eCon;
    for (std::uint32_t j : p.freeNodes) {  // back to world units (and frame)
      t_[j] *= unit;
      if (report.rigidStart) {
        t_[j] = fit.r * (g.nodes[j] + t_[j]) + fit.shift - g.nodes[j];
        a_[j] = fit.r * a_[j];
      }
    }
    restore.done = true;
    return report;
  };
  // Rounding level: the energy with every residual 1e-10 of its term's scale (the handles'
  // spread, the edges' lengths, a unit rotation residual). Nothing is left to solve below it.
  double scale = options.rotationWeight * 6.0 * double(p.freeNodes.size());
  for (const auto& [j, kk] : p.regEdges) {
    const Vec3 d = p.nodes[kk] - p.nodes[j];
    scale += options.regularizationWeight * glm::dot(d, d);
  }
  Vec3 centre(0.0);
  for (const Vec3& h : p.handles) centre += h / double(handles.size());
  for (const Vec3& h : p.handles)
    scale += options.constraintWeight * glm::dot(h - centre, h - centre);
  // Residuals are computed from coordinates of magnitude up to `reach`, so each carries a
  // rounding error of a few ulps of it: far from the origin that, not the scene's size, is
  // the floor (a rigid motion 1e7 away would otherwise iterate on rounding noise).
  double reach = 0.0;
  for (const auto* points : {&p.handles, &p.targets})
    for (const Vec3& x : *points)
      reach = std::max({reach, std::abs(x.x), std::abs(x.y), std::abs(x.z)});
  for (std::uint32_t j : p.freeNodes) {
    const Vec3& x = p.nodes[j];
    reach = std::max({reach, std::abs(x.x), std::abs(x.y), std::abs(x.z)});
  }
  const double ulps = 16.0 * std::numeric_limits<double>::epsilon() * reach;
  const double negligible =
      1e-20 * scale + 3.0 * ulps * ulps *
                          (options.constraintWeight * double(handles.size()) +
                           options.regularizationWeight * double(p.regEdges.size()));
  if (n == 0 || energy <= negligible) {
    report.converged = true;
    return finish();
  }

  // CHOLMOD's supernodal Cholesky (dense BLAS kernels on the supernodes): the fill of a 3D
  // graph makes the factor several times denser than JᵀJ, where a simplicial factorisation
  // crawls. JᵀJ is written straight into a fixed pattern kept in cache_ with its constant part
  // and symbolic analysis (see detail::SolverCache); per iteration only the nodes' diagonal
  // blocks are rewritten. The BLAS runs single-threaded (inside detail::SparseCholesky) so that
  // the result does not depend on its thread count.
  if (!cache_) cache_ = std::make_unique<detail::SolverCache>();
  detail::SolverCache& cache = *cache_;
  if (!cache.matches(p)) cache.build(p);
  const auto solveWith = [&](const Eigen::VectorXd& b, Eigen::VectorXd& x) {
    x = cache.cholesky.solve(b);
  };
  // The factor of an earlier iteration's matrix preconditions conjugate gradients on the
  // current one: only the rotation blocks and the damping change between iterations, so a few
  // iterations usually reach the direct solve's accuracy at a fraction of a factorisation.
  // When they do not, the current matrix is factorised. Only a factor computed (or found
  // current) during this solve is used, so the result never depends on earlier solves.
  bool factored = false;
  Eigen::VectorXd cgR, cgZ, cgD, cgAd;
  const auto refine = [&](const Eigen::VectorXd& b, Eigen::VectorXd& x) {
    constexpr int kMaxCgIterations = 25;
    // Relative residual: an inexact Gauss-Newton step, which the energy test below still
    // guards. On the 1,000-node benchmark 1e-4 needs 3 iterations per step where 1e-10 needs
    // 7, changes the final energy by 2e-13 (relative) and no iteration count.
    constexpr double kCgTolerance = 1e-4;
    x.setZero(b.size());
    const double bNorm = b.norm();
    if (!(bNorm > 0.0)) return std::isfinite(bNorm);
    cgR = b;
    solveWith(cgR, cgZ);
    cgD = cgZ;
    double rz = cgR.dot(cgZ);
    for (int i = 0; i < kMaxCgIterations; ++i) {
      symmetricProduct(cache.lower, cgD, cgAd);
      const double dad = cgD.dot(cgAd);
      if (!(dad > 0.0) || !(rz > 0.0)) return false;
      const double alpha = rz / dad;
      x += alpha * cgD;
      cgR -= alpha * cgAd;
      if (cgR.norm() <= kCgTolerance * bNorm) return true;
      solveWith(cgR, cgZ);
      const double rzNext = cgR.dot(cgZ);
      cgD = cgZ + (rzNext / rz) * cgD;
      rz = rzNext;
    }
    return false;
  };
  double lambda = -1.0;  // Levenberg-Marquardt damping, relative to the mean diagonal
  std::vector<Mat3> a2(a_);
  std::vector<Vec3> t2(t_);
  Eigen::VectorXd diag, delta;
  constexpr double kMaxLambda = 1e12;
  bool anyFactor = false;

  for (int iter = 0; iter < options.maxIterations; ++iter) {
    energyOf(a_, t_, rhs.data());  // −Jᵀf at the current state
    cache.assemble(p, a_, diag);
    const double meanDiag = std::max(diag.mean(), 1e-300);
    if (lambda < 0.0) lambda = 1e-9;
    bool accepted = false;
    double next = energy;
    while (lambda <= kMaxLambda) {
      cache.damp(diag, lambda * meanDiag);
      if (cache.factorIsCurrent()) {
        factored = true;
        solveWith(rhs, delta);
      } else if (!(factored && refine(rhs, delta))) {
        if (!cache.factorize()) {
          factored = false;
          lambda *= 10.0;
          continue;
        }
        factored = true;
        solveWith(rhs, delta);
      }
      anyFactor = true;
      for (std::uint32_t j : p.freeNodes) {
        const int v = p.var[j];
        for (int c = 0; c < 3; ++c)
          for (int r = 0; r < 3; ++r) a2[j][c][r] = a_[j][c][r] + delta[v + 3 * c + r];
        for (int r = 0; r < 3; ++r) t2[j][r] = t_[j][r] + delta[v + 9 + r];
      }
      next = energyOf(a2, t2, nullptr);
      if (next < energy) {  // strictly: an unchanged energy is no progress (and not NaN)
        accepted = true;
        break;
      }
      lambda *= 10.0;
    }
    if (!accepted) {
      if (!anyFactor)
        throw SolverError("DeformationGraph::solve: the normal equations are singular");
      // No step lowers the energy: a (numerical) minimum.
      report.converged = true;
      break;
    }
    a_.swap(a2);
    t_.swap(t2);
    a2 = a_;
    t2 = t_;
    const double previous = energy;
    energy = next;
    report.energies.push_back(energy);
    report.iterations = iter + 1;
    lambda = std::max(lambda / 10.0, 1e-12);
    // A relative decrease of a few ulps is rounding in the energy's sum, not progress.
    constexpr double kRoundingDecrease = 64.0 * std::numeric_limits<double>::epsilon();
    if (previous - energy <= std::max(options.tolerance, kRoundingDecrease) * previous ||
        energy <= negligible) {
      report.converged = true;
      break;
    }
  }
  return finish();
}

}  // namespace spacewarp
