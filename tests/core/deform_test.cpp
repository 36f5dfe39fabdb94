#include <spacewarp/core/deform.h>

#include <cmath>
#include <limits>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include <spacewarp/core/bend.h>
#include <spacewarp/core/combinators.h>
#include <spacewarp/core/errors.h>
#include <spacewarp/core/twist.h>
#include "test_util.h"

namespace spacewarp {
namespace {

using test::randomPoints;

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

TwistWarp sampleTwist() {
  TwistOptions p;
  p.origin = Vec3(0.1, 0.0, -0.2);
  p.axis = Vec3(0.2, 0.1, 1.0);
  p.rate = 1.1;
  p.lo = -1.0;
  p.hi = 1.5;
  return TwistWarp(p);
}

BendWarp sampleBend() {
  BendOptions p;
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

/// The affine warp x -> a x + b.
AffineWarp affine(const Mat3& a, const Vec3& b) {
  Mat4 m(a);
  m[3] = glm::dvec4(b, 1.0);
  return AffineWarp(m);
}

/// A rotation by `angle` about the unit `axis` (Rodrigues).
Mat3 rotation(const Vec3& axis, double angle) {
  const Mat3 k(Vec3(0, axis.z, -axis.y), Vec3(-axis.z, 0, axis.x), Vec3(axis.y, -axis.x, 0));
  return Mat3(1.0) + std::sin(angle) * k + (1.0 - std::cos(angle)) * (k * k);
}

/// Flat-shaded quads with every attribute a soup can carry: texture coordinates with a seam,
/// per-corner normals shared by corners of different vertices, vertex and face attributes.
PolygonSoup attributedSoup() {
  PolygonSoup soup;
  static_cast<PointSet&>(soup) = samplePointSet(8, false);
  soup.addPolygon({0, 1, 2, 3});
  soup.addPolygon({4, 5, 6, 7});
  soup.addPolygon({1, 2, 6, 5});
  soup.faceAttributes = {{"material_index", ScalarType::Int32, {3, -1, 7}}};
  std::mt19937 rng(5);
  for (int k = 0; k < 3; ++k) soup.cornerNormals.values.push_back(test::randomUnit(rng));
  soup.cornerNormals.indices = {0, 0, 0, 0, 1, 1, 1, 1, 2, 2, 2, CornerAttribute::kNone};
  soup.texcoords.values = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}, {0.5, 0.25, 0}};
  soup.texcoords.indices = {0, 1, 2, 3, 0, 1, 2, 3, 4, 2, 1, 0};
  return soup;
}

void expectAttributesCopied(const PolygonSoup& before, const PolygonSoup& after) {
  expectSameAttributes(before, after);
  ASSERT_EQ(after.faceAttributes.size(), before.faceAttributes.size());
  EXPECT_EQ(after.faceAttributes[0].values, before.faceAttributes[0].values);
  EXPECT_EQ(after.texcoords.values, before.texcoords.values);
  EXPECT_EQ(after.texcoords.indices, before.texcoords.indices);
  EXPECT_EQ(after.faceOffsets, before.faceOffsets);
  EXPECT_EQ(after.faceIndices, before.faceIndices);
}

TEST(Deform, RigidMotionRotatesCornerNormalsAndCopiesTheRest) {
  const Mat3 r = rotation(glm::normalize(Vec3(1, 2, -0.5)), 0.7);
  const AffineWarp warp = affine(r, Vec3(3, -1, 2));
  const PolygonSoup before = attributedSoup();
  PolygonSoup after = before;
  const DeformReport report = deform(warp, after);
  EXPECT_EQ(report.singularNormals, 0u);
  expectAttributesCopied(before, after);
  EXPECT_EQ(after.cornerNormals.indices, before.cornerNormals.indices) << "sharing kept";
  ASSERT_EQ(after.cornerNormals.values.size(), before.cornerNormals.values.size());
  for (std::size_t k = 0; k < before.cornerNormals.values.size(); ++k) {
    const Vec3 expected = r * before.cornerNormals.values[k];
    EXPECT_LT(glm::length(after.cornerNormals.values[k] - expected), 1e-14) << k;
  }
  for (std::size_t i = 0; i < before.size(); ++i)
    EXPECT_TRUE(test::bitEqual(after.positions[i], warp.apply(before.positions[i]))) << i;
}

TEST(Deform, NonUniformScaleCarriesCornerNormalsByTheInverseTranspose) {
  // J = diag(2, 0.5, 3): J^-T n = (nx / 2, 2 ny, nz / 3), then normalised.
  const AffineWarp warp = affine(Mat3(Vec3(2, 0, 0), Vec3(0, 0.5, 0), Vec3(0, 0, 3)), Vec3(0.0));
  const PolygonSoup before = attributedSoup();
  PolygonSoup after = before;
  EXPECT_EQ(deform(warp, after).singularNormals, 0u);
  expectAttributesCopied(before, after);
  EXPECT_EQ(after.cornerNormals.indices, before.cornerNormals.indices);
  for (std::size_t k = 0; k < before.cornerNormals.values.size(); ++k) {
    const Vec3 n = before.cornerNormals.values[k];
    const Vec3 expected = glm::normalize(Vec3(n.x / 2.0, 2.0 * n.y, n.z / 3.0));
    EXPECT_LT(glm::length(after.cornerNormals.values[k] - expected), 1e-14) << k;
  }
}

TEST(Deform, NonlinearWarpGivesEachCornerItsVertexNormal) {
  // Under a bend the shared normals differ from vertex to vertex: the sharing splits, and
  // every corner gets J^-T n at its own vertex.
  const BendWarp warp = sampleBend();
  const PolygonSoup before = attributedSoup();
  PolygonSoup after = before;
  deform(warp, after);
  expectAttributesCopied(before, after);
  ASSERT_EQ(after.cornerNormals.indices.size(), before.cornerNormals.indices.size());
  EXPECT_GT(after.cornerNormals.values.size(), before.cornerNormals.values.size());
  for (std::size_t c = 0; c < before.faceIndices.size(); ++c) {
    const std::uint32_t k = before.cornerNormals.indices[c];
    if (k == CornerAttribute::kNone) {
      EXPECT_EQ(after.cornerNormals.indices[c], CornerAttribute::kNone);
      continue;
    }
    const Vec3 expected = transformNormal(warp, before.positions[before.faceIndices[c]],
                                          before.cornerNormals.values[k]);
    EXPECT_TRUE(
        test::bitEqual(after.cornerNormals.values[after.cornerNormals.indices[c]], expected))
        << "corner " << c;
  }
  EXPECT_NO_THROW(after.validate());
}

TEST(Deform, SingularWarpReportsTheVerticesWithUndefinedNormals) {
  // A projection onto the plane z = 0: J is singular everywhere.
  const AffineWarp flatten = affine(Mat3(Vec3(1, 0, 0), Vec3(0, 1, 0), Vec3(0, 0, 0)), Vec3(0.0));
  PointSet withNormals = samplePointSet(100, true);
  EXPECT_EQ(deform(flatten, withNormals).singularNormals, 100u);
  PointSet withoutNormals = samplePointSet(100, false);
  EXPECT_EQ(deform(flatten, withoutNormals).singularNormals, 0u) << "no normals, no warning";
  // Per-corner normals: counted once per vertex (8), not per corner (11 with a normal).
  PolygonSoup soup = attributedSoup();
  EXPECT_EQ(deform(flatten, soup).singularNormals, 8u);
  // A reflection is not singular.
  const AffineWarp mirror = affine(Mat3(Vec3(-1, 0, 0), Vec3(0, 1, 0), Vec3(0, 0, 1)), Vec3(0.0));
  PointSet mirrored = samplePointSet(100, true);
  EXPECT_EQ(deform(mirror, mirrored).singularNormals, 0u);
  // Singular up to rounding, at any scale: a projection onto a tilted plane, whose computed
  // determinant is not exactly 0.
  const Vec3 u = glm::normalize(Vec3(1, 2, 3));
  for (const double scale : {1e-6, 1.0, 1e6}) {
    const AffineWarp project = affine(scale * (Mat3(1.0) - glm::outerProduct(u, u)), Vec3(0.0));
    PointSet projected = samplePointSet(10, true);
    EXPECT_EQ(deform(project, projected).singularNormals, 10u) << scale;
  }
  // Huge or tiny but regular (det J overflows to inf or underflows to 0): no vertex is
  // singular, and the normals are those of the unscaled warp.
  const Mat3 shear = Mat3(Vec3(2.0, 0.5, 0.0), Vec3(0.0, 1.0, 0.3), Vec3(0.1, 0.0, 3.0));
  PointSet unscaled = samplePointSet(10, true);
  deform(affine(shear, Vec3(0.0)), unscaled);
  for (const double scale : {1e-300, 1e300}) {
    PointSet scaled = samplePointSet(10, true);
    EXPECT_EQ(deform(affine(scale * shear, Vec3(0.0)), scaled).singularNormals, 0u) << scale;
    for (std::size_t i = 0; i < scaled.size(); ++i)
      EXPECT_LT(test::relativeError(scaled.normals[i], unscaled.normals[i]), 1e-14) << scale;
  }
  // Strongly anisotropic but invertible: the normals are defined (along z).
  const AffineWarp squash =
      affine(Mat3(Vec3(1, 0, 0), Vec3(0, 1, 0), Vec3(0, 0, 1e-10)), Vec3(0.0));
  PointSet squashed = samplePointSet(10, true);
  EXPECT_EQ(deform(squash, squashed).singularNormals, 0u);
}

TEST(Deform, EmptySetIsFine) {
  PointSet set;
  EXPECT_NO_THROW(deform(sampleTwist(), set));
  EXPECT_TRUE(set.positions.empty());
}

// The identity plus a smooth perturbation of Lipschitz constant 0.3: injective, no closed-form
// inverse, so deformInverse() solves every point by Newton.
class WobbleWarp final : public Warp {
 public:
  Vec3 apply(const Vec3& x) const override {
    return x + 0.1 * Vec3(std::sin(3.0 * x.y), std::sin(3.0 * x.z), std::sin(3.0 * x.x));
  }
};

// deformInverse() after deform() gives the positions and normals back (per vertex and per
// corner), by the closed form where the warp has one and by Newton where it has not.
TEST(DeformInverse, UndoesDeform) {
  const TwistWarp twist = sampleTwist();
  const WobbleWarp wobble;
  for (const Warp* warp : {static_cast<const Warp*>(&twist), static_cast<const Warp*>(&wobble)}) {
    const bool closedForm = warp == &twist;
    SCOPED_TRACE(closedForm ? "twist" : "wobble");
    const PointSet before = samplePointSet(500, true);
    PointSet set = before;
    deform(*warp, set);
    const InverseDeformReport report = deformInverse(*warp, set);
    EXPECT_EQ(report.closedForm, closedForm ? 500u : 0u);
    EXPECT_EQ(report.iterative, closedForm ? 0u : 500u);
    EXPECT_EQ(report.singularNormals, 0u);
    EXPECT_LE(report.maxResidual, 1e-12 * 3.0);  // |y| <= 2 + 0.5: inverse()'s own scale
    for (std::size_t i = 0; i < before.size(); ++i) {
      EXPECT_LT(glm::length(set.positions[i] - before.positions[i]), 1e-11) << i;
      EXPECT_LT(glm::length(set.normals[i] - before.normals[i]), 1e-10) << i;
    }
    expectSameAttributes(before, set);

    const PolygonSoup soupBefore = attributedSoup();
    PolygonSoup soup = soupBefore;
    deform(*warp, soup);
    deformInverse(*warp, soup);
    ASSERT_EQ(soup.cornerNormals.indices.size(), soupBefore.cornerNormals.indices.size());
    for (std::size_t c = 0; c < soup.faceIndices.size(); ++c) {
      const std::uint32_t k = soupBefore.cornerNormals.indices[c];
      if (k == CornerAttribute::kNone) continue;
      const Vec3 n = soup.cornerNormals.values[soup.cornerNormals.indices[c]];
      EXPECT_LT(glm::length(n - soupBefore.cornerNormals.values[k]), 1e-10) << "corner " << c;
    }
    for (std::size_t i = 0; i < soup.size(); ++i)
      EXPECT_LT(glm::length(soup.positions[i] - soupBefore.positions[i]), 1e-11) << i;
    EXPECT_EQ(soup.faceIndices, soupBefore.faceIndices);
    EXPECT_EQ(soup.texcoords.indices, soupBefore.texcoords.indices);
  }
}

// Under an affine warp the inverse carries normals by J^T: checked against the closed form.
TEST(DeformInverse, CarriesNormalsByTheTransposedJacobian) {
  const Mat3 j = Mat3(Vec3(2, 0.3, 0), Vec3(0, 0.5, 0.1), Vec3(0.2, 0, 3));
  const AffineWarp warp = affine(j, Vec3(1, 2, 3));
  const PointSet before = samplePointSet(50, true);
  PointSet set = before;
  deformInverse(warp, set);
  for (std::size_t i = 0; i < set.size(); ++i) {
    EXPECT_LT(glm::length(warp.apply(set.positions[i]) - before.positions[i]), 1e-14) << i;
    const Vec3 expected = glm::normalize(glm::transpose(j) * before.normals[i]);
    EXPECT_LT(glm::length(set.normals[i] - expected), 1e-14) << i;
  }
}

// z -> z^2 / 4 + 0.01: folds space at z = 0, so that points with z < 0.01 have no preimage.
class FoldWarp final : public Warp {
 public:
  Vec3 apply(const Vec3& x) const override { return Vec3(x.x, x.y, 0.25 * x.z * x.z + 0.01); }
};

// Points that a folding warp never reaches have no preimage: SolverError naming the first of
// them and how many failed, and the set left as it was.
TEST(DeformInverse, NonConvergenceThrowsNamingTheFirstVertexAndLeavesTheSetUnchanged) {
  const FoldWarp fold;
  PointSet set = samplePointSet(6, true);
  const double z[] = {0.5, 0.1, -0.3, 0.2, -0.7, 0.0};
  for (std::size_t i = 0; i < 6; ++i) set.positions[i].z = z[i];
  const PointSet before = set;
  const std::string message = test::messageOf<SolverError>([&] { deformInverse(fold, set); });
  EXPECT_NE(message.find("at 3 of 6 vertices"), std::string::npos) << message;
  EXPECT_NE(message.find("vertex 2 at ("), std::string::npos) << message;
  EXPECT_NE(message.find("residual"), std::string::npos) << message;
  expectUnchanged(set, before);
}

TEST(DeformInverse, NaNPositionThrowsAndLeavesTheSetUnchanged) {
  PointSet set = samplePointSet(5, false);
  set.positions[3].y = kNaN;
  const PointSet before = set;
  EXPECT_THROW(deformInverse(sampleTwist(), set), InvalidInput);
  EXPECT_EQ(set.positions.size(), before.positions.size());
  EXPECT_TRUE(std::isnan(set.positions[3].y));
}

}  // namespace
}  // namespace spacewarp
