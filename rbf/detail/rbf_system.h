#pragma once
// Internals shared by RbfWarp and RbfCoordinates: validation and merging of the centers, and
// the one factorisation of the RBF saddle-point system. Not a user-facing API (namespace detail).

#include <optional>
#include <span>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Householder>
#include <Eigen/QR>

#include <spacewarp/core/math.h>
#include <spacewarp/rbf/detail/dense_cholesky.h>
#include <spacewarp/rbf/kernels.h>

namespace spacewarp::detail {

/// The centers of an RBF fit after validation and merging of duplicates.
struct RbfCenters {
  /// Distinct centers: one per group of coinciding handles (in the order of each group's first
  /// handle), then the fixed centers that coincide with no handle.
  std::vector<Vec3> unique;
  /// How many of `unique` come from handles (the first ones).
  std::size_t handleCenters = 0;
  /// Per input handle: its index in `unique`.
  std::vector<std::size_t> handleColumn;
  /// Per unique handle center: how many input handles it merges.
  std::vector<std::size_t> multiplicity;
  /// Per unique center: target − center (zero for fixed centers); empty without targets.
  std::vector<Vec3> displacement;
};

/// Validates and merges the centers (n handles, their targets if `targets` is not null, and
/// the fixed centers; world units). Throws InvalidInput, prefixed with `who`, for an empty
/// handle list, mismatched sizes, non-finite points (naming the index) and coinciding centers
/// whose targets differ (naming both). Without targets (coordinates), coinciding handles are
/// merged and a fixed center that coincides with a handle is dropped.
RbfCenters prepareRbfCenters(const std::string& who, std::span<const Vec3> handles,
                             const std::span<const Vec3>* targets, std::span<const Vec3> fixed,
                             const RbfOptions& options);

/// Throws InvalidInput (prefixed with `who`) unless the distinct `centers` hold at least 4
/// affinely independent points, as the linear polynomial of the fit needs.
void checkRbfPolynomial(const std::string& who, std::span<const Vec3> centers);

/// The factorisation of [[Φ + σλI, P], [Pᵀ, 0]] (see RbfOptions::smoothing) by null-space
/// reduction: with P = Q [R; 0] (Householder QR of the n × 4 polynomial block), the kernel
/// weights are w = Q [0; u] with (σ Q₂ᵀ Φ Q₂ + λ I) u = σ Q₂ᵀ D, an SPD system (the kernels are
/// conditionally definite of order ≤ 2 with sign σ) factorised once by Cholesky (LAPACK on the
/// BLAS, tiled over threads: DenseCholesky), in place in QᵀΦQ, and the
/// polynomial coefficients follow from R a = Q₁ᵀ (D − Φ w). The polynomial basis is
/// q(x) = [1, (x − origin) / length], centered and scaled for conditioning.
// How many RBF systems (fits) this process has set up: tests check that loading a saved fit
// fits nothing.
std::size_t rbfSystemCount();

class RbfSystem {
 public:
  /// The peak memory (bytes) of building the system for n centers: one dense n × n matrix (the
  /// kernel matrix, transformed and factorised in place), and the BLAS work buffers of the
  /// threads (denseCholeskyWorkspaceBytes).
  static double memoryEstimate(std::size_t n);

  /// Throws InvalidInput (fewer than 4 affinely independent centers, or a system larger than
  /// the memory available: memoryEstimate(), detail::checkMemory) or SolverError (a system that
  /// is numerically singular after all).
  RbfSystem(const std::string& who, std::span<const Vec3> centers, const RbfOptions& options);
  RbfSystem(const RbfSystem&) = delete;  // cholesky_ points into factor_
  RbfSystem& operator=(const RbfSystem&) = delete;

  std::size_t size() const { return n_; }
  const Vec3& origin() const { return origin_; }
  double length() const { return length_; }

  /// Solves for the right-hand sides D (n × m): kernel weights W (n × m) and polynomial
  /// coefficients A (4 × m) in the basis q.
  void solve(const Eigen::MatrixXd& d, Eigen::MatrixXd& w, Eigen::MatrixXd& a) const;

 private:
  std::size_t n_ = 0;
  Vec3 origin_{0.0};
  double length_ = 1.0;
  double sigma_ = 1.0;
  Eigen::HouseholderQR<Eigen::MatrixXd> qr_;  // of P
  Eigen::MatrixXd b12_;                       // 4 × (n − 4): the top-right block of QᵀΦQ
  // n × n: QᵀΦQ, its bottom-right (n − 4) × (n − 4) block overwritten by the Cholesky factor
  // of σ Q₂ᵀ Φ Q₂ + λ I (lower triangle).
  Eigen::MatrixXd factor_;
  std::optional<DenseCholesky> cholesky_;
};

}  // namespace spacewarp::detail
