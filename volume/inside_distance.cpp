#include <spacewarp/volume/inside_distance.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <limits>
#include <memory>
#include <string>
#include <tuple>
#include <utility>

#include <tbb/blocked_range.h>
#include <tbb/info.h>
#include <tbb/parallel_for.h>

#include <spacewarp/core/archive.h>
#include <spacewarp/core/detail/memory_budget.h>
#include <spacewarp/core/errors.h>
#include <spacewarp/volume/mesh_level_set.h>

namespace spacewarp {

namespace {

constexpr double kBandVoxels = 2.0;   // handles may be this far outside the surface
constexpr double kSeedVoxels = 4.0;   // exact Euclidean seeds around each handle
constexpr double kNearVoxels = 1.0;   // exact |x - p| within this ...
constexpr double kBlendVoxels = 1.0;  // ... blended into the grid over this much more
constexpr int kPadVoxels = 4;         // grid margin around the model's bounding box
constexpr double kInf = std::numeric_limits<double>::infinity();

std::string str(double v) {
  char text[32];
  std::snprintf(text, sizeof text, "%.6g", v);
  return text;
}

std::string str(const Vec3& p) { return "(" + str(p.x) + ", " + str(p.y) + ", " + str(p.z) + ")"; }

// The soup's boundary edges: edges (between vertices at equal positions, so unwelded soups count
// as closed) used by an odd number of polygons. A closed surface has none; an open one has no
// inside, and its level set's sign is then arbitrary, so handles would be blamed for it.
struct BoundaryEdges {
  std::size_t count = 0;
  std::uint32_t a = 0, b = 0;  // one of them, by vertex index
};

BoundaryEdges boundaryEdges(const PolygonSoup& soup) {
  const std::size_t nv = soup.positions.size();
  std::vector<std::uint32_t> order(nv);
  for (std::size_t v = 0; v < nv; ++v) order[v] = static_cast<std::uint32_t>(v);
  const auto less = [&](std::uint32_t u, std::uint32_t v) {
    const Vec3& p = soup.positions[u];
    const Vec3& q = soup.positions[v];
    return std::tie(p.x, p.y, p.z) < std::tie(q.x, q.y, q.z);
  };
  std::sort(order.begin(), order.end(), less);
  std::vector<std::uint32_t> id(nv);  // the first vertex at the same position
  for (std::size_t k = 0; k < nv; ++k)
    id[order[k]] = k > 0 && !less(order[k - 1], order[k]) ? id[order[k - 1]] : order[k];
  std::vector<std::pair<std::uint32_t, std::uint32_t>> edges;
  edges.reserve(soup.faceIndices.size());
  for (std::size_t f = 0; f < soup.polygonCount(); ++f) {
    const auto polygon = soup.polygon(f);
    for (std::size_t c = 0; c < polygon.size(); ++c) {
      const std::uint32_t u = id[polygon[c]], v = id[polygon[(c + 1) % polygon.size()]];
      if (u != v) edges.emplace_back(std::min(u, v), std::max(u, v));
    }
  }
  std::sort(edges.begin(), edges.end());
  BoundaryEdges result;
  for (std::size_t k = 0; k < edges.size();) {
    std::size_t end = k;
    while (end < edges.size() && edges[end] == edges[k]) ++end;
    if ((end - k) % 2 == 1 && result.count++ == 0) std::tie(result.a, result.b) = edges[k];
    k = end;
  }
  return result;
}

// Fast marching of |∇u| = 1 on a dense grid of voxel edge h (Sethian 1996; second-order upwind
// differences where two known voxels line up), over the voxels a phase allows, from the voxels
// already known (frozen).
class Marcher {
 public:
  Marcher(std::array<int, 3> dims, double h)
      : nx_(dims[0]),
        ny_(dims[1]),
        nz_(dims[2]),
        h_(h),
        u_(static_cast<std::size_t>(nx_) * ny_ * nz_, kInf),
        known_(u_.size(), 0) {}

  std::vector<double>& values() { return u_; }
  bool known(std::size_t idx) const { return known_[idx] != 0; }

