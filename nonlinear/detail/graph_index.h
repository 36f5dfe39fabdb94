#pragma once
// The deformation graph's node index: the nodes, a KD-tree and a lookup grid answering "the
// k + 1 nearest nodes of x", the graph's edges and connected components, and the weights and
// warp of one point. Built once per graph and shared, read-only, by the graph and its warps.
// The per-point functions are inline: they are the inner loop of every warp evaluation.

#include <array>
#include <cmath>
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include <nanoflann.hpp>

#include <spacewarp/core/math.h>

namespace spacewarp::detail {

// nanoflann's view of the node positions.
struct NodeCloud {
  const std::vector<Vec3>* points = nullptr;
  std::size_t kdtree_get_point_count() const { return points->size(); }
  double kdtree_get_pt(std::size_t i, std::size_t dim) const { return (*points)[i][int(dim)]; }
  template <class Box>
  bool kdtree_get_bbox(Box&) const {
    return false;
  }
};

using KdTree = nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<double, NodeCloud>,
                                                   NodeCloud, 3, std::uint32_t>;

// Thrown by GraphIndex::nearest() for a point so far from the nodes that its squared distances
// overflow; the callers turn it into an InvalidInput naming the point.
struct PointOutOfReach {};

// "(x, y, z)" with every digit, for messages.
std::string describePoint(const Vec3& x);

// Throws InvalidInput: `what` (e.g. "the point (1, 2, 3)") is out of the nodes' reach.
[[noreturn]] void throwOutOfReach(const std::string& what);

// Largest coordinate magnitude accepted: squared distances between such points stay finite
// ((2e150)² · 3 ≈ 1e301). Beyond it nanoflann would find no neighbour at all.
constexpr double kMaxCoordinate = 1e150;

inline bool withinReach(const Vec3& x) {
  return std::abs(x.x) <= kMaxCoordinate && std::abs(x.y) <= kMaxCoordinate &&
         std::abs(x.z) <= kMaxCoordinate;
}

// Everything that does not change when the graph is solved: shared by the graph and its warps.
// Not movable: the KD-tree refers to `cloud`, which refers to `nodes`.
struct GraphIndex {
  explicit GraphIndex(std::vector<Vec3> nodePositions, int kNearest)
      : nodes(std::move(nodePositions)), k(kNearest) {
    cloud.points = &nodes;
    tree = std::make_unique<KdTree>(3, cloud, nanoflann::KDTreeSingleIndexAdaptorParams(10));
    buildLookupGrid();
  }
  GraphIndex(const GraphIndex&) = delete;
  GraphIndex& operator=(const GraphIndex&) = delete;

  // The k + 1 nearest nodes of x, sorted by (squared distance, index): the canonical order
  // every evaluation uses. Inside the lookup grid the candidates of x's cell are scanned;
  // elsewhere (or in cells with too many candidates) the KD-tree answers.
  void nearest(const Vec3& x, std::uint32_t* idx, double* d2) const {
    const std::size_t n = static_cast<std::size_t>(k) + 1;
    const std::int64_t cell = cellOf(x);
    if (cell >= 0 && cellOffsets[std::size_t(cell)] != cellOffsets[std::size_t(cell) + 1]) {
      std::size_t count = 0;
      const std::uint32_t* c = candidates.data() + cellOffsets[std::size_t(cell)];
      const std::uint32_t* cEnd = candidates.data() + cellOffsets[std::size_t(cell) + 1];
      for (; c != cEnd; ++c) {
        const Vec3 d = x - nodes[*c];
        const double di = d.x * d.x + d.y * d.y + d.z * d.z;
        if (count == n && !(di < d2[n - 1] || (di == d2[n - 1] && *c < idx[n - 1]))) continue;
        std::size_t j = count < n ? count++ : n - 1;
        while (j > 0 && (d2[j - 1] > di || (d2[j - 1] == di && idx[j - 1] > *c))) {
          idx[j] = idx[j - 1];
          d2[j] = d2[j - 1];
          --j;
        }
        idx[j] = *c;
        d2[j] = di;
      }
      return;
    }
    const double q[3] = {x.x, x.y, x.z};
    // Squared distances that overflow are never "nearer" than anything: nanoflann then finds
    // fewer than n nodes and leaves the rest of idx/d2 unwritten.
    if (tree->knnSearch(q, n, idx, d2) < n) throw PointOutOfReach{};
    for (std::size_t i = 1; i < n; ++i) {  // insertion sort: n is tiny, mostly sorted
      const std::uint32_t ii = idx[i];
      const double di = d2[i];
      std::size_t j = i;
      while (j > 0 && (d2[j - 1] > di || (d2[j - 1] == di && idx[j - 1] > ii))) {
        idx[j] = idx[j - 1];
        d2[j] = d2[j - 1];
        --j;
      }
      idx[j] = ii;
      d2[j] = di;
    }
  }

