#include <spacewarp/nonlinear/detail/graph_index.h>

#include <algorithm>
#include <limits>
#include <sstream>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <spacewarp/core/errors.h>

namespace spacewarp::detail {

std::string describePoint(const Vec3& x) {
  std::ostringstream s;
  s.precision(17);
  s << "(" << x.x << ", " << x.y << ", " << x.z << ")";
  return s.str();
}

void throwOutOfReach(const std::string& what) {
  throw InvalidInput("DeformationGraph: " + what +
                     " is so far from the graph's nodes that squared distances overflow");
}

void requireFinite(const char* what, std::span<const Vec3> points, bool bounded) {
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
                       " needs at least k + 1 = " + std::to_string(std::int64_t{k} + 1) +
                       " nodes, but the graph has " + std::to_string(nodeCount));
  }
}

// ---- the lookup grid ----

namespace {

// The typical distance from a node to its (k+1)-th nearest node: the median over up to ~256
// nodes spread through the list.
double typicalReach(const GraphIndex& g) {
  const std::size_t m = g.nodes.size();
  const std::size_t n = static_cast<std::size_t>(g.k) + 1;
  std::vector<double> reach;
  std::vector<std::uint32_t> idx(n);
  std::vector<double> d2(n);
  const std::size_t step = std::max<std::size_t>(1, m / 256);
  for (std::size_t i = 0; i < m; i += step) {
    const double q[3] = {g.nodes[i].x, g.nodes[i].y, g.nodes[i].z};
    g.tree->knnSearch(q, n, idx.data(), d2.data());
    reach.push_back(std::sqrt(*std::max_element(d2.begin(), d2.end())));
  }
  std::nth_element(reach.begin(), reach.begin() + std::ptrdiff_t(reach.size() / 2), reach.end());
  return reach[reach.size() / 2];
}

// Sets the grid's cells: edge h (returned), a quarter of the typical reach, over the nodes'
// bounding box padded by that reach, widened until there are at most 64 cells per node (plus
// 4096). False, leaving no grid, if the reach is zero or no edge keeps the count that low.
bool chooseGridCells(GraphIndex& g, double& h) {
  const double typical = typicalReach(g);
  h = 0.25 * typical;
  Vec3 lo(std::numeric_limits<double>::infinity()), hi(-std::numeric_limits<double>::infinity());
  for (const Vec3& p : g.nodes) {
    lo = glm::min(lo, p);
    hi = glm::max(hi, p);
  }
  if (!(h > 0.0) || !std::isfinite(h)) return false;
  lo -= Vec3(typical);  // points a little outside the nodes' box use the grid too
  hi += Vec3(typical);
  const double maxCells = 64.0 * double(g.nodes.size()) + 4096.0;
  std::array<double, 3> counts{};
  for (int attempt = 0; attempt < 64; ++attempt) {
    for (int a = 0; a < 3; ++a) counts[size_t(a)] = std::floor((hi[a] - lo[a]) / h) + 1.0;
    const double total = counts[0] * counts[1] * counts[2];
    if (total <= maxCells) break;
    h *= std::max(1.01, std::cbrt(total / maxCells));
  }
  if (!(counts[0] * counts[1] * counts[2] <= maxCells)) return false;
  for (int a = 0; a < 3; ++a) g.dims[size_t(a)] = static_cast<std::int64_t>(counts[size_t(a)]);
  g.gridOrigin = lo;
  g.inverseCell = 1.0 / h;
  return true;
}

// Lists every cell's candidates (see buildLookupGrid) into g.cellOffsets and g.candidates.
// Compressed rows (one offset per cell, one flat candidate array): a std::vector per cell cost
// more than its few dozen indices. Cells are listed in chunks, in parallel, each into a flat
// buffer of its own, and the buffers joined in cell order: the same array for any thread
// count. An empty list leaves the cell to the KD-tree (too many candidates).
void listCandidates(GraphIndex& g, double h) {
  const std::size_t n = static_cast<std::size_t>(g.k) + 1;
  const std::array<std::int64_t, 3> dims = g.dims;
  const std::size_t cells = std::size_t(dims[0] * dims[1] * dims[2]);
  const double r = 0.5 * std::sqrt(3.0) * h;
  constexpr std::size_t kMaxList = 96;
  constexpr std::size_t kChunk = 4096;
  const std::size_t chunks = (cells + kChunk - 1) / kChunk;
  std::vector<std::vector<std::uint32_t>> chunkLists(chunks);
  std::vector<std::uint32_t> listSizes(cells, 0);
  tbb::parallel_for(
      tbb::blocked_range<std::size_t>(0, chunks, 1),
      [&](const tbb::blocked_range<std::size_t>& br) {
        std::vector<std::uint32_t> ki(n);
        std::vector<double> kd(n);
        std::vector<std::uint32_t> li(kMaxList + 1);
        std::vector<double> ld(kMaxList + 1);
        for (std::size_t chunk = br.begin(); chunk != br.end(); ++chunk) {
          auto& flat = chunkLists[chunk];
          for (std::size_t cIndex = chunk * kChunk; cIndex < std::min(cells, (chunk + 1) * kChunk);
               ++cIndex) {
            const std::int64_t ci = std::int64_t(cIndex);
            const Vec3 center = g.gridOrigin + h * Vec3(double(ci % dims[0]) + 0.5,
                                                        double((ci / dims[0]) % dims[1]) + 0.5,
                                                        double(ci / (dims[0] * dims[1])) + 0.5);
            const double q[3] = {center.x, center.y, center.z};
            g.tree->knnSearch(q, n, ki.data(), kd.data());
            const double radius = std::sqrt(*std::max_element(kd.begin(), kd.end())) + 2.0 * r;
            // Squared radius, widened by a relative margin against rounding.
            const double r2 = radius * radius * (1.0 + 1e-9);
            // The nodes within r2 (nanoflann's radius test, d² < r2) found among the
            // kMaxList + 1 nearest: if the last of those is inside, the list is too long
            // anyway. A radius search would visit every node within r2 (all of a far cluster,
            // from a cell far from it), which made the build quadratic.
            const std::size_t nearest =
                g.tree->knnSearch(q, std::min(kMaxList + 1, g.nodes.size()), li.data(), ld.data());
            std::size_t inside = 0;
            while (inside < nearest && ld[inside] < r2) ++inside;
            if (inside > kMaxList || inside < n) continue;
            const std::size_t first = flat.size();
            flat.insert(flat.end(), li.begin(), li.begin() + std::ptrdiff_t(inside));
            std::sort(flat.begin() + std::ptrdiff_t(first), flat.end());
            listSizes[cIndex] = static_cast<std::uint32_t>(inside);
          }
          flat.shrink_to_fit();
        }
      });
  g.cellOffsets.assign(cells + 1, 0);
  for (std::size_t c = 0; c < cells; ++c) g.cellOffsets[c + 1] = g.cellOffsets[c] + listSizes[c];
  g.candidates.reserve(g.cellOffsets[cells]);
  for (auto& flat : chunkLists) {
    g.candidates.insert(g.candidates.end(), flat.begin(), flat.end());
    std::vector<std::uint32_t>().swap(flat);
  }
}

}  // namespace

