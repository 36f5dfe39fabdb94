#pragma once
// The library's one sparse direct solver: CHOLMOD's supernodal LLᵀ factor of a symmetric
// positive definite matrix, given by its lower triangle. Used by the harmonic coordinates'
// Laplace solve and the deformation graph's normal equations.
//
// Why a wrapper rather than Eigen's CholmodSupernodalLLT at each use:
//  - every CHOLMOD status is checked (Eigen's wrapper ignores it: a failed analysis leaves a
//    null factor that its factorize() dereferences, and a factorisation that ran out of memory
//    reports success) and turned into a SolverError naming the caller, with advice (an
//    OutOfMemory, which the command line reports as out of memory, when CHOLMOD ran out);
//  - the BLAS runs single-threaded inside every call (detail::SerialBlas), so results do not
//    depend on OPENBLAS_NUM_THREADS and no caller can forget it;
//  - CHOLMOD never prints (print = 0): failures come back as exceptions;
//  - cholmod.h stays in the .cpp (pointer to implementation), so includers need only Eigen.
//
// Not thread-safe: a solve uses the factor's workspace. Calls of different objects may run on
// different threads; SerialBlas's process-wide lock then serialises them.

#include <memory>
#include <string>

#include <Eigen/Core>
#include <Eigen/SparseCore>

namespace spacewarp::detail {

/// The fill-reducing ordering of the symbolic analysis.
enum class CholeskyOrdering {
  /// CHOLMOD's default strategy (as Eigen's wrapper leaves it): AMD, and METIS as well when
  /// AMD's factor is dense, keeping the one with less fill.
  CholmodDefault,
  /// AMD alone (postordered): a cheaper analysis for matrices where METIS saves little.
  Amd,
};

/// How a SparseCholesky reports failures and orders the matrix.
struct SparseCholeskyOptions {
  /// Who factorises, the start of every error message ("DeformationGraph::solve").
  std::string caller = "SparseCholesky";
  /// What the user can do when CHOLMOD fails (out of memory, a factor beyond its 32-bit
  /// indices), the end of the message ("use fewer graph nodes"). Empty: no advice.
  std::string advice;
  /// Fill-reducing ordering (default: CHOLMOD's own choice).
  CholeskyOrdering ordering = CholeskyOrdering::CholmodDefault;
};

/// A supernodal sparse Cholesky factor A = L Lᵀ. Matrices are n × n, compressed, holding the
/// lower triangle (diagonal included) of A; the upper triangle is not read. Where a method
/// throws SolverError because CHOLMOD ran out of memory, it is an OutOfMemory; any call may
/// also throw InvalidInput when the thread's BLAS work buffer would not fit (SerialBlas).
class SparseCholesky {
 public:
  explicit SparseCholesky(SparseCholeskyOptions options = {});
  ~SparseCholesky();
  SparseCholesky(SparseCholesky&&) noexcept;
  SparseCholesky& operator=(SparseCholesky&&) noexcept;
  SparseCholesky(const SparseCholesky&) = delete;
  SparseCholesky& operator=(const SparseCholesky&) = delete;

  /// Symbolic analysis of `lower`'s pattern (ordering, supernodes); forgets any factor. Throws
  /// SolverError if CHOLMOD fails (e.g. out of memory).
  void analyzePattern(const Eigen::SparseMatrix<double>& lower);

  /// Numeric factorisation of `lower`, whose pattern must be the analysed one. Returns false
  /// if the matrix is not (numerically) positive definite: there is no factor then. Throws
  /// SolverError if CHOLMOD fails, std::logic_error if no pattern was analysed.
  bool factorize(const Eigen::SparseMatrix<double>& lower);

  /// x = A⁻¹ b for one (n) or several (n × m) right-hand sides, with the last successful
  /// factor. Throws SolverError if CHOLMOD fails, std::logic_error if there is no factor.
  Eigen::VectorXd solve(const Eigen::VectorXd& b);
  Eigen::MatrixXd solve(const Eigen::MatrixXd& b);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace spacewarp::detail