  void seed(std::size_t idx, double value) {
    u_[idx] = value;
    known_[idx] = 1;
  }

  // Marches every voxel that `allowed` accepts and that is connected to the known ones through
  // allowed voxels.
  template <class Allowed>
  void run(const Allowed& allowed) {
    heap_.clear();
    for (std::size_t idx = 0; idx < u_.size(); ++idx) {
      if (known_[idx]) visitNeighbours(idx, allowed);
    }
    while (!heap_.empty()) {
      std::pop_heap(heap_.begin(), heap_.end(), std::greater<>());
      const auto [value, idx] = heap_.back();
      heap_.pop_back();
      if (known_[idx] || value > u_[idx]) continue;  // stale entry
      known_[idx] = 1;
      visitNeighbours(idx, allowed);
    }
  }

 private:
  template <class Allowed>
  void visitNeighbours(std::size_t idx, const Allowed& allowed) {
    const std::size_t sx = 1, sy = static_cast<std::size_t>(nx_), sz = sy * ny_;
    const int i = static_cast<int>(idx % sy);
    const int j = static_cast<int>((idx / sy) % ny_);
    const int k = static_cast<int>(idx / sz);
    if (i > 0) update(idx - sx, allowed);
    if (i + 1 < nx_) update(idx + sx, allowed);
    if (j > 0) update(idx - sy, allowed);
    if (j + 1 < ny_) update(idx + sy, allowed);
    if (k > 0) update(idx - sz, allowed);
    if (k + 1 < nz_) update(idx + sz, allowed);
  }

  template <class Allowed>
  void update(std::size_t idx, const Allowed& allowed) {
    if (known_[idx] || !allowed(idx)) return;
    const double t = solve(idx);
    if (t < u_[idx]) {
      u_[idx] = t;
      heap_.emplace_back(t, idx);
      std::push_heap(heap_.begin(), heap_.end(), std::greater<>());
    }
  }

  double knownValue(std::size_t idx) const { return known_[idx] ? u_[idx] : kInf; }

  // One axis's upwind term α (u − m)²: first order (α = 1, m = u₁) from the nearer known
  // neighbour, second order (α = 9/4, m = (4 u₁ − u₂) / 3) when the one beyond it is known and
  // not larger (Sethian's higher-accuracy scheme).
  struct Term {
    double alpha = 1.0;
    double m = kInf;
  };
  Term axisTerm(std::size_t idx, int coordinate, int size, std::size_t stride) const {
    Term best;
    for (int side = -1; side <= 1; side += 2) {
      const int c1 = coordinate + side;
      if (c1 < 0 || c1 >= size) continue;
      const std::size_t n1 = side < 0 ? idx - stride : idx + stride;
      const double u1 = knownValue(n1);
      if (!(u1 < kInf)) continue;
      Term t{1.0, u1};
      const int c2 = c1 + side;
      if (c2 >= 0 && c2 < size) {
        const double u2 = knownValue(side < 0 ? n1 - stride : n1 + stride);
        if (u2 <= u1) t = {2.25, (4.0 * u1 - u2) / 3.0};
      }
      if (t.m < best.m) best = t;
    }
    return best;
  }

  // The upwind solution at idx of Σ α_a (u − m_a)² = h² over the axes whose m_a are below u.
  double solve(std::size_t idx) const {
    const std::size_t sy = static_cast<std::size_t>(nx_), sz = sy * ny_;
    const int i = static_cast<int>(idx % sy);
    const int j = static_cast<int>((idx / sy) % ny_);
    const int k = static_cast<int>(idx / sz);
    Term t[3] = {axisTerm(idx, i, nx_, 1), axisTerm(idx, j, ny_, sy), axisTerm(idx, k, nz_, sz)};
    std::sort(t, t + 3, [](const Term& a, const Term& b) { return a.m < b.m; });
    double u = t[0].m + h_ / std::sqrt(t[0].alpha);
    double a = t[0].alpha, b = t[0].alpha * t[0].m, c = t[0].alpha * t[0].m * t[0].m;
    for (int n = 1; n < 3 && u > t[n].m; ++n) {
      a += t[n].alpha;
      b += t[n].alpha * t[n].m;
      c += t[n].alpha * t[n].m * t[n].m;
      const double disc = b * b - a * (c - h_ * h_);
      if (!(disc >= 0.0)) break;  // keep the solution with fewer axes
      u = (b + std::sqrt(disc)) / a;
    }
    return u;
  }

