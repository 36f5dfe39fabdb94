#pragma once
// Per-point math types (GLM, double) and the few conversions to Eigen, the project's linear
// algebra. Convert at that boundary only.

#include <algorithm>
#include <cmath>

#include <Eigen/Core>
#include <glm/glm.hpp>

namespace spacewarp {

using Vec3 = glm::dvec3;  ///< A point or vector in world units.
using Mat3 = glm::dmat3;  ///< Column-major 3 x 3: m[c][r] is row r of column c.
using Mat4 = glm::dmat4;  ///< Column-major 4 x 4 homogeneous transform.

inline Eigen::Vector3d toEigen(const Vec3& v) { return {v.x, v.y, v.z}; }
inline Vec3 toVec3(const Eigen::Vector3d& v) { return {v.x(), v.y(), v.z()}; }

inline Eigen::Matrix3d toEigen(const Mat3& m) {
  Eigen::Matrix3d e;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) e(r, c) = m[c][r];
  return e;
}

inline Mat3 toMat3(const Eigen::Matrix3d& e) {
  Mat3 m;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) m[c][r] = e(r, c);
  return m;
}

/// True when every component is finite (no NaN, no infinity).
inline bool isFinite(const Vec3& v) {
  return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
}

/// Largest absolute component: a cheap, scale-aware magnitude.
inline double maxAbs(const Vec3& v) {
  return std::max({std::abs(v.x), std::abs(v.y), std::abs(v.z)});
}

}  // namespace spacewarp
