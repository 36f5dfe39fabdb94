#pragma once
// Lattices shared by the ffd tests: an oriented, non-cubic box for every basis, random poses,
// and points inside, on the faces and outside of it.

#include <random>
#include <string>
#include <vector>

#include <spacewarp/ffd/lattice.h>
#include "test_util.h"

namespace spacewarp::test {

inline const char* basisName(LatticeBasis basis) {
  switch (basis) {
    case LatticeBasis::Trilinear:
      return "trilinear";
    case LatticeBasis::Bernstein:
      return "bernstein";
    case LatticeBasis::BSpline:
      return "bspline";
  }
  return "?";
}

inline const std::vector<LatticeBasis> kAllBases = {LatticeBasis::Trilinear,
                                                    LatticeBasis::Bernstein, LatticeBasis::BSpline};

/// A rotated box at (1, −2, 0.5) with extents 2 × 1 × 3 and resolution 5 × 4 × 6.
inline LatticeOptions orientedParams(LatticeBasis basis,
                                     LatticeOutside outside = LatticeOutside::Identity) {
  LatticeOptions p;
  p.origin = Vec3(1.0, -2.0, 0.5);
  const Vec3 a = glm::normalize(Vec3(1.0, 2.0, 2.0));
  const Vec3 b = glm::normalize(glm::cross(a, Vec3(0.0, 0.0, 1.0)));
  p.axes = {a, b, glm::cross(a, b)};
  p.extents = Vec3(2.0, 1.0, 3.0);
  p.resolution = {5, 4, 6};
  p.basis = basis;
  p.outside = outside;
  return p;
}

/// The rest grid moved by random offsets of up to `amount` × the smallest cell size.
inline std::vector<Vec3> randomPose(const Lattice& lattice, std::mt19937& rng, double amount) {
  const auto rest = lattice.restControlPoints();
  std::vector<Vec3> posed(rest.begin(), rest.end());
  const double cell = 0.25;
  for (Vec3& p : posed) p += amount * cell * randomPoint(rng, -1.0, 1.0);
  return posed;
}

/// Points uniform in the box (u, v, w) ∈ [lo, hi)³.
inline std::vector<Vec3> boxPoints(const Lattice& lattice, std::mt19937& rng, std::size_t n,
                                   double lo = 0.0, double hi = 1.0) {
  std::vector<Vec3> points(n);
  for (Vec3& p : points) p = lattice.toWorld(randomPoint(rng, lo, hi));
  return points;
}

/// Points exactly on the box planes: on each face (u = 0 or 1 on one axis), on the edges and
/// at the 8 corners, in box coordinates.
inline std::vector<Vec3> facePointsLocal(std::mt19937& rng, std::size_t perFace) {
  std::vector<Vec3> points;
  for (int a = 0; a < 3; ++a)
    for (double side : {0.0, 1.0})
      for (std::size_t i = 0; i < perFace; ++i) {
        Vec3 p = randomPoint(rng, 0.0, 1.0);
        p[a] = side;
        points.push_back(p);
      }
  for (int c = 0; c < 8; ++c) points.emplace_back(c & 1, (c >> 1) & 1, (c >> 2) & 1);
  for (std::size_t i = 0; i < perFace; ++i) {  // edges
    Vec3 p = randomPoint(rng, 0.0, 1.0);
    p[i % 3] = static_cast<double>(i & 1);
    p[(i + 1) % 3] = static_cast<double>((i >> 1) & 1);
    points.push_back(p);
  }
  return points;
}

}  // namespace spacewarp::test