  int nx_, ny_, nz_;
  double h_;
  std::vector<double> u_;
  std::vector<std::uint8_t> known_;
  std::vector<std::pair<double, std::size_t>> heap_;
};

// The dense grid the distances live on: voxel centres at integer multiples of h (meshLevelSet's
// grid), the model's box padded by kPadVoxels; voxel (i, j, k) is i + nx (j + ny k).
struct DenseGrid {
  double h = 0.0;
  std::array<long long, 3> lo{};  // the first voxel's index (OpenVDB coordinates)
  std::size_t nx = 0, ny = 0, nz = 0;

  std::size_t count() const { return nx * ny * nz; }
  Vec3 origin() const {
    return Vec3(static_cast<double>(lo[0]), static_cast<double>(lo[1]),
                static_cast<double>(lo[2])) *
           h;
  }
  std::size_t index(std::size_t i, std::size_t j, std::size_t k) const {
    return i + nx * (j + ny * k);
  }
};

void checkInputs(const PolygonSoup& model, const std::vector<Vec3>& handles,
                 const InsideDistanceOptions& options, const std::string& who) {
  if (!std::isfinite(options.voxelSize) || options.voxelSize < 0.0)
    throw InvalidInput(who + "voxelSize must be finite and >= 0, not " + str(options.voxelSize));
  if (handles.empty()) throw InvalidInput(who + "no handles");
  for (std::size_t i = 0; i < handles.size(); ++i) {
    if (!isFinite(handles[i]))
      throw InvalidInput(who + "handle " + std::to_string(i) + " is not finite");
  }
  if (model.positions.empty() || model.polygonCount() == 0)
    throw InvalidInput(who + "the model has no polygons");
  model.validate();
  if (const BoundaryEdges open = boundaryEdges(model); open.count > 0) {
    throw InvalidInput(who + "the model is not closed (" + std::to_string(open.count) +
                       " boundary edges, e.g. between vertices " + std::to_string(open.a) + " " +
                       str(model.positions[open.a]) + " and " + std::to_string(open.b) + " " +
                       str(model.positions[open.b]) + "): inside distances need a closed surface");
  }
}

// The grid around `box` at voxel h for n handles, its memory checked before anything is
// allocated. Counts in double: a tiny voxel gives counts far beyond any integer type.
DenseGrid planGrid(const BoundingBox& box, double h, std::size_t n, const std::string& who) {
  double voxels = 1.0;
  std::array<double, 3> first{}, counts{};
  for (int a = 0; a < 3; ++a) {
    first[a] = std::floor(box.min[a] / h) - kPadVoxels;
    counts[a] = std::ceil(box.max[a] / h) + kPadVoxels - first[a] + 1.0;
    voxels *= counts[a];
  }
  const std::string what = "'voxelSize' " + str(h) + " (" + str(counts[0]) + " x " +
                           str(counts[1]) + " x " + str(counts[2]) + " voxels, " +
                           std::to_string(n) + " handles)";
  const double workers = std::min<double>(static_cast<double>(n),
                                          static_cast<double>(tbb::info::default_concurrency()));
  // Per voxel: 4 bytes per handle kept; the level set, inside flags, nearest inside voxels and
  // their heap (about 40 bytes, OpenVDB's narrow band included); per marching thread the
  // values, states and heap (about 25).
  const double bytes = voxels * (4.0 * static_cast<double>(n) + 40.0 + 25.0 * workers);
  if (!(bytes < 1e21)) {  // beyond any machine: say so rather than print a byte count
    const std::size_t available = detail::availableMemory();
    throw InvalidInput(
        who + what + " needs far more memory than any machine has" +
        (available != std::numeric_limits<std::size_t>::max()
             ? " (" + detail::formatBytes(static_cast<double>(available)) + " available)"
             : std::string()));
  }
  detail::checkMemory(bytes, who + what);
  if (!(voxels < 4e9)) throw InvalidInput(who + what + " has too many voxels");
  DenseGrid grid;
  grid.h = h;
  for (int a = 0; a < 3; ++a) {
    grid.lo[a] = static_cast<long long>(std::clamp(first[a], -1e15, 1e15));
    // OpenVDB's coordinates are 32-bit.
    if (!(std::abs(static_cast<double>(grid.lo[a])) + counts[a] < 0x1p30)) {
      throw InvalidInput(who + "the model lies too far from the origin for " + what +
                         " (voxel indices beyond 2^30)");
    }
  }
  grid.nx = static_cast<std::size_t>(counts[0]);
  grid.ny = static_cast<std::size_t>(counts[1]);
  grid.nz = static_cast<std::size_t>(counts[2]);
  return grid;
}

// The signed distance to the model's surface at every voxel of the grid (OpenVDB's level set,
// background beyond its narrow band).
std::vector<float> sampleLevelSet(const PolygonSoup& model, const DenseGrid& g) {
  const openvdb::FloatGrid::Ptr surface = meshLevelSet(model, g.h, 3.0f);
  std::vector<float> phi(g.count());
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, g.nz), [&](const auto& range) {
    const auto accessor = surface->getConstAccessor();
    for (std::size_t k = range.begin(); k != range.end(); ++k) {
      for (std::size_t j = 0; j < g.ny; ++j) {
        for (std::size_t i = 0; i < g.nx; ++i) {
          const openvdb::Coord c(static_cast<int>(g.lo[0] + static_cast<long long>(i)),
                                 static_cast<int>(g.lo[1] + static_cast<long long>(j)),
                                 static_cast<int>(g.lo[2] + static_cast<long long>(k)));
          phi[g.index(i, j, k)] = accessor.getValue(c);
        }
      }
    }
  });
  return phi;
}

