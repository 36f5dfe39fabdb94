#include <spacewarp/core/detail/simd.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <random>
#include <vector>

#include <gtest/gtest.h>

namespace spacewarp::detail::simd {
namespace {

// Distance in units in the last place between two finite doubles of the same sign.
std::int64_t ulps(double a, double b) {
  std::int64_t ia, ib;
  std::memcpy(&ia, &a, sizeof a);
  std::memcpy(&ib, &b, sizeof b);
  return ia > ib ? ia - ib : ib - ia;
}

// The lane functions over an array, in a function with the x86-64-v3 clone, as the kernels
// use them. (The two clones may differ in the last bits, FMA contracting in one of them; the
// clone is chosen once per process, so a machine's results are consistent.)
SPACEWARP_SIMD_CLONES void lanes(const double* x, double* r, double* s, double* a, std::size_t n) {
  for (std::size_t i = 0; i + kLanes <= n; i += kLanes) {
    VD v, y;
    std::memcpy(&v, x + i, sizeof v);
    rsqrt(v, y);
    std::memcpy(r + i, &y, sizeof y);
    sqrtLanes(v, y);
    std::memcpy(s + i, &y, sizeof y);
    absLanes(0.0 - v, y);
    std::memcpy(a + i, &y, sizeof y);
  }
}

std::vector<double> samples() {
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> exponent(-300.0, 300.0);
  std::vector<double> x{1.0,
                        2.0,
                        4.0,
                        0.25,
                        1e-300,
                        1e300,
                        std::numeric_limits<double>::min(),
                        std::numeric_limits<double>::max()};
  while (x.size() < 4096) x.push_back(std::pow(10.0, exponent(rng)));
  return x;
}

TEST(SimdTest, RsqrtIsWithinTwoUlpsOfTheCorrectlyRoundedValue) {
  const std::vector<double> x = samples();
  std::vector<double> r(x.size()), s(x.size()), a(x.size());
  lanes(x.data(), r.data(), s.data(), a.data(), x.size());
  for (std::size_t i = 0; i < x.size(); ++i) {
    // 1/√x from the correctly rounded square root: itself within one ulp of the exact value.
    const long double exact = 1.0L / std::sqrt(static_cast<long double>(x[i]));
    EXPECT_LE(ulps(r[i], static_cast<double>(exact)), 2) << "x = " << x[i];
  }
}

TEST(SimdTest, RsqrtOfZeroIsFiniteAndItsProductWithZeroIsZero) {
  const VD zero{};
  VD y;
  rsqrt(zero, y);
  for (int l = 0; l < kLanes; ++l) {
    EXPECT_TRUE(std::isfinite(y[l]));
    EXPECT_EQ(zero[l] * y[l], 0.0);
  }
}

TEST(SimdTest, SqrtAndAbsAreExact) {
  const std::vector<double> x = samples();
  std::vector<double> r(x.size()), s(x.size()), a(x.size());
  lanes(x.data(), r.data(), s.data(), a.data(), x.size());
  for (std::size_t i = 0; i < x.size(); ++i) {
    EXPECT_EQ(s[i], std::sqrt(x[i]));
    EXPECT_EQ(a[i], x[i]);
  }
}

// A value's result does not depend on the lane it is computed in: the kernels' single-point
// and batch paths give the same bits.
TEST(SimdTest, ResultsDoNotDependOnTheLane) {
  const std::vector<double> x = samples();
  std::vector<double> shifted(x.size());
  for (std::size_t i = 0; i < x.size(); ++i) shifted[(i + 1) % x.size()] = x[i];
  std::vector<double> r1(x.size()), s1(x.size()), a1(x.size());
  std::vector<double> r2(x.size()), s2(x.size()), a2(x.size());
  lanes(x.data(), r1.data(), s1.data(), a1.data(), x.size());
  lanes(shifted.data(), r2.data(), s2.data(), a2.data(), x.size());
  for (std::size_t i = 0; i < x.size(); ++i) {
    const std::size_t j = (i + 1) % x.size();
    EXPECT_EQ(std::memcmp(&r1[i], &r2[j], sizeof(double)), 0) << "x = " << x[i];
    EXPECT_EQ(std::memcmp(&s1[i], &s2[j], sizeof(double)), 0) << "x = " << x[i];
    EXPECT_EQ(std::memcmp(&a1[i], &a2[j], sizeof(double)), 0) << "x = " << x[i];
  }
}

TEST(SimdTest, AnyLaneSeesEachLane) {
  EXPECT_FALSE(anyLane(VI{0, 0, 0, 0}));
  for (int l = 0; l < kLanes; ++l) {
    VI mask{0, 0, 0, 0};
    mask[l] = -1;  // a comparison's "true"
    EXPECT_TRUE(anyLane(mask)) << "lane " << l;
  }
  const VD x{1.0, 2.0, 3.0, 4.0};
  EXPECT_TRUE(anyLane(x > 3.5));
  EXPECT_FALSE(anyLane(x > 4.0));
}

}  // namespace
}  // namespace spacewarp::detail::simd
