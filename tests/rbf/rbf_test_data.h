#pragma once
// Shared data of the RBF tests: a configuration per kernel and random handles.

#include <random>
#include <string>
#include <vector>

#include <spacewarp/core/math.h>
#include <spacewarp/rbf/kernels.h>
#include "test_util.h"

namespace spacewarp::test {

/// One set of options per kernel, with scales that suit centers in [-1, 1]^3.
inline std::vector<RbfOptions> everyKernel(double smoothing = 0.0) {
  std::vector<RbfOptions> all;
  for (const std::string& name : rbfKernelNames()) {
    RbfOptions o;
    o.kernel = rbfKernelFromName(name);
    o.scale = 0.7;
    o.radius = 1.5;
    o.smoothing = smoothing;
    all.push_back(o);
  }
  return all;
}

/// Handles in [-1, 1]^3 and targets displaced by up to `amplitude` per axis.
struct Handles {
  std::vector<Vec3> centers, targets;
};

inline Handles randomHandles(std::mt19937& rng, std::size_t n, double amplitude = 0.2) {
  Handles h;
  h.centers = randomPoints(rng, n, -1.0, 1.0);
  for (const Vec3& c : h.centers) h.targets.push_back(c + randomPoint(rng, -amplitude, amplitude));
  return h;
}

}  // namespace spacewarp::test