// Handles must be inside or within the band: trilinear φ at the handle.
void checkHandlesInside(const std::vector<Vec3>& handles, const std::vector<float>& phi,
                        const DenseGrid& g, const std::string& who) {
  const double band = kBandVoxels * g.h;
  const std::size_t dims[3] = {g.nx, g.ny, g.nz};
  for (std::size_t hi = 0; hi < handles.size(); ++hi) {
    const Vec3 u = (handles[hi] - g.origin()) / g.h;
    bool inGrid = true;
    for (int a = 0; a < 3; ++a)
      inGrid = inGrid && u[a] >= 0.0 && u[a] <= static_cast<double>(dims[a]) - 1.0;
    double value = kInf;
    if (inGrid) {
      std::size_t i0[3];
      double t[3];
      for (int a = 0; a < 3; ++a) {
        i0[a] = std::min(static_cast<std::size_t>(std::floor(u[a])), dims[a] - 2);
        t[a] = u[a] - static_cast<double>(i0[a]);
      }
      value = 0.0;
      for (int c = 0; c < 8; ++c) {
        const std::size_t di = c & 1, dj = (c >> 1) & 1, dk = (c >> 2) & 1;
        const double w =
            (di ? t[0] : 1.0 - t[0]) * (dj ? t[1] : 1.0 - t[1]) * (dk ? t[2] : 1.0 - t[2]);
        value += w * phi[g.index(i0[0] + di, i0[1] + dj, i0[2] + dk)];
      }
    }
    if (!(value <= band)) {
      throw InvalidInput(who + "handle " + std::to_string(hi) + " " + str(handles[hi]) +
                         " is outside the model (" +
                         (inGrid && value < 3.0 * g.h ? str(value) : "more than " + str(band)) +
                         " from its surface; handles must be inside or within 2 voxels (" +
                         str(band) + ") of it)");
    }
  }
}

