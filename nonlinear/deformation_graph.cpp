#include "nonlinear/deformation_graph.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numeric>
#include <string>
#include <tuple>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <Eigen/CholmodSupport>
#include <Eigen/Sparse>
#include <nanoflann.hpp>

#include "core/errors.h"

namespace spacewarp {

namespace detail {

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
    if (cell >= 0 && cellOffsets[std::size_t(cell)] != kNoList) {
      std::size_t count = 0;
      const std::uint32_t* c = candidates.data() + cellOffsets[std::size_t(cell)];
      const std::uint32_t* cEnd = candidates.data() + cellEnds[std::size_t(cell)];
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
    tree->knnSearch(q, n, idx, d2);
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

  // Builds the lookup grid: cells of edge h (a quarter of the typical distance to the (k+1)-th
  // nearest node) over the nodes' bounding box padded by that distance; each cell lists every node
  // within D + 2r of its centre, D = the centre's (k+1)-th nearest distance, r = the cell's
  // half-diagonal. For any x in the cell, its k + 1 nearest nodes lie within
  // d_(k+1)(x) <= |x − c| + D <= r + D of x, so within D + 2r of c: the list is complete.
  void buildLookupGrid() {
    const std::size_t m = nodes.size();
    const std::size_t n = static_cast<std::size_t>(k) + 1;
    std::vector<double> reach;
    std::vector<std::uint32_t> idx(n);
    std::vector<double> d2(n);
    const std::size_t step = std::max<std::size_t>(1, m / 256);
    for (std::size_t i = 0; i < m; i += step) {
      const double q[3] = {nodes[i].x, nodes[i].y, nodes[i].z};
      tree->knnSearch(q, n, idx.data(), d2.data());
      reach.push_back(std::sqrt(*std::max_element(d2.begin(), d2.end())));
    }
    std::nth_element(reach.begin(), reach.begin() + std::ptrdiff_t(reach.size() / 2), reach.end());
    const double typical = reach[reach.size() / 2];
    double h = 0.25 * typical;
    Vec3 lo(std::numeric_limits<double>::infinity()), hi(-std::numeric_limits<double>::infinity());
    for (const Vec3& p : nodes) {
      lo = glm::min(lo, p);
      hi = glm::max(hi, p);
    }
    if (!(h > 0.0) || !std::isfinite(h)) return;
    lo -= Vec3(typical);  // points a little outside the nodes' box use the grid too
    hi += Vec3(typical);
    const double maxCells = 64.0 * double(m) + 4096.0;
    std::array<double, 3> counts{};
    for (int attempt = 0; attempt < 64; ++attempt) {
      for (int a = 0; a < 3; ++a) counts[size_t(a)] = std::floor((hi[a] - lo[a]) / h) + 1.0;
      const double total = counts[0] * counts[1] * counts[2];
      if (total <= maxCells) break;
      h *= std::max(1.01, std::cbrt(total / maxCells));
    }
    if (!(counts[0] * counts[1] * counts[2] <= maxCells)) return;
    for (int a = 0; a < 3; ++a) dims[size_t(a)] = static_cast<std::int64_t>(counts[size_t(a)]);
    gridOrigin = lo;
    inverseCell = 1.0 / h;
    const std::size_t cells = std::size_t(dims[0] * dims[1] * dims[2]);
    const double r = 0.5 * std::sqrt(3.0) * h;
    constexpr std::size_t kMaxList = 96;
    std::vector<std::vector<std::uint32_t>> lists(cells);
    tbb::parallel_for(
        tbb::blocked_range<std::size_t>(0, cells, 256),
        [&](const tbb::blocked_range<std::size_t>& br) {
          std::vector<std::uint32_t> ki(n);
          std::vector<double> kd(n);
          std::vector<std::pair<std::uint32_t, double>> found;
          for (std::size_t cIndex = br.begin(); cIndex != br.end(); ++cIndex) {
            const std::int64_t ci = std::int64_t(cIndex);
            const Vec3 centre = gridOrigin + h * Vec3(double(ci % dims[0]) + 0.5,
                                                      double((ci / dims[0]) % dims[1]) + 0.5,
                                                      double(ci / (dims[0] * dims[1])) + 0.5);
            const double q[3] = {centre.x, centre.y, centre.z};
            tree->knnSearch(q, n, ki.data(), kd.data());
            const double radius = std::sqrt(*std::max_element(kd.begin(), kd.end())) + 2.0 * r;
            // Squared radius, widened by a relative margin against rounding.
            const double r2 = radius * radius * (1.0 + 1e-9);
            found.clear();
            tree->radiusSearch(q, r2, found, nanoflann::SearchParams(32, 0.0f, false));
            if (found.size() > kMaxList) continue;  // leave the cell to the KD-tree
            auto& list = lists[cIndex];
            list.reserve(found.size());
            for (const auto& f : found) list.push_back(f.first);
            std::sort(list.begin(), list.end());
          }
        });
    cellOffsets.resize(cells);
    cellEnds.resize(cells);
    for (std::size_t c = 0; c < cells; ++c) {
      if (lists[c].size() < n) {  // too many candidates (or too few nodes): KD-tree
        cellOffsets[c] = kNoList;
        cellEnds[c] = kNoList;
        continue;
      }
      cellOffsets[c] = static_cast<std::uint32_t>(candidates.size());
      candidates.insert(candidates.end(), lists[c].begin(), lists[c].end());
      cellEnds[c] = static_cast<std::uint32_t>(candidates.size());
    }
  }

  static constexpr std::uint32_t kNoList = std::uint32_t(-1);
  std::array<std::int64_t, 3> dims{0, 0, 0};
  Vec3 gridOrigin{0.0};
  double inverseCell = 0.0;
  std::vector<std::uint32_t> cellOffsets, cellEnds, candidates;

  std::vector<Vec3> nodes;
  int k;
  NodeCloud cloud;
  std::unique_ptr<KdTree> tree;
  std::vector<std::pair<std::uint32_t, std::uint32_t>> edges;  // i < j, sorted
  std::vector<std::uint32_t> adjacencyOffsets;                 // CSR, both directions
  std::vector<std::uint32_t> adjacency;
  std::vector<std::uint32_t> component;  // per node
  int componentCount = 0;
};

}  // namespace detail

namespace {

using detail::GraphIndex;

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

void requireFinite(const char* what, std::span<const Vec3> points) {
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (!isFinite(points[i]))
      throw InvalidInput(std::string("DeformationGraph: ") + what + "[" + std::to_string(i) +
                         "] is not finite");
  }
}

void requireK(int k, std::size_t nodeCount) {
  if (k < 1) throw InvalidInput("DeformationGraph: k = " + std::to_string(k) + " must be >= 1");
  if (static_cast<std::size_t>(k) >= nodeCount) {
    throw InvalidInput("DeformationGraph: k = " + std::to_string(k) +
                       " needs at least k + 1 = " + std::to_string(k + 1) +
                       " nodes, but the graph has " + std::to_string(nodeCount));
  }
}

// Voxel-grid sampling: one node per occupied cell, the point nearest the cell's centroid.
std::vector<Vec3> sampleNodes(std::span<const Vec3> positions, double spacing) {
  using Key = std::array<std::int64_t, 3>;
  std::vector<std::pair<Key, std::uint32_t>> cells(positions.size());
  constexpr double kLimit = 4.0e18;
  for (std::size_t i = 0; i < positions.size(); ++i) {
    Key key;
    for (int a = 0; a < 3; ++a) {
      const double c = std::floor(positions[i][a] / spacing);
      if (!(std::abs(c) < kLimit)) {
        throw InvalidInput("DeformationGraph: positions[" + std::to_string(i) +
                           "] is too far from the origin for spacing " + std::to_string(spacing));
      }
      key[a] = static_cast<std::int64_t>(c);
    }
    cells[i] = {key, static_cast<std::uint32_t>(i)};
  }
  std::sort(cells.begin(), cells.end());
  std::vector<Vec3> nodes;
  using Iter = std::vector<std::pair<Key, std::uint32_t>>::const_iterator;
  for (Iter begin = cells.cbegin(); begin != cells.cend();) {
    const Iter end =
        std::find_if(begin, cells.cend(), [&](const auto& c) { return c.first != begin->first; });
    Vec3 centroid(0.0);
    for (Iter it = begin; it != end; ++it) centroid += positions[it->second];
    centroid /= double(end - begin);
    // The point nearest the centroid; indices ascend within a cell, so ties keep the lower.
    std::uint32_t best = begin->second;
    double bestD = std::numeric_limits<double>::infinity();
    for (Iter it = begin; it != end; ++it) {
      const Vec3 d = positions[it->second] - centroid;
      if (glm::dot(d, d) < bestD) {
        bestD = glm::dot(d, d);
        best = it->second;
      }
    }
    nodes.push_back(positions[best]);
    begin = end;
  }
  return nodes;
}

// Edges (nodes influencing a common point), adjacency and connected components.
void buildTopology(GraphIndex& g, std::span<const Vec3> positions) {
  const int k = g.k;
  const std::size_t n = positions.size();
  std::vector<std::uint32_t> influence(n * std::size_t(k));
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, 1024),
                    [&](const tbb::blocked_range<std::size_t>& r) {
                      Scratch s(k);
                      for (std::size_t i = r.begin(); i != r.end(); ++i) {
                        g.nearest(positions[i], s.idx(), s.d2());
                        std::copy(s.idx(), s.idx() + k, influence.begin() + i * k);
                      }
                    });
  std::vector<std::pair<std::uint32_t, std::uint32_t>> pairs;
  pairs.reserve(n * std::size_t(k) * std::size_t(k - 1) / 2);
  for (std::size_t i = 0; i < n; ++i) {
    const std::uint32_t* v = influence.data() + i * k;
    for (int a = 0; a < k; ++a)
      for (int b = a + 1; b < k; ++b)
        pairs.emplace_back(std::min(v[a], v[b]), std::max(v[a], v[b]));
  }
  std::sort(pairs.begin(), pairs.end());
  pairs.erase(std::unique(pairs.begin(), pairs.end()), pairs.end());
  g.edges = std::move(pairs);

  const std::size_t m = g.nodes.size();
  std::vector<std::uint32_t> degree(m, 0);
  for (const auto& [a, b] : g.edges) {
    ++degree[a];
    ++degree[b];
  }
  g.adjacencyOffsets.assign(m + 1, 0);
  for (std::size_t i = 0; i < m; ++i) g.adjacencyOffsets[i + 1] = g.adjacencyOffsets[i] + degree[i];
  g.adjacency.resize(g.adjacencyOffsets[m]);
  std::vector<std::uint32_t> fill(g.adjacencyOffsets.begin(), g.adjacencyOffsets.end() - 1);
  for (const auto& [a, b] : g.edges) {
    g.adjacency[fill[a]++] = b;
    g.adjacency[fill[b]++] = a;
  }

  // Components by breadth-first search, numbered in order of their lowest node.
  g.component.assign(m, std::uint32_t(-1));
  std::vector<std::uint32_t> queue;
  for (std::uint32_t s = 0; s < m; ++s) {
    if (g.component[s] != std::uint32_t(-1)) continue;
    const std::uint32_t c = static_cast<std::uint32_t>(g.componentCount++);
    g.component[s] = c;
    queue.assign(1, s);
    for (std::size_t q = 0; q < queue.size(); ++q) {
      const std::uint32_t v = queue[q];
      for (std::uint32_t e = g.adjacencyOffsets[v]; e < g.adjacencyOffsets[v + 1]; ++e) {
        const std::uint32_t u = g.adjacency[e];
        if (g.component[u] == std::uint32_t(-1)) {
          g.component[u] = c;
          queue.push_back(u);
        }
      }
    }
  }
}

