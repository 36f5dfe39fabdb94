#pragma once
// The nonlinear least-squares problem of one DeformationGraph::solve(): the data that fix it
// (nodes, free unknowns, handles with their nodes and weights, regulariser edges, weights) and
// its energy terms with their gradient. Lengths are in units of GraphIndex::unit.

#include <cstdint>
#include <utility>
#include <vector>

#include <spacewarp/core/math.h>
#include <spacewarp/nonlinear/detail/graph_index.h>

namespace spacewarp::detail {

struct Problem {
  const GraphIndex& g;
  // Node positions, handles and targets (and the translations solved for) are in units of
  // g.unit, so that the problem, and every step of its solution, is the same at any scale.
  std::vector<Vec3> nodes;
  std::vector<int> var;  // per node: first unknown (12 per free node), −1 if pinned
  int unknowns = 0;
  double sRot, sReg, sCon;  // square roots of the weights
  // Handles: k nodes and weights each.
  std::vector<std::uint32_t> hNodes;
  std::vector<double> hWeights;
  std::vector<Vec3> handles, targets;
  // Directed regulariser edges (j, k) with j free.
  std::vector<std::pair<std::uint32_t, std::uint32_t>> regEdges;
  std::vector<std::uint32_t> freeNodes;

  // The unweighted energies at (A, t) and, if `rhs` is given (`unknowns` entries), −Jᵀf: the
  // right-hand side of the Gauss-Newton equations. The unknowns of a node are
  // A[0][0..2], A[1][0..2], A[2][0..2] (GLM columns), t[0..2]. Serial: the same sums in the
  // same order on every call, whatever the thread count.
  void evaluate(const std::vector<Mat3>& a, const std::vector<Vec3>& t, double& eRot, double& eReg,
                double& eCon, double* rhs) const;

 private:
  // The three terms, each adding to its energy and to rhs (if given), in this order.
  void addRotation(const std::vector<Mat3>& a, double& eRot, double* rhs) const;
  void addRegularization(const std::vector<Mat3>& a, const std::vector<Vec3>& t, double& eReg,
                         double* rhs) const;
  void addConstraints(const std::vector<Mat3>& a, const std::vector<Vec3>& t, double& eCon,
                      double* rhs) const;
};

}  // namespace spacewarp::detail
