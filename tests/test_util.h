#pragma once
// Shared helpers of the test suites: seeded random points, an independent finite-difference
// Jacobian, relative errors, exception messages, the checks every Warp must pass (analytic
// Jacobian, normals, inversion, deterministic batches), those checks run over the test
// configurations of one kind of warp, and the checks of the axial warps' limits.

#include <dlfcn.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <functional>
#include <limits>
#include <random>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include <gtest/gtest.h>
#include <tbb/task_arena.h>

#include <spacewarp/core/errors.h>
#include <spacewarp/core/inverse.h>
#include <spacewarp/core/math.h>
#include <spacewarp/core/progress.h>
#include <spacewarp/core/warp.h>

namespace spacewarp::test {

/// Records what a long operation reports for `stage`: every fraction, in order, and whether
/// any report named another stage.
struct ProgressLog {
  explicit ProgressLog(std::string name) : stage(std::move(name)) {}

  std::string stage;
  std::vector<double> fractions;
  bool otherStage = false;

  ProgressCallback callback() {
    return [this](std::string_view s, double fraction) {
      if (s == stage)
        fractions.push_back(fraction);
      else
        otherStage = true;
      return true;
    };
  }

  /// The stage reported 0 first, 1 last, never went back, and no other stage was named.
  void expectFromZeroToOne() const {
    ASSERT_GE(fractions.size(), 2u) << stage;
    EXPECT_EQ(fractions.front(), 0.0) << stage;
    EXPECT_EQ(fractions.back(), 1.0) << stage;
    for (std::size_t i = 1; i < fractions.size(); ++i)
      EXPECT_LE(fractions[i - 1], fractions[i]) << stage;
    EXPECT_FALSE(otherStage) << stage;
  }
};

/// A point with components uniform in [lo, hi).
inline Vec3 randomPoint(std::mt19937& rng, double lo, double hi) {
  std::uniform_real_distribution<double> u(lo, hi);
  const double x = u(rng);
  const double y = u(rng);
  const double z = u(rng);
  return {x, y, z};
}

/// n points with components uniform in [lo, hi).
inline std::vector<Vec3> randomPoints(std::mt19937& rng, std::size_t n, double lo, double hi) {
  std::vector<Vec3> points(n);
  for (Vec3& p : points) p = randomPoint(rng, lo, hi);
  return points;
}

/// n points with components uniform in [lo, hi) that satisfy `keep` (rejection sampling).
inline std::vector<Vec3> randomPointsWhere(std::mt19937& rng, std::size_t n, double lo, double hi,
                                           const std::function<bool(const Vec3&)>& keep) {
  std::vector<Vec3> points;
  points.reserve(n);
  while (points.size() < n) {
    const Vec3 p = randomPoint(rng, lo, hi);
    if (keep(p)) points.push_back(p);
  }
  return points;
}

/// The message of the exception of type E that `action()` throws, or "" if it throws none
/// (an exception of another type propagates). Expect a substring of it to check a message.
template <typename E, typename Action>
std::string messageOf(Action&& action) {
  try {
    action();
  } catch (const E& e) {
    return e.what();
  }
  return "";
}

/// A uniformly distributed unit vector.
inline Vec3 randomUnit(std::mt19937& rng) {
  std::normal_distribution<double> g;
  for (;;) {
    const double x = g(rng);
    const double y = g(rng);
    const double z = g(rng);
    const Vec3 v(x, y, z);
    const double len = glm::length(v);
    if (len > 1e-3) return v / len;
  }
}

/// Frobenius norm.
inline double frobenius(const Mat3& m) {
  double sum = 0.0;
  for (int c = 0; c < 3; ++c) sum += glm::dot(m[c], m[c]);
  return std::sqrt(sum);
}

/// |a - b| / max(1, |b|): the relative error of a against the reference b.
inline double relativeError(const Vec3& a, const Vec3& b) {
  return glm::length(a - b) / std::max(1.0, glm::length(b));
}

/// |A - B|_F / max(1, |B|_F): the relative error of A against the reference B.
inline double relativeError(const Mat3& a, const Mat3& b) {
  return frobenius(a - b) / std::max(1.0, frobenius(b));
}

/// The Jacobian of warp at x by fourth-order central differences with step h per axis
/// (default 1e-3 * max(1, |x|_inf)): truncation error ~ h^4, round-off ~ eps / h, both far
/// below 1e-6 for smooth warps. Independent of Warp::jacobian's own default.
inline Mat3 finiteDifferenceJacobian(const Warp& warp, const Vec3& x, double h = 0.0) {
  if (h <= 0.0) h = 1e-3 * std::max(1.0, maxAbs(x));
  Mat3 j;
  for (int axis = 0; axis < 3; ++axis) {
    Vec3 e(0.0);
    e[axis] = h;
    j[axis] = (-warp.apply(x + 2.0 * e) + 8.0 * warp.apply(x + e) - 8.0 * warp.apply(x - e) +
               warp.apply(x - 2.0 * e)) /
              (12.0 * h);
  }
  return j;
}

inline std::string toString(const Vec3& v) {
  std::ostringstream s;
  s.precision(17);
  s << "(" << v.x << ", " << v.y << ", " << v.z << ")";
  return s.str();
}

inline std::string toString(const Mat3& m) {
  std::ostringstream s;
  s.precision(10);
  s << "[";
  for (int r = 0; r < 3; ++r) s << (r ? "; " : "") << m[0][r] << " " << m[1][r] << " " << m[2][r];
  s << "]";
  return s.str();
}

/// warp.jacobian(x) agrees with finite differences within `tolerance` (relative Frobenius error,
/// relative to max(1, |J|_F)) at every point.
inline ::testing::AssertionResult jacobianMatchesFiniteDifferences(const Warp& warp,
                                                                   const std::vector<Vec3>& points,
                                                                   double tolerance = 1e-6) {
  for (std::size_t i = 0; i < points.size(); ++i) {
    const Mat3 analytic = warp.jacobian(points[i]);
    const Mat3 reference = finiteDifferenceJacobian(warp, points[i]);
    const double err = relativeError(analytic, reference);
    if (!(err <= tolerance)) {
      return ::testing::AssertionFailure()
             << "point " << i << " " << toString(points[i]) << ": relative error " << err
             << "\n  analytic  " << toString(analytic) << "\n  reference " << toString(reference);
    }
  }
  return ::testing::AssertionSuccess();
}

/// Two unit tangents spanning the plane perpendicular to the unit vector n.
inline void tangentsOf(const Vec3& n, Vec3& t1, Vec3& t2) {
  const Vec3 helper = std::abs(n.x) < 0.6 ? Vec3(1.0, 0.0, 0.0) : Vec3(0.0, 1.0, 0.0);
  t1 = glm::normalize(glm::cross(n, helper));
  t2 = glm::cross(n, t1);
}

/// At each point, with a random unit normal n: transformNormal gives a unit vector perpendicular
/// (within `tolerance`, relative to the tangents' lengths) to transformVector of two tangents
/// spanning the plane perpendicular to n.
inline ::testing::AssertionResult normalsStayPerpendicular(const Warp& warp,
                                                           const std::vector<Vec3>& points,
                                                           std::mt19937& rng,
                                                           double tolerance = 1e-12) {
  for (std::size_t i = 0; i < points.size(); ++i) {
    const Vec3 n = randomUnit(rng);
    Vec3 t1, t2;
    tangentsOf(n, t1, t2);
    const Vec3 nn = transformNormal(warp, points[i], n);
    const Vec3 tt1 = transformVector(warp, points[i], t1);
    const Vec3 tt2 = transformVector(warp, points[i], t2);
    const double unit = std::abs(glm::length(nn) - 1.0);
    const double e1 = std::abs(glm::dot(nn, tt1)) / glm::length(tt1);
    const double e2 = std::abs(glm::dot(nn, tt2)) / glm::length(tt2);
    if (!(unit <= 1e-14 && e1 <= tolerance && e2 <= tolerance)) {
      return ::testing::AssertionFailure()
             << "point " << i << " " << toString(points[i]) << " normal " << toString(n)
             << ": |n'| - 1 = " << unit << ", n'.t1'/|t1'| = " << e1 << ", n'.t2'/|t2'| = " << e2;
    }
  }
  return ::testing::AssertionSuccess();
}

/// inverse(warp, warp(x)) converges and recovers x within `tolerance` relative to max(1, |x|).
inline ::testing::AssertionResult inverseRecovers(const Warp& warp, const std::vector<Vec3>& points,
                                                  double tolerance = 1e-9) {
  for (std::size_t i = 0; i < points.size(); ++i) {
    const Vec3 y = warp.apply(points[i]);
    const InverseResult r = inverse(warp, y);
    const double err = relativeError(r.x, points[i]);
    if (!r.converged || !(err <= tolerance)) {
      return ::testing::AssertionFailure()
             << "point " << i << " " << toString(points[i]) << " -> " << toString(y)
             << ": converged = " << r.converged << " after " << r.iterations
             << " iterations, residual " << r.residual << ", found " << toString(r.x)
             << ", relative error " << err;
    }
  }
  return ::testing::AssertionSuccess();
}

/// Bit-for-bit equality of two vectors (so that -0.0 != +0.0 and NaN == NaN of the same payload).
inline bool bitEqual(const Vec3& a, const Vec3& b) {
  return std::memcmp(&a, &b, sizeof(Vec3)) == 0;
}

/// applyBatch run in a 1-thread arena and in a 2-thread arena gives the same bits, and both equal
/// apply() per point.
inline ::testing::AssertionResult batchIsDeterministic(const Warp& warp,
                                                       const std::vector<Vec3>& points) {
  std::vector<Vec3> one(points.size()), two(points.size());
  tbb::task_arena arena1(1);
  arena1.execute([&] { warp.applyBatch(points, one); });
  tbb::task_arena arena2(2);
  arena2.execute([&] { warp.applyBatch(points, two); });
  for (std::size_t i = 0; i < points.size(); ++i) {
    const Vec3 single = warp.apply(points[i]);
    if (!bitEqual(one[i], two[i]) || !bitEqual(one[i], single)) {
      return ::testing::AssertionFailure()
             << "point " << i << " " << toString(points[i]) << ": 1 thread " << toString(one[i])
             << ", 2 threads " << toString(two[i]) << ", apply() " << toString(single);
    }
  }
  return ::testing::AssertionSuccess();
}

/// applyBatch with an output span of another size than the input throws InvalidInput.
inline void expectBatchRejectsMismatchedSizes(const Warp& warp, std::size_t inSize,
                                              std::size_t outSize) {
  std::vector<Vec3> in(inSize), out(outSize);
  EXPECT_THROW(warp.applyBatch(in, out), InvalidInput) << inSize << " in, " << outSize << " out";
}

/// The checks every smooth Warp passes at `points` (see above): the analytic Jacobian matches
/// finite differences, inverse() recovers the points, and normals stay perpendicular to
/// tangents (with random normals drawn from `rng`).
inline void expectWarpProperties(const Warp& warp, const std::vector<Vec3>& points,
                                 std::mt19937& rng) {
  EXPECT_TRUE(jacobianMatchesFiniteDifferences(warp, points));
  EXPECT_TRUE(inverseRecovers(warp, points));
  EXPECT_TRUE(normalsStayPerpendicular(warp, points, rng));
}

/// warp.apply(x) == x at every point (exactly, as EXPECT_EQ compares).
inline ::testing::AssertionResult leavesPointsUnchanged(const Warp& warp,
                                                        const std::vector<Vec3>& points) {
  for (std::size_t i = 0; i < points.size(); ++i) {
    const Vec3 moved = warp.apply(points[i]);
    if (!(moved == points[i])) {
      return ::testing::AssertionFailure()
             << "point " << i << " " << toString(points[i]) << " moved to " << toString(moved);
    }
  }
  return ::testing::AssertionSuccess();
}

/// The warp moves `points` as one rigid motion: at each point the Jacobian is a rotation
/// (|JᵀJ - I| relative error below 1e-14, |det J - 1| at most 1e-14), and the distance between
/// consecutive points is kept within 1e-12 relative.
inline ::testing::AssertionResult movesRigidly(const Warp& warp, const std::vector<Vec3>& points) {
  for (std::size_t i = 0; i < points.size(); ++i) {
    const Mat3 j = warp.jacobian(points[i]);
    const double orthogonality = relativeError(glm::transpose(j) * j, Mat3(1.0));
    const double determinant = glm::determinant(j);
    if (!(orthogonality < 1e-14) || !(std::abs(determinant - 1.0) <= 1e-14)) {
      return ::testing::AssertionFailure()
             << "point " << i << " " << toString(points[i]) << ": Jacobian " << toString(j)
             << " is not a rotation (|JtJ - I| " << orthogonality << ", det " << determinant << ")";
    }
    if (i == 0) continue;
    const double before = glm::length(points[i] - points[i - 1]);
    const double after = glm::length(warp.apply(points[i]) - warp.apply(points[i - 1]));
    if (!(std::abs(after - before) <= 1e-12 * before)) {
      return ::testing::AssertionFailure() << "points " << i - 1 << " and " << i << ": distance "
                                           << before << " became " << after;
    }
  }
  return ::testing::AssertionSuccess();
}

// ---------------------------------------------------------------------------------------------
// Axial warps (twist, bend, taper): parameters, limits, and the checks above run over a list of
// test configurations.

/// Builds the parameters of an axial warp (TwistOptions, TaperOptions, BendOptions): the axis
/// through `origin` along `axis`, the rate and the limits [lo, hi] on the axial coordinate (world
/// units); other fields keep their defaults. A function object, so that a test file can name it
/// and keep the default limits: `constexpr test::AxialOptions<TwistOptions> twistParams{};`.
template <typename Params>
struct AxialOptions {
  Params operator()(const Vec3& origin, const Vec3& axis, double rate,
                    double lo = -std::numeric_limits<double>::infinity(),
                    double hi = std::numeric_limits<double>::infinity()) const {
    Params p;
    p.origin = origin;
    p.axis = axis;
    p.rate = rate;
    p.lo = lo;
    p.hi = hi;
    return p;
  }
};

/// "rate 0.5 limits [-1, 2]": names a configuration of an axial warp in failure messages.
template <typename Params>
std::string describeAxial(const Params& params) {
  std::ostringstream s;
  s << "rate " << params.rate << " limits [" << params.lo << ", " << params.hi << "]";
  return s.str();
}

/// n offsets perpendicular to the unit vector `axis`: points uniform in [-2, 2)^3 (drawn from
/// `rng` one after the other) without their component along `axis`.
inline std::vector<Vec3> perpendicularOffsets(std::mt19937& rng, std::size_t n, const Vec3& axis) {
  std::vector<Vec3> offsets(n);
  for (Vec3& p : offsets) {
    const Vec3 offset = randomPoint(rng, -2.0, 2.0);
    p = offset - glm::dot(offset, axis) * axis;
  }
  return offsets;
}

/// An axial warp is continuous across its limit plane s = `limit` on the axis through `origin`
/// along the unit vector `axis`: for each offset p (perpendicular to the axis), the images of
/// origin + (limit - 1e-10) axis + p and origin + (limit + 1e-10) axis + p differ by less than
/// `tolerance`, relative to either of them.
inline ::testing::AssertionResult continuousAcross(const Warp& warp, const Vec3& origin,
                                                   const Vec3& axis, double limit,
                                                   const std::vector<Vec3>& offsets,
                                                   double tolerance = 1e-9) {
  const double delta = 1e-10;
  for (std::size_t i = 0; i < offsets.size(); ++i) {
    const Vec3 below = warp.apply(origin + (limit - delta) * axis + offsets[i]);
    const Vec3 above = warp.apply(origin + (limit + delta) * axis + offsets[i]);
    const double err = std::max(relativeError(below, above), relativeError(above, below));
    if (!(err < tolerance)) {
      return ::testing::AssertionFailure()
             << "limit " << limit << ", offset " << i << " " << toString(offsets[i])
             << ": jumps from " << toString(below) << " to " << toString(above);
    }
  }
  return ::testing::AssertionSuccess();
}

/// Draws `n` test points for `warp` from `rng` (where it is smooth, invertible, ...).
template <typename W>
using PointSampler =
    std::function<std::vector<Vec3>(const W& warp, std::mt19937& rng, std::size_t n)>;

/// A sampler of points uniform in [lo, hi)^3, whatever the warp.
template <typename W>
PointSampler<W> uniformPoints(double lo, double hi) {
  return
      [lo, hi](const W&, std::mt19937& rng, std::size_t n) { return randomPoints(rng, n, lo, hi); };
}

/// For each configuration in turn: builds W(params), draws 200 points for it with `sample` from
/// `rng` and expects `check(warp, points)` to succeed, naming the configuration if it fails.
template <typename W, typename Params, typename Check>
void expectForEachConfiguration(const std::vector<Params>& configurations, std::mt19937& rng,
                                const PointSampler<W>& sample, Check check) {
  for (const Params& params : configurations) {
    const W warp(params);
    const std::vector<Vec3> points = sample(warp, rng, 200);
    EXPECT_TRUE(check(warp, points)) << describeAxial(params);
  }
}

/// jacobianMatchesFiniteDifferences for every configuration (see expectForEachConfiguration).
template <typename W, typename Params>
void expectJacobiansMatchFiniteDifferences(const std::vector<Params>& configurations,
                                           std::mt19937& rng, const PointSampler<W>& sample) {
  expectForEachConfiguration<W>(configurations, rng, sample,
                                [](const Warp& warp, const std::vector<Vec3>& points) {
                                  return jacobianMatchesFiniteDifferences(warp, points);
                                });
}

/// inverseRecovers for every configuration (see expectForEachConfiguration).
template <typename W, typename Params>
void expectInversesRecover(const std::vector<Params>& configurations, std::mt19937& rng,
                           const PointSampler<W>& sample) {
  expectForEachConfiguration<W>(configurations, rng, sample,
                                [](const Warp& warp, const std::vector<Vec3>& points) {
                                  return inverseRecovers(warp, points);
                                });
}

/// normalsStayPerpendicular for every configuration, the random normals drawn from `rng` after
/// each configuration's points (see expectForEachConfiguration).
template <typename W, typename Params>
void expectNormalsStayPerpendicular(const std::vector<Params>& configurations, std::mt19937& rng,
                                    const PointSampler<W>& sample) {
  expectForEachConfiguration<W>(configurations, rng, sample,
                                [&rng](const Warp& warp, const std::vector<Vec3>& points) {
                                  return normalsStayPerpendicular(warp, points, rng);
                                });
}

/// batchIsDeterministic for the warp W(params) of every configuration, at the same `points`.
template <typename W, typename Params>
void expectBatchesDeterministic(const std::vector<Params>& configurations,
                                const std::vector<Vec3>& points) {
  for (const Params& params : configurations)
    EXPECT_TRUE(batchIsDeterministic(W(params), points)) << describeAxial(params);
}

/// OpenBLAS's thread-count controls, if OpenBLAS is the BLAS in this process (looked up at
/// run time, so tests do not link a particular BLAS).
struct OpenBlasThreads {
  int (*get)() = nullptr;
  void (*set)(int) = nullptr;
  OpenBlasThreads()
      : get(reinterpret_cast<int (*)()>(dlsym(RTLD_DEFAULT, "openblas_get_num_threads"))),
        set(reinterpret_cast<void (*)(int)>(dlsym(RTLD_DEFAULT, "openblas_set_num_threads"))) {}
  bool available() const { return get && set; }
};

/// A rotation by `angle` radians about `axis` (normalised; Rodrigues).
inline Mat3 rotation(const Vec3& axis, double angle) {
  const Vec3 a = glm::normalize(axis);
  const double c = std::cos(angle), s = std::sin(angle);
  Mat3 r(c);
  r += (1.0 - c) * glm::outerProduct(a, a);
  r[0] += s * glm::cross(a, Vec3(1.0, 0.0, 0.0));
  r[1] += s * glm::cross(a, Vec3(0.0, 1.0, 0.0));
  r[2] += s * glm::cross(a, Vec3(0.0, 0.0, 1.0));
  return r;
}

/// Point handles and their targets, for the handle-based warps.
struct HandleRig {
  std::vector<Vec3> handles, targets;
};

/// n handles in [-1, 1)^3, each target displaced by up to 0.4 per component.
inline HandleRig randomHandleRig(std::mt19937& rng, std::size_t n) {
  HandleRig r;
  r.handles = randomPoints(rng, n, -1.0, 1.0);
  for (const Vec3& p : r.handles) r.targets.push_back(p + randomPoint(rng, -0.4, 0.4));
  return r;
}

}  // namespace spacewarp::test