// Outside the model a voxel takes the distance of its nearest inside voxel, extrapolated: not a
// shortest path through empty space or along the surface, which would let one part's values
// undercut another's, or cut concave corners, right at the surface. Nearest inside voxels by
// propagating them outwards in order of distance (Danielsson-style; exact up to rare ties).
std::vector<std::size_t> nearestInsideSites(const std::vector<std::uint8_t>& inside,
                                            const DenseGrid& g) {
  const std::size_t count = g.count(), nx = g.nx, ny = g.ny, nz = g.nz;
  std::vector<std::size_t> site(count, count);
  std::vector<double> key(count, kInf);
  std::vector<std::pair<double, std::size_t>> heap;
  for (std::size_t idx = 0; idx < count; ++idx) {
    if (inside[idx]) {
      site[idx] = idx;
      key[idx] = 0.0;
      heap.emplace_back(0.0, idx);
    }
  }
  std::make_heap(heap.begin(), heap.end(), std::greater<>());
  const auto position = [&](std::size_t idx) {
    return Vec3(static_cast<double>(idx % nx), static_cast<double>((idx / nx) % ny),
                static_cast<double>(idx / (nx * ny)));
  };
  while (!heap.empty()) {
    std::pop_heap(heap.begin(), heap.end(), std::greater<>());
    const auto [value, idx] = heap.back();
    heap.pop_back();
    if (value > key[idx]) continue;
    const std::size_t i = idx % nx, j = (idx / nx) % ny, k = idx / (nx * ny);
    const std::size_t steps[6] = {1, 1, nx, nx, nx * ny, nx * ny};
    const bool ok[6] = {i > 0, i + 1 < nx, j > 0, j + 1 < ny, k > 0, k + 1 < nz};
    for (int e = 0; e < 6; ++e) {
      if (!ok[e]) continue;
      const std::size_t next = e % 2 ? idx + steps[e] : idx - steps[e];
      if (inside[next]) continue;
      const double d = glm::length(position(next) - position(site[idx]));
      if (d < key[next] || (d == key[next] && site[idx] < site[next])) {
        key[next] = d;
        site[next] = site[idx];
        heap.emplace_back(d, next);
        std::push_heap(heap.begin(), heap.end(), std::greater<>());
      }
    }
  }
  return site;
}

