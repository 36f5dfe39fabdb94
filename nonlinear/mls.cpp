#include <spacewarp/nonlinear/mls.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <functional>
#include <limits>
#include <numeric>
#include <string>
#include <utility>

#include <spacewarp/core/archive.h>
#include <spacewarp/core/detail/enum_names.h>
#include <spacewarp/core/detail/rotation.h>
#include <spacewarp/core/errors.h>

namespace spacewarp {

namespace {

// Everything the per-point fit reads, by value (pointers into the warp's vectors).
struct Model {
  const Vec3* p = nullptr;
  const Vec3* q = nullptr;  // null for coordinates (no targets)
  std::size_t n = 0;
  double alpha = 1.0;
  MlsMode mode = MlsMode::Rigid;
  const HandleDistances* distances = nullptr;  // null: Euclidean
};

// Per-point scratch of n doubles: on the stack for small handle sets, else one allocation.
class Scratch {
 public:
  explicit Scratch(std::size_t n) {
    if (n > local_.size()) heap_.resize(n);
    data_ = n > local_.size() ? heap_.data() : local_.data();
  }
  double* data() { return data_; }

 private:
  std::array<double, 64> local_{};
  std::vector<double> heap_;
  double* data_;
};

inline double powAlpha(double ratio, double alpha) {
  if (alpha == 1.0) return ratio;
  if (alpha == 2.0) return ratio * ratio;
  return std::pow(ratio, alpha);
}

// The weights of one point, normalised so that the largest is 1 (or, pinned, so that the largest
// of the other handles' is 1), with the weighted centroids.
struct WeightSet {
  std::size_t nearest = 0;
  bool exact = false;   // x is the nearest handle
  bool pinned = false;  // the nearest handle dominates: limit fit, w[nearest] = 0
  double sum = 0.0;     // Σ w_i
  Vec3 pc{0.0}, qc{0.0};
};

// The nearest handle outweighs all others together by more than 2^60 (so that its limit fit
// equals the formula to rounding) when n (r_min² / r_2²)^alpha is below this.
constexpr double kPinRatio = 0x1p-60;

// Pass 1 over the handles: the squared distances into w, the nearest handle, and whether the
// point is pinned to it. Returns the normalising squared distance of the weights.
double scanHandles(const Model& m, const Vec3& x, double* w, WeightSet& s) {
  double min1 = std::numeric_limits<double>::infinity();
  double min2 = min1;
  if (m.distances) m.distances->distances(x, {w, m.n});
  for (std::size_t i = 0; i < m.n; ++i) {
    double r2;
    if (m.distances) {
      r2 = w[i] * w[i];
    } else {
      const Vec3 d = x - m.p[i];
      r2 = glm::dot(d, d);
    }
    w[i] = r2;
    if (r2 < min1) {
      min2 = min1;
      min1 = r2;
      s.nearest = i;
    } else if (r2 < min2) {
      min2 = r2;
    }
  }
  s.exact = min1 == 0.0;
  s.pinned = s.exact || static_cast<double>(m.n) * powAlpha(min1 / min2, m.alpha) < kPinRatio;
  return s.pinned ? min2 : min1;
}

// The weights of one point into w (see WeightSet) and the weighted centroids.
WeightSet computeWeights(const Model& m, const Vec3& x, double* w) {
  WeightSet s;
  const double scale = scanHandles(m, x, w, s);
  Vec3 sp(0.0), sq(0.0);
  double sum = 0.0;
  for (std::size_t i = 0; i < m.n; ++i) {
    const double wi = (s.pinned && i == s.nearest) ? 0.0 : powAlpha(scale / w[i], m.alpha);
    w[i] = wi;
    sum += wi;
    sp += wi * m.p[i];
    if (m.q) sq += wi * m.q[i];
  }
  s.sum = sum;
  if (s.pinned) {
    s.pc = m.p[s.nearest];
    if (m.q) s.qc = m.q[s.nearest];
  } else {
    s.pc = sp / sum;
    if (m.q) s.qc = sq / sum;
  }
  return s;
}

inline double frobeniusDot(const Mat3& a, const Mat3& b) {
  return glm::dot(a[0], b[0]) + glm::dot(a[1], b[1]) + glm::dot(a[2], b[2]);
}

// Weighted second moments of one point (the centroids subtracted).
struct Moments {
  Mat3 pp{0.0};   // Σ w p̂ p̂ᵀ (Affine only)
  Mat3 qp{0.0};   // Σ w q̂ p̂ᵀ
  double mu = 0;  // Σ w |p̂|² (Similarity only)
};

Moments computeMoments(const Model& m, const WeightSet& s, const double* w) {
  Moments mo;
  for (std::size_t i = 0; i < m.n; ++i) {
    const double wi = w[i];
    const Vec3 ph = m.p[i] - s.pc;
    const Vec3 wq = wi * (m.q[i] - s.qc);
    mo.qp += glm::outerProduct(wq, ph);
    if (m.mode == MlsMode::Affine) {
      mo.pp += glm::outerProduct(wi * ph, ph);
    } else if (m.mode == MlsMode::Similarity) {
      mo.mu += wi * glm::dot(ph, ph);
    }
  }
  return mo;
}

// The local transform T from the moments; for Rigid and Similarity also the rotation.
Mat3 transformOf(const Model& m, const Moments& mo, Mat3* rotation = nullptr,
                 double* scale = nullptr) {
  if (m.mode == MlsMode::Affine) return mo.qp * glm::inverse(mo.pp);
  const Mat3 r = detail::closestRotation(mo.qp);
  if (rotation) *rotation = r;
  double s = 1.0;
  if (m.mode == MlsMode::Similarity) s = frobeniusDot(r, mo.qp) / mo.mu;
  if (scale) *scale = s;
  return s * r;
}

// The local fit in two passes over the handles: the scan, then weights, centroids and moments
// together, accumulated about the nearest handle (p_k, q_k) and corrected to the centroids:
// Σ w q̂ p̂ᵀ = Σ w (q − q_k)(p − p_k)ᵀ − W b aᵀ, a = p* − p_k, b = q* − q_k. Shifting to the
// nearest handle keeps the sums at the scale of the handle spread (no cancellation from far
// coordinates), and pinned points need no correction (p* = p_k).
MlsFit fitAt(const Model& m, const Vec3& x, double* w, WeightSet& s) {
  const double scale = scanHandles(m, x, w, s);
  const Vec3 pr = m.p[s.nearest];
  const Vec3 qr = m.q[s.nearest];
  double sum = 0.0;
  Vec3 sp(0.0), sq(0.0);
  Moments mo;
  for (std::size_t i = 0; i < m.n; ++i) {
    const double wi = (s.pinned && i == s.nearest) ? 0.0 : powAlpha(scale / w[i], m.alpha);
    const Vec3 dp = m.p[i] - pr;
    const Vec3 wdp = wi * dp;
    const Vec3 wdq = wi * (m.q[i] - qr);
    sum += wi;
    sp += wdp;
    sq += wdq;
    mo.qp += glm::outerProduct(wdq, dp);
    if (m.mode == MlsMode::Affine) {
      mo.pp += glm::outerProduct(wdp, dp);
    } else if (m.mode == MlsMode::Similarity) {
      mo.mu += glm::dot(wdp, dp);
    }
  }
  s.sum = sum;
  MlsFit fit;
  if (s.pinned) {
    fit.handleCentroid = pr;
    fit.targetCentroid = qr;
  } else {
    const Vec3 a = sp / sum;
    const Vec3 b = sq / sum;
    fit.handleCentroid = pr + a;
    fit.targetCentroid = qr + b;
    mo.qp -= glm::outerProduct(sum * b, a);
    if (m.mode == MlsMode::Affine) {
      mo.pp -= glm::outerProduct(sum * a, a);
    } else if (m.mode == MlsMode::Similarity) {
      mo.mu -= sum * glm::dot(a, a);
    }
  }
  s.pc = fit.handleCentroid;
  s.qc = fit.targetCentroid;
  fit.transform = transformOf(m, mo);
  return fit;
}

// The one per-point map, used by apply() and applyBatch() alike (bit-identical results).
inline Vec3 mlsPoint(const Model& m, const Vec3& x, double* w) {
  WeightSet s;
  const MlsFit fit = fitAt(m, x, w, s);
  if (s.exact) return m.q[s.nearest];
  return fit.transform * (x - fit.handleCentroid) + fit.targetCentroid;
}

// The singular values of the centered points (their spread along the principal directions),
// largest first.
std::array<double, 3> singularSpread(const std::vector<Vec3>& pts) {
  Vec3 c(0.0);
  for (const Vec3& p : pts) c += p;
  c /= static_cast<double>(pts.size());
  Mat3 cov(0.0);
  for (const Vec3& p : pts) cov += glm::outerProduct(p - c, p - c);
  double e[3];
  Mat3 v;
  detail::symmetricEigen(cov, e, v);
  std::array<double, 3> s = {std::sqrt(std::max(e[0], 0.0)), std::sqrt(std::max(e[1], 0.0)),
                             std::sqrt(std::max(e[2], 0.0))};
  std::sort(s.begin(), s.end(), std::greater<>());
  return s;
}

std::string indexed(const std::string& what, std::size_t i) {
  return what + " " + std::to_string(i);
}

// Validates handles (and targets, if given) for the mode; `who` prefixes messages.
void validate(const std::string& who, const std::vector<Vec3>& handles,
              const std::vector<Vec3>* targets, MlsMode mode, double alpha) {
  if (!std::isfinite(alpha) || !(alpha > 0.0))
    throw InvalidInput(who + ": alpha must be finite and > 0, not " + std::to_string(alpha));
  if (targets && targets->size() != handles.size()) {
    throw InvalidInput(who + ": " + std::to_string(handles.size()) + " handles but " +
                       std::to_string(targets->size()) + " targets");
  }
  const std::size_t needed = mode == MlsMode::Affine ? 4 : 3;
  if (handles.size() < needed) {
    throw InvalidInput(who + ": " + mlsModeName(mode) + " mode needs at least " +
                       std::to_string(needed) + " handles, got " + std::to_string(handles.size()));
  }
  for (std::size_t i = 0; i < handles.size(); ++i) {
    if (!isFinite(handles[i]))
      throw InvalidInput(who + ": " + indexed("handle", i) + " is not finite");
    if (targets && !isFinite((*targets)[i]))
      throw InvalidInput(who + ": " + indexed("target", i) + " is not finite");
  }
  // Coincident handles: sort by x, compare neighbours within the tolerance along x.
  Vec3 lo = handles[0], hi = handles[0];
  for (const Vec3& p : handles) {
    lo = glm::min(lo, p);
    hi = glm::max(hi, p);
  }
  const double tol = 1e-12 * glm::length(hi - lo);
  std::vector<std::size_t> order(handles.size());
  std::iota(order.begin(), order.end(), std::size_t{0});
  std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
    return handles[a].x < handles[b].x || (handles[a].x == handles[b].x && a < b);
  });
  for (std::size_t a = 0; a < order.size(); ++a) {
    for (std::size_t b = a + 1; b < order.size(); ++b) {
      const Vec3& pa = handles[order[a]];
      const Vec3& pb = handles[order[b]];
      if (pb.x - pa.x > tol) break;
      if (glm::length(pb - pa) <= tol) {
        const std::size_t i = std::min(order[a], order[b]);
        const std::size_t j = std::max(order[a], order[b]);
        throw InvalidInput(who + ": handles " + std::to_string(i) + " and " + std::to_string(j) +
                           " coincide");
      }
    }
  }
  constexpr double kSpread = 1e-6;
  const std::array<double, 3> s = singularSpread(handles);
  if (mode == MlsMode::Affine) {
    if (!(s[2] > kSpread * s[0])) {
      throw InvalidInput(who +
                         ": the handles are coplanar (affine mode needs 4 affinely "
                         "independent handles)");
    }
  } else {
    if (!(s[1] > kSpread * s[0])) {
      throw InvalidInput(who + ": the handles are collinear (" + mlsModeName(mode) +
                         " mode needs 3 non-collinear handles for a unique rotation)");
    }
    if (targets) {
      const std::array<double, 3> t = singularSpread(*targets);
      if (!(t[1] > kSpread * t[0])) {
        throw InvalidInput(who + ": the targets are collinear (" + mlsModeName(mode) +
                           " mode needs 3 non-collinear targets for a unique rotation)");
      }
    }
  }
}

