#include <spacewarp/nonlinear/shepard.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <sstream>
#include <string>
#include <utility>

#include <nanoflann.hpp>

#include <spacewarp/core/archive.h>
#include <spacewarp/core/errors.h>
#include <spacewarp/nonlinear/detail/graph_index.h>

namespace spacewarp {

namespace {

using Tree = detail::KdTree;  // nanoflann over a vector of points (nonlinear/detail)

// The non-zero weights of one point, by increasing handle index, with what the gradients need.
struct Scratch {
  std::vector<std::uint32_t> index;
  std::vector<double> u;    // u_i normalised by the nearest handle's (largest 1)
  std::vector<double> d2;   // squared distances
  std::size_t nearest = 0;  // position of the nearest handle in `index`
  bool exact = false;       // x is at that handle (squared distance 0)
  double sum = 0.0;         // Σ u
  double inv = 1.0;         // 1 / Σ u: w_i = u_i · inv everywhere (weights, warp, gradients)
  double scale = 1.0;       // the differences behind d2 were multiplied by it (overflow)
};

// A number as a user wrote it ("0.8", not to_string's "0.800000").
std::string numberText(double v) {
  std::ostringstream s;
  s << v;
  return s.str();
}

inline double powHalf(double ratio2, double power) {  // ratio2^(power / 2)
  if (power == 2.0) return ratio2;
  if (power == 1.0) return std::sqrt(ratio2);
  return std::pow(ratio2, 0.5 * power);
}

inline double powOf(double ratio, double power) {
  if (power == 2.0) return ratio * ratio;
  if (power == 1.0) return ratio;
  return std::pow(ratio, power);
}

}  // namespace

struct ShepardCoordinates::Impl {
  std::vector<Vec3> p;
  ShepardOptions options;
  bool local = false;
  std::size_t maxNonZeros = 0;
  // Local support: a uniform grid of cells of size >= R over the handles' box padded by one
  // cell; each cell lists, by increasing index, the handles of its 3 × 3 × 3 block, which hold
  // every handle within R of any point of the cell. So a point reads one list, already in the
  // order its sums are formed in (no search, no sort).
  Vec3 gridLo{0.0};
  double cell = 1.0;
  std::array<std::int64_t, 3> dims{0, 0, 0};
  std::vector<std::uint32_t> cellStart, cellHandles;

  // The cell of x, or -1 outside the grid (then no handle is within R).
  std::int64_t cellOf(const Vec3& x) const {
    std::int64_t index = 0;
    for (int a = 2; a >= 0; --a) {
      const double f = std::floor((x[a] - gridLo[a]) / cell);
      if (!(f >= 0.0) || !(f < static_cast<double>(dims[std::size_t(a)]))) return -1;
      index = index * dims[std::size_t(a)] + static_cast<std::int64_t>(f);
    }
    return index;
  }

  void buildGrid(const Vec3& lo, const Vec3& hi) {
    const double extent = maxAbs(hi - lo);
    // At most ~64 cells per axis: more would cost memory for no speed-up.
    cell = std::max(options.radius, extent / 64.0) * (1.0 + 1e-9);
    gridLo = lo - Vec3(cell);
    for (int a = 0; a < 3; ++a)
      dims[std::size_t(a)] = static_cast<std::int64_t>(std::floor((hi[a] - gridLo[a]) / cell)) + 2;
    const std::size_t cells = std::size_t(dims[0] * dims[1] * dims[2]);
    std::vector<std::uint32_t> count(cells + 1, 0);
    const auto forNeighbours = [&](std::size_t h, auto&& f) {
      const std::int64_t c = cellOf(p[h]);
      const std::int64_t cx = c % dims[0], cy = (c / dims[0]) % dims[1],
                         cz = c / (dims[0] * dims[1]);
      for (std::int64_t z = std::max<std::int64_t>(cz - 1, 0); z <= std::min(cz + 1, dims[2] - 1);
           ++z)
        for (std::int64_t y = std::max<std::int64_t>(cy - 1, 0); y <= std::min(cy + 1, dims[1] - 1);
             ++y)
          for (std::int64_t x = std::max<std::int64_t>(cx - 1, 0);
               x <= std::min(cx + 1, dims[0] - 1); ++x)
            f(std::size_t((z * dims[1] + y) * dims[0] + x));
    };
    for (std::size_t h = 0; h < p.size(); ++h)
      forNeighbours(h, [&](std::size_t c) { ++count[c + 1]; });
    cellStart.assign(cells + 1, 0);
    for (std::size_t c = 0; c < cells; ++c) cellStart[c + 1] = cellStart[c] + count[c + 1];
    cellHandles.resize(cellStart[cells]);
    std::vector<std::uint32_t> fill(cellStart.begin(), cellStart.end() - 1);
    for (std::size_t h = 0; h < p.size(); ++h)
      forNeighbours(h,
                    [&](std::size_t c) { cellHandles[fill[c]++] = static_cast<std::uint32_t>(h); });
  }

