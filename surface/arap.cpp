#include <spacewarp/surface/arap.h>

#include <algorithm>
#include <cmath>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <spacewarp/core/detail/rotation.h>
#include <spacewarp/core/detail/sparse_cholesky.h>
#include <spacewarp/core/errors.h>
#include <spacewarp/core/geometry.h>
#include <spacewarp/surface/detail/arap_terms.h>
#include <spacewarp/surface/detail/edit_problem.h>
#include <spacewarp/surface/detail/local_global.h>

namespace spacewarp {

namespace {

// Ranges of this many vertices per task: fixed, so sums are formed in the same order whatever
// the thread count.
constexpr std::size_t kGrain = 256;

template <class Fn>
void forVertices(std::size_t n, Fn&& fn) {
  tbb::parallel_for(
      tbb::blocked_range<std::size_t>(0, n, kGrain),
      [&](const tbb::blocked_range<std::size_t>& r) {
        for (std::size_t i = r.begin(); i != r.end(); ++i) fn(i);
      },
      tbb::simple_partitioner());
}

}  // namespace

struct ArapEditor::Impl {
  detail::EditProblem problem;
  detail::ArapTerms terms;
  Eigen::SparseMatrix<double> freeFixed;  // A_fc of terms.system
  detail::SparseCholesky factor{{"ArapEditor", "check the mesh for degenerate parts"}};
  ArapOptions options;
  std::vector<Mat3> rotations;       // of the last local step
  std::vector<double> vertexEnergy;  // of the last local step
  // Scratch of the steps, per element: its covariance share Σ w d ē̅ᵀ and Σ w |d|² (d = x_a − x_b)
  // in the local step, its edges' w (Σ_owners R) ē in the global step.
  std::vector<Mat3> elementCovariance;
  std::vector<double> elementSquared;
  std::vector<std::array<Vec3, 3>> elementRhs;
  double restSquaredTotal = 0.0;  // Σ_i Σ_{T(i)} w |ē|²: the energy's scale

  // Optimal rotations of x (all n vertices) and the energy they give. The energy of vertex i is
  // Σ_{T(i)} w (|d|² + |ē|²) − 2 tr(R_iᵀ cov_i), from per-element sums (accurate to rounding of
  // the edge terms' size).
  double localStep(std::span<const Vec3> x) {
    const auto& t = terms;
    forVertices(t.elements.size(), [&](std::size_t e) {
      const detail::ArapElement& el = t.elements[e];
      Mat3 cov(0.0);
      double squared = 0.0;
      for (int k = 0; k < el.count; ++k) {
        const Vec3 wd = el.weight[k] * (x[el.a[k]] - x[el.b[k]]);
        cov += glm::outerProduct(wd, el.rest[k]);
        squared += glm::dot(wd, x[el.a[k]] - x[el.b[k]]);
      }
      elementCovariance[e] = cov;
      elementSquared[e] = squared;
    });
    forVertices(t.vertexCount(), [&](std::size_t i) {
      Mat3 cov(0.0);  // Σ w d ē̅ᵀ over T(i): tr(Rᵀ cov) = Σ w dᵀ R ē
      double squared = 0.0;
      for (std::size_t k = t.vertexOffsets[i]; k < t.vertexOffsets[i + 1]; ++k) {
        const std::uint32_t e = t.vertexElements[k];
        cov += elementCovariance[e];
        squared += elementSquared[e] + t.restSquared[e];
      }
      const Mat3 r = detail::closestRotationNear(cov, rotations[i]);
      rotations[i] = r;
      vertexEnergy[i] = squared - 2.0 * (glm::dot(r[0], cov[0]) + glm::dot(r[1], cov[1]) +
                                         glm::dot(r[2], cov[2]));
    });
    double total = 0.0;
    for (double e : vertexEnergy) total += e;
    return std::max(total, 0.0);  // non-negative; below 0 only by rounding
  }

  // The steps run relative to the rest box's centre, so that coordinates far from the origin
  // keep their digits through the global step (whose unknowns are then of the model's size).
  Vec3 origin{0.0};

  // The fixed vertices' positions relative to `origin`.
  Eigen::MatrixXd relativeFixed(std::span<const Vec3> targets, const std::string& caller) const {
    Eigen::MatrixXd fixed = problem.fixedPositions(targets, caller);
    fixed.rowwise() -= Eigen::RowVector3d(origin.x, origin.y, origin.z);
    return fixed;
  }

