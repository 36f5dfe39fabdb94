#include <spacewarp/rbf/detail/rbf_system.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <numeric>
#include <string>
#include <tuple>
#include <utility>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <Eigen/Eigenvalues>

#include <spacewarp/core/detail/memory_budget.h>
#include <spacewarp/core/errors.h>

namespace spacewarp::detail {

namespace {

// A center of the combined index space: handles 0..h−1, then fixed centers h..h+f−1.
std::string centerName(std::size_t index, std::size_t handles) {
  return index < handles ? "center " + std::to_string(index)
                         : "fixed center " + std::to_string(index - handles);
}

std::size_t findRoot(std::vector<std::size_t>& parent, std::size_t i) {
  while (parent[i] != i) i = parent[i] = parent[parent[i]];
  return i;
}

}  // namespace

RbfCenters prepareRbfCenters(const std::string& who, std::span<const Vec3> handles,
                             const std::span<const Vec3>* targets, std::span<const Vec3> fixed,
                             const RbfOptions& options) {
  validateRbfOptions(who, options);
  if (handles.empty()) throw InvalidInput(who + ": no centers given (at least one is needed)");
  if (targets && targets->size() != handles.size()) {
    throw InvalidInput(who + ": " + std::to_string(handles.size()) + " centers but " +
                       std::to_string(targets->size()) + " targets");
  }
  const std::size_t h = handles.size();
  const std::size_t total = h + fixed.size();
  std::vector<Vec3> all(handles.begin(), handles.end());
  all.insert(all.end(), fixed.begin(), fixed.end());
  for (std::size_t i = 0; i < total; ++i) {
    if (!isFinite(all[i])) throw InvalidInput(who + ": " + centerName(i, h) + " is not finite");
    if (targets && i < h && !isFinite((*targets)[i]))
      throw InvalidInput(who + ": target " + std::to_string(i) + " is not finite");
  }
  Vec3 lo = all[0], hi = all[0];
  for (const Vec3& p : all) {
    lo = glm::min(lo, p);
    hi = glm::max(hi, p);
  }
  const double tol = options.duplicateTolerance * glm::length(hi - lo);

  // Pairs closer than tol, by a sweep along x; union-find with the smallest index as the root,
  // so that a group containing a handle is represented by its first handle.
  std::vector<std::size_t> order(total);
  std::iota(order.begin(), order.end(), std::size_t{0});
  std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
    return all[a].x < all[b].x || (all[a].x == all[b].x && a < b);
  });
  std::vector<std::size_t> parent(total);
  std::iota(parent.begin(), parent.end(), std::size_t{0});
  for (std::size_t s = 0; s < total; ++s) {
    const std::size_t a = order[s];
    for (std::size_t t = s + 1; t < total && all[order[t]].x - all[a].x <= tol; ++t) {
      const std::size_t b = order[t];
      if (glm::length(all[a] - all[b]) > tol) continue;
      const std::size_t ra = findRoot(parent, a), rb = findRoot(parent, b);
      if (ra != rb) parent[std::max(ra, rb)] = std::min(ra, rb);
    }
  }

  auto displacementOf = [&](std::size_t i) {
    return i < h && targets ? (*targets)[i] - handles[i] : Vec3(0.0);
  };
  RbfCenters result;
  std::vector<std::size_t> uniqueOf(total, SIZE_MAX);
  for (std::size_t i = 0; i < total; ++i) {
    const std::size_t root = findRoot(parent, i);
    if (targets && root != i && glm::length(displacementOf(i) - displacementOf(root)) > tol) {
      throw InvalidInput(who + ": " + centerName(root, h) + " and " + centerName(i, h) +
                         " coincide but their targets differ");
    }
    if (uniqueOf[root] == SIZE_MAX) {
      uniqueOf[root] = result.unique.size();
      result.unique.push_back(all[root]);
      if (targets) result.displacement.push_back(displacementOf(root));
      if (root < h) result.multiplicity.push_back(0);
    }
    if (i < h) {
      result.handleColumn.push_back(uniqueOf[root]);
      ++result.multiplicity[uniqueOf[root]];
    }
  }
  // Handle groups come first: every handle root precedes every fixed root in index order.
  result.handleCenters = result.multiplicity.size();
  if (const std::string problem = rbfScaleProblem(options, result.unique); !problem.empty()) {
    char scale[32];
    std::snprintf(scale, sizeof scale, "%.3g", options.scale);
    throw InvalidInput(who + ": the kernel scale " + scale + " " + problem);
  }
  return result;
}

namespace {

// The centers' mean and bounding-box diagonal: the origin and length of the polynomial basis.
std::pair<Vec3, double> polynomialFrame(std::span<const Vec3> centers) {
  Vec3 lo = centers[0], hi = centers[0], sum(0.0);
  for (const Vec3& c : centers) {
    lo = glm::min(lo, c);
    hi = glm::max(hi, c);
    sum += c;
  }
  return {sum / static_cast<double>(centers.size()), glm::length(hi - lo)};
}

// The polynomial block P: rows [1, (c - origin) / length].
Eigen::MatrixXd polynomialBlock(std::span<const Vec3> centers, const Vec3& origin, double length) {
  const Eigen::Index n = static_cast<Eigen::Index>(centers.size());
  Eigen::MatrixXd p(n, 4);
  for (Eigen::Index i = 0; i < n; ++i) {
    const Vec3 q = (centers[static_cast<std::size_t>(i)] - origin) / length;
    p.row(i) << 1.0, q.x, q.y, q.z;
  }
  return p;
}

}  // namespace

