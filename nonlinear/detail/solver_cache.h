#pragma once
// The deformation graph's normal equations JᵀJ δ = −Jᵀf and their sparse Cholesky factor,
// kept between DeformationGraph::solve() calls.

#include <cstdint>
#include <vector>

#include <Eigen/Core>
#include <Eigen/SparseCore>

#include <spacewarp/core/detail/sparse_cholesky.h>
#include <spacewarp/core/math.h>
#include <spacewarp/nonlinear/detail/graph_problem.h>

namespace spacewarp::detail {

constexpr int kBlockSlots = 78;  // lower triangle of a node's 12 x 12 diagonal block

// What solve() keeps between calls, all of it a function of the problem's A-independent data
// (free nodes, handles, their weights, w_reg, w_con), which is its key:
//  - the sparsity pattern of JᵀJ (lower triangle; 12 unknowns per free node) and the values of
//    its constant part: the regulariser and the constraints are linear in the unknowns, so only
//    the rotation term, which lives in each node's 12 x 12 diagonal block, changes with A;
//  - the sparse Cholesky's symbolic analysis of that pattern (fill-reducing ordering,
//    supernodes);
//  - the last numeric factor and the diagonal blocks it was computed from. A later matrix with
//    the same key and bit-identical diagonal blocks is the same matrix: its factor is reused
//    instead of recomputed (the first iteration of a solve from the rest state with the same
//    handles, e.g. while only the targets move). Reuse gives the same bits as refactorising, so
//    every solve stays a pure function of its input and state.
struct SolverCache {
  // The key.
  std::vector<int> var;
  std::vector<std::uint32_t> hNodes;
  std::vector<double> hWeights;
  std::vector<Vec3> handles;
  double sReg = 0.0, sCon = 0.0;
  bool valid = false;

  Eigen::SparseMatrix<double> lower;  // the pattern; values written in place per iteration
  std::vector<double> constant;       // per slot: regulariser + constraints
  std::vector<int> blockSlots;        // per free node: kBlockSlots slots, column by column
  std::vector<int> diagonal;          // per unknown: its diagonal slot

  SparseCholesky cholesky;
  bool factorValid = false;
  std::vector<double> factoredBlocks;  // the diagonal blocks' values at the last factorisation

  SolverCache();

  bool matches(const Problem& p) const;

  // Rebuilds pattern, constant part and analysis for `p`. Throws SolverError if the analysis
  // fails (the cache is then invalid).
  void build(const Problem& p);

  // Writes JᵀJ at A into `lower` (its diagonal blocks: constant part + rotation term) and
  // returns the undamped diagonal in `diag`.
  void assemble(const Problem& p, const std::vector<Mat3>& a, Eigen::VectorXd& diag);

  // Sets the diagonal to diag + shift.
  void damp(const Eigen::VectorXd& diag, double shift);

  // Whether the current factor is that of `lower` as it stands.
  bool factorIsCurrent() const;

  // Factorises `lower`; false if it is not (numerically) positive definite.
  bool factorize();

 private:
  void buildPattern(const Problem& p);
  void indexBlocks(const Problem& p);
  void buildConstant(const Problem& p);
};

}  // namespace spacewarp::detail