// The nonlinear least-squares problem of one solve(): residuals, Jacobian, energy.
struct Problem {
  const GraphIndex& g;
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

  int rows() const { return int(6 * freeNodes.size() + 3 * regEdges.size() + 3 * handles.size()); }

  // Residuals at (A, t), split into the three unweighted energies.
  void residuals(const std::vector<Mat3>& a, const std::vector<Vec3>& t, Eigen::VectorXd& f,
                 double& eRot, double& eReg, double& eCon) const {
    f.resize(rows());
    int row = 0;
    eRot = eReg = eCon = 0.0;
    for (std::uint32_t j : freeNodes) {
      const Mat3& m = a[j];
      const double r[6] = {glm::dot(m[0], m[1]),       glm::dot(m[0], m[2]),
                           glm::dot(m[1], m[2]),       1.0 - glm::dot(m[0], m[0]),
                           1.0 - glm::dot(m[1], m[1]), 1.0 - glm::dot(m[2], m[2])};
      for (double v : r) {
        eRot += v * v;
        f[row++] = sRot * v;
      }
    }
    for (const auto& [j, k] : regEdges) {
      // A_j (g_k − g_j) + g_j + t_j − (g_k + t_k), written to vanish exactly at rest.
      const Vec3 e = (a[j] - Mat3(1.0)) * (g.nodes[k] - g.nodes[j]) + t[j] - t[k];
      eReg += glm::dot(e, e);
      for (int c = 0; c < 3; ++c) f[row++] = sReg * e[c];
    }
    const int k = g.k;
    for (std::size_t l = 0; l < handles.size(); ++l) {
      const Vec3& v = handles[l];
      Vec3 d(0.0);
      for (int i = 0; i < k; ++i) {
        const std::uint32_t j = hNodes[l * k + i];
        d += hWeights[l * k + i] * ((a[j] - Mat3(1.0)) * (v - g.nodes[j]) + t[j]);
      }
      const Vec3 e = v + d - targets[l];
      eCon += glm::dot(e, e);
      for (int c = 0; c < 3; ++c) f[row++] = sCon * e[c];
    }
  }

