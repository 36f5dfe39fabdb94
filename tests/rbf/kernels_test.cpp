// Tests of rbf/kernels.h: values, slopes against finite differences, names, option checks.

#include <spacewarp/rbf/kernels.h>

#include <cmath>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <spacewarp/core/errors.h>
#include "rbf_test_data.h"
#include "test_util.h"

namespace spacewarp {
namespace {

using ::testing::HasSubstr;

TEST(RbfKernels, ValuesFollowTheirFormulas) {
  RbfOptions o;
  const double r = 0.8;
  o.kernel = RbfKernel::Triharmonic;
  EXPECT_DOUBLE_EQ(rbfKernelValue(o, r), r * r * r);
  o.kernel = RbfKernel::Biharmonic;
  EXPECT_DOUBLE_EQ(rbfKernelValue(o, r), r);
  o.kernel = RbfKernel::ThinPlate;
  EXPECT_DOUBLE_EQ(rbfKernelValue(o, r), r * r * std::log(r));
  EXPECT_EQ(rbfKernelValue(o, 0.0), 0.0);
  o.kernel = RbfKernel::Gaussian;
  o.scale = 0.5;
  EXPECT_DOUBLE_EQ(rbfKernelValue(o, r), std::exp(-(r / 0.5) * (r / 0.5)));
  o.kernel = RbfKernel::InverseMultiquadric;
  EXPECT_DOUBLE_EQ(rbfKernelValue(o, r), 1.0 / std::sqrt(r * r + 0.25));
  o.kernel = RbfKernel::WendlandC2;
  o.radius = 2.0;
  EXPECT_DOUBLE_EQ(rbfKernelValue(o, r), std::pow(1.0 - 0.4, 4) * (4 * 0.4 + 1));
  EXPECT_EQ(rbfKernelValue(o, 2.0), 0.0);
  EXPECT_EQ(rbfKernelValue(o, 3.0), 0.0);
}

TEST(RbfKernels, SlopeMatchesFiniteDifferences) {
  for (const RbfOptions& o : test::everyKernel()) {
    for (double r : {0.05, 0.3, 0.9, 1.4, 2.5}) {
      const double h = 1e-5;
      const double fd = (rbfKernelValue(o, r + h) - rbfKernelValue(o, r - h)) / (2 * h);
      EXPECT_NEAR(rbfKernelSlopeOverR(o, r) * r, fd, 1e-7 * std::max(1.0, std::abs(fd)))
          << rbfKernelName(o.kernel) << " r = " << r;
    }
  }
}

TEST(RbfKernels, SlopeAtZeroIsFinite) {
  for (const RbfOptions& o : test::everyKernel())
    EXPECT_TRUE(std::isfinite(rbfKernelSlopeOverR(o, 0.0))) << rbfKernelName(o.kernel);
}

TEST(RbfKernels, NamesRoundTrip) {
  for (const std::string& name : rbfKernelNames())
    EXPECT_EQ(rbfKernelName(rbfKernelFromName(name)), name);
  const std::string message = test::messageOf<InvalidInput>([] { rbfKernelFromName("cubic"); });
  EXPECT_THAT(message, HasSubstr("'cubic'"));
  EXPECT_THAT(message, HasSubstr("triharmonic"));
}

TEST(RbfKernels, InvalidOptionsAreRejected) {
  RbfOptions o;
  o.scale = 0.0;
  EXPECT_THAT(test::messageOf<InvalidInput>([&] { validateRbfOptions("W", o); }),
              HasSubstr("scale"));
  o = {};
  o.radius = -1.0;
  EXPECT_THAT(test::messageOf<InvalidInput>([&] { validateRbfOptions("W", o); }),
              HasSubstr("radius"));
  o = {};
  o.smoothing = -1e-3;
  EXPECT_THAT(test::messageOf<InvalidInput>([&] { validateRbfOptions("W", o); }),
              HasSubstr("smoothing"));
  o = {};
  o.smoothing = std::nan("");
  EXPECT_THROW(validateRbfOptions("W", o), InvalidInput);
  EXPECT_NO_THROW(validateRbfOptions("W", RbfOptions{}));
}

}  // namespace
}  // namespace spacewarp
