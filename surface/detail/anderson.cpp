#include <spacewarp/surface/detail/anderson.h>

#include <Eigen/Cholesky>

namespace spacewarp::detail {

Eigen::VectorXd AndersonAccelerator::next(const Eigen::VectorXd& x, const Eigen::VectorXd& g) {
  Eigen::VectorXd f = g - x;
  if (window_ == 0) return g;
  if (lastF_.size() == f.size()) {
    dF_.push_back(f - lastF_);
    dG_.push_back(g - lastG_);
    if (dF_.size() > window_) {
      dF_.pop_front();
      dG_.pop_front();
    }
  }
  lastF_ = f;
  lastG_ = g;
  const auto m = static_cast<Eigen::Index>(dF_.size());
  if (m == 0) return g;
  // Normal equations of the small least-squares problem, with a relative ridge against
  // nearly dependent differences (the steps shrink together near convergence).
  Eigen::MatrixXd gram(m, m);
  Eigen::VectorXd rhs(m);
  for (Eigen::Index i = 0; i < m; ++i) {
    rhs[i] = dF_[i].dot(f);
    for (Eigen::Index j = 0; j <= i; ++j) gram(i, j) = gram(j, i) = dF_[i].dot(dF_[j]);
  }
  gram.diagonal().array() += 1e-10 * gram.diagonal().maxCoeff() + 1e-300;
  const Eigen::VectorXd theta = gram.ldlt().solve(rhs);
  Eigen::VectorXd out = g;
  for (Eigen::Index i = 0; i < m; ++i) out -= theta[i] * dG_[i];
  return out.allFinite() ? out : g;
}

void AndersonAccelerator::reset() {
  dF_.clear();
  dG_.clear();
  lastF_.resize(0);
  lastG_.resize(0);
}

}  // namespace spacewarp::detail