  // The lookup grid's cell of x (x fastest), or −1 outside the grid.
  std::int64_t cellOf(const Vec3& x) const {
    if (dims[0] == 0) return -1;
    std::int64_t c[3];
    for (int a = 0; a < 3; ++a) {
      const double f = (x[a] - gridOrigin[a]) * inverseCell;
      if (!(f >= 0.0 && f < double(dims[a]))) return -1;  // also rejects NaN
      c[a] = static_cast<std::int64_t>(f);
    }
    return c[0] + dims[0] * (c[1] + dims[1] * c[2]);
  }

  // Builds the lookup grid (graph_index.cpp); leaves it empty (dims 0) when it would not fit.
  void buildLookupGrid();

  std::array<std::int64_t, 3> dims{0, 0, 0};
  Vec3 gridOrigin{0.0};
  double inverseCell = 0.0;
  std::vector<std::uint32_t> cellOffsets;  // per cell + 1: its candidates' range (CSR)
  std::vector<std::uint32_t> candidates;

  std::vector<Vec3> nodes;
  int k;
  NodeCloud cloud;
  std::unique_ptr<KdTree> tree;
  std::vector<std::pair<std::uint32_t, std::uint32_t>> edges;  // i < j, sorted
  std::vector<std::uint32_t> adjacencyOffsets;                 // CSR, both directions
  std::vector<std::uint32_t> adjacency;
  std::vector<std::uint32_t> component;  // per node
  int componentCount = 0;
  // The solve's unit of length: the largest extent of the nodes' bounding box (1 if they all
  // coincide), so that the paper's weights keep their meaning in a unit-sized scene.
  double unit = 1.0;
};

// Edges (nodes influencing a common point of `positions`, and each node with the nodes within
// its own cut-off), adjacency, connected components and the unit of length of `g`.
void buildTopology(GraphIndex& g, std::span<const Vec3> positions);

// Throws InvalidInput unless every point is finite and (if `bounded`: points whose distances
// to the nodes are measured) within reach. `what` names the array in the message.
void requireFinite(const char* what, std::span<const Vec3> points, bool bounded = true);

// Throws InvalidInput unless 1 <= k < nodeCount (the weights need k + 1 nodes).
void requireK(int k, std::size_t nodeCount);

constexpr int kSmallK = 32;  // stack buffers up to this k; larger k uses a heap buffer per call

// Per-evaluation scratch for k + 1 neighbours without per-point allocation when k is small.
struct Scratch {
  explicit Scratch(int k) {
    if (k + 1 > kSmallK) {
      heapIdx.resize(std::size_t(k) + 1);
      heapD2.resize(std::size_t(k) + 1);
      heapW.resize(std::size_t(k) + 1);
    }
  }
  std::uint32_t* idx() { return heapIdx.empty() ? idxBuf.data() : heapIdx.data(); }
  double* d2() { return heapD2.empty() ? d2Buf.data() : heapD2.data(); }
  double* w() { return heapW.empty() ? wBuf.data() : heapW.data(); }
  std::array<std::uint32_t, kSmallK> idxBuf;
  std::array<double, kSmallK> d2Buf, wBuf;
  std::vector<std::uint32_t> heapIdx;
  std::vector<double> heapD2, heapW;
};

// Normalised weights of the k nearest nodes (idx/d2 from GraphIndex::nearest, k + 1 entries).
// w_j = (1 − d_j / d_max)², d_max = d_(k+1). Uniform weights if all of them vanish (the k + 1
// nearest nodes are equidistant from x).
inline void weightsOf(int k, const double* d2, double* w) {
  const double dMax = std::sqrt(d2[k]);
  double sum = 0.0;
  for (int i = 0; i < k; ++i) {
    const double s = dMax > 0.0 ? 1.0 - std::sqrt(d2[i]) / dMax : 0.0;
    w[i] = s * s;
    sum += w[i];
  }
  if (sum > 0.0) {
    for (int i = 0; i < k; ++i) w[i] /= sum;
  } else {
    for (int i = 0; i < k; ++i) w[i] = 1.0 / k;
  }
}

// x' = x + Σ w_j [B_j (x − g_j) + t_j], B_j = A_j − I: exactly x in the rest state.
inline Vec3 warpPoint(const GraphIndex& g, const Mat3* b, const Vec3* t, const Vec3& x,
                      Scratch& s) {
  std::uint32_t* idx = s.idx();
  double* d2 = s.d2();
  double* w = s.w();
  g.nearest(x, idx, d2);
  weightsOf(g.k, d2, w);
  Vec3 d(0.0);
  for (int i = 0; i < g.k; ++i) {
    const std::uint32_t j = idx[i];
    d += w[i] * (b[j] * (x - g.nodes[j]) + t[j]);
  }
  return x + d;
}

}  // namespace spacewarp::detail
