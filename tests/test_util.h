#pragma once
// Shared helpers of the test suites: seeded random points, an independent finite-difference
// Jacobian, relative errors, and the checks every Warp must pass (analytic Jacobian, normals,
// inversion, deterministic batches).

#include <cmath>
#include <cstring>
#include <functional>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <tbb/task_arena.h>

#include "core/math.h"
#include "core/warp.h"

namespace spacewarp::test {

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

}  // namespace spacewarp::test