// Cells of edge h (a quarter of the typical distance to the (k+1)-th nearest node) over the
// nodes' bounding box padded by that distance; each cell lists every node within D + 2r of its
// center, D = the center's (k+1)-th nearest distance, r = the cell's half-diagonal. For any x
// in the cell, its k + 1 nearest nodes lie within d_(k+1)(x) <= |x − c| + D <= r + D of x, so
// within D + 2r of c: the list is complete.
void GraphIndex::buildLookupGrid() {
  double h = 0.0;
  if (!chooseGridCells(*this, h)) return;
  listCandidates(*this, h);
}

// ---- topology ----

namespace {

// The k nearest nodes of every position (n rows of k), in parallel.
std::vector<std::uint32_t> influencingNodes(const GraphIndex& g, std::span<const Vec3> positions) {
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
  return influence;
}

// Per node, every other node within its own cut-off d_(k+1) (the k nearest others, ties
// included up to rounding): the k nearest of a point break ties by index, which splits a
// regular grid of nodes (all neighbours tie) into parts that no handle may reach.
std::vector<std::vector<std::uint32_t>> nodesWithinCutOff(const GraphIndex& g) {
  const int k = g.k;
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
  return near;
}

// The largest extent of the nodes' bounding box, or 1 if they all coincide.
double unitOfLength(const std::vector<Vec3>& nodes) {
  Vec3 lo = nodes[0], hi = nodes[0];
  for (const Vec3& x : nodes) {
    lo = glm::min(lo, x);
    hi = glm::max(hi, x);
  }
  const double extent = std::max({hi.x - lo.x, hi.y - lo.y, hi.z - lo.z});
  return extent > 0.0 ? extent : 1.0;
}

// The undirected edges (i < j), sorted and unique: pairs of nodes that influence a common
// position (`influence`: rows of k) and each node with the nodes `near` it.
std::vector<std::pair<std::uint32_t, std::uint32_t>> collectEdges(
    const std::vector<std::uint32_t>& influence, int k,
    const std::vector<std::vector<std::uint32_t>>& near) {
  const std::size_t n = influence.size() / std::size_t(k), m = near.size();
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
  return pairs;
}

// g.adjacencyOffsets and g.adjacency (CSR, both directions) from g.edges.
void buildAdjacency(GraphIndex& g) {
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
}

// Components by breadth-first search, numbered in order of their lowest node.
void labelComponents(GraphIndex& g) {
  const std::size_t m = g.nodes.size();
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

}  // namespace

void buildTopology(GraphIndex& g, std::span<const Vec3> positions) {
  const std::vector<std::uint32_t> influence = influencingNodes(g, positions);
  const std::vector<std::vector<std::uint32_t>> near = nodesWithinCutOff(g);
  g.unit = unitOfLength(g.nodes);
  g.edges = collectEdges(influence, g.k, near);
  buildAdjacency(g);
  labelComponents(g);
}

}  // namespace spacewarp::detail