  // Positions minimising the energy for the current rotations, the fixed vertices at `fixed`.
  std::vector<Vec3> globalStep(const Eigen::MatrixXd& fixed) {
    const auto& p = problem;
    const auto& t = terms;
    forVertices(t.elements.size(), [&](std::size_t e) {
      const detail::ArapElement& el = t.elements[e];
      Mat3 sum = rotations[el.owner[0]];
      for (int o = 1; o < el.ownerCount; ++o) sum += rotations[el.owner[o]];
      for (int k = 0; k < el.count; ++k) elementRhs[e][k] = el.weight[k] * (sum * el.rest[k]);
    });
    Eigen::MatrixXd rhs(static_cast<Eigen::Index>(p.freeVertices.size()), 3);
    forVertices(p.freeVertices.size(), [&](std::size_t f) {
      const std::uint32_t v = p.freeVertices[f];
      Vec3 b(0.0);  // Σ over v's elements and their edges at v of ±w (Σ_owners R) ē
      for (std::size_t k = t.vertexOffsets[v]; k < t.vertexOffsets[v + 1]; ++k) {
        const auto& q = elementRhs[t.vertexElements[k]];
        const auto& sign = t.vertexEdgeSigns[k];
        b += double(sign[0]) * q[0] + double(sign[1]) * q[1] + double(sign[2]) * q[2];
      }
      rhs.row(static_cast<Eigen::Index>(f)) << b.x, b.y, b.z;
    });
    rhs -= freeFixed * fixed;
    return p.assemble(factor.solve(rhs), fixed);
  }
};

ArapEditor::ArapEditor(std::span<const Vec3> positions,
                       std::span<const std::array<std::uint32_t, 3>> triangles,
                       std::span<const std::uint32_t> constrained, const ArapOptions& options)
    : impl_(std::make_unique<Impl>()) {
  if (options.maxIterations < 0 || !(options.relativeTolerance >= 0.0) ||
      !std::isfinite(options.relativeTolerance) || options.accelerationWindow < 0) {
    throw InvalidInput(
        "ArapEditor: maxIterations and accelerationWindow must be >= 0, relativeTolerance finite "
        "and >= 0");
  }
  auto& im = *impl_;
  im.options = options;
  im.problem = detail::makeEditProblem(positions, triangles, constrained, "ArapEditor");
  const BoundingBox box = boundingBox(positions);
  im.origin = 0.5 * (box.min + box.max);
  im.terms = detail::makeArapTerms(options.energy, positions, triangles, im.problem.laplacian);
  im.freeFixed = im.problem.freeFixedBlock(im.terms.system);
  im.rotations.assign(positions.size(), Mat3(1.0));
  im.vertexEnergy.assign(positions.size(), 0.0);
  im.elementCovariance.resize(im.terms.elements.size());
  im.elementSquared.resize(im.terms.elements.size());
  im.elementRhs.resize(im.terms.elements.size());
  for (std::size_t e = 0; e < im.terms.elements.size(); ++e)
    im.restSquaredTotal += im.terms.elements[e].ownerCount * im.terms.restSquared[e];
  if (im.problem.freeVertices.empty()) return;
  const Eigen::SparseMatrix<double> lower = im.problem.freeBlockLower(im.terms.system);
  im.factor.analyzePattern(lower);
  if (!im.factor.factorize(lower)) {
    throw SolverError(
        "ArapEditor: the Laplacian is not positive definite on the free vertices (degenerate "
        "triangles joining the free region?)");
  }
}

ArapEditor::~ArapEditor() = default;
ArapEditor::ArapEditor(ArapEditor&&) noexcept = default;
ArapEditor& ArapEditor::operator=(ArapEditor&&) noexcept = default;

ArapResult ArapEditor::solve(std::span<const Vec3> targets, const ProgressCallback& progress) {
  auto& im = *impl_;
  const auto& p = im.problem;
  const Eigen::MatrixXd fixed = im.relativeFixed(targets, "ArapEditor::solve");
  // Start 1: Laplacian editing (harmonic displacement) — the rotations all the identity.
  std::fill(im.rotations.begin(), im.rotations.end(), Mat3(1.0));
  std::vector<Vec3> laplacian =
      p.freeVertices.empty() ? p.assemble(Eigen::MatrixXd(0, 3), fixed) : im.globalStep(fixed);
  for (Vec3& x : laplacian) x += im.origin;
  // Start 2: the handles' common rigid motion, exact when there is one.
  const auto fit = detail::rigidFit(
      [&] {
        std::vector<Vec3> r;
        for (std::uint32_t v : p.constrained) r.push_back(p.rest[v]);
        return r;
      }(),
      targets);
  std::vector<Vec3> rigid = p.rest;
  for (std::uint32_t v : p.freeVertices) rigid[v] = fit.r * p.rest[v] + fit.shift;
  for (std::size_t k = 0; k < p.constrained.size(); ++k) rigid[p.constrained[k]] = targets[k];
  const double rigidEnergy = energy(rigid);
  const bool startRigid = rigidEnergy < energy(laplacian);
  ArapResult result = solveFrom(startRigid ? rigid : laplacian, targets, progress);
  result.report.startedRigid = startRigid;
  return result;
}

ArapResult ArapEditor::solveFrom(std::span<const Vec3> start, std::span<const Vec3> targets,
                                 const ProgressCallback& progress) {
  auto& im = *impl_;
  const auto& p = im.problem;
  const Vec3 origin = im.origin;
  const Eigen::MatrixXd fixed = im.relativeFixed(targets, "ArapEditor::solveFrom");
  if (start.size() != p.rest.size()) {
    throw InvalidInput("ArapEditor::solveFrom: " + std::to_string(start.size()) +
                       " start positions for " + std::to_string(p.rest.size()) + " vertices");
  }
  ArapResult result;
  result.positions.assign(start.begin(), start.end());
  for (std::size_t v = 0; v < start.size(); ++v) {
    if (!isFinite(start[v])) {
      throw InvalidInput("ArapEditor::solveFrom: start position " + std::to_string(v) +
                         " is not finite");
    }
    const std::int64_t s = p.slot[v];
    result.positions[v] =
        s < 0 ? Vec3(fixed(-s - 1, 0), fixed(-s - 1, 1), fixed(-s - 1, 2)) : start[v] - origin;
  }
  const auto toWorld = [&] {
    for (std::size_t v = 0; v < result.positions.size(); ++v) {
      const std::int64_t s = p.slot[v];
      // Fixed vertices exactly at their targets (or rest), not at (target − origin) + origin.
      result.positions[v] = s >= 0 ? result.positions[v] + origin
                            : -s - 1 < std::int64_t(p.constrained.size()) ? targets[-s - 1]
                                                                          : p.rest[v];
    }
  };
  const double e = im.localStep(result.positions);
  if (p.freeVertices.empty()) {
    result.report.energies.push_back(e);
    result.report.converged = true;
    toWorld();
    return result;
  }
  ProgressTracker tracker(progress, "arap", static_cast<std::size_t>(im.options.maxIterations));
  detail::LocalGlobalOptions o;
  o.maxIterations = im.options.maxIterations;
  o.relativeTolerance = im.options.relativeTolerance;
  o.accelerationWindow = im.options.accelerationWindow;
  // The energy is zero to the rounding of its terms (a rigid motion): nothing left to move.
  o.floor = 1e-14 * im.restSquaredTotal;
  std::vector<Mat3> keep;
  detail::LocalGlobalReport r = detail::minimiseLocalGlobal(
      result.positions, e, o, tracker, [&](const std::vector<Vec3>& x) { return im.localStep(x); },
      [&](const std::vector<Vec3>&) { return im.globalStep(fixed); }, [&] { keep = im.rotations; },
      [&] { im.rotations = keep; },
      [](std::vector<Vec3>& x) {
        return Eigen::Map<Eigen::VectorXd>(&x[0].x, static_cast<Eigen::Index>(3 * x.size()));
      });
  result.report.energies = std::move(r.energies);
  result.report.iterations = r.iterations;
  result.report.converged = r.converged;
  toWorld();
  return result;
}

double ArapEditor::energy(std::span<const Vec3> positions) const {
  if (positions.size() != impl_->problem.rest.size()) {
    throw InvalidInput("ArapEditor::energy: " + std::to_string(positions.size()) +
                       " positions for " + std::to_string(impl_->problem.rest.size()) +
                       " vertices");
  }
  for (std::size_t v = 0; v < positions.size(); ++v)
    if (!isFinite(positions[v]))
      throw InvalidInput("ArapEditor::energy: position " + std::to_string(v) + " is not finite");
  // localStep writes scratch state only; the editor is documented as not thread-safe.
  return impl_->localStep(positions);
}

std::span<const std::uint32_t> ArapEditor::heldVertices() const { return impl_->problem.held; }

}  // namespace spacewarp
