#include <spacewarp/surface/laplacian_editing.h>

#include <spacewarp/core/detail/sparse_cholesky.h>
#include <spacewarp/core/errors.h>
#include <spacewarp/surface/cotan_laplacian.h>
#include <spacewarp/surface/detail/edit_problem.h>

namespace spacewarp {

struct LinearEditor::Impl {
  detail::EditProblem problem;
  Eigen::SparseMatrix<double> freeFixed;  // A_fc
  Eigen::MatrixXd restFixed;              // rest positions of the fixed vertices
  detail::SparseCholesky factor{{"LinearEditor", "check the mesh for degenerate parts"}};
};

LinearEditor::LinearEditor(std::span<const Vec3> positions,
                           std::span<const std::array<std::uint32_t, 3>> triangles,
                           std::span<const std::uint32_t> constrained,
                           const LinearEditOptions& options)
    : impl_(std::make_unique<Impl>()) {
  auto& p = impl_->problem;
  p = detail::makeEditProblem(positions, triangles, constrained, "LinearEditor");
  // The displacement d solves A_ff d_f = −A_fc d_c with A = L (harmonic) or L M⁻¹ L (biharmonic).
  Eigen::SparseMatrix<double> a = p.laplacian;
  if (options.method == LinearEditMethod::BiLaplacian) {
    const Eigen::VectorXd inverseMass = massMatrixDiagonal(positions, triangles).cwiseInverse();
    a = (p.laplacian * inverseMass.asDiagonal() * p.laplacian).pruned();
  }
  impl_->freeFixed = p.freeFixedBlock(a);
  std::vector<Vec3> restFixed;
  for (std::uint32_t v : p.constrained) restFixed.push_back(p.rest[v]);
  impl_->restFixed = p.fixedPositions(restFixed, "LinearEditor");
  if (p.freeVertices.empty()) return;
  const Eigen::SparseMatrix<double> lower = p.freeBlockLower(a);
  impl_->factor.analyzePattern(lower);
  if (!impl_->factor.factorize(lower)) {
    throw SolverError(
        "LinearEditor: the system is not positive definite (degenerate triangles joining the "
        "free region?)");
  }
}

LinearEditor::~LinearEditor() = default;
LinearEditor::LinearEditor(LinearEditor&&) noexcept = default;
LinearEditor& LinearEditor::operator=(LinearEditor&&) noexcept = default;

std::vector<Vec3> LinearEditor::solve(std::span<const Vec3> targets) {
  const auto& p = impl_->problem;
  const Eigen::MatrixXd fixed = p.fixedPositions(targets, "LinearEditor::solve");
  Eigen::MatrixXd freeRest(static_cast<Eigen::Index>(p.freeVertices.size()), 3);
  for (std::size_t k = 0; k < p.freeVertices.size(); ++k) {
    const Vec3& x = p.rest[p.freeVertices[k]];
    freeRest.row(static_cast<Eigen::Index>(k)) << x.x, x.y, x.z;
  }
  if (p.freeVertices.empty()) return p.assemble(freeRest, fixed);
  // The displacements relative to their mean over the constrained vertices: a common
  // translation (a constant, which the operator maps to 0) is then carried exactly, not through
  // the factor's rounding.
  Eigen::MatrixXd displacement = fixed - impl_->restFixed;
  const Eigen::RowVector3d mean =
      displacement.topRows(Eigen::Index(p.constrained.size())).colwise().mean();
  displacement.rowwise() -= mean;
  const Eigen::MatrixXd rhs = -(impl_->freeFixed * displacement);
  Eigen::MatrixXd free = impl_->factor.solve(rhs);
  free.rowwise() += mean;
  return p.assemble(freeRest + free, fixed);
}

std::span<const std::uint32_t> LinearEditor::heldVertices() const { return impl_->problem.held; }

}  // namespace spacewarp
