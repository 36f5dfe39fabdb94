#pragma once
// A dense Cholesky factorisation A = L Lᵀ through LAPACK/BLAS (OpenBLAS on Debian), in place in
// a column-major array, parallel over tiles with TBB and bit-identical for any thread count.
//
// Why not LAPACK's own threads: OpenBLAS's dpotrf picks its blocking, and so its rounding, by
// its thread count. Here the tiling is fixed (kTile), every tile operation is one call of the
// single-threaded BLAS (detail::SerialBlas), and TBB only decides which thread runs which tile,
// so the bits depend on the matrix alone.
//
// Systems smaller than kLapackMinSize are factorised by Eigen on the calling thread instead:
// OpenBLAS maps a 128 MiB work buffer for each thread that makes a level-3 call, which a small
// fit should not need (nor memory caps such as the fuzzers' refuse), and at that size Eigen
// takes a few milliseconds; their results also stay what they were before LAPACK was used.

#include <cstddef>
#include <optional>
#include <string>

#include <Eigen/Cholesky>
#include <Eigen/Core>

namespace spacewarp::detail {

/// The smallest n factorised through LAPACK.
inline constexpr std::size_t kLapackMinSize = 512;

/// The bytes the factorisation needs beyond the matrix: the BLAS work buffers of the threads
/// that may run its tiles (detail::blasWorkBufferBytes() each).
double denseCholeskyWorkspaceBytes(std::size_t n);

class DenseCholesky {
 public:
  /// Factorises the symmetric positive-definite n × n matrix whose lower triangle is at `a`
  /// (column-major, leading dimension lda ≥ n), overwriting it with L; the strict upper triangle
  /// is left alone (LAPACK) or overwritten (Eigen, below kLapackMinSize). Throws InvalidInput
  /// (detail::checkMemory: the BLAS work buffers do not fit). ok() is false if a pivot is not
  /// positive.
  DenseCholesky(double* a, std::size_t n, std::size_t lda);

  bool ok() const { return ok_; }

  /// The smallest squared diagonal entry of L (the smallest pivot), when ok().
  double minPivot() const { return minPivot_; }

  /// An estimate of the reciprocal condition number in the 1-norm (LAPACK dpocon, or Eigen's
  /// estimate below kLapackMinSize); when ok().
  double rcond() const;

  /// Solves A X = B in place for B (n × nrhs, column-major, leading dimension ldb ≥ n). Columns
  /// are solved in fixed blocks in parallel, so the bits do not depend on the thread count.
  void solve(double* b, std::size_t nrhs, std::size_t ldb) const;

 private:
  double* a_;
  std::size_t n_;
  std::size_t lda_;
  bool ok_ = true;
  double minPivot_ = 0.0;
  double norm1_ = 0.0;  // of the matrix before factorisation (LAPACK path)
  using Block = Eigen::Ref<Eigen::MatrixXd, 0, Eigen::OuterStride<>>;
  std::optional<Eigen::LLT<Block>> small_;  // in place, below kLapackMinSize
};

}  // namespace spacewarp::detail
