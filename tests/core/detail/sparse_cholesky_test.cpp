// Tests of the sparse Cholesky wrapper (core/detail/sparse_cholesky.h): solves with one and
// several right-hand sides under both orderings, refactorisation on a kept analysis, a matrix
// that is not positive definite, CHOLMOD failures as SolverError (OutOfMemory when memory ran
// out), and misuse.

#include <spacewarp/core/detail/sparse_cholesky.h>

#include <cstdlib>
#include <stdexcept>
#include <vector>

#include <SuiteSparse_config.h>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <spacewarp/core/errors.h>

using namespace spacewarp;
using detail::CholeskyOrdering;
using detail::SparseCholesky;
using detail::SparseCholeskyOptions;
using ::testing::HasSubstr;

namespace {

// The lower triangle of the 7-point Laplacian of an m³ grid (zero outside it) plus shift · I:
// symmetric positive definite for shift >= 0. m = 8 (512 unknowns) makes real supernodes.
Eigen::SparseMatrix<double> gridLaplacian(int m, double shift) {
  const auto id = [m](int x, int y, int z) { return x + m * (y + m * z); };
  std::vector<Eigen::Triplet<double>> entries;
  for (int z = 0; z < m; ++z) {
    for (int y = 0; y < m; ++y) {
      for (int x = 0; x < m; ++x) {
        const int i = id(x, y, z);
        entries.emplace_back(i, i, 6.0 + shift);
        if (x + 1 < m) entries.emplace_back(id(x + 1, y, z), i, -1.0);
        if (y + 1 < m) entries.emplace_back(id(x, y + 1, z), i, -1.0);
        if (z + 1 < m) entries.emplace_back(id(x, y, z + 1), i, -1.0);
      }
    }
  }
  Eigen::SparseMatrix<double> lower(m * m * m, m * m * m);
  lower.setFromTriplets(entries.begin(), entries.end());
  return lower;
}

// |A x − b| / |b| for the symmetric A whose lower triangle `lower` holds.
double relativeResidual(const Eigen::SparseMatrix<double>& lower, const Eigen::MatrixXd& x,
                        const Eigen::MatrixXd& b) {
  const Eigen::MatrixXd ax = lower.selfadjointView<Eigen::Lower>() * x;
  return (ax - b).norm() / b.norm();
}

SparseCholeskyOptions optionsWith(CholeskyOrdering ordering) {
  SparseCholeskyOptions o;
  o.caller = "SparseCholeskyTest";
  o.advice = "try something smaller";
  o.ordering = ordering;
  return o;
}

class SparseCholeskyOrderings : public ::testing::TestWithParam<CholeskyOrdering> {};

TEST_P(SparseCholeskyOrderings, SolvesASmallSpdSystem) {
  const Eigen::SparseMatrix<double> a = gridLaplacian(8, 0.1);
  SparseCholesky cholesky(optionsWith(GetParam()));
  cholesky.analyzePattern(a);
  ASSERT_TRUE(cholesky.factorize(a));

  srand(7);
  const Eigen::VectorXd b = Eigen::VectorXd::Random(a.rows());
  const Eigen::VectorXd x = cholesky.solve(b);
  ASSERT_EQ(x.size(), a.rows());
  EXPECT_LE(relativeResidual(a, x, b), 1e-12);

  const Eigen::MatrixXd bs = Eigen::MatrixXd::Random(a.rows(), 5);
  const Eigen::MatrixXd xs = cholesky.solve(bs);
  ASSERT_EQ(xs.rows(), a.rows());
  ASSERT_EQ(xs.cols(), 5);
  EXPECT_LE(relativeResidual(a, xs, bs), 1e-12);
  // A column of a multi-column solve is the single solve of that column, up to rounding (the
  // BLAS-3 and BLAS-2 kernels sum in different orders).
  const Eigen::VectorXd single = cholesky.solve(Eigen::VectorXd(bs.col(2)));
  EXPECT_LE((xs.col(2) - single).norm(), 1e-12 * single.norm());
}

TEST_P(SparseCholeskyOrderings, RefactorisesNewValuesOnTheKeptAnalysis) {
  Eigen::SparseMatrix<double> a = gridLaplacian(6, 1.0);
  SparseCholesky cholesky(optionsWith(GetParam()));
  cholesky.analyzePattern(a);
  ASSERT_TRUE(cholesky.factorize(a));
  a = gridLaplacian(6, 0.01);  // same pattern, other values
  ASSERT_TRUE(cholesky.factorize(a));
  const Eigen::VectorXd b = Eigen::VectorXd::LinSpaced(a.rows(), -1.0, 2.0);
  EXPECT_LE(relativeResidual(a, cholesky.solve(b), b), 1e-12);
}

INSTANTIATE_TEST_SUITE_P(Orderings, SparseCholeskyOrderings,
                         ::testing::Values(CholeskyOrdering::CholmodDefault,
                                           CholeskyOrdering::Amd));

TEST(SparseCholesky, NotPositiveDefiniteIsFalse) {
  Eigen::SparseMatrix<double> a = gridLaplacian(5, 0.5);
  a.coeffRef(40, 40) = -3.0;
  SparseCholesky cholesky(optionsWith(CholeskyOrdering::Amd));
  cholesky.analyzePattern(a);
  const Eigen::VectorXd b = Eigen::VectorXd::Ones(a.rows());
  EXPECT_FALSE(cholesky.factorize(a));
  // No factor: solving is a programming error, not a silent result.
  EXPECT_THROW((void)cholesky.solve(b), std::logic_error);
  // The analysis is kept: a positive definite matrix of the same pattern factorises.
  a.coeffRef(40, 40) = 7.0;
  EXPECT_TRUE(cholesky.factorize(a));
  EXPECT_LE(relativeResidual(a, cholesky.solve(b), b), 1e-12);
}

TEST(SparseCholesky, MisuseIsALogicError) {
  const Eigen::SparseMatrix<double> a = gridLaplacian(3, 1.0);
  const Eigen::VectorXd b = Eigen::VectorXd::Ones(a.rows());
  SparseCholesky cholesky;
  EXPECT_THROW(cholesky.factorize(a), std::logic_error);
  EXPECT_THROW((void)cholesky.solve(b), std::logic_error);
  cholesky.analyzePattern(a);
  EXPECT_THROW((void)cholesky.solve(b), std::logic_error);
}

// CHOLMOD's allocations fail after a given number of successes: every failure (analysis,
// factorisation, solve) is a SolverError naming the caller, the step and the advice.
long allocationsLeft = -1;  // < 0: no limit
bool spend() {
  if (allocationsLeft == 0) return false;
  if (allocationsLeft > 0) --allocationsLeft;
  return true;
}
void* failingMalloc(std::size_t n) { return spend() ? std::malloc(n) : nullptr; }
void* failingCalloc(std::size_t n, std::size_t size) {
  return spend() ? std::calloc(n, size) : nullptr;
}
void* failingRealloc(void* p, std::size_t n) { return spend() ? std::realloc(p, n) : nullptr; }

TEST(SparseCholesky, CholmodFailuresAreSolverErrors) {
  const Eigen::SparseMatrix<double> a = gridLaplacian(8, 0.1);
  const Eigen::MatrixXd b = Eigen::MatrixXd::Ones(a.rows(), 3);
  const auto saved = SuiteSparse_config;
  SuiteSparse_config.malloc_func = failingMalloc;
  SuiteSparse_config.calloc_func = failingCalloc;
  SuiteSparse_config.realloc_func = failingRealloc;
  std::vector<std::string> steps;
  bool solved = false;
  for (long budget = 0; budget < 2000 && !solved; ++budget) {
    SparseCholesky cholesky(optionsWith(CholeskyOrdering::CholmodDefault));
    allocationsLeft = budget;
    try {
      cholesky.analyzePattern(a);
      const bool factored = cholesky.factorize(a);
      if (factored) (void)cholesky.solve(b);
      solved = factored;
    } catch (const SolverError& e) {
      const std::string message = e.what();
      EXPECT_THAT(message, HasSubstr("SparseCholeskyTest: the sparse Cholesky ")) << budget;
      EXPECT_THAT(message, HasSubstr("(out of memory); try something smaller")) << budget;
      // Every failure here is an allocation: reported as such (exit 3 in the command line).
      EXPECT_NE(dynamic_cast<const OutOfMemory*>(&e), nullptr) << budget << ": " << message;
      for (const char* step : {"analysis", "factorisation", "solve"})
        if (message.find(std::string("Cholesky ") + step + " failed") != std::string::npos &&
            (steps.empty() || steps.back() != step))
          steps.push_back(step);
    }
    allocationsLeft = -1;
  }
  SuiteSparse_config = saved;
  EXPECT_TRUE(solved);
  EXPECT_THAT(steps, ::testing::ElementsAre("analysis", "factorisation", "solve"));
}

}  // namespace