constexpr detail::EnumNames<MlsMode, 3> kModeNames = {
    {{MlsMode::Affine, "affine"}, {MlsMode::Similarity, "similarity"}, {MlsMode::Rigid, "rigid"}}};

}  // namespace

std::string mlsModeName(MlsMode mode) { return detail::enumName(kModeNames, mode); }

MlsMode mlsModeFromName(std::string_view name) {
  return detail::enumFromName(kModeNames, name, "MLS mode");
}

MlsWarp::MlsWarp(std::vector<Vec3> handles, std::vector<Vec3> targets, const MlsOptions& options)
    : handles_(std::move(handles)), targets_(std::move(targets)), options_(options) {
  validate("MlsWarp", handles_, &targets_, options_.mode, options_.alpha);
  if (options_.distances) {
    const std::span<const Vec3> built = options_.distances->handles();
    if (built.size() != handles_.size()) {
      throw InvalidInput("MlsWarp: the distances were built for " + std::to_string(built.size()) +
                         " handles, not " + std::to_string(handles_.size()));
    }
    for (std::size_t i = 0; i < built.size(); ++i) {
      if (built[i] != handles_[i]) {
        throw InvalidInput("MlsWarp: the distances were built for another " + indexed("handle", i));
      }
    }
  }
}

namespace {

Model modelOf(const std::vector<Vec3>& p, const std::vector<Vec3>& q, const MlsOptions& o) {
  return {p.data(), q.data(), p.size(), o.alpha, o.mode, o.distances.get()};
}

}  // namespace

