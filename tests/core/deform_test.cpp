#include "core/deform.h"

#include <cmath>
#include <limits>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "core/bend.h"
#include "core/errors.h"
#include "core/twist.h"
#include "test_util.h"

namespace spacewarp {
namespace {

using test::randomPoints;

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

TwistWarp sampleTwist() {
  TwistParams p;
  p.origin = Vec3(0.1, 0.0, -0.2);
  p.axis = Vec3(0.2, 0.1, 1.0);
  p.rate = 1.1;
  p.lo = -1.0;
  p.hi = 1.5;
  return TwistWarp(p);
}

BendWarp sampleBend() {
  BendParams p;
  p.axis = Vec3(0, 1, 0);
  p.direction = Vec3(1, 0, 0);
  p.rate = 0.4;
  return BendWarp(p);
}

// Sends points with x > 1 to NaN.
class PartialWarp final : public Warp {
 public:
  Vec3 apply(const Vec3& x) const override {
    return x.x > 1.0 ? Vec3(std::numeric_limits<double>::quiet_NaN()) : 2.0 * x;
  }
  Mat3 jacobian(const Vec3&) const override { return Mat3(2.0); }
};

PointSet samplePointSet(std::size_t n, bool withNormals) {
  std::mt19937 rng(21);
  PointSet set;
  set.positions = randomPoints(rng, n, -2.0, 2.0);
  if (withNormals) {
    set.normals.resize(n);
    for (Vec3& v : set.normals) v = test::randomUnit(rng);
  }
  VertexAttribute confidence{"confidence", ScalarType::Float32, {}};
  VertexAttribute label{"label", ScalarType::UInt8, {}};
  for (std::size_t i = 0; i < n; ++i) {
    confidence.values.push_back(0.001 * static_cast<double>(i));
    label.values.push_back(static_cast<double>(i % 7));
  }
  set.attributes = {confidence, label};
  return set;
}

void expectSameAttributes(const PointSet& a, const PointSet& b) {
  ASSERT_EQ(a.attributes.size(), b.attributes.size());
  for (std::size_t k = 0; k < a.attributes.size(); ++k) {
    EXPECT_EQ(a.attributes[k].name, b.attributes[k].name);
    EXPECT_EQ(a.attributes[k].type, b.attributes[k].type);
    EXPECT_EQ(a.attributes[k].values, b.attributes[k].values);
  }
}

/// Positions and normals of `set` are those of `before`, bit for bit (nothing was deformed).
void expectUnchanged(const PointSet& set, const PointSet& before) {
  ASSERT_EQ(set.positions.size(), before.positions.size());
  ASSERT_EQ(set.normals.size(), before.normals.size());
  for (std::size_t i = 0; i < set.positions.size(); ++i)
    EXPECT_TRUE(test::bitEqual(set.positions[i], before.positions[i])) << i;
  for (std::size_t i = 0; i < set.normals.size(); ++i)
    EXPECT_TRUE(test::bitEqual(set.normals[i], before.normals[i])) << i;
}

void expectDeformed(const Warp& warp, const PointSet& before, const PointSet& after) {
  ASSERT_EQ(after.positions.size(), before.positions.size());
  ASSERT_EQ(after.normals.size(), before.normals.size());
  for (std::size_t i = 0; i < before.positions.size(); ++i) {
    EXPECT_TRUE(test::bitEqual(after.positions[i], warp.apply(before.positions[i]))) << i;
    if (before.hasNormals()) {
      EXPECT_TRUE(test::bitEqual(after.normals[i],
                                 transformNormal(warp, before.positions[i], before.normals[i])))
          << i;
      EXPECT_NEAR(glm::length(after.normals[i]), 1.0, 1e-14);
    }
  }
  expectSameAttributes(before, after);
}

TEST(Deform, PointSetWithNormals) {
  const TwistWarp warp = sampleTwist();
  const PointSet before = samplePointSet(20'000, true);
  PointSet after = before;
  deform(warp, after);
  expectDeformed(warp, before, after);
}

TEST(Deform, PointSetWithoutNormals) {
  const BendWarp warp = sampleBend();
  const PointSet before = samplePointSet(5'000, false);
  PointSet after = before;
  deform(warp, after);
  EXPECT_FALSE(after.hasNormals());
  expectDeformed(warp, before, after);
}

TEST(Deform, PolygonSoupKeepsPolygons) {
  const BendWarp warp = sampleBend();
  PolygonSoup soup;
  static_cast<PointSet&>(soup) = samplePointSet(9, true);
  soup.addPolygon({0, 1, 2});
  soup.addPolygon({2, 3, 4, 5});
  soup.addPolygon({5, 6, 7, 8, 0});
  const PolygonSoup before = soup;
  deform(warp, soup);
  expectDeformed(warp, before, soup);
  EXPECT_EQ(soup.faceOffsets, before.faceOffsets);
  EXPECT_EQ(soup.faceIndices, before.faceIndices);
}

TEST(Deform, NaNPositionThrowsAndLeavesTheSetUnchanged) {
  const TwistWarp warp = sampleTwist();
  PointSet set = samplePointSet(100, true);
  set.positions[42].y = kNaN;
  const PointSet before = set;
  const std::string message = test::messageOf<InvalidInput>([&] { deform(warp, set); });
  EXPECT_NE(message.find("42"), std::string::npos) << message;
  expectUnchanged(set, before);
  expectSameAttributes(before, set);

  PolygonSoup soup;
  static_cast<PointSet&>(soup) = before;
  soup.addPolygon({0, 1, 2});
  const PolygonSoup soupBefore = soup;
  EXPECT_THROW(deform(warp, soup), InvalidInput);
  expectUnchanged(soup, soupBefore);
}

TEST(Deform, NonFiniteResultThrowsAndLeavesTheSetUnchanged) {
  const PartialWarp warp;
  PointSet set = samplePointSet(50, true);
  for (Vec3& x : set.positions) x.x = std::min(x.x, 0.9);
  set.positions[7] = Vec3(1.5, 0.0, 0.0);  // the only one sent to NaN
  const PointSet before = set;
  const std::string message = test::messageOf<InvalidInput>([&] { deform(warp, set); });
  EXPECT_NE(message.find("vertex 7"), std::string::npos) << message;
  expectUnchanged(set, before);
}

TEST(Deform, RejectsMalformedSets) {
  const TwistWarp warp = sampleTwist();
  PointSet set = samplePointSet(10, true);
  set.normals.pop_back();
  EXPECT_THROW(deform(warp, set), InvalidInput);
  PolygonSoup soup;
  static_cast<PointSet&>(soup) = samplePointSet(3, false);
  soup.addPolygon({0, 1, 3});
  EXPECT_THROW(deform(warp, soup), InvalidInput);
}

TEST(Deform, EmptySetIsFine) {
  PointSet set;
  EXPECT_NO_THROW(deform(sampleTwist(), set));
  EXPECT_TRUE(set.positions.empty());
}

}  // namespace
}  // namespace spacewarp
