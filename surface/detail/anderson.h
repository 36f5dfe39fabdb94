#pragma once
// Anderson acceleration of a fixed-point iteration x <- G(x) (Walker and Ni 2011; for
// local/global solvers such as ARAP, Peng et al. 2018): from the last few steps, the
// combination of their results whose residual G(x) − x is smallest in the least-squares sense.
// The caller keeps the energy monotone by accepting an extrapolation only when it lowers the
// energy (reset() and take G(x) otherwise).

#include <cstddef>
#include <deque>

#include <Eigen/Core>

namespace spacewarp::detail {

class AndersonAccelerator {
 public:
  /// `window`: how many previous steps are combined (0 disables: next() returns g).
  explicit AndersonAccelerator(std::size_t window) : window_(window) {}

  /// Records the step x -> g = G(x) and returns the next iterate: g itself while there is no
  /// history, else g − ΔG θ with θ minimising |f − ΔF θ| (f = g − x; ΔF, ΔG the differences of
  /// consecutive residuals and results).
  Eigen::VectorXd next(const Eigen::VectorXd& x, const Eigen::VectorXd& g);

  /// Forgets the history (after a rejected extrapolation).
  void reset();

 private:
  std::size_t window_;
  std::deque<Eigen::VectorXd> dF_, dG_;
  Eigen::VectorXd lastF_, lastG_;
};

}  // namespace spacewarp::detail
