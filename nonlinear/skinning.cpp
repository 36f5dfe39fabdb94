#include <spacewarp/nonlinear/skinning.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <numeric>
#include <string>
#include <utility>

#include <glm/gtc/quaternion.hpp>

#include <spacewarp/core/archive.h>
#include <spacewarp/core/detail/aligned_buffer.h>
#include <spacewarp/core/detail/batch.h>
#include <spacewarp/core/detail/enum_names.h>
#include <spacewarp/core/detail/simd.h>
#include <spacewarp/core/errors.h>
#include <spacewarp/nonlinear/detail/graph_index.h>

namespace spacewarp {

namespace {

using detail::simd::VD;

// Per bone, in the kernel's layout. LBS: the columns of A − I and t (x' = x + Σ w_i ((A_i − I) x
// + t_i): identity bones give x exactly). DQS: the unit dual quaternion (real, dual), each as
// (w, x, y, z).
constexpr std::size_t kLbsBlocks = 4;
constexpr std::size_t kDqsBlocks = 2;

struct Quat {  // (w, x, y, z)
  double w = 1.0;
  Vec3 v{0.0};
};

Quat rotationQuaternion(const Mat4& m) {
  const glm::dquat q = glm::normalize(glm::quat_cast(Mat3(m)));
  return {q.w, {q.x, q.y, q.z}};
}

// The dual part ½ (0, t) q of the rigid motion (q, t).
Quat dualPart(const Quat& q, const Vec3& t) {
  return {-0.5 * glm::dot(t, q.v), 0.5 * (q.w * t + glm::cross(t, q.v))};
}

// The posed bones in the kernel's layout. DQS with few bones also keeps the hemisphere of every
// bone's quaternion relative to every other's, so that the blend reads a sign instead of
// computing a dot product per influence (the same comparison, so the same signs).
constexpr std::size_t kMaxSignTableBones = 256;  // a table of at most 512 kB

struct PreparedBones {
  detail::AlignedBuffer<VD> blocks;  // aligned for the kernel's loads (std::vector<VD> is not)
  std::vector<double> signs;         // DQS: signs[i · count + j] = ±1, bone j relative to bone i
  std::size_t count = 0;
};

// What the kernel reads of PreparedBones.
struct BoneView {
  const VD* blocks;
  const double* signs;  // null: computed per influence
  std::size_t count;
};

BoneView viewOf(const PreparedBones& p) {
  return {p.blocks.data(), p.signs.empty() ? nullptr : p.signs.data(), p.count};
}

// Whether quaternion q lies in the other hemisphere than `pivot` (the shorter arc flips it).
[[gnu::always_inline]] inline bool oppositeHemisphere(const VD& q, const VD& pivot) {
  const VD p = q * pivot;
  return (p[0] + p[1]) + (p[2] + p[3]) < 0.0;
}

void prepareBones(std::span<const Mat4> bones, SkinningMode mode, PreparedBones& out) {
  std::size_t n = 0;
  out.count = bones.size();
  out.signs.clear();
  if (mode == SkinningMode::Linear) {
    out.blocks.reserve(bones.size() * kLbsBlocks);
    for (const Mat4& m : bones) {
      for (int c = 0; c < 4; ++c) {
        VD col = {m[c][0], m[c][1], m[c][2], 0.0};
        if (c < 3) col[c] -= 1.0;
        out.blocks[n++] = col;
      }
    }
    return;
  }
  out.blocks.reserve(bones.size() * kDqsBlocks);
  for (const Mat4& m : bones) {
    const Quat q = rotationQuaternion(m);
    const Quat d = dualPart(q, Vec3(m[3]));
    out.blocks[n++] = VD{q.w, q.v.x, q.v.y, q.v.z};
    out.blocks[n++] = VD{d.w, d.v.x, d.v.y, d.v.z};
  }
  if (bones.size() > kMaxSignTableBones) return;
  out.signs.resize(bones.size() * bones.size());
  for (std::size_t i = 0; i < bones.size(); ++i)
    for (std::size_t j = 0; j < bones.size(); ++j)
      out.signs[i * bones.size() + j] =
          oppositeHemisphere(out.blocks[kDqsBlocks * j], out.blocks[kDqsBlocks * i]) ? -1.0 : 1.0;
}

// One point by LBS: the blend of the bones' (A − I | t) columns applied to x.
[[gnu::always_inline]] inline Vec3 lbsPoint(const BoneView& bones, const std::uint32_t* b,
                                            const double* w, std::size_t k, const Vec3& x) {
  const VD* m = bones.blocks + kLbsBlocks * b[0];
  VD c0 = w[0] * m[0], c1 = w[0] * m[1], c2 = w[0] * m[2], c3 = w[0] * m[3];
  for (std::size_t j = 1; j < k; ++j) {
    m = bones.blocks + kLbsBlocks * b[j];
    c0 += w[j] * m[0];
    c1 += w[j] * m[1];
    c2 += w[j] * m[2];
    c3 += w[j] * m[3];
  }
  const VD d = c0 * x.x + c1 * x.y + c2 * x.z + c3;
  return {x.x + d[0], x.y + d[1], x.z + d[2]};
}

// The blended dual quaternion of one point (not normalised): each bone's quaternion is taken in
// the hemisphere of the pivot bone's (the point's first, largest influence), so that the blend
// follows the shorter arc (Kavan et al. 2008, §3.4).
[[gnu::always_inline]] inline void dqsBlend(const BoneView& bones, const std::uint32_t* b,
                                            const double* w, std::size_t k, VD& real, VD& dual) {
  const VD* m = bones.blocks + kDqsBlocks * b[0];
  const VD pivot = m[0];
  real = w[0] * m[0];
  dual = w[0] * m[1];
  const double* signs = bones.signs ? bones.signs + b[0] * bones.count : nullptr;
  for (std::size_t j = 1; j < k; ++j) {
    m = bones.blocks + kDqsBlocks * b[j];
    const double s = signs ? signs[b[j]] * w[j] : oppositeHemisphere(m[0], pivot) ? -w[j] : w[j];
    real += s * m[0];
    dual += s * m[1];
  }
}

// DQS of four points whose blends are q[l], d[l], with the points in the lanes: the normalisation
// (one vector square root and division) and, for the unit dual quaternion (w, v) + ε (we, ve),
// x' = x + 2 v × (v × x + w x) + 2 (w ve − we v + v × ve).
[[gnu::always_inline]] inline void dqsLanes(const VD* q, const VD* d, const VD& px, const VD& py,
                                            const VD& pz, VD& ox, VD& oy, VD& oz) {
  VD rw = {q[0][0], q[1][0], q[2][0], q[3][0]}, rx = {q[0][1], q[1][1], q[2][1], q[3][1]};
  VD ry = {q[0][2], q[1][2], q[2][2], q[3][2]}, rz = {q[0][3], q[1][3], q[2][3], q[3][3]};
  VD ew = {d[0][0], d[1][0], d[2][0], d[3][0]}, ex = {d[0][1], d[1][1], d[2][1], d[3][1]};
  VD ey = {d[0][2], d[1][2], d[2][2], d[3][2]}, ez = {d[0][3], d[1][3], d[2][3], d[3][3]};
  const VD n2 = rw * rw + rx * rx + ry * ry + rz * rz;
  VD norm;
  detail::simd::sqrtLanes(n2, norm);
  const VD inv = 1.0 / norm;
  rw *= inv, rx *= inv, ry *= inv, rz *= inv, ew *= inv, ex *= inv, ey *= inv, ez *= inv;
  const VD ax = (ry * pz - rz * py) + rw * px;  // v × x + w x
  const VD ay = (rz * px - rx * pz) + rw * py;
  const VD az = (rx * py - ry * px) + rw * pz;
  ox = px + 2.0 * ((ry * az - rz * ay) + (rw * ex - ew * rx + (ry * ez - rz * ey)));
  oy = py + 2.0 * ((rz * ax - rx * az) + (rw * ey - ew * ry + (rz * ex - rx * ez)));
  oz = pz + 2.0 * ((rx * ay - ry * ax) + (rw * ez - ew * rz + (rx * ey - ry * ex)));
}

// DQS of the `count` ≤ 8 points in[0, count) (weight rows rows[l], or first + l when `rows` is
// null): the blends point by point, then two groups of four lanes (two independent square roots
// and divisions in flight, whose latency is the kernel's main cost). Every point goes through
// this same code (spare lanes repeat the last point), so a point's result does not depend on
// its group.
[[gnu::always_inline]] inline void dqsGroup(const BoneView& bones, const SkinningWeights& weights,
                                            const Vec3* in, const std::size_t* rows, Vec3* out,
                                            std::size_t first, std::size_t count) {
  const std::size_t k = weights.influences;
  VD q[8], d[8];
  VD px[2], py[2], pz[2];
  for (std::size_t l = 0; l < 8; ++l) {
    const std::size_t p = std::min(l, count - 1);
    const std::size_t r = (rows ? rows[p] : first + p) * k;
    dqsBlend(bones, weights.bones.data() + r, weights.weights.data() + r, k, q[l], d[l]);
    px[l / 4][l % 4] = in[p].x;
    py[l / 4][l % 4] = in[p].y;
    pz[l / 4][l % 4] = in[p].z;
  }
  VD ox[2], oy[2], oz[2];
  for (int h = 0; h < 2; ++h)
    dqsLanes(q + 4 * h, d + 4 * h, px[h], py[h], pz[h], ox[h], oy[h], oz[h]);
  for (std::size_t l = 0; l < count; ++l)
    out[l] = Vec3(ox[l / 4][l % 4], oy[l / 4][l % 4], oz[l / 4][l % 4]);
}

// out[i] = the skinned in[i], with the weights of row rows[i] (row i when `rows` is null).
// `in` and `out` may alias. Compiled for AVX2 + FMA and for the baseline.
SPACEWARP_SIMD_CLONES
void skinPoints(const BoneView& bones, SkinningMode mode, const SkinningWeights& weights,
                const Vec3* in, const std::size_t* rows, Vec3* out, std::size_t n) {
  const std::size_t k = weights.influences;
  const std::uint32_t* b = weights.bones.data();
  const double* w = weights.weights.data();
  if (mode == SkinningMode::Linear) {
    for (std::size_t i = 0; i < n; ++i) {
      const std::size_t r = (rows ? rows[i] : i) * k;
      out[i] = lbsPoint(bones, b + r, w + r, k, in[i]);
    }
  } else {
    for (std::size_t i = 0; i < n; i += 8)
      dqsGroup(bones, weights, in + i, rows ? rows + i : nullptr, out + i, i,
               std::min<std::size_t>(8, n - i));
  }
}

// The kept influences of one dense row into bones/raw (k entries), in decreasing order (ties to
// the lower bone); returns their sum. Keeping every bone (k == boneCount) keeps the signed
// weights. Truncating clamps negative weights to 0 first, so that the kept sum is at least the
// largest weight: signed weights (RBF, MLS coordinates) cut to their k largest magnitudes can
// sum to ~0 and put a pole in space. With `fade` (weights that vary in space) the (k + 1)-th
// largest weight τ is also subtracted from the kept ones, so that a bone leaves the kept set
// with weight 0 and the result stays continuous where the kept set changes; `faded` gets τ's
// bone (or boneCount when τ = 0). Throws for non-finite weights, a sum that overflows and a sum
// ≤ 0, naming the point: index `point` of a batch, or the position `at` when not null.
double selectInfluences(const double* row, std::size_t boneCount, std::size_t k, std::size_t point,
                        std::uint32_t* bones, double* raw, const Vec3* at = nullptr,
                        bool fade = false, std::size_t* faded = nullptr) {
  const auto name = [&] {
    return at ? "the point " + detail::describePoint(*at) : "point " + std::to_string(point);
  };
  for (std::size_t c = 0; c < boneCount; ++c)
    if (!std::isfinite(row[c]))
      throw InvalidInput("skinning weights: " + name() + " has a non-finite weight for bone " +
                         std::to_string(c));
  const bool truncate = k < boneCount;
  const auto key = [&](double v) { return truncate ? std::max(v, 0.0) : std::abs(v); };
  const auto before = [&](std::uint32_t a, std::uint32_t b) {
    const double x = key(row[a]), y = key(row[b]);
    return x > y || (x == y && a < b);
  };
  // k + 1 entries when fading (the last is τ): std::partial_sort, the callers' scratch has room.
  const std::size_t m = fade && truncate ? k + 1 : k;
  std::vector<std::uint32_t> order(boneCount);
  std::iota(order.begin(), order.end(), 0u);
  std::partial_sort(order.begin(), order.begin() + std::ptrdiff_t(m), order.end(), before);
  for (std::size_t j = 0; j < m; ++j) {
    bones[j] = order[j];
    raw[j] = truncate ? key(row[order[j]]) : row[order[j]];
  }
  if (faded) *faded = boneCount;
  if (m > k && raw[k] > 0.0 && raw[0] > raw[k]) {  // all k + 1 equal: no fade (bounded, a tie)
    for (std::size_t j = 0; j < k; ++j) raw[j] = std::max(raw[j] - raw[k], 0.0);
    if (faded) *faded = bones[k];
  }
  double sum = 0.0, magnitude = 0.0;
  for (std::size_t j = 0; j < k; ++j) {
    sum += raw[j];
    magnitude += std::abs(raw[j]);
  }
  if (!std::isfinite(magnitude))
    throw InvalidInput("skinning weights: the weights of " + name() +
                       " are too large: their sum is not finite");
  if (!(sum > 1e-12 * magnitude))
    throw InvalidInput(
        "skinning weights: the weights of " + name() +
        (truncate ? " have no positive weight (negative weights are dropped when "
                    "only the largest are kept)"
                  : " sum to " + std::to_string(sum) + " (the sum must be > 0 to normalise them)"));
  return sum;
}

void normaliseInfluences(std::size_t k, double sum, const double* raw, double* w) {
  for (std::size_t j = 0; j < k; ++j) w[j] = raw[j] / sum;
}

void checkWeights(const SkinningWeights& w, std::size_t pointCount, std::size_t boneCount) {
  if (w.pointCount != pointCount)
    throw InvalidInput("skinning weights: " + std::to_string(w.pointCount) +
                       " points have weights, but there are " + std::to_string(pointCount) +
                       " points");
  if (w.influences == 0) throw InvalidInput("skinning weights: influences per point must be >= 1");
  if (w.influences > std::numeric_limits<std::size_t>::max() / std::max<std::size_t>(pointCount, 1))
    throw InvalidInput("skinning weights: " + std::to_string(w.influences) +
                       " influences per point are too many");
  const std::size_t n = w.pointCount * w.influences;
  if (w.bones.size() != n || w.weights.size() != n)
    throw InvalidInput("skinning weights: the bone and weight arrays must have points × " +
                       std::string("influences = ") + std::to_string(n) + " entries");
  for (std::size_t i = 0; i < n; ++i) {
    if (w.bones[i] >= boneCount)
      throw InvalidInput("skinning weights: point " + std::to_string(i / w.influences) +
                         " names bone " + std::to_string(w.bones[i]) + ", but there are " +
                         std::to_string(boneCount) + " bones");
    if (!std::isfinite(w.weights[i]))
      throw InvalidInput("skinning weights: point " + std::to_string(i / w.influences) +
                         " has a non-finite weight");
  }
}

void checkPoints(const char* what, std::span<const Vec3> points) {
  for (std::size_t i = 0; i < points.size(); ++i)
    if (!isFinite(points[i]))
      throw InvalidInput(std::string(what) + ": point " + std::to_string(i) + " is not finite");
}

std::size_t effectiveInfluences(std::size_t maxInfluences, std::size_t boneCount) {
  return maxInfluences == 0 ? boneCount : std::min(maxInfluences, boneCount);
}

}  // namespace

namespace {

constexpr detail::EnumNames<SkinningMode, 2> kModeNames = {
    {{SkinningMode::Linear, "lbs"}, {SkinningMode::DualQuaternion, "dqs"}}};

}  // namespace

std::string skinningModeName(SkinningMode mode) { return detail::enumName(kModeNames, mode); }

SkinningMode skinningModeFromName(std::string_view name) {
  return detail::enumFromName(kModeNames, name, "skinning mode");
}

SkinningWeights sparseSkinningWeights(std::span<const double> rows, std::size_t boneCount,
                                      std::size_t maxInfluences) {
  if (boneCount == 0 || boneCount > std::numeric_limits<std::uint32_t>::max())
    throw InvalidInput("skinning weights: the number of bones must be between 1 and 2^32 - 1");
  if (rows.size() % boneCount != 0)
    throw InvalidInput("skinning weights: " + std::to_string(rows.size()) +
                       " weights are not a whole number of rows of " + std::to_string(boneCount) +
                       " bones");
  SkinningWeights out;
  out.pointCount = rows.size() / boneCount;
  out.influences = effectiveInfluences(maxInfluences, boneCount);
  const std::size_t k = out.influences;
  out.bones.resize(out.pointCount * k);
  out.weights.resize(out.pointCount * k);
  std::vector<double> raw(k);
  for (std::size_t i = 0; i < out.pointCount; ++i) {
    const double sum = selectInfluences(rows.data() + i * boneCount, boneCount, k, i,
                                        out.bones.data() + i * k, raw.data());
    normaliseInfluences(k, sum, raw.data(), out.weights.data() + i * k);
  }
  return out;
}

SkinningWeights skinningWeights(const Coordinates& coordinates, std::span<const Vec3> points,
                                std::size_t maxInfluences) {
  const std::size_t bones = coordinates.controlPointCount();
  if (coordinates.columnCount() != bones)
    throw InvalidInput("skinning: the coordinates have " +
                       std::to_string(coordinates.columnCount()) + " columns for " +
                       std::to_string(bones) +
                       " control points; skinning needs one weight per bone");
  // In chunks, so that the dense rows never take more than ~64 MB.
  const std::size_t chunk = std::max<std::size_t>(1, (std::size_t{8} << 20) / bones);
  SkinningWeights out;
  out.pointCount = points.size();
  out.influences = effectiveInfluences(maxInfluences, bones);
  const std::size_t k = out.influences;
  out.bones.resize(points.size() * k);
  out.weights.resize(points.size() * k);
  std::vector<double> rows;
  for (std::size_t start = 0; start < points.size(); start += chunk) {
    const std::size_t n = std::min(chunk, points.size() - start);
    rows.resize(n * bones);
    coordinates.weightsBatch(points.subspan(start, n), rows);
    detail::forEachRange(n, 1024, [&](std::size_t begin, std::size_t end) {
      std::vector<double> raw(k + 1);
      std::vector<std::uint32_t> b(k + 1);
      for (std::size_t i = begin; i < end; ++i) {
        const std::size_t p = start + i;
        const double sum =
            selectInfluences(rows.data() + i * bones, bones, k, p, b.data(), raw.data(), nullptr,
                             /*fade=*/true);
        std::copy_n(b.data(), k, out.bones.data() + p * k);
        normaliseInfluences(k, sum, raw.data(), out.weights.data() + p * k);
      }
      return UnmappedPoints{};
    });
  }
  return out;
}

void checkBones(std::span<const Mat4> bones, SkinningMode mode) {
  for (std::size_t i = 0; i < bones.size(); ++i) {
    const Mat4& m = bones[i];
    const std::string name = "bone " + std::to_string(i);
    for (int c = 0; c < 4; ++c)
      for (int r = 0; r < 4; ++r)
        if (!std::isfinite(m[c][r])) throw InvalidInput(name + ": the matrix is not finite");
    if (m[0][3] != 0.0 || m[1][3] != 0.0 || m[2][3] != 0.0 || m[3][3] != 1.0)
      throw InvalidInput(name + ": the last row of the matrix must be 0 0 0 1");
    if (mode != SkinningMode::DualQuaternion) continue;
    const Mat3 a(m);
    const Mat3 g = glm::transpose(a) * a;
    double off = 0.0;
    for (int c = 0; c < 3; ++c)
      for (int r = 0; r < 3; ++r) off = std::max(off, std::abs(g[c][r] - (c == r ? 1.0 : 0.0)));
    if (glm::determinant(a) < 0.0 && off <= 1e-4)
      throw InvalidInput(name + ": the bone is a reflection (determinant −1): dual-quaternion " +
                         "skinning needs rotations; use mode \"lbs\"");
    if (!(off <= 1e-4) || !(glm::determinant(a) > 0.0))
      throw InvalidInput(name + ": dual-quaternion skinning needs a rigid bone (rotation and " +
                         "translation), but its 3 × 3 part is not a rotation (|RᵀR − I| = " +
                         std::to_string(off) + "); use mode \"lbs\" for scaled or sheared bones");
  }
}

// ---- SkinningBinding ----

SkinningBinding::SkinningBinding(std::vector<Vec3> points, SkinningWeights weights,
                                 std::size_t boneCount)
    : points_(std::move(points)), weights_(std::move(weights)), boneCount_(boneCount) {
  checkPoints("skinning binding", points_);
  checkWeights(weights_, points_.size(), boneCount_);
}

void SkinningBinding::deform(std::span<const Mat4> bones, SkinningMode mode,
                             std::span<Vec3> out) const {
  if (bones.size() != boneCount_)
    throw InvalidInput("skinning: " + std::to_string(bones.size()) +
                       " bones given, the binding has " + std::to_string(boneCount_));
  detail::requireSameSize("SkinningBinding::deform", points_.size(), out.size());
  checkBones(bones, mode);
  PreparedBones prepared;
  prepareBones(bones, mode, prepared);
  const BoneView view = viewOf(prepared);
  detail::forEachRange(points_.size(), 16384, [&](std::size_t begin, std::size_t end) {
    skinPoints(view, mode, weights_, points_.data() + begin, nullptr, out.data() + begin,
               end - begin);
    return UnmappedPoints{};
  });
}

std::vector<Vec3> SkinningBinding::deform(std::span<const Mat4> bones, SkinningMode mode) const {
  std::vector<Vec3> out(points_.size());
  deform(bones, mode, out);
  return out;
}

// ---- SkinningWarp ----

struct SkinningWarp::Impl {
  PreparedBones prepared;
  // Nearest-vertex weights: the model, its weights and its KD-tree (which refers to `cloud`,
  // which refers to `model`: Impl is never moved).
  std::vector<Vec3> model;
  SkinningWeights weights;
  detail::NodeCloud cloud;
  std::unique_ptr<detail::KdTree> tree;
  // Weights from coordinates.
  std::shared_ptr<const Coordinates> coordinates;
  std::size_t influences = 0;