  // The non-zero weights of x into s (unnormalised u and their sum); false when no handle is
  // within the radius.
  bool weigh(const Vec3& x, Scratch& s) const {
    s.exact = false;
    s.nearest = 0;
    s.scale = 1.0;
    if (local) {
      s.index.clear();
      s.d2.clear();
      gatherLocal(x, s);
      if (s.index.empty()) return false;
    } else {
      gatherAll(x, s);
    }
    double min2 = s.d2[0];
    for (std::size_t k = 1; k < s.d2.size(); ++k) {
      if (s.d2[k] < min2) {
        min2 = s.d2[k];
        s.nearest = k;
      }
    }
    const double power = options.power;
    s.u.resize(s.index.size());
    if (min2 == 0.0) {
      s.exact = true;
      std::fill(s.u.begin(), s.u.end(), 0.0);
      s.u[s.nearest] = 1.0;
      s.sum = 1.0;
      s.inv = 1.0;
      return true;
    }
    double sum = 0.0;
    if (local) {
      const double r = options.radius;
      const double dk = std::sqrt(min2);
      const double scale = dk / (r - dk);
      for (std::size_t k = 0; k < s.u.size(); ++k) {
        const double d = std::sqrt(s.d2[k]);
        s.u[k] = k == s.nearest ? 1.0 : std::min(1.0, powOf((r - d) / d * scale, power));
        sum += s.u[k];
      }
    } else {
      for (std::size_t k = 0; k < s.u.size(); ++k) {
        s.u[k] = k == s.nearest ? 1.0 : powHalf(min2 / s.d2[k], power);
        sum += s.u[k];
      }
    }
    s.sum = sum;
    s.inv = 1.0 / sum;
    return true;
  }

  // Every handle; squared distances computed on scaled differences when they overflow (points
  // ~1e154 away), which leaves their ratios unchanged.
  void gatherAll(const Vec3& x, Scratch& s) const {
    const std::size_t n = p.size();
    if (s.index.size() != n) {
      s.index.resize(n);
      for (std::size_t i = 0; i < n; ++i) s.index[i] = static_cast<std::uint32_t>(i);
    }
    s.d2.resize(n);
    bool overflow = false;
    for (std::size_t i = 0; i < n; ++i) {
      const Vec3 d = x - p[i];
      s.d2[i] = glm::dot(d, d);
      overflow = overflow || !std::isfinite(s.d2[i]);
    }
    if (!overflow) return;
    double big = 0.0;
    for (std::size_t i = 0; i < n; ++i) big = std::max(big, maxAbs(x - p[i]));
    const double inv = 1.0 / big;
    s.scale = inv;
    for (std::size_t i = 0; i < n; ++i) {
      const Vec3 d = (x - p[i]) * inv;
      s.d2[i] = glm::dot(d, d);
    }
  }

