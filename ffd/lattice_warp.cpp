#include <spacewarp/ffd/lattice_warp.h>

#include <cstring>
#include <string>

#include <spacewarp/core/archive.h>
#include <spacewarp/core/detail/simd.h>
#include <spacewarp/core/errors.h>
#include <spacewarp/ffd/detail/lattice_basis.h>

namespace spacewarp {

namespace {

// Four doubles (x, y, z, 0) of one control's displacement: one AVX register in the x86-64-v3
// clones. Loaded with memcpy and never returned by value (that would change the psABI).
using V4 = detail::simd::VD;

// Everything the per-point map needs, by value, so the batch loop keeps it at hand.
struct Kernel {
  detail::BoxFrame frame;
  int n[3];
  std::size_t strideJ;  // l
  std::size_t strideK;  // l m
  const double* d;      // displacements, 4 doubles per control (x, y, z, 0)
};

// x + s Σ w_i w_j w_k d_ijk for a basis with K weights per axis: each row of K controls along i
// is summed first, then weighted by w_j w_k. The weights are only ever read one at a time
// (broadcast), so no vector load waits on the scalar stores that wrote them.
template <int K, int (*Axis)(double, int, double*, double*)>
inline Vec3 displaceFixed(const Kernel& k, const Vec3& x) {
  double u[3];
  bool clamped[3];
  double s = 1.0;
  if (!detail::locate(k.frame, x, u, clamped, s, nullptr)) return x;
  double w0[K], w1[K], w2[K];
  const int i0 = Axis(u[0], k.n[0], w0, nullptr);
  const int j0 = Axis(u[1], k.n[1], w1, nullptr);
  const int k0 = Axis(u[2], k.n[2], w2, nullptr);
  const double* base = k.d + 4 * (static_cast<std::size_t>(i0) + k.strideJ * j0 + k.strideK * k0);
  V4 acc = {0.0, 0.0, 0.0, 0.0};
  for (int c = 0; c < K; ++c) {
    for (int b = 0; b < K; ++b) {
      const double* row = base + 4 * (k.strideJ * b + k.strideK * c);
      V4 r = {0.0, 0.0, 0.0, 0.0};
      for (int a = 0; a < K; ++a) {
        V4 v;
        std::memcpy(&v, row + 4 * a, sizeof v);
        r += w0[a] * v;
      }
      acc += (w1[b] * w2[c]) * r;
    }
  }
  return x + s * Vec3(acc[0], acc[1], acc[2]);
}

inline Vec3 displaceBernstein(const Kernel& k, const Vec3& x) {
  double u[3];
  bool clamped[3];
  double s = 1.0;
  if (!detail::locate(k.frame, x, u, clamped, s, nullptr)) return x;
  constexpr int kMax = detail::kMaxBernsteinResolution;
  double w[3][kMax];
  for (int a = 0; a < 3; ++a) detail::bernsteinAxis(u[a], k.n[a], w[a], nullptr);
  double ax = 0.0, ay = 0.0, az = 0.0;
  for (int c = 0; c < k.n[2]; ++c) {
    for (int b = 0; b < k.n[1]; ++b) {
      const double* row = k.d + 4 * (k.strideJ * b + k.strideK * c);
      double rx = 0.0, ry = 0.0, rz = 0.0;
      for (int a = 0; a < k.n[0]; ++a) {
        rx += w[0][a] * row[4 * a];
        ry += w[0][a] * row[4 * a + 1];
        rz += w[0][a] * row[4 * a + 2];
      }
      const double wbc = w[1][b] * w[2][c];
      ax += wbc * rx;
      ay += wbc * ry;
      az += wbc * rz;
    }
  }
  return x + s * Vec3(ax, ay, az);
}

// One function per basis over a range of points, each with an x86-64-v3 (AVX2 + FMA) clone
// chosen once at load time. apply() calls the same functions on one point, so that apply() and
// applyBatch() give the same bits on any machine.

SPACEWARP_SIMD_CLONES void trilinearRange(const Kernel& k, const Vec3* in, Vec3* out,
                                          std::size_t n) {
  for (std::size_t i = 0; i < n; ++i) out[i] = displaceFixed<2, detail::trilinearAxis>(k, in[i]);
}

SPACEWARP_SIMD_CLONES void bsplineRange(const Kernel& k, const Vec3* in, Vec3* out, std::size_t n) {
  for (std::size_t i = 0; i < n; ++i) out[i] = displaceFixed<4, detail::bsplineAxis>(k, in[i]);
}

SPACEWARP_SIMD_CLONES void bsplineRepeatRange(const Kernel& k, const Vec3* in, Vec3* out,
                                              std::size_t n) {
  for (std::size_t i = 0; i < n; ++i)
    out[i] = displaceFixed<4, detail::bsplineRepeatAxis>(k, in[i]);
}

SPACEWARP_SIMD_CLONES void bernsteinRange(const Kernel& k, const Vec3* in, Vec3* out,
                                          std::size_t n) {
  for (std::size_t i = 0; i < n; ++i) out[i] = displaceBernstein(k, in[i]);
}

using RangeFunction = void (*)(const Kernel&, const Vec3*, Vec3*, std::size_t);

RangeFunction rangeFunctionOf(const LatticeOptions& options) {
  switch (options.basis) {
    case LatticeBasis::Trilinear:
      return trilinearRange;
    case LatticeBasis::BSpline:
      return options.ends == LatticeEnds::Repeat ? bsplineRepeatRange : bsplineRange;
    case LatticeBasis::Bernstein:
      break;
  }
  return bernsteinRange;
}

}  // namespace

LatticeWarp::LatticeWarp(Lattice lattice, std::span<const Vec3> posed)
    : lattice_(std::move(lattice)), posed_(posed.begin(), posed.end()) {
  const std::size_t count = lattice_.controlPointCount();
  if (posed_.size() != count) {
    throw InvalidInput("LatticeWarp: " + std::to_string(posed_.size()) +
                       " posed control points given, the lattice has " + std::to_string(count));
  }
  const auto rest = lattice_.restControlPoints();
  displacement_.assign(4 * count, 0.0);
  for (std::size_t c = 0; c < count; ++c) {
    if (!isFinite(posed_[c]))
      throw InvalidInput("LatticeWarp: posed control point " + std::to_string(c) +
                         " is not finite");
    const Vec3 d = posed_[c] - rest[c];
    displacement_[4 * c] = d.x;
    displacement_[4 * c + 1] = d.y;
    displacement_[4 * c + 2] = d.z;
  }
}

namespace {

Kernel kernelOf(const Lattice& lattice, const std::vector<double>& displacement) {
  const auto& n = lattice.resolution();
  return {detail::BoxFrame(lattice.params()),
          {n[0], n[1], n[2]},
          static_cast<std::size_t>(n[0]),
          static_cast<std::size_t>(n[0]) * static_cast<std::size_t>(n[1]),
          displacement.data()};
}

}  // namespace

Vec3 LatticeWarp::apply(const Vec3& x) const {
  const Kernel k = kernelOf(lattice_, displacement_);
  Vec3 out;
  rangeFunctionOf(lattice_.params())(k, &x, &out, 1);
  return out;
}

UnmappedPoints LatticeWarp::applyRange(std::span<const Vec3> in, std::span<Vec3> out,
                                       std::size_t begin, std::size_t end) const {
  // One call per range of points (not per point); each point is computed on its own, so the
  // split does not affect the result.
  const Kernel k = kernelOf(lattice_, displacement_);
  rangeFunctionOf(lattice_.params())(k, in.data() + begin, out.data() + begin, end - begin);
  return {};
}

Mat3 LatticeWarp::jacobian(const Vec3& x) const {
  const std::size_t most = lattice_.maxNonZeros();
  std::vector<SparseWeight> weights(most);
  std::vector<Vec3> gradients(most);
  const std::size_t n = lattice_.sparseWeights(x, weights, gradients);
  Mat3 j(1.0);
  for (std::size_t e = 0; e < n; ++e) {
    const double* d = displacement_.data() + 4 * weights[e].column;
    const Vec3 disp(d[0], d[1], d[2]);
    for (int c = 0; c < 3; ++c) j[c] += disp * gradients[e][c];
  }
  return j;
}

void LatticeWarp::save(ArchiveWriter& out) const {
  out.tag("lattice-warp");
  lattice_.save(out);
  out.vec3s(posed_);
}

std::shared_ptr<const LatticeWarp> LatticeWarp::load(ArchiveReader& in) {
  const LatticeOptions params = Lattice::loadOptions(in);
  const std::size_t posedAt = in.position();
  const std::vector<Vec3> posed = in.vec3s();
  // The posed points must be one per control point: checked before the lattice is built (its
  // size follows the resolution, which hostile bytes could make huge).
  const auto [l, m, n] = params.resolution;
  const double controls = double(l) * double(m) * double(n);
  if (l < 1 || m < 1 || n < 1 || controls != double(posed.size())) {
    in.seek(posedAt);
    in.fail("the lattice warp stores " + std::to_string(posed.size()) +
            " posed control points, but its resolution " + std::to_string(l) + " x " +
            std::to_string(m) + " x " + std::to_string(n) + " needs one per control point");
  }
  return std::make_shared<const LatticeWarp>(Lattice(params), posed);
}

}  // namespace spacewarp
