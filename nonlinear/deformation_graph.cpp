#include <spacewarp/nonlinear/deformation_graph.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <cstring>
#include <limits>
#include <mutex>
#include <numeric>
#include <sstream>
#include <string>
#include <tuple>
#include <unordered_map>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <Eigen/CholmodSupport>
#include <Eigen/LU>
#include <Eigen/SVD>
#include <Eigen/Sparse>
#include <nanoflann.hpp>

#include <spacewarp/core/detail/serial_blas.h>
#include <spacewarp/core/errors.h>

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

// Thrown by GraphIndex::nearest() for a point so far from the nodes that its squared distances
// overflow; the callers turn it into an InvalidInput naming the point.
struct PointOutOfReach {};

std::string describePoint(const Vec3& x) {
  std::ostringstream s;
  s.precision(17);
  s << "(" << x.x << ", " << x.y << ", " << x.z << ")";
  return s.str();
}

[[noreturn]] void throwOutOfReach(const std::string& what) {
  throw InvalidInput("DeformationGraph: " + what +
                     " is so far from the graph's nodes that squared distances overflow");
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
    // Compressed rows (one offset per cell, one flat candidate array): a std::vector per cell
    // cost more than its few dozen indices. Cells are listed in chunks, in parallel, each into
    // a flat buffer of its own, and the buffers joined in cell order: the same array for any
    // thread count. An empty list leaves the cell to the KD-tree (too many candidates).
    constexpr std::size_t kChunk = 4096;
    const std::size_t chunks = (cells + kChunk - 1) / kChunk;
    std::vector<std::vector<std::uint32_t>> chunkLists(chunks);
    std::vector<std::uint32_t> listSizes(cells, 0);
    tbb::parallel_for(
        tbb::blocked_range<std::size_t>(0, chunks, 1),
        [&](const tbb::blocked_range<std::size_t>& br) {
          std::vector<std::uint32_t> ki(n);
          std::vector<double> kd(n);
          std::vector<std::pair<std::uint32_t, double>> found;
          for (std::size_t chunk = br.begin(); chunk != br.end(); ++chunk) {
            auto& flat = chunkLists[chunk];
            for (std::size_t cIndex = chunk * kChunk;
                 cIndex < std::min(cells, (chunk + 1) * kChunk); ++cIndex) {
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
              if (found.size() > kMaxList || found.size() < n) continue;
              const std::size_t first = flat.size();
              for (const auto& f : found) flat.push_back(f.first);
              std::sort(flat.begin() + std::ptrdiff_t(first), flat.end());
              listSizes[cIndex] = static_cast<std::uint32_t>(found.size());
            }
            flat.shrink_to_fit();
          }
        });
    cellOffsets.assign(cells + 1, 0);
    for (std::size_t c = 0; c < cells; ++c) cellOffsets[c + 1] = cellOffsets[c] + listSizes[c];
    candidates.reserve(cellOffsets[cells]);
    for (auto& flat : chunkLists) {
      candidates.insert(candidates.end(), flat.begin(), flat.end());
      std::vector<std::uint32_t>().swap(flat);
    }
  }

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

}  // namespace detail