MlsFit MlsWarp::localFit(const Vec3& x) const {
  Scratch scratch(handles_.size());
  WeightSet s;
  return fitAt(modelOf(handles_, targets_, options_), x, scratch.data(), s);
}

Vec3 MlsWarp::apply(const Vec3& x) const {
  Scratch scratch(handles_.size());
  return mlsPoint(modelOf(handles_, targets_, options_), x, scratch.data());
}

std::size_t MlsWarp::batchGrain() const { return 1024; }

UnmappedPoints MlsWarp::applyRange(std::span<const Vec3> in, std::span<Vec3> out, std::size_t begin,
                                   std::size_t end) const {
  const Model m = modelOf(handles_, targets_, options_);
  Scratch scratch(m.n);
  for (std::size_t i = begin; i != end; ++i) out[i] = mlsPoint(m, in[i], scratch.data());
  return {};
}

Mat3 MlsWarp::jacobian(const Vec3& x) const {
  const Model m = modelOf(handles_, targets_, options_);
  Scratch scratch(m.n);
  double* w = scratch.data();
  const WeightSet s = computeWeights(m, x, w);
  const Moments mo = computeMoments(m, s, w);
  Mat3 rot(1.0);
  double scale = 1.0;
  const Mat3 t = transformOf(m, mo, &rot, &scale);
  if (s.pinned) return t;  // the limit fit at the handle

  const Vec3 y = x - s.pc;
  // Weight gradients g_i = ∇w_i = −2 alpha w_i (x − p_i) / |x − p_i|² (the normalisation of the
  // weights is a common factor, which the fit does not depend on).
  Mat3 dp(0.0), dq(0.0), first(0.0), cross(0.0);
  Vec3 ds(0.0);
  Mat3 pinv(1.0);
  Vec3 z(0.0);
  if (m.mode == MlsMode::Affine) {
    pinv = glm::inverse(mo.pp);
    z = pinv * y;
  }
  const Mat3 rt = glm::transpose(rot);
  // With other distances, ∇w_i = −2 alpha w_i ∇d_i / d_i.
  std::vector<double> dist;
  std::vector<Vec3> grad;
  if (m.distances) {
    dist.resize(m.n);
    grad.resize(m.n);
    m.distances->distancesAndGradients(x, dist, grad);
  }
  for (std::size_t i = 0; i < m.n; ++i) {
    Vec3 g;
    if (m.distances) {
      g = (-2.0 * m.alpha * w[i] / dist[i]) * grad[i];
    } else {
      const Vec3 d = x - m.p[i];
      g = (-2.0 * m.alpha * w[i] / glm::dot(d, d)) * d;
    }
    const Vec3 ph = m.p[i] - s.pc;
    const Vec3 qh = m.q[i] - s.qc;
    dp += glm::outerProduct(ph, g);
    dq += glm::outerProduct(qh, g);
    if (m.mode == MlsMode::Affine) {
      first += glm::outerProduct(glm::dot(ph, z) * (qh - t * ph), g);
    } else {
      cross += glm::outerProduct(glm::cross(ph, rt * qh), g);
      if (m.mode == MlsMode::Similarity)
        ds += (glm::dot(qh, rot * ph) - scale * glm::dot(ph, ph)) * g;
    }
  }
  dp /= s.sum;
  dq /= s.sum;
  if (m.mode != MlsMode::Affine) {
    Mat3 sym = rt * mo.qp;
    sym = 0.5 * (sym + glm::transpose(sym));
    const Mat3 h = Mat3(sym[0][0] + sym[1][1] + sym[2][2]) - sym;
    const double det = glm::determinant(h);
    const double hs = frobeniusDot(h, h);
    if (!(std::abs(det) > 1e-12 * hs * std::sqrt(hs))) return Warp::jacobian(x);
    const Mat3 omega = glm::inverse(h) * cross;
    first = -scale * rot * detail::crossMatrix(y) * omega;
    if (m.mode == MlsMode::Similarity) first += glm::outerProduct(rot * y, ds / mo.mu);
  }
  return first + t * (Mat3(1.0) - dp) + dq;
}