// The distances from the handle p at every voxel: exact Euclidean seeds around p, marched over
// the inside, extrapolated from each outside voxel's nearest inside site, then marched through
// any voxel for the parts no handle's inside reaches.
std::vector<double> handleDistances(const Vec3& p, const DenseGrid& g,
                                    const std::vector<std::uint8_t>& inside,
                                    const std::vector<std::size_t>& site) {
  const std::size_t count = g.count(), nx = g.nx, ny = g.ny, nz = g.nz;
  const double h = g.h;
  Marcher march({static_cast<int>(nx), static_cast<int>(ny), static_cast<int>(nz)}, h);
  const Vec3 u = (p - g.origin()) / h;
  const int r = static_cast<int>(std::ceil(kSeedVoxels));
  const int dims[3] = {static_cast<int>(nx), static_cast<int>(ny), static_cast<int>(nz)};
  int from[3], to[3];
  for (int a = 0; a < 3; ++a) {
    from[a] = std::max(static_cast<int>(std::floor(u[a])) - r, 0);
    to[a] = std::min(static_cast<int>(std::ceil(u[a])) + r, dims[a] - 1);
  }
  for (int k = from[2]; k <= to[2]; ++k) {
    for (int j = from[1]; j <= to[1]; ++j) {
      for (int i = from[0]; i <= to[0]; ++i) {
        const double dist = glm::length(g.origin() + Vec3(i, j, k) * h - p);
        if (dist <= kSeedVoxels * h) {
          march.seed(g.index(static_cast<std::size_t>(i), static_cast<std::size_t>(j),
                             static_cast<std::size_t>(k)),
                     dist);
        }
      }
    }
  }
  march.run([&](std::size_t idx) { return inside[idx]; });
  std::vector<double>& marched = march.values();
  for (std::size_t idx = 0; idx < count; ++idx) {
    if (inside[idx] || march.known(idx) || !(marched[site[idx]] < kInf)) continue;
    const std::size_t s = site[idx];
    const Vec3 step(static_cast<double>(idx % nx) - static_cast<double>(s % nx),
                    static_cast<double>((idx / nx) % ny) - static_cast<double>((s / nx) % ny),
                    static_cast<double>(idx / (nx * ny)) - static_cast<double>(s / (nx * ny)));
    // Linear extrapolation along the distance's gradient at the site (differences over inside
    // voxels, unit length at most) for the first voxels out, so that a distance that runs along
    // the surface stays level across it; growing with the way out beyond.
    const std::size_t strides[3] = {1, nx, nx * ny};
    const std::size_t coords[3] = {s % nx, (s / nx) % ny, s / (nx * ny)};
    const std::size_t sizes[3] = {nx, ny, nz};
    Vec3 grad(0.0);
    for (int a = 0; a < 3; ++a) {
      const bool lo = coords[a] > 0 && inside[s - strides[a]];
      const bool hi = coords[a] + 1 < sizes[a] && inside[s + strides[a]];
      const double ulo = lo ? marched[s - strides[a]] : marched[s];
      const double uhi = hi ? marched[s + strides[a]] : marched[s];
      if (lo || hi) grad[a] = (uhi - ulo) / ((lo && hi ? 2.0 : 1.0) * h);
    }
    const double gl = glm::length(grad);
    if (gl > 1.0) grad /= gl;
    const double way = h * glm::length(step);
    const double value =
        marched[s] + h * glm::dot(grad, step) + std::max(way - kBandVoxels * h, 0.0);
    march.seed(idx, std::max(value, 0.0));
  }
  // Parts of the model that no handle's inside reaches (another component), and their
  // surroundings: through any voxel.
  march.run([](std::size_t) { return true; });
  return std::move(march.values());
}

}  // namespace

InsideDistances::InsideDistances(const PolygonSoup& model, std::vector<Vec3> handles,
                                 const InsideDistanceOptions& options)
    : handles_(std::move(handles)) {
  const std::string who = "InsideDistances: ";
  checkInputs(model, handles_, options, who);
  const BoundingBox box = boundingBox(model.positions);
  const double diagonal = box.diagonal();
  if (!(diagonal > 0.0)) throw InvalidInput(who + "the model is a single point");
  h_ = options.voxelSize > 0.0 ? options.voxelSize : diagonal / 128.0;
  const std::size_t n = handles_.size();
  const DenseGrid grid = planGrid(box, h_, n, who);
  origin_ = grid.origin();
  dims_ = {static_cast<int>(grid.nx), static_cast<int>(grid.ny), static_cast<int>(grid.nz)};

  const std::vector<float> phi = sampleLevelSet(model, grid);
  const std::size_t count = grid.count();
  std::vector<std::uint8_t> inside(count);
  std::size_t insideCount = 0;
  for (std::size_t idx = 0; idx < count; ++idx) {
    inside[idx] = phi[idx] < 0.0f;
    insideCount += inside[idx];
  }
  if (insideCount == 0) {
    throw InvalidInput(who + "the model encloses no voxel of " + str(h_) +
                       " (is it closed? a smaller voxelSize resolves thinner models)");
  }
  checkHandlesInside(handles_, phi, grid, who);
  const std::vector<std::size_t> site = nearestInsideSites(inside, grid);

  // One march per handle, in parallel; each writes its own entries of values_.
  values_.assign(count * n, 0.0f);
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, 1), [&](const auto& range) {
    for (std::size_t hi = range.begin(); hi != range.end(); ++hi) {
      const std::vector<double> values = handleDistances(handles_[hi], grid, inside, site);
      for (std::size_t idx = 0; idx < count; ++idx)
        values_[idx * n + hi] = static_cast<float>(values[idx]);
    }
  });
}

