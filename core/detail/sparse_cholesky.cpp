#include <spacewarp/core/detail/sparse_cholesky.h>

#include <stdexcept>
#include <utility>

#include <Eigen/CholmodSupport>

#include <spacewarp/core/detail/serial_blas.h>
#include <spacewarp/core/errors.h>

namespace spacewarp::detail {

// Eigen's wrapper does the calls (the same CHOLMOD calls as before the wrapper existed, so the
// same bits); this class adds what it lacks: status checks, the serial BLAS, no printing.
struct SparseCholesky::Impl {
  SparseCholeskyOptions options;
  // final_asis = 1 and supernodal = CHOLMOD_SUPERNODAL, set by Eigen.
  Eigen::CholmodSupernodalLLT<Eigen::SparseMatrix<double>, Eigen::Lower> llt;
  bool analysed = false;
  bool factored = false;

  explicit Impl(SparseCholeskyOptions o) : options(std::move(o)) {
    cholmod_common& c = llt.cholmod();
    c.print = 0;  // the library never writes to stderr: failures come back as exceptions
    if (options.ordering == CholeskyOrdering::Amd) {
      c.nmethods = 1;
      c.method[0].ordering = CHOLMOD_AMD;
      c.postorder = 1;
    }
  }

  // Throws SolverError (OutOfMemory when CHOLMOD ran out of memory) unless CHOLMOD's last call
  // (`step`) succeeded. Positive statuses are warnings (e.g. not positive definite), reported
  // through the factor instead.
  void require(const char* step) {
    const int status = llt.cholmod().status;
    if (status >= CHOLMOD_OK) return;
    std::string why;
    switch (status) {
      case CHOLMOD_OUT_OF_MEMORY:
        why = "out of memory";
        break;
      case CHOLMOD_TOO_LARGE:
        why = "the factor is too large for CHOLMOD's 32-bit indices";
        break;
      default:
        why = "CHOLMOD status " + std::to_string(status);
    }
    std::string message =
        options.caller + ": the sparse Cholesky " + step + " failed (" + why + ")";
    if (!options.advice.empty()) message += "; " + options.advice;
    if (status == CHOLMOD_OUT_OF_MEMORY) throw OutOfMemory(message);
    throw SolverError(message);
  }

  template <class Dense>
  Dense solve(const Dense& b) {
    if (!factored)
      throw std::logic_error(options.caller + ": SparseCholesky::solve without a factor");
    const SerialBlas serialBlas;
    Dense x = llt.solve(b);
    require("solve");
    return x;
  }
};

SparseCholesky::SparseCholesky(SparseCholeskyOptions options)
    : impl_(std::make_unique<Impl>(std::move(options))) {}

SparseCholesky::~SparseCholesky() = default;
SparseCholesky::SparseCholesky(SparseCholesky&&) noexcept = default;
SparseCholesky& SparseCholesky::operator=(SparseCholesky&&) noexcept = default;

void SparseCholesky::analyzePattern(const Eigen::SparseMatrix<double>& lower) {
  Impl& im = *impl_;
  im.analysed = false;
  im.factored = false;
  const SerialBlas serialBlas;
  im.llt.analyzePattern(lower);
  im.require("analysis");
  im.analysed = true;
}

bool SparseCholesky::factorize(const Eigen::SparseMatrix<double>& lower) {
  Impl& im = *impl_;
  if (!im.analysed) {
    throw std::logic_error(im.options.caller +
                           ": SparseCholesky::factorize before a successful analysis");
  }
  im.factored = false;
  const SerialBlas serialBlas;
  im.llt.factorize(lower);
  im.require("factorisation");
  im.factored = im.llt.info() == Eigen::Success;
  return im.factored;
}

Eigen::VectorXd SparseCholesky::solve(const Eigen::VectorXd& b) { return impl_->solve(b); }
Eigen::MatrixXd SparseCholesky::solve(const Eigen::MatrixXd& b) { return impl_->solve(b); }

}  // namespace spacewarp::detail
