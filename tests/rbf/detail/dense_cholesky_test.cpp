// Tests of rbf/detail/dense_cholesky.h: the factor and the solve against the matrix (both the
// Eigen path of small systems and the tiled LAPACK path), failure on indefinite matrices, and the
// same bits for any TBB or OpenBLAS thread count.

#include <spacewarp/rbf/detail/dense_cholesky.h>
#include <spacewarp/rbf/detail/rbf_system.h>

#include <random>
#include <vector>

#include <gtest/gtest.h>
#include <tbb/task_arena.h>
#include <Eigen/Core>
#include <Eigen/LU>

#include "test_util.h"

namespace spacewarp {
namespace {

using detail::DenseCholesky;
using detail::denseCholeskyWorkspaceBytes;
using detail::kLapackMinSize;
using detail::RbfSystem;

// A random SPD matrix B Bᵀ / n + I of size n, stored with a leading dimension n + 7 so that the
// strided access is tested; and a right-hand side of `rhs` columns.
struct Problem {
  Eigen::MatrixXd a;  // (n + 7) × n; the top n × n block is the matrix
  Eigen::MatrixXd b;  // n × rhs
};

Problem randomProblem(std::size_t size, std::size_t rhs, unsigned seed) {
  const Eigen::Index n = static_cast<Eigen::Index>(size);
  std::srand(seed);
  const Eigen::MatrixXd g = Eigen::MatrixXd::Random(n, n);
  Problem p;
  p.a = Eigen::MatrixXd::Zero(n + 7, n);
  p.a.topRows(n) = g * g.transpose() / static_cast<double>(n);
  p.a.topRows(n).diagonal().array() += 1.0;
  p.b = Eigen::MatrixXd::Random(n, static_cast<Eigen::Index>(rhs));
  return p;
}

// Factorises and solves a copy of p; returns the solution.
Eigen::MatrixXd factorAndSolve(const Problem& p, Eigen::MatrixXd* factor = nullptr) {
  Eigen::MatrixXd a = p.a;
  const std::size_t n = static_cast<std::size_t>(a.cols());
  const DenseCholesky chol(a.data(), n, static_cast<std::size_t>(a.rows()));
  EXPECT_TRUE(chol.ok());
  Eigen::MatrixXd x = p.b;
  chol.solve(x.data(), static_cast<std::size_t>(x.cols()), n);
  if (factor) *factor = a.topRows(a.cols()).triangularView<Eigen::Lower>();
  return x;
}

TEST(DenseCholesky, FactorAndSolveMatchTheMatrixOnBothPaths) {
  // 100: Eigen; 512 and 700: LAPACK tiles, with partial tiles at the edges; 130 right-hand
  // sides: three solve blocks, the last partial.
  for (const std::size_t n : {std::size_t{100}, detail::kLapackMinSize, std::size_t{700}}) {
    const Problem p = randomProblem(n, 130, static_cast<unsigned>(n));
    Eigen::MatrixXd l;
    const Eigen::MatrixXd x = factorAndSolve(p, &l);
    const Eigen::MatrixXd a = p.a.topRows(p.a.cols());
    EXPECT_LE((l * l.transpose() - a).cwiseAbs().maxCoeff(), 1e-13 * a.cwiseAbs().maxCoeff()) << n;
    EXPECT_LE((a * x - p.b).cwiseAbs().maxCoeff(), 1e-12 * p.b.cwiseAbs().maxCoeff()) << n;
    // The padding rows below the matrix are not touched.
    Eigen::MatrixXd copy = p.a;
    const DenseCholesky chol(copy.data(), n, n + 7);
    EXPECT_EQ(copy.bottomRows(7), p.a.bottomRows(7)) << n;
    // rcond: an estimate within a small factor of the true 1-norm reciprocal condition number.
    const Eigen::MatrixXd inverse = a.inverse();
    const double norm1 = a.cwiseAbs().colwise().sum().maxCoeff();
    const double truth = 1.0 / (norm1 * inverse.cwiseAbs().colwise().sum().maxCoeff());
    EXPECT_GE(chol.rcond(), 0.1 * truth) << n;
    EXPECT_LE(chol.rcond(), 10.0 * truth) << n;
  }
}

// The RBF system factorises n − 4 unknowns (the polynomial's 4 are eliminated), so the BLAS
// work buffers count from n = kLapackMinSize + 4 on: 512..515 centers once were charged them
// (2 × 128 MiB) for an Eigen factorisation and refused under a tight memory limit.
TEST(DenseCholesky, RbfMemoryEstimateChargesTheBlasBuffersOnlyOnTheLapackPath) {
  const auto matrixOnly = [](double n) { return 1.1 * sizeof(double) * n * n + 4e6; };
  for (std::size_t n = kLapackMinSize - 1; n < kLapackMinSize + 4; ++n)
    EXPECT_EQ(RbfSystem::memoryEstimate(n), matrixOnly(static_cast<double>(n))) << n;
  const std::size_t lapack = kLapackMinSize + 4;
  EXPECT_EQ(RbfSystem::memoryEstimate(lapack),
            matrixOnly(static_cast<double>(lapack)) + denseCholeskyWorkspaceBytes(kLapackMinSize));
  EXPECT_GT(denseCholeskyWorkspaceBytes(kLapackMinSize), 0.0);
}

TEST(DenseCholesky, IndefiniteMatricesAreNotOk) {
  for (const std::size_t n : {std::size_t{50}, std::size_t{800}}) {
    Problem p = randomProblem(n, 1, 3);
    p.a(static_cast<Eigen::Index>(n) - 3, static_cast<Eigen::Index>(n) - 3) = -1.0;
    const DenseCholesky chol(p.a.data(), n, n + 7);
    EXPECT_FALSE(chol.ok()) << n;
  }
}

TEST(DenseCholesky, SameBitsForAnyThreadCount) {
  const Problem p = randomProblem(900, 70, 11);
  const test::OpenBlasThreads openblas;
  const int before = openblas.available() ? openblas.get() : 1;
  Eigen::MatrixXd reference, factor;
  {
    tbb::task_arena one(1);
    if (openblas.available()) openblas.set(1);
    one.execute([&] { reference = factorAndSolve(p, &factor); });
  }
  for (const int threads : {2}) {
    tbb::task_arena arena(threads);
    if (openblas.available()) openblas.set(threads);
    Eigen::MatrixXd x, l;
    arena.execute([&] { x = factorAndSolve(p, &l); });
    EXPECT_EQ(x, reference) << threads;
    EXPECT_EQ(l, factor) << threads;
    // SerialBlas restored the caller's OpenBLAS thread count.
    if (openblas.available()) {
      EXPECT_EQ(openblas.get(), threads);
    }
  }
  if (openblas.available()) openblas.set(before);
}

}  // namespace
}  // namespace spacewarp