template <bool Gradients>
void InsideDistances::evaluate(const Vec3& x, double* d, Vec3* g) const {
  const std::size_t n = handles_.size();
  if (!isFinite(x)) {
    for (std::size_t k = 0; k < n; ++k) {
      d[k] = std::numeric_limits<double>::quiet_NaN();
      if constexpr (Gradients) g[k] = Vec3(d[k]);
    }
    return;
  }
  // The nearest point of the grid's box, its cell and the trilinear weights there.
  const Vec3 u = (x - origin_) / h_;
  Vec3 clamped(0.0);
  Vec3 inside(1.0);  // 0 on the axes where x is clamped (the box does not move with x there)
  int i0[3];
  double t[3];
  for (int a = 0; a < 3; ++a) {
    const double hiEdge = dims_[a] - 1.0;
    double ua = u[a];
    if (!(ua >= 0.0)) {
      ua = 0.0;
      inside[a] = 0.0;
    } else if (ua > hiEdge) {
      ua = hiEdge;
      inside[a] = 0.0;
    }
    clamped[a] = ua;
    i0[a] = std::min(static_cast<int>(ua), dims_[a] - 2);
    t[a] = ua - i0[a];
  }
  Vec3 out(0.0);  // x − c, exactly 0 on the axes where x is in the box
  for (int a = 0; a < 3; ++a) {
    if (inside[a] == 0.0) out[a] = x[a] - (origin_[a] + clamped[a] * h_);
  }
  const double outLength = glm::length(out);
  const std::size_t nx = static_cast<std::size_t>(dims_[0]);
  const std::size_t ny = static_cast<std::size_t>(dims_[1]);
  const std::size_t base =
      static_cast<std::size_t>(i0[0]) +
      nx * (static_cast<std::size_t>(i0[1]) + ny * static_cast<std::size_t>(i0[2]));
  const std::size_t offsets[8] = {0,       1,           nx,           nx + 1,
                                  nx * ny, nx * ny + 1, nx * ny + nx, nx * ny + nx + 1};
  double w[8];
  double dw[8][3];
  for (int c = 0; c < 8; ++c) {
    const int b[3] = {c & 1, (c >> 1) & 1, (c >> 2) & 1};
    double f[3], df[3];
    for (int a = 0; a < 3; ++a) {
      f[a] = b[a] ? t[a] : 1.0 - t[a];
      df[a] = b[a] ? 1.0 : -1.0;
    }
    w[c] = f[0] * f[1] * f[2];
    if constexpr (Gradients) {
      dw[c][0] = df[0] * f[1] * f[2];
      dw[c][1] = f[0] * df[1] * f[2];
      dw[c][2] = f[0] * f[1] * df[2];
    }
  }
  const double nearRadius = kNearVoxels * h_;
  const double blendWidth = kBlendVoxels * h_;
  for (std::size_t k = 0; k < n; ++k) {
    double value = 0.0;
    Vec3 grad(0.0);
    for (int c = 0; c < 8; ++c) {
      const double v = values_[(base + offsets[c]) * n + k];
      value += w[c] * v;
      if constexpr (Gradients) grad += Vec3(dw[c][0], dw[c][1], dw[c][2]) * v;
    }
    if constexpr (Gradients) grad = grad * inside / h_;
    if (outLength > 0.0) {
      value += outLength;
      if constexpr (Gradients) grad += out / outLength;
    }
    // Near the handle: the exact Euclidean distance, blended in (smoothstep in r).
    const Vec3 e = x - handles_[k];
    const double r2 = glm::dot(e, e);
    if (r2 < (nearRadius + blendWidth) * (nearRadius + blendWidth)) {
      const double r = std::sqrt(r2);
      const Vec3 dir = r > 0.0 ? e / r : Vec3(0.0);
      if (r <= nearRadius) {
        value = r;
        if constexpr (Gradients) grad = dir;
      } else {
        const double s = (r - nearRadius) / blendWidth;
        const double blend = s * s * (3.0 - 2.0 * s);
        if constexpr (Gradients) {
          const double dBlend = 6.0 * s * (1.0 - s) / blendWidth;
          grad = (1.0 - blend) * dir + blend * grad + (value - r) * dBlend * dir;
        }
        value = (1.0 - blend) * r + blend * value;
      }
    }
    d[k] = value;
    if constexpr (Gradients) g[k] = grad;
  }
}

