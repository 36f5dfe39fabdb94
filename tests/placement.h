#pragma once
// Scale-invariance tests (issue 12): a problem moved far from the world origin and scaled must
// give the answers of the original, to the precision double coordinates there allow.

#include <algorithm>
#include <cmath>
#include <limits>
#include <span>
#include <string>
#include <vector>

#include <spacewarp/core/coordinates.h>
#include <spacewarp/core/math.h>

namespace spacewarp::test {

/// Where a scale-invariance test puts its problem: every point p goes to p · scale + offset ·
/// placementDirection (not along an axis, so every coordinate is offset).
struct Placement {
  double offset = 0.0;  ///< world units, along placementDirection
  double scale = 1.0;
};
inline const Vec3 placementDirection(1.0, -0.6, 0.35);
inline Vec3 place(const Vec3& p, const Placement& at) {
  return p * at.scale + at.offset * placementDirection;
}
/// Offsets {0, 1e3, 1e6, 1e8} × scales {1e-3, 1, 1e3}.
inline std::vector<Placement> placements() {
  std::vector<Placement> all;
  for (const double offset : {0.0, 1e3, 1e6, 1e8})
    for (const double scale : {1e-3, 1.0, 1e3}) all.push_back({offset, scale});
  return all;
}
/// The relative resolution of a placed problem of size `size` (world units, after placing): a
/// placed coordinate carries the round-off ε·(|offset| + size), so no computation on it can be
/// more accurate than this fraction of its size (≈ 1e-8 for a unit problem at 1e8, 2e-5 for a
/// 1e-3 one there). The tests bound errors by a multiple of it.
inline double placementResolution(const Placement& at, double size) {
  return std::numeric_limits<double>::epsilon() *
         (std::abs(at.offset) * glm::length(placementDirection) + size) / size;
}
/// "offset1e8_scale1em3": a test-name suffix.
inline std::string placementName(const Placement& at) {
  const auto exponent = [](double v) {
    std::string text = "0";
    if (v == 0.0) return text;
    const long e = std::lround(std::log10(v));
    text = "1e";
    if (e < 0) text += 'm';
    text += std::to_string(std::labs(e));
    return text;
  };
  return "offset" + exponent(at.offset) + "_scale" + exponent(at.scale);
}

/// max |w'(place(x)) − w(x)| over `samples` (of the base problem) and every column, where w
/// are the `base` coordinates and w' the `placed` ones (the same controls, placed). Columns past
/// controlPointCount() (Green's face columns, which carry a length) are divided by at.scale.
inline double placedWeightError(const Coordinates& base, const Coordinates& placed,
                                std::span<const Vec3> samples, const Placement& at) {
  const std::size_t m = base.columnCount(), nv = base.controlPointCount();
  std::vector<Vec3> moved;
  for (const Vec3& x : samples) moved.push_back(place(x, at));
  std::vector<double> expected(samples.size() * m), actual(samples.size() * m);
  base.weightsBatch(samples, expected);
  placed.weightsBatch(moved, actual);
  double worst = 0.0;
  for (std::size_t i = 0; i < actual.size(); ++i) {
    const double unit = i % m < nv ? 1.0 : at.scale;
    worst = std::max(worst, std::abs(actual[i] / unit - expected[i]));
  }
  return worst;
}

}  // namespace spacewarp::test