  // The Jacobian of the residuals at A (the constraints and regulariser are linear in the
  // unknowns; only the rotation rows depend on A). Same triplet order every call.
  void jacobian(const std::vector<Mat3>& a, std::vector<Eigen::Triplet<double>>& tr) const {
    tr.clear();
    int row = 0;
    for (std::uint32_t j : freeNodes) {
      const int v = var[j];
      const Mat3& m = a[j];
      const int pairs[3][2] = {{0, 1}, {0, 2}, {1, 2}};
      for (const auto& p : pairs) {  // d(c_p · c_q): c_q for c_p and c_p for c_q
        for (int r = 0; r < 3; ++r) {
          tr.emplace_back(row, v + 3 * p[0] + r, sRot * m[p[1]][r]);
          tr.emplace_back(row, v + 3 * p[1] + r, sRot * m[p[0]][r]);
        }
        ++row;
      }
      for (int c = 0; c < 3; ++c) {  // d(1 − c·c) = −2 c
        for (int r = 0; r < 3; ++r) tr.emplace_back(row, v + 3 * c + r, -2.0 * sRot * m[c][r]);
        ++row;
      }
    }
    for (const auto& [j, k] : regEdges) {
      const Vec3 d = g.nodes[k] - g.nodes[j];
      const int vj = var[j];
      const int vk = var[k];
      for (int r = 0; r < 3; ++r) {
        for (int c = 0; c < 3; ++c) tr.emplace_back(row, vj + 3 * c + r, sReg * d[c]);
        tr.emplace_back(row, vj + 9 + r, sReg);
        tr.emplace_back(row, vk + 9 + r, -sReg);
        ++row;
      }
    }
    const int k = g.k;
    for (std::size_t l = 0; l < handles.size(); ++l) {
      for (int r = 0; r < 3; ++r) {
        for (int i = 0; i < k; ++i) {
          const std::uint32_t j = hNodes[l * k + i];
          if (var[j] < 0) continue;
          const double w = sCon * hWeights[l * k + i];
          const Vec3 d = handles[l] - g.nodes[j];
          for (int c = 0; c < 3; ++c) tr.emplace_back(row, var[j] + 3 * c + r, w * d[c]);
          tr.emplace_back(row, var[j] + 9 + r, w);
        }
        ++row;
      }
    }
  }
};

