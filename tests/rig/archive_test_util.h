#pragma once
// Checks of a saved-and-loaded object against the original: bit for bit, on random points inside
// and outside its domain, including the same refusal for the points it cannot map.

#include <cstring>
#include <random>
#include <span>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include <spacewarp/core/coordinates.h>
#include <spacewarp/core/warp.h>
#include <spacewarp/rig/warp_archive.h>

#include "test_util.h"

namespace spacewarp::test {

/// Bit-for-bit equality of two matrices.
inline bool bitEqual(const Mat3& a, const Mat3& b) {
  return std::memcmp(&a, &b, sizeof(Mat3)) == 0;
}

/// What a call gives: its result's bytes, or the type and message of what it threw.
template <class F>
std::string outcomeOf(F&& f) {
  try {
    return "ok:" + f();
  } catch (const InvalidInput& e) {
    return std::string("InvalidInput:") + e.what();
  } catch (const SolverError& e) {
    return std::string("SolverError:") + e.what();
  }
}

template <class T>
std::string bytesOf(const std::vector<T>& values) {
  return std::string(reinterpret_cast<const char*>(values.data()), values.size() * sizeof(T));
}

/// `points`, or random points of the box [lo, hi]^3 when empty.
inline std::vector<Vec3> pointsOrRandom(std::vector<Vec3> points, double lo, double hi) {
  if (!points.empty()) return points;
  std::mt19937 rng(17);
  return randomPoints(rng, 200, lo, hi);
}

/// applyBatch (whole and per point), jacobian and exactInverse of `a` and `b` agree bit for bit
/// at `points`, refusals included (the same exception type and message).
inline ::testing::AssertionResult sameWarp(const Warp& a, const Warp& b,
                                           std::vector<Vec3> points = {}, double lo = -2.0,
                                           double hi = 2.0) {
  points = pointsOrRandom(std::move(points), lo, hi);
  const auto batch = [&](const Warp& w) {
    std::vector<Vec3> out(points.size());
    w.applyBatch(points, out);
    return bytesOf(out);
  };
  if (outcomeOf([&] { return batch(a); }) != outcomeOf([&] { return batch(b); }))
    return ::testing::AssertionFailure()
           << "applyBatch differs: " << outcomeOf([&] { return batch(a); }).substr(0, 200) << " vs "
           << outcomeOf([&] { return batch(b); }).substr(0, 200);
  for (std::size_t i = 0; i < points.size(); ++i) {
    const Vec3& x = points[i];
    const auto one = [&](const Warp& w) {
      std::vector<Vec3> out(1);
      w.applyBatch(std::span<const Vec3>(&x, 1), out);
      std::vector<Mat3> j{w.jacobian(x)};
      const std::optional<Vec3> inv = w.exactInverse(x);
      return bytesOf(out) + bytesOf(j) + (inv ? bytesOf(std::vector<Vec3>{*inv}) : "none");
    };
    const std::string oa = outcomeOf([&] { return one(a); });
    const std::string ob = outcomeOf([&] { return one(b); });
    if (oa != ob)
      return ::testing::AssertionFailure()
             << "point " << i << " " << toString(x) << " differs: " << oa.substr(0, 200) << " vs "
             << ob.substr(0, 200);
  }
  return ::testing::AssertionSuccess();
}

/// Saved and loaded, `warp` gives the same bits (sameWarp) and saves to the same bytes.
inline ::testing::AssertionResult warpRoundTrips(const Warp& warp, std::vector<Vec3> points = {},
                                                 double lo = -2.0, double hi = 2.0) {
  const std::string bytes = saveWarp(warp);
  const std::shared_ptr<const Warp> loaded = loadWarp(bytes);
  if (typeid(*loaded) != typeid(warp))
    return ::testing::AssertionFailure() << "loaded as another type";
  if (saveWarp(*loaded) != bytes)
    return ::testing::AssertionFailure() << "saves to other bytes once loaded";
  return sameWarp(warp, *loaded, std::move(points), lo, hi);
}

/// weightsBatch, sparseWeights, gradients and column controls of `a` and `b` agree bit for bit.
inline ::testing::AssertionResult sameCoordinates(const Coordinates& a, const Coordinates& b,
                                                  std::vector<Vec3> points = {}, double lo = -2.0,
                                                  double hi = 2.0) {
  points = pointsOrRandom(std::move(points), lo, hi);
  if (a.columnCount() != b.columnCount() || a.controlPointCount() != b.controlPointCount() ||
      a.maxNonZeros() != b.maxNonZeros())
    return ::testing::AssertionFailure() << "sizes differ";
  if (bytesOf(std::vector<Vec3>(a.restControlPoints().begin(), a.restControlPoints().end())) !=
      bytesOf(std::vector<Vec3>(b.restControlPoints().begin(), b.restControlPoints().end())))
    return ::testing::AssertionFailure() << "rest controls differ";
  const auto batch = [&](const Coordinates& c) {
    std::vector<double> rows(points.size() * c.columnCount());
    c.weightsBatch(points, rows);
    return bytesOf(rows);
  };
  const std::string ba = outcomeOf([&] { return batch(a); });
  if (ba != outcomeOf([&] { return batch(b); }))
    return ::testing::AssertionFailure() << "weightsBatch differs: " << ba.substr(0, 200);
  for (std::size_t i = 0; i < points.size(); ++i) {
    const auto one = [&](const Coordinates& c) {
      std::vector<double> row(c.columnCount());
      c.weights(points[i], row);
      std::vector<SparseWeight> sparse(c.maxNonZeros());
      sparse.resize(c.sparseWeights(points[i], sparse));
      std::vector<double> sparseValues;  // not the structs' bytes: they have padding
      for (const SparseWeight& s : sparse) {
        sparseValues.push_back(static_cast<double>(s.column));
        sparseValues.push_back(s.weight);
      }
      std::vector<Vec3> gradients(c.columnCount());
      const bool has = c.weightGradients(points[i], gradients);
      return bytesOf(row) + bytesOf(sparseValues) + (has ? bytesOf(gradients) : "none");
    };
    const std::string oa = outcomeOf([&] { return one(a); });
    const std::string ob = outcomeOf([&] { return one(b); });
    if (oa != ob) return ::testing::AssertionFailure() << "point " << i << " differs";
  }
  std::vector<Vec3> posed(a.restControlPoints().begin(), a.restControlPoints().end());
  std::mt19937 rng(3);
  for (Vec3& p : posed) p += 0.1 * randomPoint(rng, -1.0, 1.0);
  std::vector<Vec3> ca(a.columnCount()), cb(b.columnCount());
  a.columnControls(posed, ca);
  b.columnControls(posed, cb);
  if (bytesOf(ca) != bytesOf(cb)) return ::testing::AssertionFailure() << "columnControls differ";
  return ::testing::AssertionSuccess();
}

/// Saved and loaded, `coordinates` give the same bits, save to the same bytes, and make the same
/// warp for a random pose.
inline ::testing::AssertionResult coordinatesRoundTrip(std::shared_ptr<const Coordinates> c,
                                                       std::vector<Vec3> points = {},
                                                       double lo = -2.0, double hi = 2.0) {
  const std::string bytes = saveCoordinates(*c);
  const std::shared_ptr<const Coordinates> loaded = loadCoordinates(bytes);
  if (typeid(*loaded) != typeid(*c)) return ::testing::AssertionFailure() << "another type";
  if (saveCoordinates(*loaded) != bytes)
    return ::testing::AssertionFailure() << "saves to other bytes once loaded";
  points = pointsOrRandom(std::move(points), lo, hi);
  if (auto r = sameCoordinates(*c, *loaded, points); !r) return r;
  std::vector<Vec3> posed(c->restControlPoints().begin(), c->restControlPoints().end());
  std::mt19937 rng(5);
  for (Vec3& p : posed) p += 0.1 * randomPoint(rng, -1.0, 1.0);
  return sameWarp(*makeWarp(c, posed), *makeWarp(loaded, posed), points);
}

}  // namespace spacewarp::test
