#include <spacewarp/rbf/detail/dense_cholesky.h>

#include <algorithm>
#include <limits>
#include <vector>

#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <spacewarp/core/detail/memory_budget.h>
#include <spacewarp/core/detail/serial_blas.h>

// LAPACK and BLAS, Fortran calling convention (the trailing lengths are gfortran's hidden
// lengths of the character arguments).
extern "C" {
double dlansy_(const char* norm, const char* uplo, const int* n, const double* a, const int* lda,
               double* work, std::size_t, std::size_t);
void dpotrf_(const char* uplo, const int* n, double* a, const int* lda, int* info, std::size_t);
void dpotrs_(const char* uplo, const int* n, const int* nrhs, const double* a, const int* lda,
             double* b, const int* ldb, int* info, std::size_t);
void dpocon_(const char* uplo, const int* n, const double* a, const int* lda, const double* anorm,
             double* rcond, double* work, int* iwork, int* info, std::size_t);
void dtrsm_(const char* side, const char* uplo, const char* transa, const char* diag, const int* m,
            const int* n, const double* alpha, const double* a, const int* lda, double* b,
            const int* ldb, std::size_t, std::size_t, std::size_t, std::size_t);
void dsyrk_(const char* uplo, const char* trans, const int* n, const int* k, const double* alpha,
            const double* a, const int* lda, const double* beta, double* c, const int* ldc,
            std::size_t, std::size_t);
void dgemm_(const char* transa, const char* transb, const int* m, const int* n, const int* k,
            const double* alpha, const double* a, const int* lda, const double* b, const int* ldb,
            const double* beta, double* c, const int* ldc, std::size_t, std::size_t);
}

namespace spacewarp::detail {

namespace {

// The tile edge: large enough for the BLAS's level-3 kernels to run near peak, small enough
// that a 2,000-center system has a few dozen tiles to share among threads.
constexpr std::size_t kTile = 192;
// The columns of one solve task.
constexpr std::size_t kSolveBlock = 64;

int asInt(std::size_t v) { return static_cast<int>(v); }

std::size_t tiles(std::size_t n) { return (n + kTile - 1) / kTile; }

}  // namespace

double denseCholeskyWorkspaceBytes(std::size_t n) {
  if (n < kLapackMinSize) return 0.0;
  const std::size_t workers = std::min<std::size_t>(
      static_cast<std::size_t>(tbb::this_task_arena::max_concurrency()), tiles(n) * tiles(n));
  return static_cast<double>(workers) * static_cast<double>(blasWorkBufferBytes());
}

DenseCholesky::DenseCholesky(double* a, std::size_t n, std::size_t lda) : a_(a), n_(n), lda_(lda) {
  if (n == 0) return;
  if (n < kLapackMinSize) {
    Eigen::Map<Eigen::MatrixXd, 0, Eigen::OuterStride<>> map(
        a, static_cast<Eigen::Index>(n), static_cast<Eigen::Index>(n), Eigen::OuterStride<>(lda));
    Block block(map);
    small_.emplace(block);
    ok_ = small_->info() == Eigen::Success;
    if (ok_) minPivot_ = small_->matrixLLT().diagonal().array().square().minCoeff();
    return;
  }
  // Checked again now that the matrix is allocated; named for the rig key whose size it is.
  checkMemory(denseCholeskyWorkspaceBytes(n),
              "'centers' (an RBF fit of " + std::to_string(n) +
                  " unknowns): the work space of its factorisation's threads");
  const SerialBlas serial;
  const int ld = asInt(lda);
  {
    const int size = asInt(n);
    std::vector<double> work(n);
    norm1_ = dlansy_("1", "L", &size, a, &ld, work.data(), 1, 1);
  }
  auto tile = [&](std::size_t i, std::size_t j) { return a + j * kTile * lda + i * kTile; };
  auto edge = [&](std::size_t i) { return asInt(std::min(kTile, n - i * kTile)); };
  const std::size_t t = tiles(n);
  const double one = 1.0, minusOne = -1.0;
  // Right-looking: factor the diagonal tile, solve the tiles below it, update the trailing
  // lower triangle. Isolated, so that a thread waiting here runs no outer task that could take
  // the SerialBlas lock it holds.
  tbb::this_task_arena::isolate([&] {
    for (std::size_t k = 0; k < t; ++k) {
      const int bk = edge(k);
      int info = 0;
      dpotrf_("L", &bk, tile(k, k), &ld, &info, 1);
      if (info != 0) {
        ok_ = false;
        return;
      }
      tbb::parallel_for(k + 1, t, [&](std::size_t i) {
        const int bi = edge(i);
        dtrsm_("R", "L", "T", "N", &bi, &bk, &one, tile(k, k), &ld, tile(i, k), &ld, 1, 1, 1, 1);
      });
      // The trailing tiles (i, j), k < j ≤ i, enumerated row by row.
      const std::size_t rest = t - k - 1;
      tbb::parallel_for(std::size_t{0}, rest * (rest + 1) / 2, [&](std::size_t p) {
        std::size_t i = 0;
        while ((i + 1) * (i + 2) / 2 <= p) ++i;
        const std::size_t j = p - i * (i + 1) / 2;
        const std::size_t ti = k + 1 + i, tj = k + 1 + j;
        const int bi = edge(ti), bj = edge(tj);
        if (ti == tj) {
          dsyrk_("L", "N", &bi, &bk, &minusOne, tile(ti, k), &ld, &one, tile(ti, ti), &ld, 1, 1);
        } else {
          dgemm_("N", "T", &bi, &bj, &bk, &minusOne, tile(ti, k), &ld, tile(tj, k), &ld, &one,
                 tile(ti, tj), &ld, 1, 1);
        }
      });
    }
  });
  if (!ok_) return;
  minPivot_ = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < n; ++i)
    minPivot_ = std::min(minPivot_, a[i * lda + i] * a[i * lda + i]);
}

double DenseCholesky::rcond() const {
  if (n_ == 0) return 1.0;
  if (small_) return small_->rcond();  // Eigen kept the norm of the matrix
  const SerialBlas serial;
  const int n = asInt(n_), ld = asInt(lda_);
  std::vector<double> work(3 * n_);
  std::vector<int> iwork(n_);
  double result = 0.0;
  int info = 0;
  dpocon_("L", &n, a_, &ld, &norm1_, &result, work.data(), iwork.data(), &info, 1);
  return result;
}

void DenseCholesky::solve(double* b, std::size_t nrhs, std::size_t ldb) const {
  if (n_ == 0 || nrhs == 0) return;
  if (small_) {
    Eigen::Map<Eigen::MatrixXd, 0, Eigen::OuterStride<>> x(b, static_cast<Eigen::Index>(n_),
                                                           static_cast<Eigen::Index>(nrhs),
                                                           Eigen::OuterStride<>(ldb));
    small_->solveInPlace(x);
    return;
  }
  const SerialBlas serial;
  const int n = asInt(n_), ld = asInt(lda_), ldB = asInt(ldb);
  tbb::this_task_arena::isolate([&] {
    tbb::parallel_for(std::size_t{0}, (nrhs + kSolveBlock - 1) / kSolveBlock, [&](std::size_t s) {
      const int cols = asInt(std::min(kSolveBlock, nrhs - s * kSolveBlock));
      int info = 0;
      dpotrs_("L", &n, &cols, a_, &ld, b + s * kSolveBlock * ldb, &ldB, &info, 1);
    });
  });
}

}  // namespace spacewarp::detail