// The fill-reducing ordering of the normal equations: AMD alone. CHOLMOD's default would also
// try METIS on a graph this filled; on the 1,000-node benchmark METIS saves ~10 % of the
// factorisation's flops (2.9 vs 3.2 GFlop) but its analysis takes ~90 ms against AMD's ~23 ms.
void configureCholmod(cholmod_common& c) {
  c.nmethods = 1;
  c.method[0].ordering = CHOLMOD_AMD;
  c.postorder = 1;
  c.print = 0;  // the library never writes to stderr: failures come back through info()
}

}  // namespace

namespace detail {

// The symbolic analysis (fill-reducing ordering, supernodes) of the last normal-equation
// pattern, kept across solve() calls: it costs about as much as a tenth of a factorisation.
struct SolverCache {
  Eigen::CholmodSupernodalLLT<Eigen::SparseMatrix<double>, Eigen::Lower> llt;
  std::vector<int> outer, inner;  // the analysed pattern (compressed column storage)
  bool analysed = false;

  SolverCache() { configureCholmod(llt.cholmod()); }

  // Analyses `a` unless its pattern is the one analysed last. Returns true if it analysed.
  bool analyse(const Eigen::SparseMatrix<double>& a) {
    const int* o = a.outerIndexPtr();
    const int* i = a.innerIndexPtr();
    const auto cols = static_cast<std::size_t>(a.cols());
    const auto nnz = static_cast<std::size_t>(a.nonZeros());
    if (analysed && outer.size() == cols + 1 && inner.size() == nnz &&
        std::equal(outer.begin(), outer.end(), o) && std::equal(inner.begin(), inner.end(), i))
      return false;
    llt.analyzePattern(a);
    outer.assign(o, o + cols + 1);
    inner.assign(i, i + nnz);
    analysed = true;
    return true;
  }
};

}  // namespace detail