MlsAffineCoordinates::MlsAffineCoordinates(std::vector<Vec3> handles, double alpha)
    : handles_(std::move(handles)), alpha_(alpha) {
  validate("MlsAffineCoordinates", handles_, nullptr, MlsMode::Affine, alpha_);
}

void MlsAffineCoordinates::weights(const Vec3& x, std::span<double> row) const {
  checkWeightsArguments(x, row.size());
  const Model m{handles_.data(), nullptr, handles_.size(), alpha_, MlsMode::Affine};
  double* w = row.data();  // the weights are computed in place, then turned into A_j
  const WeightSet s = computeWeights(m, x, w);
  Mat3 pp(0.0);
  for (std::size_t i = 0; i < m.n; ++i) {
    const Vec3 ph = m.p[i] - s.pc;
    pp += glm::outerProduct(w[i] * ph, ph);
  }
  const Vec3 z = glm::inverse(pp) * (x - s.pc);
  if (s.pinned) {
    // x' = q_k + Σ_{j≠k} w_j p̂_jᵀ z (q_j − q_k), p̂_j = p_j − p_k.
    double others = 0.0;
    for (std::size_t j = 0; j < m.n; ++j) {
      if (j == s.nearest) continue;
      row[j] = w[j] * glm::dot(m.p[j] - s.pc, z);
      others += row[j];
    }
    row[s.nearest] = 1.0 - others;
    return;
  }
  const double inv = 1.0 / s.sum;
  for (std::size_t j = 0; j < m.n; ++j) row[j] = w[j] * (inv + glm::dot(m.p[j] - s.pc, z));
}