namespace {

using detail::describePoint;
using detail::GraphIndex;
using detail::throwOutOfReach;

// Largest coordinate magnitude accepted: squared distances between such points stay finite
// ((2e150)² · 3 ≈ 1e301). Beyond it nanoflann would find no neighbour at all.
constexpr double kMaxCoordinate = 1e150;

inline bool withinReach(const Vec3& x) {
  return std::abs(x.x) <= kMaxCoordinate && std::abs(x.y) <= kMaxCoordinate &&
         std::abs(x.z) <= kMaxCoordinate;
}

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

// Finite, and (if `bounded`: points whose distances to the nodes are measured) within reach.
void requireFinite(const char* what, std::span<const Vec3> points, bool bounded = true) {
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (!isFinite(points[i]))
      throw InvalidInput(std::string("DeformationGraph: ") + what + "[" + std::to_string(i) +
                         "] is not finite");
    if (bounded && !withinReach(points[i])) {
      throw InvalidInput(std::string("DeformationGraph: ") + what + "[" + std::to_string(i) +
                         "] has a coordinate beyond ±1e150, where squared distances overflow");
    }
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

// The integer cell of x in a grid of edge `spacing` (corner at the origin); throws for points
// whose cell index would not fit.
std::array<std::int64_t, 3> cellKey(const Vec3& x, double spacing, std::size_t i) {
  constexpr double kLimit = 4.0e18;
  std::array<std::int64_t, 3> key;
  for (int a = 0; a < 3; ++a) {
    const double c = std::floor(x[a] / spacing);
    if (!(std::abs(c) < kLimit)) {
      throw InvalidInput("DeformationGraph: positions[" + std::to_string(i) +
                         "] is too far from the origin for spacing " + std::to_string(spacing));
    }
    key[std::size_t(a)] = static_cast<std::int64_t>(c);
  }
  return key;
}

// Voxel-grid sampling: one node per occupied cell, the point nearest the cell's centroid.
std::vector<Vec3> sampleNodes(std::span<const Vec3> positions, double spacing) {
  using Key = std::array<std::int64_t, 3>;
  std::vector<std::pair<Key, std::uint32_t>> cells(positions.size());
  for (std::size_t i = 0; i < positions.size(); ++i)
    cells[i] = {cellKey(positions[i], spacing, i), static_cast<std::uint32_t>(i)};
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

// SplitMix64's finaliser: a fixed, well-mixed permutation of 64-bit integers.
std::uint64_t mix64(std::uint64_t x) {
  x += 0x9e3779b97f4a7c15ull;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ull;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebull;
  return x ^ (x >> 31);
}

// Poisson-disk sampling by greedy dart throwing over the input points: visited in the order
// of a hash of their index (so that scan-line or sorted inputs do not imprint their order on
// the nodes), a point becomes a node unless a node lies closer than `spacing`. The nodes are
// binned in a hash grid of edge `spacing`, so only the 27 cells around a point are searched.
// Serial; the result depends only on the positions.
std::vector<Vec3> sampleNodesPoissonDisk(std::span<const Vec3> positions, double spacing) {
  using Key = std::array<std::int64_t, 3>;
  struct KeyHash {
    std::size_t operator()(const Key& k) const {
      return std::size_t(
          mix64(std::uint64_t(k[0]) ^ mix64(std::uint64_t(k[1]) ^ mix64(std::uint64_t(k[2])))));
    }
  };
  const std::size_t n = positions.size();
  std::vector<Key> keys(n);
  for (std::size_t i = 0; i < n; ++i) keys[i] = cellKey(positions[i], spacing, i);
  std::vector<std::pair<std::uint64_t, std::uint32_t>> order(n);
  for (std::size_t i = 0; i < n; ++i) order[i] = {mix64(i), static_cast<std::uint32_t>(i)};
  std::sort(order.begin(), order.end());
  const double r2 = spacing * spacing;
  std::unordered_map<Key, std::vector<std::uint32_t>, KeyHash> grid;
  grid.reserve(n / 4 + 16);
  std::vector<std::uint32_t> chosen;
  for (const auto& [hash, i] : order) {
    const Vec3& x = positions[i];
    const Key& key = keys[i];
    bool covered = false;
    for (std::int64_t dz = -1; dz <= 1 && !covered; ++dz) {
      for (std::int64_t dy = -1; dy <= 1 && !covered; ++dy) {
        for (std::int64_t dx = -1; dx <= 1 && !covered; ++dx) {
          const auto it = grid.find(Key{key[0] + dx, key[1] + dy, key[2] + dz});
          if (it == grid.end()) continue;
          for (std::uint32_t j : it->second) {
            const Vec3 d = x - positions[j];
            if (glm::dot(d, d) < r2) {
              covered = true;
              break;
            }
          }
        }
      }
    }
    if (covered) continue;
    grid[key].push_back(i);
    chosen.push_back(i);
  }
  std::sort(chosen.begin(), chosen.end());
  std::vector<Vec3> nodes;
  nodes.reserve(chosen.size());
  for (std::uint32_t i : chosen) nodes.push_back(positions[i]);
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
  // Each node also joins every node within its own cut-off d_(k+1) (the k nearest others,
  // ties included up to rounding): the k nearest of a point break ties by index, which splits
  // a regular grid of nodes (all neighbours tie) into parts that no handle may reach.
  const std::size_t m = g.nodes.size();
  std::vector<std::vector<std::uint32_t>> near(m);
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, m, 256),
                    [&](const tbb::blocked_range<std::size_t>& r) {
                      Scratch s(k);
                      std::vector<std::pair<std::uint32_t, double>> found;
                      for (std::size_t j = r.begin(); j != r.end(); ++j) {
                        const Vec3& x = g.nodes[j];
                        g.nearest(x, s.idx(), s.d2());
                        const double q[3] = {x.x, x.y, x.z};
                        found.clear();
                        g.tree->radiusSearch(q, s.d2()[k] * (1.0 + 1e-6), found,
                                             nanoflann::SearchParams(32, 0.0f, false));
                        for (const auto& f : found)
                          if (f.first != j) near[j].push_back(f.first);
                      }
                    });
  Vec3 lo = g.nodes[0], hi = g.nodes[0];
  for (const Vec3& x : g.nodes) {
    lo = glm::min(lo, x);
    hi = glm::max(hi, x);
  }
  const double extent = std::max({hi.x - lo.x, hi.y - lo.y, hi.z - lo.z});
  g.unit = extent > 0.0 ? extent : 1.0;
  std::vector<std::pair<std::uint32_t, std::uint32_t>> pairs;
  pairs.reserve(n * std::size_t(k) * std::size_t(k - 1) / 2 + m * std::size_t(k));
  for (std::size_t i = 0; i < n; ++i) {
    const std::uint32_t* v = influence.data() + i * k;
    for (int a = 0; a < k; ++a)
      for (int b = a + 1; b < k; ++b)
        pairs.emplace_back(std::min(v[a], v[b]), std::max(v[a], v[b]));
  }
  for (std::size_t j = 0; j < m; ++j)
    for (std::uint32_t i : near[j])
      pairs.emplace_back(std::min(std::uint32_t(j), i), std::max(std::uint32_t(j), i));
  std::sort(pairs.begin(), pairs.end());
  pairs.erase(std::unique(pairs.begin(), pairs.end()), pairs.end());
  g.edges = std::move(pairs);

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

// The rigid motion x -> r x + shift that best maps the handles onto their targets in the
// least-squares sense (Kabsch: the rotation from the SVD of the cross-covariance, a reflection
// turned into a rotation). The identity for no handles; for collinear handles r is one of the
// rotations that fit equally well.
struct RigidFit {
  Mat3 r{1.0};
  Vec3 shift{0.0};
};

RigidFit rigidFit(std::span<const Vec3> handles, std::span<const Vec3> targets) {
  RigidFit fit;
  if (handles.empty()) return fit;
  Vec3 ch(0.0), ct(0.0);
  for (std::size_t l = 0; l < handles.size(); ++l) {
    ch += handles[l];
    ct += targets[l];
  }
  ch /= double(handles.size());
  ct /= double(handles.size());
  Eigen::Matrix3d h = Eigen::Matrix3d::Zero();
  for (std::size_t l = 0; l < handles.size(); ++l)
    h += toEigen(handles[l] - ch) * toEigen(targets[l] - ct).transpose();
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(h, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d d = Eigen::Matrix3d::Identity();
  d(2, 2) = (svd.matrixV() * svd.matrixU().transpose()).determinant() < 0.0 ? -1.0 : 1.0;
  fit.r = toMat3(svd.matrixV() * d * svd.matrixU().transpose());
  fit.shift = ct - fit.r * ch;
  return fit;
}

// The nonlinear least-squares problem of one solve(): energies and the gradient.
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
                double& eCon, double* rhs) const {
    eRot = eReg = eCon = 0.0;
    if (rhs) std::fill(rhs, rhs + unknowns, 0.0);
    const double wRot = sRot * sRot, wReg = sReg * sReg, wCon = sCon * sCon;
    constexpr int kPairs[3][2] = {{0, 1}, {0, 2}, {1, 2}};
    for (std::uint32_t j : freeNodes) {
      const Mat3& m = a[j];
      double* x = rhs ? rhs + var[j] : nullptr;
      for (const auto& pq : kPairs) {  // c_p · c_q: gradient c_q for c_p and c_p for c_q
        const double v = glm::dot(m[pq[0]], m[pq[1]]);
        eRot += v * v;
        if (x) {
          for (int r = 0; r < 3; ++r) {
            x[3 * pq[0] + r] -= wRot * v * m[pq[1]][r];
            x[3 * pq[1] + r] -= wRot * v * m[pq[0]][r];
          }
        }
      }
      for (int c = 0; c < 3; ++c) {  // 1 − c·c: gradient −2 c
        const double v = 1.0 - glm::dot(m[c], m[c]);
        eRot += v * v;
        if (x)
          for (int r = 0; r < 3; ++r) x[3 * c + r] += 2.0 * wRot * v * m[c][r];
      }
    }
    for (const auto& [j, k] : regEdges) {
      // A_j (g_k − g_j) + g_j + t_j − (g_k + t_k), written to vanish exactly at rest.
      const Vec3 d = nodes[k] - nodes[j];
      const Vec3 e = (a[j] - Mat3(1.0)) * d + t[j] - t[k];
      eReg += glm::dot(e, e);
      if (rhs) {
        double* xj = rhs + var[j];
        double* xk = rhs + var[k];
        for (int r = 0; r < 3; ++r) {
          const double s = wReg * e[r];
          for (int c = 0; c < 3; ++c) xj[3 * c + r] -= s * d[c];
          xj[9 + r] -= s;
          xk[9 + r] += s;
        }
      }
    }
    const int k = g.k;
    for (std::size_t l = 0; l < handles.size(); ++l) {
      const Vec3& v = handles[l];
      Vec3 d(0.0);
      for (int i = 0; i < k; ++i) {
        const std::uint32_t j = hNodes[l * k + i];
        d += hWeights[l * k + i] * ((a[j] - Mat3(1.0)) * (v - nodes[j]) + t[j]);
      }
      const Vec3 e = v + d - targets[l];
      eCon += glm::dot(e, e);
      if (!rhs) continue;
      for (int i = 0; i < k; ++i) {
        const std::uint32_t j = hNodes[l * k + i];
        if (var[j] < 0) continue;
        double* x = rhs + var[j];
        const double w = wCon * hWeights[l * k + i];
        const Vec3 dv = v - nodes[j];
        for (int r = 0; r < 3; ++r) {
          for (int c = 0; c < 3; ++c) x[3 * c + r] -= w * e[r] * dv[c];
          x[9 + r] -= w * e[r];
        }
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

// Throws SolverError unless CHOLMOD's last call (`step`) succeeded (OutOfMemory, a SolverError,
// when memory ran out). Eigen's CHOLMOD wrapper does not look at the status: a failed analysis
// leaves no factor, which its factorize() dereferences, and a factorisation that ran out of
// memory still reports success.
void requireCholmod(const cholmod_common& c, const char* step) {
  if (c.status >= CHOLMOD_OK) return;  // positive values are warnings (e.g. not positive definite)
  std::string why;
  switch (c.status) {
    case CHOLMOD_OUT_OF_MEMORY:
      throw OutOfMemory("DeformationGraph::solve: the sparse Cholesky " + std::string(step) +
                        " ran out of memory; use fewer graph nodes");
    case CHOLMOD_TOO_LARGE:
      why = "the factor is too large for CHOLMOD's 32-bit indices";
      break;
    default:
      why = "CHOLMOD status " + std::to_string(c.status);
  }
  throw SolverError("DeformationGraph::solve: the sparse Cholesky " + std::string(step) +
                    " failed (" + why + "); use fewer graph nodes");
}

// On this machine a single BLAS thread is as fast as two for the graph's supernodes
// (measured: 189 vs 197 ms), so determinism (detail::SerialBlas) costs nothing here.

// y = A x for the symmetric A whose lower triangle (diagonal included) `lower` holds. Serial.
void symmetricProduct(const Eigen::SparseMatrix<double>& lower, const Eigen::VectorXd& x,
                      Eigen::VectorXd& y) {
  y.setZero(x.size());
  const int* outer = lower.outerIndexPtr();
  const int* inner = lower.innerIndexPtr();
  const double* value = lower.valuePtr();
  for (Eigen::Index c = 0; c < lower.outerSize(); ++c) {
    const double xc = x[c];
    double yc = 0.0;
    for (int s = outer[c]; s < outer[c + 1]; ++s) {
      const int r = inner[s];
      if (r == c) {
        yc += value[s] * xc;
      } else {
        y[r] += value[s] * xc;
        yc += value[s] * x[r];
      }
    }
    y[c] += yc;
  }
}

constexpr int kBlockSlots = 78;  // lower triangle of a node's 12 x 12 diagonal block

}  // namespace

namespace detail {

// What solve() keeps between calls, all of it a function of the problem's A-independent data
// (free nodes, handles, their weights, w_reg, w_con), which is its key:
//  - the sparsity pattern of JᵀJ (lower triangle; 12 unknowns per free node) and the values of
//    its constant part: the regulariser and the constraints are linear in the unknowns, so only
//    the rotation term, which lives in each node's 12 x 12 diagonal block, changes with A;
//  - CHOLMOD's symbolic analysis of that pattern (fill-reducing ordering, supernodes);
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

  Eigen::CholmodSupernodalLLT<Eigen::SparseMatrix<double>, Eigen::Lower> llt;
  bool factorValid = false;
  std::vector<double> factoredBlocks;  // the diagonal blocks' values at the last factorisation

  SolverCache() { configureCholmod(llt.cholmod()); }

  bool matches(const Problem& p) const {
    return valid && var == p.var && hNodes == p.hNodes && hWeights == p.hWeights &&
           handles == p.handles && sReg == p.sReg && sCon == p.sCon;
  }

  // Rebuilds pattern, constant part and analysis for `p`.
  void build(const Problem& p) {
    valid = false;
    factorValid = false;
    const GraphIndex& g = p.g;
    const int n = p.unknowns;
    // Coupled pairs of free nodes (j < k): 1 = regulariser edge, 2 = a common handle.
    std::vector<std::tuple<std::uint32_t, std::uint32_t, int>> rel;
    for (const auto& [i, j] : g.edges)
      if (p.var[i] >= 0 && p.var[j] >= 0) rel.emplace_back(i, j, 1);
    const int k = g.k;
    for (std::size_t l = 0; l < p.handles.size(); ++l) {
      for (int a = 0; a < k; ++a) {
        for (int b = a + 1; b < k; ++b) {
          const std::uint32_t x = p.hNodes[l * k + a], y = p.hNodes[l * k + b];
          if (p.var[x] >= 0 && p.var[y] >= 0 && x != y)
            rel.emplace_back(std::min(x, y), std::max(x, y), 2);
        }
      }
    }
    std::sort(rel.begin(), rel.end());
    // Columns node by node. Column o of a node (coordinate r = o % 3; o >= 9 is t[r]) meets,
    // in a coupled node's block, rows {r, 3+r, 6+r, 9+r} (a common handle, or a regulariser
    // edge seen from t) or only 9+r (a regulariser edge seen from A): the regulariser and the
    // constraints never mix coordinates, only the rotation term does, within a node.
    std::vector<int> outer(std::size_t(n) + 1, 0);
    std::vector<int> inner;
    inner.reserve(std::size_t(n) * 48);
    std::size_t relBegin = 0;
    for (std::uint32_t j : p.freeNodes) {
      while (relBegin < rel.size() && std::get<0>(rel[relBegin]) < j) ++relBegin;
      std::size_t relEnd = relBegin;
      while (relEnd < rel.size() && std::get<0>(rel[relEnd]) == j) ++relEnd;
      const int vj = p.var[j];
      for (int o = 0; o < 12; ++o) {
        const int r = o % 3;
        for (int o2 = o; o2 < 12; ++o2) inner.push_back(vj + o2);
        for (std::size_t e = relBegin; e < relEnd;) {
          const std::uint32_t node = std::get<1>(rel[e]);
          int flags = 0;
          for (; e < relEnd && std::get<1>(rel[e]) == node; ++e) flags |= std::get<2>(rel[e]);
          const int vk = p.var[node];
          if ((flags & 2) || o >= 9) {
            for (int c = 0; c < 4; ++c) inner.push_back(vk + 3 * c + r);
          } else {
            inner.push_back(vk + 9 + r);
          }
        }
        outer[std::size_t(vj + o) + 1] = int(inner.size());
      }
      relBegin = relEnd;
    }
    lower = Eigen::SparseMatrix<double>(n, n);
    lower.resizeNonZeros(Eigen::Index(inner.size()));
    std::copy(outer.begin(), outer.end(), lower.outerIndexPtr());
    std::copy(inner.begin(), inner.end(), lower.innerIndexPtr());
    std::fill(lower.valuePtr(), lower.valuePtr() + inner.size(), 0.0);

    blockSlots.resize(p.freeNodes.size() * kBlockSlots);
    diagonal.resize(std::size_t(n));
    for (std::size_t f = 0; f < p.freeNodes.size(); ++f) {
      const int vj = p.var[p.freeNodes[f]];
      int* s = blockSlots.data() + f * kBlockSlots;
      for (int o = 0; o < 12; ++o) {
        diagonal[std::size_t(vj + o)] = outer[std::size_t(vj + o)];
        for (int o2 = o; o2 < 12; ++o2) *s++ = outer[std::size_t(vj + o)] + (o2 - o);
      }
    }

    // The constant part, JᵀJ of the regulariser and constraint rows, one row at a time.
    constant.assign(inner.size(), 0.0);
    const auto slotOf = [&](int row, int col) {
      if (row < col) std::swap(row, col);
      if (row / 12 == col / 12) return outer[std::size_t(col)] + (row - col);
      const int* b = inner.data() + outer[std::size_t(col)];
      const int* e = inner.data() + outer[std::size_t(col) + 1];
      return int(std::lower_bound(b, e, row) - inner.data());
    };
    const auto addRow = [&](const int* idx, const double* u, int count) {
      for (int a = 0; a < count; ++a)
        for (int b = 0; b <= a; ++b) constant[std::size_t(slotOf(idx[a], idx[b]))] += u[a] * u[b];
    };
    for (const auto& [j, kk] : p.regEdges) {
      const Vec3 d = p.nodes[kk] - p.nodes[j];
      const int vj = p.var[j], vk = p.var[kk];
      for (int r = 0; r < 3; ++r) {
        const int idx[5] = {vj + r, vj + 3 + r, vj + 6 + r, vj + 9 + r, vk + 9 + r};
        const double u[5] = {p.sReg * d[0], p.sReg * d[1], p.sReg * d[2], p.sReg, -p.sReg};
        addRow(idx, u, 5);
      }
    }
    std::vector<int> idx;
    std::vector<double> u;
    for (std::size_t l = 0; l < p.handles.size(); ++l) {
      for (int r = 0; r < 3; ++r) {
        idx.clear();
        u.clear();
        for (int i = 0; i < k; ++i) {
          const std::uint32_t j = p.hNodes[l * k + i];
          if (p.var[j] < 0) continue;
          const double w = p.sCon * p.hWeights[l * k + i];
          const Vec3 dv = p.handles[l] - p.nodes[j];
          for (int c = 0; c < 3; ++c) {
            idx.push_back(p.var[j] + 3 * c + r);
            u.push_back(w * dv[c]);
          }
          idx.push_back(p.var[j] + 9 + r);
          u.push_back(w);
        }
        addRow(idx.data(), u.data(), int(idx.size()));
      }
    }
    std::copy(constant.begin(), constant.end(), lower.valuePtr());
    llt.analyzePattern(lower);
    requireCholmod(llt.cholmod(), "analysis");

    var = p.var;
    hNodes = p.hNodes;
    hWeights = p.hWeights;
    handles = p.handles;
    sReg = p.sReg;
    sCon = p.sCon;
    valid = true;
  }

  // Writes JᵀJ at A into `lower` (its diagonal blocks: constant part + rotation term) and
  // returns the undamped diagonal in `diag`.
  void assemble(const Problem& p, const std::vector<Mat3>& a, Eigen::VectorXd& diag) {
    double* value = lower.valuePtr();
    const double wRot = p.sRot * p.sRot;
    constexpr int kPairs[3][2] = {{0, 1}, {0, 2}, {1, 2}};
    for (std::size_t f = 0; f < p.freeNodes.size(); ++f) {
      const Mat3& m = a[p.freeNodes[f]];
      // Rows of the rotation Jacobian (9 entries over A) and their Gram matrix.
      double rows[6][9] = {};
      for (int q = 0; q < 3; ++q) {
        for (int r = 0; r < 3; ++r) {
          rows[q][3 * kPairs[q][0] + r] = m[kPairs[q][1]][r];
          rows[q][3 * kPairs[q][1] + r] = m[kPairs[q][0]][r];
          rows[3 + q][3 * q + r] = -2.0 * m[q][r];
        }
      }
      const int* s = blockSlots.data() + f * kBlockSlots;
      for (int o = 0; o < 12; ++o) {
        for (int o2 = o; o2 < 12; ++o2, ++s) {
          double v = constant[std::size_t(*s)];
          if (o2 < 9) {
            double rot = 0.0;
            for (int q = 0; q < 6; ++q) rot += rows[q][o] * rows[q][o2];
            v += wRot * rot;
          }
          value[*s] = v;
        }
      }
    }
    diag.resize(p.unknowns);
    for (int i = 0; i < p.unknowns; ++i) diag[i] = value[diagonal[std::size_t(i)]];
  }

  // Sets the diagonal to diag + shift.
  void damp(const Eigen::VectorXd& diag, double shift) {
    double* value = lower.valuePtr();
    for (Eigen::Index i = 0; i < diag.size(); ++i)
      value[diagonal[std::size_t(i)]] = diag[i] + shift;
  }

  // Whether the current factor is that of `lower` as it stands.
  bool factorIsCurrent() const {
    if (!factorValid) return false;
    const double* value = lower.valuePtr();
    for (std::size_t i = 0; i < blockSlots.size(); ++i) {
      if (std::memcmp(&value[blockSlots[i]], &factoredBlocks[i], sizeof(double)) != 0) return false;
    }
    return true;
  }

  // Factorises `lower`; false if it is not (numerically) positive definite.
  bool factorize() {
    factorValid = false;
    llt.factorize(lower);
    requireCholmod(llt.cholmod(), "factorisation");
    factorValid = llt.info() == Eigen::Success;
    if (factorValid) {
      const double* value = lower.valuePtr();
      factoredBlocks.resize(blockSlots.size());
      for (std::size_t i = 0; i < blockSlots.size(); ++i) factoredBlocks[i] = value[blockSlots[i]];
    }
    return factorValid;
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
  // The lowest point out of reach, whatever the thread count (each range stops at its first).
  std::atomic<std::size_t> firstOutOfReach{in.size()};
  tbb::parallel_for(
      tbb::blocked_range<std::size_t>(0, in.size(), 2048),
      [g, b, t, src, dst, &firstOutOfReach](const tbb::blocked_range<std::size_t>& r) {
        Scratch s(g->k);
        std::size_t i = r.begin();
        try {
          for (; i != r.end(); ++i) dst[i] = warpPoint(*g, b, t, src[i], s);
        } catch (const detail::PointOutOfReach&) {
          std::size_t seen = firstOutOfReach.load();
          while (i < seen && !firstOutOfReach.compare_exchange_weak(seen, i)) {
          }
        }
      });
  const std::size_t bad = firstOutOfReach.load();
  if (bad < in.size())
    throwOutOfReach("point " + std::to_string(bad) + " " + describePoint(in[bad]));
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
                                ? sampleNodesPoissonDisk(positions, options.spacing)
                                : sampleNodes(positions, options.spacing);
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
  const GraphIndex& g = *index_;
  if (handles.size() != targets.size()) {
    throw InvalidInput("DeformationGraph::solve: " + std::to_string(handles.size()) +
                       " handles but " + std::to_string(targets.size()) + " targets");
  }
  requireFinite("handles", handles);
  requireFinite("targets", targets, false);  // overflow: see the energy check
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
  const double unit = g.unit;
  p.nodes.resize(m);
  for (std::size_t j = 0; j < m; ++j) p.nodes[j] = g.nodes[j] / unit;
  p.handles.resize(handles.size());
  p.targets.resize(targets.size());
  for (std::size_t l = 0; l < handles.size(); ++l) {
    p.handles[l] = handles[l] / unit;
    p.targets[l] = targets[l] / unit;
  }
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
  // The maps are solved with translations in units of g.unit; an exception leaves the graph
  // as it was.
  struct Restore {
    DeformationGraph& graph;
    std::vector<Mat3> a;
    std::vector<Vec3> t;
    bool done = false;
    ~Restore() {
      if (done) return;
      graph.a_.swap(a);
      graph.t_.swap(t);
    }
  } restore{*this, a_, t_};
  for (std::uint32_t j : p.freeNodes) t_[j] /= unit;

  const int n = p.unknowns;
  Eigen::VectorXd rhs(n);
  double eRot = 0.0, eReg = 0.0, eCon = 0.0;
  const auto energyOf = [&](const std::vector<Mat3>& a, const std::vector<Vec3>& t,
                            double* gradient) {
    p.evaluate(a, t, eRot, eReg, eCon, gradient);
    return options.rotationWeight * eRot + options.regularizationWeight * eReg +
           options.constraintWeight * eCon;
  };
  double energy = energyOf(a_, t_, nullptr);
  // Start from the best rigid fit of the handles to the targets when it beats the current
  // maps. Gauss-Newton then runs in the fit's frame (targets mapped back by its inverse, the
  // fit itself being the identity there): every term is invariant under a rigid change of
  // frame, so any rigid motion of the handles is met at iteration 0, and the start is the rest
  // state, whose kept factor serves while only the targets move.
  const RigidFit fit = rigidFit(handles, targets);
  const Mat3 rt = glm::transpose(fit.r);
  if (n > 0) {
    for (std::size_t l = 0; l < handles.size(); ++l)
      p.targets[l] = rt * (targets[l] - fit.shift) / unit;
    std::vector<Mat3> a0(a_);
    std::vector<Vec3> t0(t_);
    for (std::uint32_t j : p.freeNodes) {
      a0[j] = Mat3(1.0);
      t0[j] = Vec3(0.0);
    }
    const double rigid = energyOf(a0, t0, nullptr);
    if (rigid < energy) {
      a_.swap(a0);
      t_.swap(t0);
      energy = rigid;
      report.rigidStart = true;
    } else {
      for (std::size_t l = 0; l < targets.size(); ++l) p.targets[l] = targets[l] / unit;
    }
  }
  if (!std::isfinite(energy)) {
    // eRot, eReg, eCon are those of the start evaluated last (the rigid fit, if any).
    const char* term = !std::isfinite(options.constraintWeight * eCon)       ? "constraint"
                       : !std::isfinite(options.regularizationWeight * eReg) ? "regulariser"
                                                                             : "rotation";
    throw SolverError(std::string("DeformationGraph::solve: the energy overflows (its ") + term +
                      " term is not finite): the targets are too far from the handles, or the "
                      "weights too large, for double precision");
  }
  report.energies.push_back(energy);
  const auto finish = [&] {
    // The terms are invariant under the fit's rigid change of frame: evaluated in it.
    energyOf(a_, t_, nullptr);
    report.rotationEnergy = eRot;
    report.regularizationEnergy = eReg;
    report.constraintEnergy = eCon;
    for (std::uint32_t j : p.freeNodes) {  // back to world units (and frame)
      t_[j] *= unit;
      if (report.rigidStart) {
        t_[j] = fit.r * (g.nodes[j] + t_[j]) + fit.shift - g.nodes[j];
        a_[j] = fit.r * a_[j];
      }
    }
    restore.done = true;
    return report;
  };
  // Rounding level: the energy with every residual 1e-10 of its term's scale (the handles'
  // spread, the edges' lengths, a unit rotation residual). Nothing is left to solve below it.
  double scale = options.rotationWeight * 6.0 * double(p.freeNodes.size());
  for (const auto& [j, kk] : p.regEdges) {
    const Vec3 d = p.nodes[kk] - p.nodes[j];
    scale += options.regularizationWeight * glm::dot(d, d);
  }
  Vec3 centre(0.0);
  for (const Vec3& h : p.handles) centre += h / double(handles.size());
  for (const Vec3& h : p.handles)
    scale += options.constraintWeight * glm::dot(h - centre, h - centre);
  // Residuals are computed from coordinates of magnitude up to `reach`, so each carries a
  // rounding error of a few ulps of it: far from the origin that, not the scene's size, is
  // the floor (a rigid motion 1e7 away would otherwise iterate on rounding noise).
  double reach = 0.0;
  for (const auto* points : {&p.handles, &p.targets})
    for (const Vec3& x : *points)
      reach = std::max({reach, std::abs(x.x), std::abs(x.y), std::abs(x.z)});
  for (std::uint32_t j : p.freeNodes) {
    const Vec3& x = p.nodes[j];
    reach = std::max({reach, std::abs(x.x), std::abs(x.y), std::abs(x.z)});
  }
  const double ulps = 16.0 * std::numeric_limits<double>::epsilon() * reach;
  const double negligible =
      1e-20 * scale + 3.0 * ulps * ulps *
                          (options.constraintWeight * double(handles.size()) +
                           options.regularizationWeight * double(p.regEdges.size()));
  if (n == 0 || energy <= negligible) {
    report.converged = true;
    return finish();
  }

  // CHOLMOD's supernodal Cholesky (dense BLAS kernels on the supernodes): the fill of a 3D
  // graph makes the factor several times denser than JᵀJ, where a simplicial factorisation
  // crawls. JᵀJ is written straight into a fixed pattern kept in cache_ with its constant part
  // and symbolic analysis (see detail::SolverCache); per iteration only the nodes' diagonal
  // blocks are rewritten. The BLAS runs single-threaded so that the result does not depend on
  // its thread count.
  const detail::SerialBlas serialBlas;
  if (!cache_) cache_ = std::make_unique<detail::SolverCache>();
  detail::SolverCache& cache = *cache_;
  if (!cache.matches(p)) cache.build(p);
  auto& llt = cache.llt;
  const auto solveWith = [&](const Eigen::VectorXd& b, Eigen::VectorXd& x) {
    x = llt.solve(b);
    requireCholmod(llt.cholmod(), "solve");
  };
  // The factor of an earlier iteration's matrix preconditions conjugate gradients on the
  // current one: only the rotation blocks and the damping change between iterations, so a few
  // iterations usually reach the direct solve's accuracy at a fraction of a factorisation.
  // When they do not, the current matrix is factorised. Only a factor computed (or found
  // current) during this solve is used, so the result never depends on earlier solves.
  bool factored = false;
  Eigen::VectorXd cgR, cgZ, cgD, cgAd;
  const auto refine = [&](const Eigen::VectorXd& b, Eigen::VectorXd& x) {
    constexpr int kMaxCgIterations = 25;
    // Relative residual: an inexact Gauss-Newton step, which the energy test below still
    // guards. On the 1,000-node benchmark 1e-4 needs 3 iterations per step where 1e-10 needs
    // 7, changes the final energy by 2e-13 (relative) and no iteration count.
    constexpr double kCgTolerance = 1e-4;
    x.setZero(b.size());
    const double bNorm = b.norm();
    if (!(bNorm > 0.0)) return std::isfinite(bNorm);
    cgR = b;
    solveWith(cgR, cgZ);
    cgD = cgZ;
    double rz = cgR.dot(cgZ);
    for (int i = 0; i < kMaxCgIterations; ++i) {
      symmetricProduct(cache.lower, cgD, cgAd);
      const double dad = cgD.dot(cgAd);
      if (!(dad > 0.0) || !(rz > 0.0)) return false;
      const double alpha = rz / dad;
      x += alpha * cgD;
      cgR -= alpha * cgAd;
      if (cgR.norm() <= kCgTolerance * bNorm) return true;
      solveWith(cgR, cgZ);
      const double rzNext = cgR.dot(cgZ);
      cgD = cgZ + (rzNext / rz) * cgD;
      rz = rzNext;
    }
    return false;
  };
  double lambda = -1.0;  // Levenberg-Marquardt damping, relative to the mean diagonal
  std::vector<Mat3> a2(a_);
  std::vector<Vec3> t2(t_);
  Eigen::VectorXd diag, delta;
  constexpr double kMaxLambda = 1e12;
  bool anyFactor = false;

  for (int iter = 0; iter < options.maxIterations; ++iter) {
    energyOf(a_, t_, rhs.data());  // −Jᵀf at the current state
    cache.assemble(p, a_, diag);
    const double meanDiag = std::max(diag.mean(), 1e-300);
    if (lambda < 0.0) lambda = 1e-9;
    bool accepted = false;
    double next = energy;
    while (lambda <= kMaxLambda) {
      cache.damp(diag, lambda * meanDiag);
      if (cache.factorIsCurrent()) {
        factored = true;
        solveWith(rhs, delta);
      } else if (!(factored && refine(rhs, delta))) {
        if (!cache.factorize()) {
          factored = false;
          lambda *= 10.0;
          continue;
        }
        factored = true;
        solveWith(rhs, delta);
      }
      anyFactor = true;
      for (std::uint32_t j : p.freeNodes) {
        const int v = p.var[j];
        for (int c = 0; c < 3; ++c)
          for (int r = 0; r < 3; ++r) a2[j][c][r] = a_[j][c][r] + delta[v + 3 * c + r];
        for (int r = 0; r < 3; ++r) t2[j][r] = t_[j][r] + delta[v + 9 + r];
      }
      next = energyOf(a2, t2, nullptr);
      if (next < energy) {  // strictly: an unchanged energy is no progress (and not NaN)
        accepted = true;
        break;
      }
      lambda *= 10.0;
    }
    if (!accepted) {
      if (!anyFactor)
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
    // A relative decrease of a few ulps is rounding in the energy's sum, not progress.
    constexpr double kRoundingDecrease = 64.0 * std::numeric_limits<double>::epsilon();
    if (previous - energy <= std::max(options.tolerance, kRoundingDecrease) * previous ||
        energy <= negligible) {
      report.converged = true;
      break;
    }
  }
  return finish();
}

}  // namespace spacewarp