// ---------------------------------------------------------------------------------------------

DeformationGraphWarp::DeformationGraphWarp(std::shared_ptr<const detail::GraphIndex> index,
                                           std::vector<Mat3> a, std::vector<Vec3> t)
    : index_(std::move(index)), a_(std::move(a)), t_(std::move(t)) {
  for (Mat3& m : a_) m -= Mat3(1.0);  // stored as B = A − I
}

Vec3 DeformationGraphWarp::apply(const Vec3& x) const {
  Scratch s(index_->k);
  return warpPoint(*index_, a_.data(), t_.data(), x, s);
}

Mat3 DeformationGraphWarp::jacobian(const Vec3& x) const {
  const GraphIndex& g = *index_;
  const int k = g.k;
  Scratch s(k);
  std::uint32_t* idx = s.idx();
  double* d2 = s.d2();
  g.nearest(x, idx, d2);
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

void DeformationGraphWarp::applyBatch(std::span<const Vec3> in, std::span<Vec3> out) const {
  if (in.size() != out.size()) {
    throw InvalidInput("DeformationGraphWarp::applyBatch: input has " + std::to_string(in.size()) +
                       " points but output has " + std::to_string(out.size()));
  }
  const GraphIndex* g = index_.get();
  const Mat3* b = a_.data();
  const Vec3* t = t_.data();
  const Vec3* src = in.data();
  Vec3* dst = out.data();
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, in.size(), 2048),
                    [g, b, t, src, dst](const tbb::blocked_range<std::size_t>& r) {
                      Scratch s(g->k);
                      for (std::size_t i = r.begin(); i != r.end(); ++i)
                        dst[i] = warpPoint(*g, b, t, src[i], s);
                    });
}

// ---------------------------------------------------------------------------------------------