void InsideDistances::distances(const Vec3& x, std::span<double> distances) const {
  if (distances.size() != handles_.size()) {
    throw InvalidInput("InsideDistances::distances: " + std::to_string(distances.size()) +
                       " entries for " + std::to_string(handles_.size()) + " handles");
  }
  evaluate<false>(x, distances.data(), nullptr);
}

void InsideDistances::distancesAndGradients(const Vec3& x, std::span<double> distances,
                                            std::span<Vec3> gradients) const {
  if (distances.size() != handles_.size() || gradients.size() != handles_.size()) {
    throw InvalidInput(
        "InsideDistances::distancesAndGradients: " + std::to_string(distances.size()) +
        " distances and " + std::to_string(gradients.size()) + " gradients for " +
        std::to_string(handles_.size()) + " handles");
  }
  evaluate<true>(x, distances.data(), gradients.data());
}

void InsideDistances::save(ArchiveWriter& out) const {
  out.tag("inside-distances");
  out.vec3s(handles_);
  out.f64(h_);
  out.vec3(origin_);
  for (int a = 0; a < 3; ++a) out.i32(dims_[a]);
  // The floats' bits, not widened to double: half the size, and read back exactly.
  std::vector<std::uint32_t> bits(values_.size());
  for (std::size_t i = 0; i < values_.size(); ++i)
    bits[i] = std::bit_cast<std::uint32_t>(values_[i]);
  out.u32s(bits);
}

std::shared_ptr<const InsideDistances> InsideDistances::load(ArchiveReader& in) {
  const std::string who = "inside-distances: ";
  std::shared_ptr<InsideDistances> d(new InsideDistances());
  d->handles_ = in.vec3s();
  d->h_ = in.f64();
  d->origin_ = in.vec3();
  for (int a = 0; a < 3; ++a) d->dims_[a] = in.i32();
  const std::size_t n = d->handles_.size();
  if (n == 0) in.fail(who + "no handles");
  for (std::size_t i = 0; i < n; ++i) {
    if (!isFinite(d->handles_[i])) in.fail(who + "handle " + std::to_string(i) + " is not finite");
  }
  if (!std::isfinite(d->h_) || !(d->h_ > 0.0))
    in.fail(who + "voxel size " + str(d->h_) + " is not finite and > 0");
  if (!isFinite(d->origin_)) in.fail(who + "the grid's origin is not finite");
  // The bits are read (their count checked against the archive's size) before the voxel count
  // is trusted, so a hostile grid size allocates nothing.
  const std::vector<std::uint32_t> bits = in.u32s();
  std::uint64_t voxels = 1;
  for (int a = 0; a < 3; ++a) {
    const int size = d->dims_[a];
    if (size < 2)
      in.fail(who + "grid size " + std::to_string(size) + " along axis " + std::to_string(a) +
              " (at least 2)");
    if (voxels > bits.size() / static_cast<std::uint64_t>(size))
      voxels = bits.size() + 1;
    else
      voxels *= static_cast<std::uint64_t>(size);
  }
  if (voxels > bits.size() || bits.size() % voxels != 0 || bits.size() / voxels != n) {
    in.fail(who + std::to_string(bits.size()) + " values for a grid of " +
            std::to_string(d->dims_[0]) + " x " + std::to_string(d->dims_[1]) + " x " +
            std::to_string(d->dims_[2]) + " voxels and " + std::to_string(n) + " handles");
  }
  d->values_.resize(bits.size());
  for (std::size_t i = 0; i < bits.size(); ++i) {
    const float v = std::bit_cast<float>(bits[i]);
    if (!std::isfinite(v) || !(v >= 0.0f)) {
      in.fail(who + "the distance of handle " + std::to_string(i % n) + " at voxel " +
              std::to_string(i / n) + " is " + str(v) + " (finite and >= 0 expected)");
    }
    d->values_[i] = v;
  }
  return d;
}

}  // namespace spacewarp