  // The handles strictly within the radius, by increasing index.
  void gatherLocal(const Vec3& x, Scratch& s) const {
    const std::int64_t c = cellOf(x);
    if (c < 0) return;
    const double r = options.radius;
    const double r2 = r * r * (1.0 + 1e-9);  // a cheap reject before the exact test d < R
    for (std::uint32_t k = cellStart[std::size_t(c)]; k != cellStart[std::size_t(c) + 1]; ++k) {
      const std::uint32_t h = cellHandles[k];
      const Vec3 d = x - p[h];
      const double d2 = glm::dot(d, d);
      if (!(d2 < r2) || !(std::sqrt(d2) < r)) continue;
      s.index.push_back(h);
      s.d2.push_back(d2);
    }
  }

  // Gradients of the normalised weights at the non-zero ones of s (after weigh): into g, one per
  // entry of s.index. False where they are not defined (at a handle for p <= 1).
  bool gradients(const Vec3& x, const Scratch& s, std::vector<Vec3>& g) const {
    const std::size_t m = s.index.size();
    g.assign(m, Vec3(0.0));
    const double power = options.power;
    if (s.exact) return power > 1.0;
    // ∇u_i = −p u_i (x − p_i) c_i with c_i = 1 / d_i² (global) or R / (d_i² (R − d_i)) (local);
    // ∇w_i = (∇u_i (1 − w_i) − w_i Σ_{j≠i} ∇u_j) / Σ u, with the nearest handle's 1 − w and
    // Σ_{j≠i} summed over the others (no cancellation when it dominates).
    const double r = options.radius;
    Vec3 others(0.0);
    double otherU = 0.0;
    for (std::size_t k = 0; k < m; ++k) {
      const Vec3 d = (x - p[s.index[k]]) * (s.scale * s.scale);  // d / |d|² = s² d / |s d|²
      double c = 1.0 / s.d2[k];
      if (local) c *= r / (r - std::sqrt(s.d2[k]));
      g[k] = (-power * s.u[k] * c) * d;
      if (k != s.nearest) {
        others += g[k];
        otherU += s.u[k];
      }
    }
    const Vec3 gk = g[s.nearest];
    const double inv = s.inv;
    for (std::size_t k = 0; k < m; ++k) {
      const double w = s.u[k] * inv;
      if (k == s.nearest) {
        g[k] = (gk * (otherU * inv) - w * others) * inv;
      } else {
        g[k] = (g[k] * (1.0 - w) - w * (others - g[k] + gk)) * inv;
      }
    }
    return true;
  }

