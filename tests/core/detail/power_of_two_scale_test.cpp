#include <spacewarp/core/detail/power_of_two_scale.h>

#include <cmath>
#include <limits>
#include <random>

#include <gtest/gtest.h>

#include <spacewarp/core/warp.h>

#include "test_util.h"

namespace spacewarp::detail {
namespace {

Mat3 randomRegular(std::mt19937& rng) {
  std::uniform_real_distribution<double> u(-2.0, 2.0);
  for (;;) {
    Mat3 j;
    for (int c = 0; c < 3; ++c) j[c] = Vec3(u(rng), u(rng), u(rng));
    if (!isSingularJacobian(j)) return j;
  }
}

// Where glm::inverse neither overflows nor underflows, the rescaled forms give its bits: the
// solver's steps (and so volume outputs) are the same as before the rescaling.
TEST(PowerOfTwoScale, SameBitsAsThePlainInverseAtOrdinaryScales) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> exponent(-20.0, 20.0);
  for (int k = 0; k < 1000; ++k) {
    const Mat3 j = std::pow(10.0, exponent(rng)) * randomRegular(rng);
    const Vec3 r = test::randomPoint(rng, -3.0, 3.0);
    const Mat3 plain = glm::inverse(j);
    EXPECT_EQ(inverseScaled(j), plain) << test::toString(j);
    EXPECT_TRUE(test::bitEqual(solveScaled(j, r), plain * r)) << test::toString(j);
  }
}

// At entries of 1e±300 the plain inverse overflows or underflows (to inf, NaN or 0); the
// rescaled one is J^-1, as the same matrix at scale 1 shows: J^-1 of s J is J^-1 / s.
TEST(PowerOfTwoScale, HugeAndTinyMatricesInvert) {
  std::mt19937 rng(6);
  for (const double scale : {0x1p-1000, 0x1p-990, 0x1p990, 0x1p1000}) {
    SCOPED_TRACE(scale);
    const Mat3 j = randomRegular(rng);
    const Vec3 r = test::randomPoint(rng, -3.0, 3.0);
    EXPECT_FALSE(isFinite(glm::inverse(scale * j)[0]) &&
                 test::relativeError(glm::inverse(scale * j), glm::inverse(j) / scale) < 1e-12)
        << "the plain inverse should fail at this scale";
    EXPECT_EQ(inverseScaled(scale * j), glm::inverse(j) / scale);
    EXPECT_TRUE(test::bitEqual(solveScaled(scale * j, scale * r), glm::inverse(j) * r));
  }
}

TEST(PowerOfTwoScale, ScaledToUnitKeepsZeroAndNonFiniteMatrices) {
  EXPECT_EQ(scaledToUnit(Mat3(0.0)), Mat3(0.0));
  const Mat3 j = scaledToUnit(Mat3(3.0e200));
  EXPECT_GE(maxAbsEntry(j), 1.0);
  EXPECT_LT(maxAbsEntry(j), 2.0);
  const double inf = std::numeric_limits<double>::infinity();
  const Mat3 infinite(Vec3(inf, 0, 0), Vec3(0, 1, 0), Vec3(0, 0, 1));
  EXPECT_EQ(scaledToUnit(infinite), infinite);
}

}  // namespace
}  // namespace spacewarp::detail