  // The nearest model vertex of x, or false when none is in reach (x not finite, or so far
  // away that squared distances overflow).
  bool nearest(const Vec3& x, std::size_t& row) const {
    if (!isFinite(x) || !detail::withinReach(x)) return false;
    const double q[3] = {x.x, x.y, x.z};
    std::uint32_t idx = 0;
    double d2 = 0.0;
    if (tree->knnSearch(q, 1, &idx, &d2) < 1) return false;
    row = idx;
    return true;
  }

  // The sparse weights of x from the coordinates (k entries in w; b and raw have room for
  // k + 1, `dense` for a row); returns the raw kept weights' sum, and in `faded` the bone whose
  // weight was subtracted (selectInfluences).
  double coordinateWeights(const Vec3& x, std::vector<double>& dense, std::uint32_t* b, double* raw,
                           double* w, std::size_t* faded = nullptr) const {
    coordinates->weights(x, dense);
    const double sum = selectInfluences(dense.data(), dense.size(), influences, 0, b, raw, &x,
                                        /*fade=*/true, faded);
    normaliseInfluences(influences, sum, raw, w);
    return sum;
  }
};

SkinningWarp::SkinningWarp(std::vector<Mat4> bones, std::vector<Vec3> model,
                           SkinningWeights weights, SkinningMode mode)
    : bones_(std::move(bones)), mode_(mode) {
  if (bones_.empty()) throw InvalidInput("skinning: no bones");
  checkBones(bones_, mode_);
  if (model.empty()) throw InvalidInput("skinning: the weighted model has no points");
  checkPoints("skinning model", model);
  checkWeights(weights, model.size(), bones_.size());
  for (std::size_t i = 0; i < model.size(); ++i)
    if (!detail::withinReach(model[i]))
      throw InvalidInput("skinning model: point " + std::to_string(i) +
                         " is too far out (|x| > 1e150)");
  auto impl = std::make_unique<Impl>();
  prepareBones(bones_, mode_, impl->prepared);
  impl->model = std::move(model);
  impl->weights = std::move(weights);
  impl->cloud.points = &impl->model;
  impl->tree = std::make_unique<detail::KdTree>(3, impl->cloud,
                                                nanoflann::KDTreeSingleIndexAdaptorParams(10));
  impl_ = std::move(impl);
}

SkinningWarp::SkinningWarp(std::vector<Mat4> bones, std::shared_ptr<const Coordinates> coordinates,
                           const SkinningOptions& options)
    : bones_(std::move(bones)), mode_(options.mode) {
  if (!coordinates) throw InvalidInput("skinning: the coordinates are null");
  if (bones_.empty()) throw InvalidInput("skinning: no bones");
  checkBones(bones_, mode_);
  if (coordinates->controlPointCount() != bones_.size() ||
      coordinates->columnCount() != bones_.size())
    throw InvalidInput("skinning: " + std::to_string(bones_.size()) +
                       " bones, but the coordinates have " +
                       std::to_string(coordinates->columnCount()) +
                       " weights per point (one per bone's handle is needed)");
  auto impl = std::make_unique<Impl>();
  prepareBones(bones_, mode_, impl->prepared);
  impl->coordinates = std::move(coordinates);
  impl->influences = effectiveInfluences(options.maxInfluences, bones_.size());
  impl->weights.influences = impl->influences;
  impl_ = std::move(impl);
}

SkinningWarp::~SkinningWarp() = default;

std::size_t SkinningWarp::batchGrain() const { return impl_->coordinates ? 256 : 4096; }

Vec3 SkinningWarp::apply(const Vec3& x) const {
  Vec3 y;
  const UnmappedPoints unmapped = applyRange({&x, 1}, {&y, 1}, 0, 1);
  if (unmapped.count != 0)
    throw InvalidInput("skinning: the point " + detail::describePoint(x) +
                       " has no nearest model vertex");
  return y;
}

UnmappedPoints SkinningWarp::applyRange(std::span<const Vec3> in, std::span<Vec3> out,
                                        std::size_t begin, std::size_t end) const {
  const Impl& m = *impl_;
  const BoneView bones = viewOf(m.prepared);
  UnmappedPoints unmapped;
  // Blocks of points: their weights first, then one kernel call (DQS works on eight at a time).
  constexpr std::size_t kBlock = 64;
  Vec3 points[kBlock], moved[kBlock];
  std::size_t rows[kBlock], index[kBlock];
  if (m.coordinates) {
    const std::size_t k = m.influences;
    std::vector<double> dense(bones_.size()), raw(k + 1);
    std::vector<std::uint32_t> b(k + 1);
    SkinningWeights block;
    block.pointCount = kBlock;
    block.influences = k;
    block.bones.resize(kBlock * k);
    block.weights.resize(kBlock * k);
    for (std::size_t start = begin; start < end; start += kBlock) {
      const std::size_t n = std::min(kBlock, end - start);
      for (std::size_t i = 0; i < n; ++i) {
        m.coordinateWeights(in[start + i], dense, b.data(), raw.data(),
                            block.weights.data() + i * k);
        std::copy_n(b.data(), k, block.bones.data() + i * k);
      }
      skinPoints(bones, mode_, block, &in[start], nullptr, &out[start], n);
    }
    return unmapped;
  }
  for (std::size_t start = begin; start < end; start += kBlock) {
    const std::size_t n = std::min(kBlock, end - start);
    std::size_t found = 0;  // the points in reach, gathered; the others are left as they are
    for (std::size_t i = start; i < start + n; ++i) {
      if (!m.nearest(in[i], rows[found])) {
        unmapped.add(i);
        unmapped.by = this;
        continue;
      }
      points[found] = in[i];
      index[found++] = i;
    }
    skinPoints(bones, mode_, m.weights, points, rows, moved, found);
    for (std::size_t j = 0; j < found; ++j) out[index[j]] = moved[j];
  }
  return unmapped;
}

Mat3 SkinningWarp::jacobian(const Vec3& x) const {
  const Impl& m = *impl_;
  const std::size_t k = m.coordinates ? m.influences : m.weights.influences;
  std::vector<std::uint32_t> b(k + 1);
  std::vector<double> w(k), raw(k + 1);
  std::vector<Vec3> grad;  // ∇w_j of the kept, normalised weights; empty when constant
  if (m.coordinates) {
    std::vector<double> dense(bones_.size());
    std::size_t faded = bones_.size();
    const double sum = m.coordinateWeights(x, dense, b.data(), raw.data(), w.data(), &faded);
    std::vector<Vec3> all(bones_.size());
    if (!m.coordinates->weightGradients(x, all)) return Warp::jacobian(x);
    // w_j = u_j / S over the kept u = v_j − τ (τ the faded weight, 0 if none; u_j = 0 where a
    // weight ties τ): ∇w_j = (∇u_j − w_j Σ ∇u) / S.
    const Vec3 dTau = faded < bones_.size() ? all[faded] : Vec3(0.0);
    grad.resize(k);
    Vec3 total(0.0);
    for (std::size_t j = 0; j < k; ++j) {
      grad[j] = raw[j] > 0.0 || k == bones_.size() ? all[b[j]] - dTau : Vec3(0.0);
      total += grad[j];
    }
    for (std::size_t j = 0; j < k; ++j) grad[j] = (grad[j] - w[j] * total) / sum;
  } else {
    std::size_t row = 0;
    if (!m.nearest(x, row))
      throw InvalidInput("skinning: the point " + detail::describePoint(x) +
                         " has no nearest model vertex");
    std::copy_n(m.weights.bones.data() + row * k, k, b.data());
    std::copy_n(m.weights.weights.data() + row * k, k, w.data());
  }

  if (mode_ == SkinningMode::Linear) {
    Mat3 j(1.0);
    for (std::size_t i = 0; i < k; ++i) {
      const Mat4& bone = bones_[b[i]];
      const Mat3 a(bone);
      j += w[i] * (a - Mat3(1.0));
      if (!grad.empty()) j += glm::outerProduct(a * x + Vec3(bone[3]) - x, grad[i]);
    }
    return j;
  }

  VD real, dual;
  dqsBlend(viewOf(m.prepared), b.data(), w.data(), k, real, dual);
  const double norm =
      std::sqrt(real[0] * real[0] + real[1] * real[1] + real[2] * real[2] + real[3] * real[3]);
  const double c0w = real[0] / norm, cew = dual[0] / norm;
  const Vec3 c0v(real[1] / norm, real[2] / norm, real[3] / norm);
  const Vec3 cev(dual[1] / norm, dual[2] / norm, dual[3] / norm);
  Mat3 j;
  for (int a = 0; a < 3; ++a) {  // the rotation R(c₀): ∂x'/∂x at fixed weights
    Vec3 e(0.0);
    e[a] = 1.0;
    j[a] = e + 2.0 * glm::cross(c0v, glm::cross(c0v, e) + c0w * e);
  }
  if (grad.empty()) return j;
  // Signs of the blend, as dqsBlend chose them.
  const VD pivot = m.prepared.blocks[kDqsBlocks * b[0]];
  for (int a = 0; a < 3; ++a) {
    // d(blend)/dx_a, then through the normalisation c = b / |b₀|.
    double db[8] = {0, 0, 0, 0, 0, 0, 0, 0};
    for (std::size_t i = 0; i < k; ++i) {
      const VD* q = m.prepared.blocks.data() + kDqsBlocks * b[i];
      const double s = i > 0 && oppositeHemisphere(q[0], pivot) ? -1.0 : 1.0;
      const double g = s * grad[i][a];
      for (int c = 0; c < 4; ++c) {
        db[c] += g * q[0][c];
        db[4 + c] += g * q[1][c];
      }
    }
    const double along = (c0w * db[0] + c0v.x * db[1] + c0v.y * db[2] + c0v.z * db[3]);
    const double dw = (db[0] - c0w * along) / norm;
    const Vec3 dv = (Vec3(db[1], db[2], db[3]) - c0v * along) / norm;
    const double dwe = (db[4] - cew * along) / norm;
    const Vec3 dve = (Vec3(db[5], db[6], db[7]) - cev * along) / norm;
    // The derivative of dqsApply's polynomial in the direction (dw, dv, dwe, dve).
    const Vec3 d = glm::cross(dv, glm::cross(c0v, x) + c0w * x) +
                   glm::cross(c0v, glm::cross(dv, x) + dw * x) + dw * cev + c0w * dve - dwe * c0v -
                   cew * dv + glm::cross(dv, cev) + glm::cross(c0v, dve);
    j[a] += 2.0 * d;
  }
  return j;
}

namespace {

void saveWeights(ArchiveWriter& out, const SkinningWeights& w) {
  out.u64(w.pointCount);
  out.u64(w.influences);
  out.u32s(w.bones);
  out.doubles(w.weights);
}

SkinningWeights loadWeights(ArchiveReader& in) {
  SkinningWeights w;
  w.pointCount = in.u64();
  w.influences = in.u64();
  w.bones = in.u32s();
  w.weights = in.doubles();
  return w;  // checked by the constructor it is given to
}

}  // namespace

void SkinningWarp::save(ArchiveWriter& out) const {
  out.tag("skinning");
  out.enumeration(mode_);
  std::vector<double> bones;  // column by column, 16 per bone
  bones.reserve(bones_.size() * 16);
  for (const Mat4& m : bones_)
    for (int c = 0; c < 4; ++c)
      for (int r = 0; r < 4; ++r) bones.push_back(m[c][r]);
  out.doubles(bones);
  out.boolean(impl_->coordinates != nullptr);
  if (impl_->coordinates) {
    out.coordinates(*impl_->coordinates);
    out.u64(impl_->influences);
  } else {
    out.vec3s(impl_->model);
    saveWeights(out, impl_->weights);
  }
}

std::shared_ptr<const SkinningWarp> SkinningWarp::load(ArchiveReader& in) {
  const SkinningMode mode = in.enumeration<SkinningMode>(kModeNames.size());
  const std::vector<double> entries = in.doubles();
  if (entries.size() % 16 != 0)
    in.fail("skinning: " + std::to_string(entries.size()) + " bone entries (16 per bone)");
  std::vector<Mat4> bones(entries.size() / 16);
  for (std::size_t b = 0; b < bones.size(); ++b)
    for (int c = 0; c < 4; ++c)
      for (int r = 0; r < 4; ++r)
        bones[b][c][r] = entries[b * 16 + std::size_t(c) * 4 + std::size_t(r)];
  if (in.boolean()) {
    std::shared_ptr<const Coordinates> coordinates = in.coordinates();
    const std::uint64_t influences = in.u64();
    if (influences == 0) in.fail("skinning: 0 influences kept (the count stored is never 0)");
    return std::make_shared<const SkinningWarp>(std::move(bones), std::move(coordinates),
                                                SkinningOptions{mode, influences});
  }
  std::vector<Vec3> model = in.vec3s();
  SkinningWeights weights = loadWeights(in);
  return std::make_shared<const SkinningWarp>(std::move(bones), std::move(model),
                                              std::move(weights), mode);
}

}  // namespace spacewarp
