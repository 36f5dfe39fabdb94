#include <spacewarp/rbf/rbf_warp.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

#include <spacewarp/core/archive.h>
#include <spacewarp/core/detail/simd.h>
#include <spacewarp/core/errors.h>
#include <spacewarp/rbf/detail/rbf_system.h>

namespace spacewarp {

namespace {

// The fit's residual at the centers, relative to the largest displacement (targets − centers):
// beyond kRbfRefineAbove one step of iterative refinement is applied and kept if it lowers the
// residual (fits of 3000 random centers reach 1.4e-8: the rounding of the evaluation, which
// refinement does not lower), and beyond
// kRbfMaxResidual the fit is refused (SolverError).
constexpr double kRbfRefineAbove = 1e-7;
constexpr double kRbfMaxResidual = 1e-6;

}  // namespace

namespace {

using namespace detail::simd;

constexpr std::size_t kPointsPerTask = 256;  // a multiple of kLanes

// What the batch kernel reads: the centers and weights in structure-of-arrays form, the kernel
// and its parameter, and the polynomial.
struct EvalData {
  const double* cx;
  const double* cy;
  const double* cz;
  const double* wx;
  const double* wy;
  const double* wz;
  std::size_t n;
  RbfKernel kernel;
  double param;  // ε² (inverse multiquadric), 1/ε² (Gaussian), 1/ρ (Wendland)
  Mat3 linear;
  Vec3 translation;
};

// e^x for x ≤ 0 (0 below −708): x = k ln 2 + f with |f| ≤ ln 2 / 2 (Cody–Waite), e^f by its
// Taylor polynomial of degree 13 (truncation below 5e-18), 2^k built in the exponent bits.
// No libm, no branches on lane values; within a few ulp of std::exp.
[[gnu::always_inline]] inline void expNonPositive(const VD& x, VD& y) {
  const VD zero{};
  const VD floor = zero - 708.0;
  const VD xc = x < floor ? floor : x;
  constexpr double kMagic = 6755399441055744.0;  // 1.5 * 2^52: adding it rounds to an integer
  const VD t = xc * 1.4426950408889634 + kMagic;
  const VD k = t - kMagic;
  const VD f = (xc - k * 6.93147180369123816490e-01) - k * 1.90821492927058770002e-10;
  VD p = zero + 1.0 / 6227020800.0;  // 1/13!
  constexpr double kInvFactorial[13] = {1.0,
                                        1.0,
                                        1.0 / 2,
                                        1.0 / 6,
                                        1.0 / 24,
                                        1.0 / 120,
                                        1.0 / 720,
                                        1.0 / 5040,
                                        1.0 / 40320,
                                        1.0 / 362880,
                                        1.0 / 3628800,
                                        1.0 / 39916800,
                                        1.0 / 479001600};
  for (int i = 12; i >= 0; --i) p = p * f + kInvFactorial[i];
  // k is in [−1021, 0]: the low bits of t hold it in two's complement.
  const VU kBits = reinterpret_cast<VU>(t) - std::uint64_t{0x4338000000000000};
  const VD scale = reinterpret_cast<VD>((kBits + std::uint64_t{1023}) << 52);
  y = x < floor ? zero : p * scale;
}

// ½ x log x for x ≥ 0 (0 for x below the smallest normal double): x = m 2^e with
// m ∈ [√½, √2), log m = 2 atanh(s), s = (m − 1) / (m + 1), |s| ≤ 0.172, by its series to s²¹
// (truncation below 1e-18). No libm; within a few ulp of x log(x) / 2.
[[gnu::always_inline]] inline void halfXLogX(const VD& x, VD& y) {
  const VD zero{}, one = zero + 1.0;
  const VU bits = reinterpret_cast<VU>(x);
  VD m = reinterpret_cast<VD>((bits & std::uint64_t{0x000FFFFFFFFFFFFF}) |
                              std::uint64_t{0x3FF0000000000000});
  // The biased exponent (0..2047) as a double, through the bits of 2^52 + e.
  const VD biased =
      reinterpret_cast<VD>((bits >> 52) | std::uint64_t{0x4330000000000000}) - 4503599627370496.0;
  const auto big = m > 1.4142135623730951;
  m = big ? 0.5 * m : m;
  const VD e = biased - 1023.0 + (big ? one : zero);
  const VD s = (m - 1.0) / (m + 1.0);
  const VD z = s * s;
  VD p = zero + 1.0 / 21;
  for (int k = 9; k >= 0; --k) p = p * z + 1.0 / (2 * k + 1);
  const VD logX = e * 6.93147180369123816490e-01 + (2.0 * s * p + e * 1.90821492927058770002e-10);
  y = x < 2.2250738585072014e-308 ? zero : (0.5 * x) * logX;
}

// Σ_j w_j φ(|c_j − x|) for the kLanes points (X, Y, Z), added to (ax, ay, az) in center order.
template <RbfKernel K>
[[gnu::always_inline]] inline void sumKernel(const EvalData& d, const VD& X, const VD& Y,
                                             const VD& Z, VD& ax, VD& ay, VD& az) {
  const VD zero{};
  for (std::size_t j = 0; j < d.n; ++j) {
    const VD dx = d.cx[j] - X, dy = d.cy[j] - Y, dz = d.cz[j] - Z;
    const VD r2 = dx * dx + dy * dy + dz * dz;
    VD phi;
    if constexpr (K == RbfKernel::Triharmonic) {
      VD y;
      rsqrt(r2, y);
      phi = r2 * (r2 * y);
    } else if constexpr (K == RbfKernel::Biharmonic) {
      VD y;
      rsqrt(r2, y);
      phi = r2 * y;
    } else if constexpr (K == RbfKernel::InverseMultiquadric) {
      rsqrt(r2 + d.param, phi);
    } else if constexpr (K == RbfKernel::WendlandC2) {
      VD y;
      rsqrt(r2, y);
      const VD s = (r2 * y) * d.param;
      VD t = 1.0 - s;
      t = t > zero ? t : zero;
      const VD t2 = t * t;
      phi = (t2 * t2) * (4.0 * s + 1.0);
    } else if constexpr (K == RbfKernel::Gaussian) {
      expNonPositive(-(r2 * d.param), phi);
    } else {
      halfXLogX(r2, phi);  // r² log r = ½ r² log r²
    }
    ax += d.wx[j] * phi;
    ay += d.wy[j] * phi;
    az += d.wz[j] * phi;
  }
}

// x' for kLanes points: in = x[4], y[4], z[4]; out likewise. Every lane runs the same
// instructions, so a point's result does not depend on its lane or on the other lanes.
SPACEWARP_SIMD_CLONES void evalLanes(const EvalData& d, const double* in, double* out) {
  VD X, Y, Z;
  std::memcpy(&X, in, sizeof X);
  std::memcpy(&Y, in + kLanes, sizeof Y);
  std::memcpy(&Z, in + 2 * kLanes, sizeof Z);
  VD ax{}, ay{}, az{};
  switch (d.kernel) {
    case RbfKernel::Triharmonic:
      sumKernel<RbfKernel::Triharmonic>(d, X, Y, Z, ax, ay, az);
      break;
    case RbfKernel::Biharmonic:
      sumKernel<RbfKernel::Biharmonic>(d, X, Y, Z, ax, ay, az);
      break;
    case RbfKernel::ThinPlate:
      sumKernel<RbfKernel::ThinPlate>(d, X, Y, Z, ax, ay, az);
      break;
    case RbfKernel::Gaussian:
      sumKernel<RbfKernel::Gaussian>(d, X, Y, Z, ax, ay, az);
      break;
    case RbfKernel::InverseMultiquadric:
      sumKernel<RbfKernel::InverseMultiquadric>(d, X, Y, Z, ax, ay, az);
      break;
    case RbfKernel::WendlandC2:
      sumKernel<RbfKernel::WendlandC2>(d, X, Y, Z, ax, ay, az);
      break;
  }
  const Mat3& m = d.linear;
  const Vec3& b = d.translation;
  const VD ox = X + (ax + (((m[0][0] * X + m[1][0] * Y) + m[2][0] * Z) + b.x));
  const VD oy = Y + (ay + (((m[0][1] * X + m[1][1] * Y) + m[2][1] * Z) + b.y));
  const VD oz = Z + (az + (((m[0][2] * X + m[1][2] * Y) + m[2][2] * Z) + b.z));
  std::memcpy(out, &ox, sizeof ox);
  std::memcpy(out + kLanes, &oy, sizeof oy);
  std::memcpy(out + 2 * kLanes, &oz, sizeof oz);
}

double kernelParam(const RbfOptions& o) {
  switch (o.kernel) {
    case RbfKernel::Gaussian:
      return 1.0 / (o.scale * o.scale);
    case RbfKernel::InverseMultiquadric:
      return o.scale * o.scale;
    case RbfKernel::WendlandC2:
      return 1.0 / o.radius;
    default:
      return 0.0;
  }
}

}  // namespace

RbfWarp::RbfWarp(std::span<const Vec3> centers, std::span<const Vec3> targets,
                 const RbfOptions& options)
    : RbfWarp(centers, targets, {}, options) {}

void RbfWarp::check(std::span<const Vec3> centers, std::span<const Vec3> targets,
                    std::span<const Vec3> fixed, const RbfOptions& options) {
  const std::string who = "RbfWarp";
  const detail::RbfCenters c = detail::prepareRbfCenters(who, centers, &targets, fixed, options);
  detail::checkRbfPolynomial(who, c.unique);
}

RbfWarp::RbfWarp(std::span<const Vec3> centers, std::span<const Vec3> targets,
                 std::span<const Vec3> fixed, const RbfOptions& options)
    : options_(options) {
  options_.progress = nullptr;  // the caller's, for this fit only
  const std::string who = "RbfWarp";
  const detail::RbfCenters c = detail::prepareRbfCenters(who, centers, &targets, fixed, options);
  const detail::RbfSystem system(who, c.unique, options);
  const Eigen::Index n = static_cast<Eigen::Index>(c.unique.size());
  Eigen::MatrixXd d(n, 3);
  for (Eigen::Index i = 0; i < n; ++i) {
    const Vec3& v = c.displacement[static_cast<std::size_t>(i)];
    d.row(i) << v.x, v.y, v.z;
  }
  Eigen::MatrixXd w, a;
  system.solve(d, w, a);
  centers_ = c.unique;
  const auto build = [&] {
    weights_.resize(c.unique.size());
    for (Eigen::Index i = 0; i < n; ++i)
      weights_[static_cast<std::size_t>(i)] = Vec3(w(i, 0), w(i, 1), w(i, 2));
    // a in the basis [1, (x − origin) / length] → L x + b in world coordinates.
    for (int i = 0; i < 3; ++i) {
      double b = a(0, i);
      for (int k = 0; k < 3; ++k) {
        linear_[k][i] = a(k + 1, i) / system.length();
        b -= linear_[k][i] * system.origin()[k];
      }
      translation_[i] = b;
    }
    buildSoa();
  };
  // The residual r of the fit's equations as apply() evaluates them (its rounding included):
  // x'(c_i) = c_i + D_i − σλ w_i (σ = −1 for the biharmonic kernel; exact interpolation at
  // λ = 0); returns its largest row norm.
  const double sigmaLambda =
      (options.kernel == RbfKernel::Biharmonic ? -1.0 : 1.0) * options.smoothing;
  Eigen::MatrixXd r(n, 3);
  std::vector<Vec3> moved(centers_.size());
  const auto residualOf = [&] {
    applyBatch(centers_, moved);
    double largest = 0.0;
    for (std::size_t i = 0; i < centers_.size(); ++i) {
      const Vec3 e = centers_[i] + c.displacement[i] - sigmaLambda * weights_[i] - moved[i];
      r.row(static_cast<Eigen::Index>(i)) << e.x, e.y, e.z;
      largest = std::max(largest, glm::length(e));
    }
    return largest;
  };
  build();
  // A nearly singular system (centers far closer than the others, targets far apart) can pass
  // the factorisation's checks yet miss its equations: one step of iterative refinement (one
  // solve for the residual) where the residual is beyond rounding, so that well-posed fits keep
  // their bits; what the warp still misses is refused.
  const double scale = d.rowwise().norm().maxCoeff();
  double residual = residualOf();
  if (residual > kRbfRefineAbove * scale) {
    Eigen::MatrixXd dw, da;
    system.solve(r, dw, da);
    w += dw;
    a += da;
    build();
    const double refined = residualOf();
    if (refined < residual) {
      residual = refined;
    } else {  // at the evaluation's rounding floor already: back to the first solution's bits
      system.solve(d, w, a);
      build();
    }
  }
  if (!(residual <= kRbfMaxResidual * scale)) {
    char text[320];
    std::snprintf(text, sizeof text,
                  "the fit misses its 'targets' by %.3g (%.3g of the largest displacement, more "
                  "than %g): the system is nearly singular (centers "
                  "much closer than the others with different displacements?); try smoothing > 0",
                  residual, residual / scale, kRbfMaxResidual);
    throw SolverError(who + ": " + text);
  }
}

void RbfWarp::buildSoa() {
  const std::size_t count = centers_.size();
  soa_.resize(6 * count);
  for (std::size_t j = 0; j < count; ++j) {
    for (int k = 0; k < 3; ++k) {
      soa_[k * count + j] = centers_[j][k];
      soa_[(3 + k) * count + j] = weights_[j][k];
    }
  }
}

namespace {

EvalData evalDataOf(const std::vector<double>& soa, std::size_t n, const RbfOptions& options,
                    const Mat3& linear, const Vec3& translation) {
  const double* p = soa.data();
  return {p,         p + n,          p + 2 * n,
          p + 3 * n, p + 4 * n,      p + 5 * n,
          n,         options.kernel, kernelParam(options),
          linear,    translation};
}

}  // namespace

Vec3 RbfWarp::apply(const Vec3& x) const {
  const EvalData d = evalDataOf(soa_, centers_.size(), options_, linear_, translation_);
  double in[3 * kLanes], out[3 * kLanes];
  for (int l = 0; l < kLanes; ++l) {
    in[l] = x.x;
    in[kLanes + l] = x.y;
    in[2 * kLanes + l] = x.z;
  }
  evalLanes(d, in, out);
  return {out[0], out[kLanes], out[2 * kLanes]};
}

Mat3 RbfWarp::jacobian(const Vec3& x) const {
  Mat3 j = Mat3(1.0) + linear_;
  for (std::size_t i = 0; i < centers_.size(); ++i) {
    const Vec3 v = x - centers_[i];
    const double s = rbfKernelSlopeOverR(options_, glm::length(v));
    j += glm::outerProduct(weights_[i], s * v);
  }
  return j;
}

std::size_t RbfWarp::batchGrain() const { return kPointsPerTask; }

UnmappedPoints RbfWarp::applyRange(std::span<const Vec3> in, std::span<Vec3> out, std::size_t begin,
                                   std::size_t end) const {
  const EvalData d = evalDataOf(soa_, centers_.size(), options_, linear_, translation_);
  double lanesIn[3 * kLanes], lanesOut[3 * kLanes];
  for (std::size_t i = begin; i < end; i += kLanes) {
    const std::size_t count = std::min<std::size_t>(kLanes, end - i);
    for (std::size_t l = 0; l < kLanes; ++l) {
      const Vec3& p = in[i + std::min(l, count - 1)];
      lanesIn[l] = p.x;
      lanesIn[kLanes + l] = p.y;
      lanesIn[2 * kLanes + l] = p.z;
    }
    evalLanes(d, lanesIn, lanesOut);
    for (std::size_t l = 0; l < count; ++l)
      out[i + l] = Vec3(lanesOut[l], lanesOut[kLanes + l], lanesOut[2 * kLanes + l]);
  }
  return {};
}

void RbfWarp::save(ArchiveWriter& out) const {
  out.tag("rbf-warp");
  writeRbfOptions(out, options_);
  out.vec3s(centers_);
  out.vec3s(weights_);
  out.mat3(linear_);
  out.vec3(translation_);
}

std::shared_ptr<const RbfWarp> RbfWarp::load(ArchiveReader& in) {
  std::shared_ptr<RbfWarp> warp(new RbfWarp());
  warp->options_ = readRbfOptions(in);
  warp->centers_ = in.vec3s();
  warp->weights_ = in.vec3s();
  warp->linear_ = in.mat3();
  warp->translation_ = in.vec3();
  if (warp->centers_.empty() || warp->weights_.size() != warp->centers_.size())
    in.fail("an RBF warp has " + std::to_string(warp->centers_.size()) + " centers and " +
            std::to_string(warp->weights_.size()) + " weights");
  bool finite = isFinite(warp->translation_);
  for (int c = 0; c < 3; ++c) finite = finite && isFinite(warp->linear_[c]);
  for (const Vec3& p : warp->centers_) finite = finite && isFinite(p);
  for (const Vec3& w : warp->weights_) finite = finite && isFinite(w);
  if (!finite) in.fail("an RBF warp's state is not finite");
  warp->buildSoa();
  return warp;
}

}  // namespace spacewarp
