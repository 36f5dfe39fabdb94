#pragma once
// Bind once, deform every frame: the weights of a fixed point set with respect to some
// Coordinates, stored as a dense or sparse matrix and re-posed by a matrix product.

#include <memory>
#include <span>
#include <vector>

#include <Eigen/Core>
#include <Eigen/SparseCore>

#include <spacewarp/core/coordinates.h>
#include <spacewarp/core/progress.h>

namespace spacewarp {

/// The weight matrix W (pointCount() × columnCount()) of a fixed point set.
/// deform(posed) gives x_i + Σ_c W_ic (C_c(posed) − C_c(rest)) for every point i.
class Binding {
 public:
  using DenseMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
  using SparseMatrix = Eigen::SparseMatrix<double, Eigen::RowMajor, std::int64_t>;

  /// Computes the weights of `points` (n points, world units) in parallel; the result does not
  /// depend on the thread count. Storage is sparse (CSR) when the coordinates have at most a
  /// quarter of their columns non-zero per point, dense row-major otherwise. Throws
  /// InvalidInput if `coordinates` is null or a point is not finite (naming its index).
  /// Reports the stage "bind" to `progress`; a cancel throws Cancelled.
  Binding(std::shared_ptr<const Coordinates> coordinates, std::span<const Vec3> points,
          const ProgressCallback& progress = {});

  std::size_t pointCount() const { return restPoints_.size(); }
  std::size_t columnCount() const { return coordinates_->columnCount(); }
  bool isSparse() const { return sparse_; }

  /// The points as bound (n entries, world units).
  std::span<const Vec3> restPoints() const { return restPoints_; }
  const Coordinates& coordinates() const { return *coordinates_; }

  /// The weight matrix; dense() is empty when isSparse(), sparse() is empty otherwise.
  const DenseMatrix& dense() const { return dense_; }
  const SparseMatrix& sparse() const { return sparseMatrix_; }

  /// Deformed positions for the posed control points (controlPointCount() entries) into `out`
  /// (pointCount() entries). Parallel, deterministic. Throws InvalidInput on size mismatches
  /// or non-finite posed points.
  void deform(std::span<const Vec3> posed, std::span<Vec3> out) const;
  std::vector<Vec3> deform(std::span<const Vec3> posed) const;

 private:
  std::shared_ptr<const Coordinates> coordinates_;
  std::vector<Vec3> restPoints_;
  std::vector<Vec3> restColumns_;  // C(rest), columnCount() entries
  bool sparse_ = false;
  DenseMatrix dense_;
  SparseMatrix sparseMatrix_;
};

}  // namespace spacewarp
