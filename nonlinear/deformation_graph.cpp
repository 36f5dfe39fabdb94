#include <spacewarp/nonlinear/deformation_graph.h>

// The public face of the deformation graph: the graph's construction and accessors and its
// Warp view. The work lives in nonlinear/detail/: node sampling (node_sampling.h), the node
// index with its weights and topology (graph_index.h), and the solve (graph_solver.h over
// graph_problem.h and solver_cache.h).

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <string>
#include <utility>

#include <spacewarp/core/archive.h>
#include <spacewarp/core/errors.h>
#include <spacewarp/nonlinear/detail/graph_index.h>
#include <spacewarp/nonlinear/detail/graph_solver.h>
#include <spacewarp/nonlinear/detail/node_sampling.h>
#include <spacewarp/nonlinear/detail/solver_cache.h>

namespace spacewarp {

namespace {

using detail::describePoint;
using detail::GraphIndex;
using detail::kMaxCoordinate;
using detail::requireFinite;
using detail::requireK;
using detail::Scratch;
using detail::throwOutOfReach;
using detail::warpPoint;
using detail::weightsOf;

}  // namespace

// ---------------------------------------------------------------------------------------------

DeformationGraphWarp::DeformationGraphWarp(std::shared_ptr<const detail::GraphIndex> index,
                                           std::vector<Mat3> a, std::vector<Vec3> t)
    : index_(std::move(index)), a_(std::move(a)), t_(std::move(t)) {
  for (Mat3& m : a_) m -= Mat3(1.0);  // stored as B = A − I
}

DeformationGraphWarp::DeformationGraphWarp(std::shared_ptr<const detail::GraphIndex> index,
                                           std::vector<Mat3> b, std::vector<Vec3> t, Stored)
    : index_(std::move(index)), a_(std::move(b)), t_(std::move(t)) {}

void DeformationGraphWarp::save(ArchiveWriter& out) const {
  out.tag("deformation-graph");
  out.i32(index_->k);
  out.vec3s(index_->nodes);
  std::vector<double> b;  // B_j column by column, 9 per node
  b.reserve(a_.size() * 9);
  for (const Mat3& m : a_)
    for (int c = 0; c < 3; ++c)
      for (int r = 0; r < 3; ++r) b.push_back(m[c][r]);
  out.doubles(b);
  out.vec3s(t_);
}

std::shared_ptr<const DeformationGraphWarp> DeformationGraphWarp::load(ArchiveReader& in) {
  const int k = in.i32();
  std::vector<Vec3> nodes = in.vec3s();
  const std::vector<double> b = in.doubles();
  std::vector<Vec3> t = in.vec3s();
  if (nodes.empty()) in.fail("deformation-graph: no nodes");
  requireFinite("nodes", nodes);
  requireK(k, nodes.size());
  if (nodes.size() > std::numeric_limits<std::uint32_t>::max())
    in.fail("deformation-graph: " + std::to_string(nodes.size()) + " nodes (at most 2^32 - 1)");
  if (b.size() != nodes.size() * 9 || t.size() != nodes.size()) {
    in.fail("deformation-graph: " + std::to_string(b.size()) + " matrix entries and " +
            std::to_string(t.size()) + " translations for " + std::to_string(nodes.size()) +
            " nodes (9 and 1 per node)");
  }
  std::vector<Mat3> maps(nodes.size());
  for (std::size_t j = 0; j < maps.size(); ++j) {
    for (int c = 0; c < 3; ++c)
      for (int r = 0; r < 3; ++r) maps[j][c][r] = b[j * 9 + std::size_t(c) * 3 + std::size_t(r)];
    if (!isFinite(maps[j][0]) || !isFinite(maps[j][1]) || !isFinite(maps[j][2]) || !isFinite(t[j]))
      in.fail("deformation-graph: the map of node " + std::to_string(j) + " is not finite");
  }
  auto index = std::make_shared<const detail::GraphIndex>(std::move(nodes), k);
  return std::shared_ptr<const DeformationGraphWarp>(
      new DeformationGraphWarp(std::move(index), std::move(maps), std::move(t), Stored{}));
}

Vec3 DeformationGraphWarp::apply(const Vec3& x) const {
  Scratch s(index_->k);
  try {
    return warpPoint(*index_, a_.data(), t_.data(), x, s);
  } catch (const detail::PointOutOfReach&) {
    throwOutOfReach("the point " + describePoint(x));
  }
}

Mat3 DeformationGraphWarp::jacobian(const Vec3& x) const {
  const GraphIndex& g = *index_;
  const int k = g.k;
  Scratch s(k);
  std::uint32_t* idx = s.idx();
  double* d2 = s.d2();
  try {
    g.nearest(x, idx, d2);
  } catch (const detail::PointOutOfReach&) {
    throwOutOfReach("the point " + describePoint(x));
  }
  // Unnormalised weights u_i = (1 − d_i / d_max)² and their gradients.
  const double dMax = std::sqrt(d2[k]);
  if (!(dMax > 0.0)) return Warp::jacobian(x);  // k + 1 coincident nodes: no analytic form
  const Vec3 gradDMax = (x - g.nodes[idx[k]]) / dMax;
  std::vector<double> u(std::size_t(k), 0.0);
  std::vector<Vec3> gradU(std::size_t(k), Vec3(0.0));
  double sum = 0.0;
  Vec3 gradSum(0.0);
  for (int i = 0; i < k; ++i) {
    const double d = std::sqrt(d2[i]);
    const double sI = 1.0 - d / dMax;
    u[i] = sI * sI;
    // d(d / d_max) = ∇d / d_max − d ∇d_max / d_max²; ∇d = (x − g) / d (zero at the node).
    const Vec3 gradD = d > 0.0 ? (x - g.nodes[idx[i]]) / d : Vec3(0.0);
    gradU[i] = -2.0 * sI * (gradD / dMax - d * gradDMax / (dMax * dMax));
    sum += u[i];
    gradSum += gradU[i];
  }
  if (!(sum > 0.0)) return Warp::jacobian(x);
  Mat3 j(1.0);
  for (int i = 0; i < k; ++i) {
    const std::uint32_t n = idx[i];
    const double w = u[i] / sum;
    const Vec3 gradW = (gradU[i] - w * gradSum) / sum;
    const Vec3 q = a_[n] * (x - g.nodes[n]) + t_[n];
    j += w * a_[n] + glm::outerProduct(q, gradW);
  }
  return j;
}

std::size_t DeformationGraphWarp::batchGrain() const { return 2048; }

// A range stops at its first point out of reach: the batch reports the lowest one, whatever the
// thread count.
UnmappedPoints DeformationGraphWarp::applyRange(std::span<const Vec3> in, std::span<Vec3> out,
                                                std::size_t begin, std::size_t end) const {
  Scratch s(index_->k);
  UnmappedPoints outOfReach;
  std::size_t i = begin;
  try {
    for (; i != end; ++i) out[i] = warpPoint(*index_, a_.data(), t_.data(), in[i], s);
  } catch (const detail::PointOutOfReach&) {
    outOfReach.add(i);
  }
  return outOfReach;
}

void DeformationGraphWarp::throwUnmapped(const UnmappedPoints& unmapped,
                                         std::span<const Vec3> in) const {
  throwOutOfReach("point " + std::to_string(unmapped.first) + " " +
                  describePoint(in[unmapped.first]));
}

// ---------------------------------------------------------------------------------------------

DeformationGraph::DeformationGraph(std::span<const Vec3> positions,
                                   const DeformationGraphOptions& options) {
  if (positions.empty()) throw InvalidInput("DeformationGraph: no positions to sample nodes from");
  if (!(options.spacing > 0.0) || !(options.spacing <= kMaxCoordinate)) {
    throw InvalidInput("DeformationGraph: spacing = " + std::to_string(options.spacing) +
                       " must be > 0 and at most 1e150");
  }
  if (options.k < 1)
    throw InvalidInput("DeformationGraph: k = " + std::to_string(options.k) + " must be >= 1");
  requireFinite("positions", positions);
  std::vector<Vec3> nodes = options.sampling == NodeSampling::PoissonDisk
                                ? detail::sampleNodesPoissonDisk(positions, options.spacing)
                                : detail::sampleNodesVoxel(positions, options.spacing);
  requireK(options.k, nodes.size());
  auto index = std::make_shared<detail::GraphIndex>(std::move(nodes), options.k);
  detail::buildTopology(*index, positions);
  index_ = std::move(index);
  reset();
}

DeformationGraph::DeformationGraph(std::span<const Vec3> nodes, std::span<const Vec3> positions,
                                   const DeformationGraphOptions& options) {
  if (nodes.empty()) throw InvalidInput("DeformationGraph: no nodes");
  requireFinite("nodes", nodes);
  requireFinite("positions", positions);
  requireK(options.k, nodes.size());
  auto index = std::make_shared<detail::GraphIndex>(std::vector<Vec3>(nodes.begin(), nodes.end()),
                                                    options.k);
  detail::buildTopology(*index, positions.empty() ? nodes : positions);
  index_ = std::move(index);
  reset();
}

DeformationGraph::~DeformationGraph() = default;
DeformationGraph::DeformationGraph(DeformationGraph&&) noexcept = default;
DeformationGraph& DeformationGraph::operator=(DeformationGraph&&) noexcept = default;

std::size_t DeformationGraph::nodeCount() const { return index_->nodes.size(); }
std::span<const Vec3> DeformationGraph::nodes() const { return index_->nodes; }
int DeformationGraph::k() const { return index_->k; }
const std::vector<std::pair<std::uint32_t, std::uint32_t>>& DeformationGraph::edges() const {
  return index_->edges;
}

NodeWeights DeformationGraph::weights(const Vec3& x) const {
  if (!isFinite(x)) throw InvalidInput("DeformationGraph::weights: the point is not finite");
  const int k = index_->k;
  Scratch s(k);
  try {
    index_->nearest(x, s.idx(), s.d2());
  } catch (const detail::PointOutOfReach&) {
    throwOutOfReach("the point " + describePoint(x));
  }
  weightsOf(k, s.d2(), s.w());
  NodeWeights out;
  out.nodes.assign(s.idx(), s.idx() + k);
  out.weights.assign(s.w(), s.w() + k);
  return out;
}

void DeformationGraph::reset() {
  a_.assign(index_->nodes.size(), Mat3(1.0));
  t_.assign(index_->nodes.size(), Vec3(0.0));
}

DeformationGraphWarp DeformationGraph::warp() const { return {index_, a_, t_}; }

DeformationGraphReport DeformationGraph::solve(std::span<const Vec3> handles,
                                               std::span<const Vec3> targets,
                                               const DeformationGraphSolveOptions& options) {
  detail::validateSolve(handles, targets, options);
  return detail::solveGraph(*index_, handles, targets, options, a_, t_, cache_);
}

}  // namespace spacewarp
