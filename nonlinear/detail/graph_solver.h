#pragma once
// The body of DeformationGraph::solve(): Levenberg-Marquardt (damped Gauss-Newton) on the
// problem of graph_problem.h over the normal equations of solver_cache.h, in stages: input
// validation, problem set-up, the rigid start, the iterations, and the way back to world units.

#include <memory>
#include <span>
#include <vector>

#include <spacewarp/core/math.h>
#include <spacewarp/nonlinear/deformation_graph.h>
#include <spacewarp/nonlinear/detail/graph_index.h>
#include <spacewarp/nonlinear/detail/solver_cache.h>

namespace spacewarp::detail {

// Throws InvalidInput for mismatched sizes, non-finite handles or targets, handles beyond
// reach, and invalid options (see DeformationGraph::solve()).
void validateSolve(std::span<const Vec3> handles, std::span<const Vec3> targets,
                   const DeformationGraphSolveOptions& options);

// Solves the validated edit from the maps (a, t) (one per node of g, world units), which it
// replaces by the solution. `cache` is created on first use and kept by the caller. On an
// exception the maps are as before the call, except that the nodes of components no handle
// reaches are already back at rest (A = I, t = 0).
DeformationGraphReport solveGraph(const GraphIndex& g, std::span<const Vec3> handles,
                                  std::span<const Vec3> targets,
                                  const DeformationGraphSolveOptions& options, std::vector<Mat3>& a,
                                  std::vector<Vec3>& t, std::unique_ptr<SolverCache>& cache);

}  // namespace spacewarp::detail