DeformationGraph::DeformationGraph(std::span<const Vec3> positions,
                                   const DeformationGraphOptions& options) {
  if (positions.empty()) throw InvalidInput("DeformationGraph: no positions to sample nodes from");
  if (!(options.spacing > 0.0) || !std::isfinite(options.spacing)) {
    throw InvalidInput("DeformationGraph: spacing = " + std::to_string(options.spacing) +
                       " must be finite and > 0");
  }
  if (options.k < 1)
    throw InvalidInput("DeformationGraph: k = " + std::to_string(options.k) + " must be >= 1");
  requireFinite("positions", positions);
  std::vector<Vec3> nodes = sampleNodes(positions, options.spacing);
  requireK(options.k, nodes.size());
  auto index = std::make_shared<detail::GraphIndex>(std::move(nodes), options.k);
  buildTopology(*index, positions);
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
  buildTopology(*index, positions.empty() ? nodes : positions);
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
  index_->nearest(x, s.idx(), s.d2());
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
  const GraphIndex& g = *index_;
  if (handles.size() != targets.size()) {
    throw InvalidInput("DeformationGraph::solve: " + std::to_string(handles.size()) +
                       " handles but " + std::to_string(targets.size()) + " targets");
  }
  requireFinite("handles", handles);
  requireFinite("targets", targets);
  const auto requireWeight = [](const char* name, double w) {
    if (!(w >= 0.0) || !std::isfinite(w)) {
      throw InvalidInput(std::string("DeformationGraph::solve: ") + name + " = " +
                         std::to_string(w) + " must be finite and >= 0");
    }
  };
  requireWeight("rotationWeight", options.rotationWeight);
  requireWeight("regularizationWeight", options.regularizationWeight);
  requireWeight("constraintWeight", options.constraintWeight);
  if (options.maxIterations < 0) {
    throw InvalidInput("DeformationGraph::solve: maxIterations = " +
                       std::to_string(options.maxIterations) + " must be >= 0");
  }
  if (!(options.tolerance >= 0.0) || !std::isfinite(options.tolerance)) {
    throw InvalidInput("DeformationGraph::solve: tolerance must be finite and >= 0");
  }

  const int k = g.k;
  const std::size_t m = g.nodes.size();
  Problem p{g,
            {},
            0,
            std::sqrt(options.rotationWeight),
            std::sqrt(options.regularizationWeight),
            std::sqrt(options.constraintWeight),
            {},
            {},
            {},
            {},
            {},
            {}};
  p.handles.assign(handles.begin(), handles.end());
  p.targets.assign(targets.begin(), targets.end());
  p.hNodes.resize(handles.size() * k);
  p.hWeights.resize(handles.size() * k);
  std::vector<char> reached(std::size_t(g.componentCount), 0);
  {
    Scratch s(k);
    for (std::size_t l = 0; l < handles.size(); ++l) {
      g.nearest(handles[l], s.idx(), s.d2());
      weightsOf(k, s.d2(), s.w());
      for (int i = 0; i < k; ++i) {
        p.hNodes[l * k + i] = s.idx()[i];
        p.hWeights[l * k + i] = s.w()[i];
        reached[g.component[s.idx()[i]]] = 1;
      }
    }
  }

  DeformationGraphReport report;
  report.componentCount = g.componentCount;
  for (int c = 0; c < g.componentCount; ++c) report.unconstrainedComponents += reached[c] ? 0 : 1;
  p.var.assign(m, -1);
  for (std::uint32_t j = 0; j < m; ++j) {
    if (reached[g.component[j]]) {
      p.var[j] = p.unknowns;
      p.unknowns += 12;
      p.freeNodes.push_back(j);
    } else {
      report.unconstrainedNodes.push_back(j);
      a_[j] = Mat3(1.0);  // pinned: rigidly in place
      t_[j] = Vec3(0.0);
    }
  }
  for (std::uint32_t j : p.freeNodes) {
    for (std::uint32_t e = g.adjacencyOffsets[j]; e < g.adjacencyOffsets[j + 1]; ++e)
      p.regEdges.emplace_back(j, g.adjacency[e]);
  }

  Eigen::VectorXd f;
  double eRot = 0.0, eReg = 0.0, eCon = 0.0;
  const auto energyOf = [&](const std::vector<Mat3>& a, const std::vector<Vec3>& t) {
    p.residuals(a, t, f, eRot, eReg, eCon);
    return options.rotationWeight * eRot + options.regularizationWeight * eReg +
           options.constraintWeight * eCon;
  };
  double energy = energyOf(a_, t_);
  report.energies.push_back(energy);
  const auto finish = [&] {
    energyOf(a_, t_);
    report.rotationEnergy = eRot;
    report.regularizationEnergy = eReg;
    report.constraintEnergy = eCon;
    return report;
  };
  if (p.unknowns == 0) {
    report.converged = true;
    return finish();
  }

  const int n = p.unknowns;
  Eigen::SparseMatrix<double> jac(p.rows(), n), normal, damping(n, n);
  {
    std::vector<Eigen::Triplet<double>> diag;
    diag.reserve(std::size_t(n));
    for (int i = 0; i < n; ++i) diag.emplace_back(i, i, 1.0);
    damping.setFromTriplets(diag.begin(), diag.end());
  }
  std::vector<Eigen::Triplet<double>> triplets;
  // CHOLMOD's supernodal Cholesky (dense BLAS kernels on the supernodes): the fill of a 3D
  // graph makes the factor ~7x denser than J^T J, where a simplicial factorisation crawls.
  // Its symbolic analysis is kept in cache_ and reused by later solves with the same pattern;
  // the numeric factor is not, so every solve is a pure function of its input and state.
  if (!cache_) cache_ = std::make_unique<detail::SolverCache>();
  auto& llt = cache_->llt;
  bool analysed = false;
  // The factor of an earlier iteration's matrix preconditions conjugate gradients on the
  // current one: only the rotation rows of J and the damping change between iterations, so a
  // few iterations usually reach the direct solve's accuracy at a fraction of a factorisation.
  // When they do not, the current matrix is factorised.
  bool factored = false;
  const auto refine = [&llt](const Eigen::SparseMatrix<double>& a, const Eigen::VectorXd& b,
                             Eigen::VectorXd& x) {
    constexpr int kMaxCgIterations = 25;
    constexpr double kCgTolerance = 1e-10;  // relative residual
    x.setZero(b.size());
    const double bNorm = b.norm();
    if (!(bNorm > 0.0)) return std::isfinite(bNorm);
    Eigen::VectorXd r = b;
    Eigen::VectorXd z = llt.solve(r);
    Eigen::VectorXd d = z;
    Eigen::VectorXd ad(b.size());
    double rz = r.dot(z);
    for (int i = 0; i < kMaxCgIterations; ++i) {
      ad.noalias() = a * d;
      const double dad = d.dot(ad);
      if (!(dad > 0.0) || !(rz > 0.0)) return false;
      const double alpha = rz / dad;
      x += alpha * d;
      r -= alpha * ad;
      if (r.norm() <= kCgTolerance * bNorm) return true;
      z = llt.solve(r);
      const double rzNext = r.dot(z);
      d = z + (rzNext / rz) * d;
      rz = rzNext;
    }
    return false;
  };
  double lambda = -1.0;  // Levenberg-Marquardt damping, relative to the mean diagonal
  std::vector<Mat3> a2(a_);
  std::vector<Vec3> t2(t_);
  constexpr double kMaxLambda = 1e12;

  for (int iter = 0; iter < options.maxIterations; ++iter) {
    energyOf(a_, t_);  // f at the current state
    p.jacobian(a_, triplets);
    jac.setFromTriplets(triplets.begin(), triplets.end());
    normal = jac.transpose() * jac;
    const Eigen::VectorXd rhs = -(jac.transpose() * f);
    const double meanDiag = std::max(normal.diagonal().mean(), 1e-300);
    if (lambda < 0.0) lambda = 1e-9;
    bool accepted = false;
    double next = energy;
    while (lambda <= kMaxLambda) {
      const Eigen::SparseMatrix<double> damped = normal + (lambda * meanDiag) * damping;
      if (!analysed) {
        cache_->analyse(damped);
        analysed = true;
      }
      Eigen::VectorXd delta;
      if (!(factored && refine(damped, rhs, delta))) {
        llt.factorize(damped);
        if (llt.info() != Eigen::Success) {
          factored = false;
          lambda *= 10.0;
          continue;
        }
        factored = true;
        delta = llt.solve(rhs);
      }
      for (std::uint32_t j : p.freeNodes) {
        const int v = p.var[j];
        for (int c = 0; c < 3; ++c)
          for (int r = 0; r < 3; ++r) a2[j][c][r] = a_[j][c][r] + delta[v + 3 * c + r];
        for (int r = 0; r < 3; ++r) t2[j][r] = t_[j][r] + delta[v + 9 + r];
      }
      next = energyOf(a2, t2);
      if (std::isfinite(next) && next <= energy) {
        accepted = true;
        break;
      }
      lambda *= 10.0;
    }
    if (!accepted) {
      if (!analysed)
        throw SolverError("DeformationGraph::solve: the normal equations are singular");
      // No step lowers the energy: a (numerical) minimum.
      report.converged = true;
      break;
    }
    a_.swap(a2);
    t_.swap(t2);
    a2 = a_;
    t2 = t_;
    const double previous = energy;
    energy = next;
    report.energies.push_back(energy);
    report.iterations = iter + 1;
    lambda = std::max(lambda / 10.0, 1e-12);
    if (std::abs(previous - energy) < options.tolerance * (1.0 + energy)) {
      report.converged = true;
      break;
    }
  }
  return finish();
}

}  // namespace spacewarp