  [[noreturn]] void throwOutside(const std::string& who, const Vec3& x) const {
    throw InvalidInput(who + ": the point " + detail::describePoint(x) +
                       " is farther than the radius " + numberText(options.radius) +
                       " from every handle (it has no weights)");
  }
};

ShepardCoordinates::ShepardCoordinates(std::vector<Vec3> handles, const ShepardOptions& options) {
  auto impl = std::make_unique<Impl>();
  impl->p = std::move(handles);
  impl->options = options;
  const std::string who = "ShepardCoordinates";
  if (!std::isfinite(options.power) || !(options.power > 0.0))
    throw InvalidInput(who + ": power must be finite and > 0, not " + numberText(options.power));
  // Up to 1e150, like the handles, so that its square and the grid's cells stay finite.
  if (std::isnan(options.radius) || !(options.radius > 0.0) ||
      (std::isfinite(options.radius) && options.radius > detail::kMaxCoordinate))
    throw InvalidInput(who +
                       ": radius must be > 0 and at most 1e150 (or infinite for global "
                       "weights), not " +
                       numberText(options.radius));
  impl->local = std::isfinite(options.radius);
  const std::vector<Vec3>& p = impl->p;
  if (p.empty()) throw InvalidInput(who + ": needs at least 1 handle, got 0");
  if (p.size() > std::numeric_limits<std::uint32_t>::max())
    throw InvalidInput(who + ": too many handles (" + std::to_string(p.size()) + ")");
  Vec3 lo = p[0], hi = p[0];
  for (std::size_t i = 0; i < p.size(); ++i) {
    if (!isFinite(p[i]) || !detail::withinReach(p[i]))
      throw InvalidInput(who + ": handle " + std::to_string(i) +
                         " is not finite (or beyond 1e150, where distances overflow)");
    lo = glm::min(lo, p[i]);
    hi = glm::max(hi, p[i]);
  }
  detail::NodeCloud cloud;
  cloud.points = &impl->p;
  const Tree tree(3, cloud, nanoflann::KDTreeSingleIndexAdaptorParams(10));
  std::vector<std::pair<std::uint32_t, double>> found;
  // Coincident handles: any other handle within 1e-12 of the bounding-box diagonal.
  const double tol = 1e-12 * glm::length(hi - lo);
  const double tol2 = std::max(tol * tol, std::numeric_limits<double>::denorm_min());
  for (std::size_t i = 0; i < p.size(); ++i) {
    const double q[3] = {p[i].x, p[i].y, p[i].z};
    found.clear();
    tree.radiusSearch(q, tol2, found, nanoflann::SearchParams(32, 0.0f, false));
    for (const auto& f : found) {
      if (f.first == i) continue;
      throw InvalidInput(who + ": handles " + std::to_string(std::min<std::size_t>(i, f.first)) +
                         " and " + std::to_string(std::max<std::size_t>(i, f.first)) + " coincide");
    }
  }
  impl->maxNonZeros = p.size();
  if (impl->local) {
    impl->buildGrid(lo, hi);
    // Every handle within R of a point is in its cell's list, so the longest list bounds the
    // non-zeros; counting the handles within 2R of each handle instead costs O(n²) when R
    // covers them all.
    std::size_t most = 1;
    for (std::size_t c = 0; c + 1 < impl->cellStart.size(); ++c)
      most = std::max<std::size_t>(most, impl->cellStart[c + 1] - impl->cellStart[c]);
    impl->maxNonZeros = std::min(most, p.size());
  }
  impl_ = std::move(impl);
}

ShepardCoordinates::~ShepardCoordinates() = default;

std::size_t ShepardCoordinates::controlPointCount() const { return impl_->p.size(); }
std::span<const Vec3> ShepardCoordinates::restControlPoints() const { return impl_->p; }
std::size_t ShepardCoordinates::maxNonZeros() const { return impl_->maxNonZeros; }
const ShepardOptions& ShepardCoordinates::options() const { return impl_->options; }
bool ShepardCoordinates::local() const { return impl_->local; }

void ShepardCoordinates::weights(const Vec3& x, std::span<double> row) const {
  checkWeightsArguments(x, row.size());
  Scratch s;
  if (!impl_->weigh(x, s)) impl_->throwOutside("ShepardCoordinates", x);
  std::fill(row.begin(), row.end(), 0.0);
  for (std::size_t k = 0; k < s.index.size(); ++k) row[s.index[k]] = s.u[k] * s.inv;
}

std::size_t ShepardCoordinates::sparseWeights(const Vec3& x, std::span<SparseWeight> out) const {
  if (!isFinite(x)) throw InvalidInput("ShepardCoordinates: the query point is not finite");
  Scratch s;
  if (!impl_->weigh(x, s)) impl_->throwOutside("ShepardCoordinates", x);
  std::size_t count = 0;
  for (std::size_t k = 0; k < s.index.size(); ++k) {
    const double w = s.u[k] * s.inv;
    if (w == 0.0) continue;
    if (count == out.size())
      throw InvalidInput("ShepardCoordinates: more non-zero weights than the sparse row holds");
    out[count++] = {s.index[k], w};
  }
  return count;
}

bool ShepardCoordinates::weightGradients(const Vec3& x, std::span<Vec3> out) const {
  if (!isFinite(x)) throw InvalidInput("ShepardCoordinates: the query point is not finite");
  if (out.size() != columnCount())
    throw InvalidInput("ShepardCoordinates: the gradient output has the wrong size");
  Scratch s;
  if (!impl_->weigh(x, s)) impl_->throwOutside("ShepardCoordinates", x);
  std::vector<Vec3> g;
  if (!impl_->gradients(x, s, g)) return false;
  std::fill(out.begin(), out.end(), Vec3(0.0));
  for (std::size_t k = 0; k < s.index.size(); ++k) out[s.index[k]] = g[k];
  return true;
}

UnmappedPoints ShepardCoordinates::weightsRange(std::span<const Vec3> points,
                                                std::span<double> rows, std::size_t begin,
                                                std::size_t end) const {
  const std::size_t m = columnCount();
  UnmappedPoints outside;
  Scratch s;
  for (std::size_t i = begin; i != end; ++i) {
    const std::span<double> row = rows.subspan(i * m, m);
    std::fill(row.begin(), row.end(), 0.0);
    if (!impl_->weigh(points[i], s)) {
      outside.add(i);
      continue;
    }
    for (std::size_t k = 0; k < s.index.size(); ++k) row[s.index[k]] = s.u[k] * s.inv;
  }
  return outside;
}

void ShepardCoordinates::throwUnmapped(const UnmappedPoints& unmapped,
                                       std::span<const Vec3> points) const {
  throw InvalidInput("ShepardCoordinates: " + std::to_string(unmapped.count) + " of " +
                     std::to_string(points.size()) + " points are farther than the radius " +
                     numberText(impl_->options.radius) + " from every handle (the first is point " +
                     std::to_string(unmapped.first) + " at " +
                     detail::describePoint(points[unmapped.first]) + ")");
}

std::shared_ptr<const Warp> ShepardCoordinates::makeWarpFor(std::shared_ptr<const Coordinates> self,
                                                            std::span<const Vec3> posed) const {
  return std::make_shared<ShepardWarp>(
      std::static_pointer_cast<const ShepardCoordinates>(std::move(self)), posed);
}

ShepardWarp::ShepardWarp(std::shared_ptr<const ShepardCoordinates> coordinates,
                         std::span<const Vec3> targets)
    : coordinates_(std::move(coordinates)) {
  if (!coordinates_) throw InvalidInput("ShepardWarp: the coordinates are null");
  const std::span<const Vec3> p = coordinates_->restControlPoints();
  if (targets.size() != p.size()) {
    throw InvalidInput("ShepardWarp: " + std::to_string(p.size()) + " handles but " +
                       std::to_string(targets.size()) + " targets");
  }
  displacement_.resize(p.size());
  for (std::size_t i = 0; i < p.size(); ++i) {
    if (!isFinite(targets[i]))
      throw InvalidInput("ShepardWarp: target " + std::to_string(i) + " is not finite");
    displacement_[i] = targets[i] - p[i];
  }
}

ShepardWarp::ShepardWarp(std::vector<Vec3> handles, std::span<const Vec3> targets,
                         const ShepardOptions& options)
    : ShepardWarp(std::make_shared<const ShepardCoordinates>(std::move(handles), options),
                  targets) {}

namespace {

// x + Σ w_i D_i in handle order: the sum CoordinateWarp forms from the same weights.
inline Vec3 displaced(const Vec3& x, const Scratch& s, const std::vector<Vec3>& displacement) {
  Vec3 sum(0.0);
  for (std::size_t k = 0; k < s.index.size(); ++k)
    sum += (s.u[k] * s.inv) * displacement[s.index[k]];
  return x + sum;
}

}  // namespace

Vec3 ShepardWarp::apply(const Vec3& x) const {
  if (!isFinite(x)) throw InvalidInput("ShepardWarp: the point is not finite");
  Scratch s;
  if (!coordinates_->impl_->weigh(x, s)) coordinates_->impl_->throwOutside("ShepardWarp", x);
  return displaced(x, s, displacement_);
}

UnmappedPoints ShepardWarp::applyRange(std::span<const Vec3> in, std::span<Vec3> out,
                                       std::size_t begin, std::size_t end) const {
  UnmappedPoints outside;
  Scratch s;
  for (std::size_t i = begin; i != end; ++i) {
    const Vec3 x = in[i];
    if (!isFinite(x) || !coordinates_->impl_->weigh(x, s)) {
      out[i] = x;
      outside.add(i);
      continue;
    }
    out[i] = displaced(x, s, displacement_);
  }
  return outside;
}

void ShepardWarp::throwUnmapped(const UnmappedPoints& unmapped, std::span<const Vec3> in) const {
  for (std::size_t i = 0; i < in.size(); ++i) {
    if (!isFinite(in[i]))
      throw InvalidInput("ShepardWarp: point " + std::to_string(i) + " is not finite");
  }
  throw InvalidInput("ShepardWarp: " + std::to_string(unmapped.count) + " of " +
                     std::to_string(in.size()) + " points are farther than the radius " +
                     numberText(coordinates_->options().radius) +
                     " from every handle (the first is point " + std::to_string(unmapped.first) +
                     " at " + detail::describePoint(in[unmapped.first]) + ")");
}

Mat3 ShepardWarp::jacobian(const Vec3& x) const {
  if (!isFinite(x)) throw InvalidInput("ShepardWarp: the point is not finite");
  const auto& impl = *coordinates_->impl_;
  Scratch s;
  if (!impl.weigh(x, s)) impl.throwOutside("ShepardWarp", x);
  std::vector<Vec3> g;
  if (!impl.gradients(x, s, g)) return Warp::jacobian(x);
  Mat3 j(1.0);
  for (std::size_t k = 0; k < s.index.size(); ++k)
    for (int c = 0; c < 3; ++c) j[c] += displacement_[s.index[k]] * g[k][c];
  return j;
}

void ShepardCoordinates::save(ArchiveWriter& out) const {
  out.tag("shepard");
  out.vec3s(impl_->p);
  out.f64(impl_->options.power);
  out.f64(impl_->options.radius);
}

std::shared_ptr<const ShepardCoordinates> ShepardCoordinates::load(ArchiveReader& in) {
  std::vector<Vec3> handles = in.vec3s();
  ShepardOptions options;
  options.power = in.f64();
  options.radius = in.f64();
  return std::make_shared<const ShepardCoordinates>(std::move(handles), options);
}

ShepardWarp::ShepardWarp(std::shared_ptr<const ShepardCoordinates> coordinates,
                         std::vector<Vec3> displacement, Displacements)
    : coordinates_(std::move(coordinates)), displacement_(std::move(displacement)) {}

void ShepardWarp::save(ArchiveWriter& out) const {
  out.tag("shepard-warp");
  out.coordinates(*coordinates_);
  out.vec3s(displacement_);
}

std::shared_ptr<const ShepardWarp> ShepardWarp::load(ArchiveReader& in) {
  auto coordinates = std::dynamic_pointer_cast<const ShepardCoordinates>(in.coordinates());
  if (!coordinates) in.fail("shepard-warp: the coordinates are not Shepard's");
  std::vector<Vec3> displacement = in.vec3s();
  if (displacement.size() != coordinates->controlPointCount()) {
    in.fail("shepard-warp: " + std::to_string(displacement.size()) + " displacements for " +
            std::to_string(coordinates->controlPointCount()) + " handles");
  }
  for (std::size_t i = 0; i < displacement.size(); ++i) {
    if (!isFinite(displacement[i]))
      in.fail("shepard-warp: displacement " + std::to_string(i) + " is not finite");
  }
  return std::shared_ptr<const ShepardWarp>(
      new ShepardWarp(std::move(coordinates), std::move(displacement), Displacements{}));
}

}  // namespace spacewarp