void MlsWarp::save(ArchiveWriter& out) const {
  out.tag("mls");
  out.vec3s(handles_);
  out.vec3s(targets_);
  out.enumeration(options_.mode);
  out.f64(options_.alpha);
  out.boolean(options_.distances != nullptr);
  if (options_.distances) out.distances(*options_.distances);
}

std::shared_ptr<const MlsWarp> MlsWarp::load(ArchiveReader& in) {
  std::vector<Vec3> handles = in.vec3s();
  std::vector<Vec3> targets = in.vec3s();
  MlsOptions options;
  options.mode = in.enumeration<MlsMode>(kModeNames.size());
  options.alpha = in.f64();
  if (in.boolean()) options.distances = in.distances();
  return std::make_shared<const MlsWarp>(std::move(handles), std::move(targets), options);
}

void MlsAffineCoordinates::save(ArchiveWriter& out) const {
  out.tag("mls-affine");
  out.vec3s(handles_);
  out.f64(alpha_);
}

std::shared_ptr<const MlsAffineCoordinates> MlsAffineCoordinates::load(ArchiveReader& in) {
  std::vector<Vec3> handles = in.vec3s();
  const double alpha = in.f64();
  return std::make_shared<const MlsAffineCoordinates>(std::move(handles), alpha);
}

}  // namespace spacewarp
