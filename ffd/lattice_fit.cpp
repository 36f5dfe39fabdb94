#include <spacewarp/ffd/lattice_fit.h>

#include <algorithm>
#include <cmath>
#include <string>

#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>

#include <spacewarp/core/detail/memory_budget.h>
#include <spacewarp/core/errors.h>
#include <spacewarp/core/geometry.h>
#include <spacewarp/ffd/lattice_warp.h>

namespace spacewarp {

namespace {

using Triplet = Eigen::Triplet<double>;

// Entries of the LDLᵀ factor per control point, over count^(1/3): about 7.5 measured (peak
// RSS) on cubic B-spline lattices of 20³ and 30³ with Eigen's AMD ordering; rounded up.
constexpr double kFillPerControlPoint = 10.0;

// The graph Laplacian of the 6-neighbourhood of the grid, scaled by `scale`, into `triplets`;
// returns the number of neighbour pairs.
std::size_t addNeighbourLaplacian(const Lattice& lattice, double scale,
                                  std::vector<Triplet>& triplets) {
  const auto [l, m, n] = lattice.resolution();
  std::size_t pairs = 0;
  auto pair = [&](std::size_t a, std::size_t b) {
    const auto ia = static_cast<Eigen::Index>(a);
    const auto ib = static_cast<Eigen::Index>(b);
    triplets.emplace_back(ia, ia, scale);
    triplets.emplace_back(ib, ib, scale);
    triplets.emplace_back(ia, ib, -scale);
    triplets.emplace_back(ib, ia, -scale);
    ++pairs;
  };
  for (int k = 0; k < n; ++k)
    for (int j = 0; j < m; ++j)
      for (int i = 0; i < l; ++i) {
        const std::size_t c = lattice.index(i, j, k);
        if (i + 1 < l) pair(c, lattice.index(i + 1, j, k));
        if (j + 1 < m) pair(c, lattice.index(i, j + 1, k));
        if (k + 1 < n) pair(c, lattice.index(i, j, k + 1));
      }
  return pairs;
}

// Bytes the fit needs: the normal matrix (summed, permuted and factorised; about 12 bytes per
// stored entry) plus the Laplacian's triplets. The LDLᵀ fill of a grid Laplacian grows as
// count^(4/3) (the separators of a 3D grid); a Bernstein lattice's rows are dense, and so is
// its factor.
double fitBytes(const Lattice& lattice, std::size_t constraints) {
  const double count = static_cast<double>(lattice.controlPointCount());
  const double nz = static_cast<double>(lattice.maxNonZeros());
  const double normal = 7.0 * count + std::min(double(constraints) * nz * nz, count * count);
  const double factor = lattice.params().basis == LatticeBasis::Bernstein
                            ? count * count / 2.0
                            : count * std::cbrt(count) * kFillPerControlPoint;
  return 12.0 * (3.0 * normal + factor) + 16.0 * 12.0 * count;
}

void checkFitInput(std::span<const Vec3> from, std::span<const Vec3> to,
                   const LatticeFitOptions& options, const std::string& who) {
  if (from.size() != to.size())
    throw InvalidInput(who + std::to_string(from.size()) + " points but " +
                       std::to_string(to.size()) + " targets");
  if (from.empty()) throw InvalidInput(who + "no constraints");
  if (!std::isfinite(options.smoothness) || options.smoothness < 0.0)
    throw InvalidInput(who + "the smoothness must be finite and non-negative");
  for (std::size_t k = 0; k < from.size(); ++k) {
    if (!isFinite(from[k]))
      throw InvalidInput(who + "point " + std::to_string(k) + " is not finite");
    if (!isFinite(to[k]))
      throw InvalidInput(who + "target " + std::to_string(k) + " is not finite");
  }
}

// The normal equations (WᵀW / K + λ/E L) D = Wᵀ R / K of the fit, with R_k = y_k − x_k, K the
// constraint count, L the neighbour Laplacian and E its number of pairs.
struct NormalEquations {
  Eigen::SparseMatrix<double> matrix;
  Eigen::MatrixXd rhs;  // count × 3
};

NormalEquations assembleNormalEquations(const Lattice& lattice, std::span<const Vec3> from,
                                        std::span<const Vec3> to, double smoothness,
                                        const std::string& who) {
  const auto cols = static_cast<Eigen::Index>(lattice.controlPointCount());
  const double inverseK = 1.0 / static_cast<double>(from.size());
  std::vector<Triplet> triplets;
  std::vector<Triplet> laplacian;
  const std::size_t pairs = addNeighbourLaplacian(lattice, 1.0, laplacian);
  NormalEquations equations{Eigen::SparseMatrix<double>(cols, cols),
                            Eigen::MatrixXd::Zero(cols, 3)};
  Eigen::MatrixXd& rhs = equations.rhs;
  std::vector<SparseWeight> row(lattice.maxNonZeros());
  bool reached = false;
  // WᵀW is summed in chunks of triplets so that dense (Bernstein) rows do not hold
  // K × rows² triplets at once.
  auto flush = [&] {
    Eigen::SparseMatrix<double> part(cols, cols);
    part.setFromTriplets(triplets.begin(), triplets.end());
    equations.matrix += part;
    triplets.clear();
  };
  for (std::size_t k = 0; k < from.size(); ++k) {
    if (triplets.size() > (std::size_t{1} << 22)) flush();
    const std::size_t nz = lattice.sparseWeights(from[k], row);
    const Vec3 r = to[k] - from[k];
    for (std::size_t a = 0; a < nz; ++a) {
      if (row[a].weight == 0.0) continue;
      reached = true;
      const auto ca = static_cast<Eigen::Index>(row[a].column);
      rhs.row(ca) += inverseK * row[a].weight * Eigen::RowVector3d(r.x, r.y, r.z);
      for (std::size_t b = 0; b < nz; ++b) {
        if (row[b].weight == 0.0) continue;
        triplets.emplace_back(ca, static_cast<Eigen::Index>(row[b].column),
                              inverseK * row[a].weight * row[b].weight);
      }
    }
  }
  if (!reached) throw InvalidInput(who + "no constraint point lies where the lattice moves points");
  const double lambda = pairs > 0 ? smoothness / static_cast<double>(pairs) : 0.0;
  for (const Triplet& t : laplacian) triplets.emplace_back(t.row(), t.col(), lambda * t.value());
  flush();
  return equations;
}

// The displacements D (count × 3); SolverError if the equations are singular.
Eigen::MatrixXd solveNormalEquations(const NormalEquations& equations, const std::string& who) {
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> solver(equations.matrix);
  if (solver.info() != Eigen::Success)
    throw SolverError(who + "the normal equations could not be factorised");
  const Eigen::MatrixXd d = solver.solve(equations.rhs);
  if (solver.info() != Eigen::Success || !d.allFinite())
    throw SolverError(who +
                      "the normal equations are singular (raise the smoothness, or add "
                      "constraints near every control point)");
  // Singular LDLᵀ factors can still "succeed": check the pivots.
  const auto& pivots = solver.vectorD();
  const double largest = pivots.cwiseAbs().maxCoeff();
  if (!(pivots.minCoeff() > 1e-13 * largest))
    throw SolverError(who +
                      "the normal equations are singular (raise the smoothness, or add "
                      "constraints near every control point)");
  return d;
}

// The largest and the RMS distance between the warped constraint points and their targets.
void measureResiduals(const Lattice& lattice, std::span<const Vec3> from, std::span<const Vec3> to,
                      ControlPointFit& fit) {
  const LatticeWarp warp(lattice, fit.controlPoints);
  std::vector<Vec3> moved(from.size());
  warp.applyBatch(from, moved);
  double sum = 0.0;
  for (std::size_t k = 0; k < from.size(); ++k) {
    const double e = glm::length(moved[k] - to[k]);
    sum += e * e;
    fit.maxResidual = std::max(fit.maxResidual, e);
  }
  fit.rmsResidual = std::sqrt(sum * (1.0 / static_cast<double>(from.size())));
}

}  // namespace

ControlPointFit fitControlPoints(const Lattice& lattice, std::span<const Vec3> from,
                                 std::span<const Vec3> to, const LatticeFitOptions& options) {
  const std::string who = "fitControlPoints: ";
  checkFitInput(from, to, options, who);
  const std::size_t count = lattice.controlPointCount();
  const auto [l, m, n] = lattice.resolution();
  detail::checkMemory(fitBytes(lattice, from.size()),
                      who + "the resolution " + std::to_string(l) + " x " + std::to_string(m) +
                          " x " + std::to_string(n) + " (" + std::to_string(count) +
                          " control points)");
  ProgressTracker tracker(options.progress, "fit lattice", 2);
  auto system = assembleNormalEquations(lattice, from, to, options.smoothness, who);
  tracker.advance();
  const Eigen::MatrixXd d = solveNormalEquations(system, who);
  tracker.finish();

  ControlPointFit fit;
  fit.controlPoints.resize(count);
  const auto rest = lattice.restControlPoints();
  for (std::size_t c = 0; c < count; ++c) {
    const auto ci = static_cast<Eigen::Index>(c);
    fit.controlPoints[c] = rest[c] + Vec3(d(ci, 0), d(ci, 1), d(ci, 2));
  }
  measureResiduals(lattice, from, to, fit);
  return fit;
}

Lattice fitLattice(std::span<const Vec3> points, double padding, std::array<int, 3> resolution,
                   LatticeBasis basis) {
  const std::string who = "fitLattice: ";
  if (points.empty()) throw InvalidInput(who + "no points");
  for (std::size_t i = 0; i < points.size(); ++i)
    if (!isFinite(points[i]))
      throw InvalidInput(who + "point " + std::to_string(i) + " is not finite");
  if (!std::isfinite(padding) || padding < 0.0)
    throw InvalidInput(who + "the padding must be finite and non-negative");
  const BoundingBox box = boundingBox(points);
  const double grow = padding * box.diagonal();
  LatticeOptions p;
  p.origin = box.min - Vec3(grow);
  p.extents = box.extent() + Vec3(2.0 * grow);
  for (int a = 0; a < 3; ++a) {
    if (!(p.extents[a] > 0.0))
      throw InvalidInput(who + "the padded box is flat along axis " + std::to_string(a) +
                         " (use a positive padding)");
  }
  p.resolution = resolution;
  p.basis = basis;
  return Lattice(p);
}

}  // namespace spacewarp
