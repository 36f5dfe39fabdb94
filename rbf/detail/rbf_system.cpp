#include <spacewarp/rbf/detail/rbf_system.h>

#include <algorithm>
#include <atomic>
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

std::atomic<std::size_t> systemCount{0};  // for rbfSystemCount()

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

// The lower triangle of QᵀΦQ in place, for a symmetric Φ (n × n) and the Q of `qr` (four
// reflections): with Q = I − V T Vᵀ (V: the unit lower-trapezoidal reflectors, T: LAPACK's
// dlarft triangle), QᵀΦQ = Φ − V Zᵀ − Z Vᵀ with Y = Φ V and Z = Y T − ½ V Tᵀ (Vᵀ Y) T: one pass
// for Y and one for the rank-8 update, parallel over fixed blocks of columns (so the bits do
// not depend on the thread count), in place of Eigen's two passes of reflections over the whole
// matrix. The strict upper triangle is left stale.
void reduceLowerTriangle(const Eigen::HouseholderQR<Eigen::MatrixXd>& qr, Eigen::MatrixXd& phi) {
  const Eigen::Index n = phi.rows();
  Eigen::MatrixXd v = qr.matrixQR().leftCols<4>();
  for (Eigen::Index c = 0; c < 4; ++c) {
    v.col(c).head(c).setZero();
    v(c, c) = 1.0;
  }
  const Eigen::Vector4d tau = qr.hCoeffs();
  Eigen::Matrix4d t = Eigen::Matrix4d::Zero();
  for (Eigen::Index c = 0; c < 4; ++c) {
    t(c, c) = tau(c);
    if (c > 0) {
      const Eigen::VectorXd w = -tau(c) * (v.leftCols(c).transpose() * v.col(c));
      t.col(c).head(c) = t.topLeftCorner(c, c).triangularView<Eigen::Upper>() * w;
    }
  }
  constexpr Eigen::Index kBlock = 64;
  const Eigen::Index blocks = (n + kBlock - 1) / kBlock;
  Eigen::MatrixXd y(n, 4);
  tbb::parallel_for(Eigen::Index{0}, blocks, [&](Eigen::Index b) {
    const Eigen::Index j0 = b * kBlock, cols = std::min(kBlock, n - j0);
    y.middleRows(j0, cols).noalias() = phi.middleCols(j0, cols).transpose() * v;  // Φ symmetric
  });
  const Eigen::Matrix4d middle = t.transpose() * (v.transpose() * y) * t;
  const Eigen::MatrixXd z = y * t - 0.5 * v * middle;
  tbb::parallel_for(Eigen::Index{0}, blocks, [&](Eigen::Index b) {
    const Eigen::Index j0 = b * kBlock, j1 = std::min(j0 + kBlock, n);
    for (Eigen::Index j = j0; j < j1; ++j) {
      const Eigen::Vector4d vj = v.row(j).transpose(), zj = z.row(j).transpose();
      for (Eigen::Index i = j; i < n; ++i) {
        phi(i, j) -= v(i, 0) * zj(0) + v(i, 1) * zj(1) + v(i, 2) * zj(2) + v(i, 3) * zj(3) +
                     z(i, 0) * vj(0) + z(i, 1) * vj(1) + z(i, 2) * vj(2) + z(i, 3) * vj(3);
      }
    }
  });
}

}  // namespace

double RbfSystem::memoryEstimate(std::size_t n) {
  const double entries = static_cast<double>(n) * static_cast<double>(n);
  // The factorised block is n − 4 (the polynomial's 4 unknowns are eliminated): LAPACK's
  // buffers are charged only when that block takes the LAPACK path.
  return 1.1 * sizeof(double) * entries + 4e6 + denseCholeskyWorkspaceBytes(n > 4 ? n - 4 : 0);
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
  if (!(ev(0) > 1e-20 * ev(2))) {
    const char* shape = ev(1) > 1e-20 * ev(2) ? "coplanar" : "collinear";
    throw InvalidInput(needs + "the " + std::to_string(n) + " distinct centers are all " + shape);
  }
}

std::size_t rbfSystemCount() { return systemCount.load(); }

RbfSystem::RbfSystem(const std::string& who, std::span<const Vec3> centers,
                     const RbfOptions& options)
    : n_(centers.size()) {
  ++systemCount;
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
  factor_.resize(n, n);
  Eigen::MatrixXd& phi = factor_;
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
  const Eigen::Index m = n - 4;
  if (static_cast<std::size_t>(m) < kLapackMinSize) {
    phi.applyOnTheLeft(qr_.householderQ().adjoint());
    phi.applyOnTheRight(qr_.householderQ());
    b12_ = phi.topRightCorner(4, m);
  } else {
    reduceLowerTriangle(qr_, phi);
    b12_ = phi.bottomLeftCorner(m, 4).transpose();
  }
  auto k = phi.bottomRightCorner(m, m);
  if (sigma_ != 1.0) k *= sigma_;
  k.diagonal().array() += options.smoothing;
  tracker.advance();
  if (m > 0) {
    cholesky_.emplace(k.data(), static_cast<std::size_t>(m), static_cast<std::size_t>(n));
    if (!cholesky_->ok() || !(cholesky_->minPivot() > pivotFloor) ||
        !(cholesky_->rcond() > std::numeric_limits<double>::epsilon())) {
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
    Eigen::MatrixXd u = sigma_ * qtd.bottomRows(m);
    cholesky_->solve(u.data(), static_cast<std::size_t>(u.cols()), static_cast<std::size_t>(m));
    rhs -= b12_ * u;
    w.bottomRows(m) = u;
    w.applyOnTheLeft(qr_.householderQ());
  }
  a = qr_.matrixQR().topLeftCorner(4, 4).triangularView<Eigen::Upper>().solve(rhs);
}

}  // namespace spacewarp::detail