double RbfSystem::memoryEstimate(std::size_t n) {
  const double entries = static_cast<double>(n) * static_cast<double>(n);
  return 2.25 * sizeof(double) * entries + 4e6;
}

void checkRbfPolynomial(const std::string& who, std::span<const Vec3> centers) {
  const std::size_t n = centers.size();
  const std::string needs =
      who +
      ": the linear polynomial needs at least 4 affinely independent centers (not all "
      "coplanar), but ";
  if (n < 4)
    throw InvalidInput(needs + "only " + std::to_string(n) + " distinct centers are given");
  const auto [origin, length] = polynomialFrame(centers);
  const Eigen::MatrixXd p = polynomialBlock(centers, origin, length);
  // Affine independence: the spread of the centered, scaled centers in their thinnest direction.
  const Eigen::Matrix3d cov = p.rightCols<3>().transpose() * p.rightCols<3>();
  const Eigen::Vector3d ev = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(cov).eigenvalues();
  if (!(ev(0) > 1e-20 * ev(2)))
    throw InvalidInput(needs + "the " + std::to_string(n) + " distinct centers are all coplanar");
}

RbfSystem::RbfSystem(const std::string& who, std::span<const Vec3> centers,
                     const RbfOptions& options)
    : n_(centers.size()) {
  checkMemory(memoryEstimate(n_),
              who + ": the RBF system of " + std::to_string(n_) + " distinct centers");
  sigma_ = options.kernel == RbfKernel::Biharmonic ? -1.0 : 1.0;
  checkRbfPolynomial(who, centers);
  std::tie(origin_, length_) = polynomialFrame(centers);
  const Eigen::Index n = static_cast<Eigen::Index>(n_);
  const Eigen::MatrixXd p = polynomialBlock(centers, origin_, length_);
  qr_.compute(p);
  ProgressTracker tracker(options.progress, "fit rbf", 3);

  // Φ, then QᵀΦQ (four Householder reflections on each side).
  Eigen::MatrixXd phi(n, n);
  tbb::parallel_for(
      tbb::blocked_range<Eigen::Index>(0, n, 16), [&](const tbb::blocked_range<Eigen::Index>& r) {
        for (Eigen::Index j = r.begin(); j != r.end(); ++j) {
          const Vec3& cj = centers[static_cast<std::size_t>(j)];
          for (Eigen::Index i = 0; i < n; ++i) {
            phi(i, j) =
                rbfKernelValue(options, glm::length(centers[static_cast<std::size_t>(i)] - cj));
          }
        }
      });
  // Pivots of the reduced system below the rounding error of forming it mean singular.
  tracker.advance();
  const double pivotFloor =
      static_cast<double>(n_) * std::numeric_limits<double>::epsilon() * phi.cwiseAbs().maxCoeff();
  phi.applyOnTheLeft(qr_.householderQ().adjoint());
  phi.applyOnTheRight(qr_.householderQ());
  const Eigen::Index m = n - 4;
  b12_ = phi.topRightCorner(4, m);
  Eigen::MatrixXd k = sigma_ * phi.bottomRightCorner(m, m);
  k.diagonal().array() += options.smoothing;
  phi.resize(0, 0);
  tracker.advance();
  if (m > 0) {
    llt_.compute(k);
    if (llt_.info() != Eigen::Success ||
        !(llt_.matrixLLT().diagonal().array().square().minCoeff() > pivotFloor) ||
        !(llt_.rcond() > std::numeric_limits<double>::epsilon())) {
      throw SolverError(who + ": the RBF system of " + std::to_string(n_) +
                        " centers is numerically singular (kernel " +
                        rbfKernelName(options.kernel) +
                        "; try another kernel scale or radius, or smoothing > 0)");
    }
  }
  tracker.finish();
}

void RbfSystem::solve(const Eigen::MatrixXd& d, Eigen::MatrixXd& w, Eigen::MatrixXd& a) const {
  const Eigen::Index n = static_cast<Eigen::Index>(n_);
  const Eigen::Index m = n - 4;
  Eigen::MatrixXd qtd = qr_.householderQ().adjoint() * d;
  Eigen::MatrixXd rhs = qtd.topRows(4);
  w.setZero(n, d.cols());
  if (m > 0) {
    const Eigen::MatrixXd u = llt_.solve(sigma_ * qtd.bottomRows(m));
    rhs -= b12_ * u;
    w.bottomRows(m) = u;
    w.applyOnTheLeft(qr_.householderQ());
  }
  a = qr_.matrixQR().topLeftCorner(4, 4).triangularView<Eigen::Upper>().solve(rhs);
}

}  // namespace spacewarp::detail
