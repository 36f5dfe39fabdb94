// Tests of volume/warp_volume.h: identity, rigid motions against OpenVDB's own
// resampling, level sets (scaled sphere, twisted against the mesh route), mass conservation,
// non-convergent inverses, determinism, cancellation and rejected inputs.

#include <spacewarp/volume/warp_volume.h>

#include <cmath>
#include <cstring>
#include <functional>
#include <limits>
#include <numbers>
#include <utility>

#include <gtest/gtest.h>
#include <openvdb/tools/Composite.h>
#include <openvdb/tools/GridTransformer.h>
#include <openvdb/tools/Interpolation.h>
#include <openvdb/tools/MeshToVolume.h>
#include <openvdb/tools/VolumeToMesh.h>
#include <tbb/global_control.h>
#include <glm/gtc/matrix_transform.hpp>

#include <spacewarp/core/combinators.h>
#include <spacewarp/core/errors.h>
#include <spacewarp/core/twist.h>
#include "volume/volume_test_util.h"

namespace spacewarp {
namespace {

using openvdb::Coord;
using openvdb::FloatGrid;
using test::FunctionWarp;
using test::makeGaussianFog;
using test::makeSphere;
using test::worldOf;

template <typename GridT>
void expectSameGrid(const GridT& in, const GridT& out, double tolerance) {
  EXPECT_EQ(out.activeVoxelCount(), in.activeVoxelCount());
  auto acc = out.getConstAccessor();
  for (auto it = in.cbeginValueOn(); it; ++it) {
    ASSERT_TRUE(acc.isValueOn(it.getCoord())) << it.getCoord();
    EXPECT_NEAR(acc.getValue(it.getCoord()), *it, tolerance) << it.getCoord();
  }
}

TEST(WarpVolume, IdentityReturnsTheSameFogVolume) {
  const FloatGrid::Ptr fog = makeGaussianFog(Vec3(0.1, -0.2, 0.3), 1.0, 0.25);
  for (VolumeSampler sampler : {VolumeSampler::Trilinear, VolumeSampler::Triquadratic}) {
    WarpVolumeOptions options;
    options.sampler = sampler;
    const auto warped = warpVolume(IdentityWarp(), *fog, options);
    expectSameGrid(*fog, *warped.grid, 1e-6);
    EXPECT_EQ(warped.report.inverseFailures, 0u);
    EXPECT_EQ(warped.report.maxNewtonIterations, 0);
    EXPECT_EQ(warped.grid->getName(), "density");
    EXPECT_EQ(warped.grid->getGridClass(), openvdb::GRID_FOG_VOLUME);
    EXPECT_NEAR(warped.report.massAfter, warped.report.massBefore, 1e-6 * warped.report.massBefore);
  }
}

TEST(WarpVolume, IdentityReturnsTheSameLevelSet) {
  const FloatGrid::Ptr sphere = makeSphere(1.5, Vec3(0.2, 0.1, -0.1), 0.1);
  sphere->insertMeta("author", openvdb::StringMetadata("spacewarp"));
  const auto warped = warpVolume(IdentityWarp(), *sphere);
  expectSameGrid(*sphere, *warped.grid, 1e-6);
  EXPECT_EQ(warped.grid->getGridClass(), openvdb::GRID_LEVEL_SET);
  EXPECT_EQ(warped.grid->background(), sphere->background());
  EXPECT_EQ(warped.grid->metaValue<std::string>("author"), "spacewarp");
  EXPECT_NEAR(warped.report.halfWidth, 3.0, 1e-6);
}

// A file may store the grid's name or class under a type OpenVDB does not know (the fuzzer's
// "class" of type "tsring"): the warp keeps the other metadata and gives a proper string class.
TEST(WarpVolume, NameAndClassOfAnUnknownTypeDoNotStopTheWarp) {
  const FloatGrid::Ptr fog = makeGaussianFog(Vec3(0.1, -0.2, 0.3), 1.0, 0.25);
  fog->removeMeta(openvdb::GridBase::META_GRID_CLASS);
  fog->removeMeta(openvdb::GridBase::META_GRID_NAME);
  fog->insertMeta(openvdb::GridBase::META_GRID_CLASS, openvdb::UnknownMetadata("tsring"));
  fog->insertMeta(openvdb::GridBase::META_GRID_NAME, openvdb::UnknownMetadata("tsring"));
  fog->insertMeta("author", openvdb::StringMetadata("spacewarp"));
  const auto warped = warpVolume(IdentityWarp(), *fog);
  expectSameGrid(*fog, *warped.grid, 1e-6);
  EXPECT_EQ(warped.grid->getGridClass(), openvdb::GRID_UNKNOWN);
  EXPECT_EQ(warped.grid->getName(), "");
  EXPECT_EQ(warped.grid->metaValue<std::string>("author"), "spacewarp");
}

TEST(WarpVolume, RigidMotionMatchesOpenVdbResampling) {
  const FloatGrid::Ptr fog = makeGaussianFog(Vec3(0.4, -0.3, 0.2), 1.0, 0.2);
  // x' = Q x + t: a rotation of 0.3 rad about z and a translation.
  const double angle = 0.3;
  const Vec3 t(0.23, -0.11, 0.07);
  const Mat4 m = glm::rotate(glm::translate(Mat4(1.0), t), angle, Vec3(0, 0, 1));
  const AffineWarp rigid(m);
  const auto warped = warpVolume(rigid, *fog);

  // OpenVDB's resampling: sample the input at R⁻¹(world(j)), then read the result with the
  // input's transform. The index-to-world map of `target` is R⁻¹ ∘ T.
  const Mat3 q = rigid.linear();
  const Mat3 qt = glm::transpose(q);
  const double h = 0.2;
  openvdb::math::Mat4d mat(openvdb::math::Mat4d::identity());
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) mat(r, c) = h * qt[r][c];
  const Vec3 shift = -(qt * t);
  for (int c = 0; c < 3; ++c) mat(3, c) = shift[c];
  auto target = FloatGrid::create(0.0f);
  target->setTransform(openvdb::math::Transform::createLinearTransform(mat));
  {
    const Vec3 j(3, -2, 5);
    const Vec3 expected = qt * (j * h - t);
    const openvdb::Vec3d got = target->indexToWorld(openvdb::Vec3d(j.x, j.y, j.z));
    ASSERT_NEAR(got[0], expected.x, 1e-12);
    ASSERT_NEAR(got[1], expected.y, 1e-12);
    ASSERT_NEAR(got[2], expected.z, 1e-12);
  }
  openvdb::tools::resampleToMatch<openvdb::tools::BoxSampler>(*fog, *target);
  target->setTransform(fog->transform().copy());

  auto refAcc = target->getConstAccessor();
  std::size_t compared = 0;
  for (auto it = warped.grid->cbeginValueOn(); it; ++it) {
    EXPECT_NEAR(*it, refAcc.getValue(it.getCoord()), 1e-4) << it.getCoord();
    ++compared;
  }
  EXPECT_GT(compared, 10000u);
  EXPECT_EQ(warped.report.inverseFailures, 0u);
  // Mass is invariant under a rigid motion (up to the resampling error).
  EXPECT_NEAR(warped.report.massAfter / warped.report.massBefore, 1.0, 5e-3);
}

struct ScaleCase {
  double scale;
  LevelSetRedistance redistance;
};

void PrintTo(const ScaleCase& c, std::ostream* os) {
  *os << "scale " << c.scale << ", redistance " << static_cast<int>(c.redistance);
}

class ScaledSphere : public ::testing::TestWithParam<ScaleCase> {};

TEST_P(ScaledSphere, IsTheScaledSphereWithTheInputBand) {
  const double voxel = 0.1, radius = 1.2, scale = GetParam().scale;
  const Vec3 center(0.13, -0.07, 0.21);
  const FloatGrid::Ptr sphere = makeSphere(radius, center, voxel);
  const AffineWarp scaling(glm::scale(Mat4(1.0), Vec3(scale)));
  WarpVolumeOptions options;
  options.redistance = GetParam().redistance;
  const auto warped = warpVolume(scaling, *sphere, options);
  const FloatGrid& out = *warped.grid;
  EXPECT_TRUE(warped.report.redistanced);
  EXPECT_EQ(out.getGridClass(), openvdb::GRID_LEVEL_SET);
  EXPECT_FLOAT_EQ(out.background(), sphere->background());

  const Vec3 c2 = center * scale;
  const double r2 = radius * scale;
  double worst = 0.0;
  for (auto it = out.cbeginValueOn(); it; ++it) {
    const double exact = glm::length(worldOf(out, it.getCoord()) - c2) - r2;
    if (std::abs(exact) < 1.5 * voxel) worst = std::max(worst, std::abs(*it - exact));
  }
  EXPECT_LE(worst, 0.5 * voxel);
  // The band: every voxel within 2.5 voxels of the surface is active, none beyond 3.5.
  auto acc = out.getConstAccessor();
  const int reach = static_cast<int>(std::ceil((r2 + 4 * voxel) / voxel));
  const Coord cc(static_cast<int>(std::round(c2.x / voxel)),
                 static_cast<int>(std::round(c2.y / voxel)),
                 static_cast<int>(std::round(c2.z / voxel)));
  for (int i = -reach; i <= reach; i += 3)
    for (int j = -reach; j <= reach; j += 3)
      for (int k = -reach; k <= reach; ++k) {
        const Coord ijk = cc + Coord(i, j, k);
        const double d = std::abs(glm::length(worldOf(out, ijk) - c2) - r2) / voxel;
        if (d < 2.5) {
          EXPECT_TRUE(acc.isValueOn(ijk)) << ijk << " at " << d << " voxels";
        }
        if (d > 3.5) {
          EXPECT_FALSE(acc.isValueOn(ijk)) << ijk << " at " << d << " voxels";
        }
      }
}

INSTANTIATE_TEST_SUITE_P(WarpVolume, ScaledSphere,
                         ::testing::Values(ScaleCase{1.5, LevelSetRedistance::Normalize},
                                           ScaleCase{0.7, LevelSetRedistance::Normalize},
                                           ScaleCase{1.5, LevelSetRedistance::Rebuild},
                                           ScaleCase{0.7, LevelSetRedistance::Rebuild}));

class TwistedSphere : public ::testing::TestWithParam<LevelSetRedistance> {};

TEST_P(TwistedSphere, MatchesTheMeshRouteWithinOneVoxel) {
  const double voxel = 0.1;
  const FloatGrid::Ptr sphere = makeSphere(1.0, Vec3(0.7, 0.0, 0.0), voxel);
  TwistOptions p;
  p.rate = 0.6;
  const TwistWarp twist(p);
  WarpVolumeOptions options;
  options.redistance = GetParam();
  const auto warped = warpVolume(twist, *sphere, options);
  EXPECT_EQ(warped.report.inverseFailures, 0u);
  EXPECT_LE(warped.report.maxNewtonIterations, 5);

  // The mesh route: extract the surface, move its vertices, voxelise again.
  std::vector<openvdb::Vec3s> points;
  std::vector<openvdb::Vec3I> triangles;
  std::vector<openvdb::Vec4I> quads;
  openvdb::tools::volumeToMesh(*sphere, points, triangles, quads, 0.0);
  for (openvdb::Vec3s& v : points) {
    const Vec3 y = twist.apply(Vec3(v[0], v[1], v[2]));
    v = openvdb::Vec3s(float(y.x), float(y.y), float(y.z));
  }
  const FloatGrid::Ptr meshRoute = openvdb::tools::meshToLevelSet<FloatGrid>(
      sphere->transform(), points, triangles, quads, 3.0f);

  auto acc = meshRoute->getConstAccessor();
  double worst = 0.0;
  std::size_t compared = 0;
  for (auto it = warped.grid->cbeginValueOn(); it; ++it) {
    float ref;
    if (!acc.probeValue(it.getCoord(), ref) || std::abs(ref) > 2 * voxel) continue;
    worst = std::max(worst, double(std::abs(*it - ref)));
    ++compared;
  }
  EXPECT_GT(compared, 1000u);
  EXPECT_LE(worst, voxel);
  // Same band width as the input.
  EXPECT_FLOAT_EQ(warped.grid->background(), sphere->background());
}

INSTANTIATE_TEST_SUITE_P(WarpVolume, TwistedSphere,
                         ::testing::Values(LevelSetRedistance::Normalize,
                                           LevelSetRedistance::Rebuild));

// x' = c + (x - c) s(r): a smooth radial squash, s from 0.6 at the center to 0.8 far away.
FunctionWarp radialSquash(const Vec3& c) {
  return FunctionWarp([c](const Vec3& x) {
    const Vec3 d = x - c;
    const double r2 = glm::dot(d, d);
    return c + d * (0.6 + 0.2 * r2 / (1.0 + r2));
  });
}

TEST(WarpVolume, ConservesMassUnderACompressiveWarpWhenAsked) {
  const FloatGrid::Ptr fog = makeGaussianFog(Vec3(0.1, 0.0, -0.1), 1.0, 0.2);
  const FunctionWarp squash = radialSquash(Vec3(0.3, -0.2, 0.0));
  WarpVolumeOptions options;
  options.conserveMass = true;
  const auto kept = warpVolume(squash, *fog, options);
  EXPECT_EQ(kept.report.inverseFailures, 0u);
  EXPECT_GT(kept.report.massBefore, 0.0);
  EXPECT_NEAR(kept.report.massAfter / kept.report.massBefore, 1.0, 0.01);

  const auto plain = warpVolume(squash, *fog);
  EXPECT_DOUBLE_EQ(plain.report.massBefore, kept.report.massBefore);
  EXPECT_LT(plain.report.massAfter / plain.report.massBefore, 0.5);
  // The reported totals are the grids' totals.
  double sum = 0.0;
  for (auto it = kept.grid->cbeginValueOn(); it; ++it) sum += *it * double(it.getVoxelCount());
  EXPECT_NEAR(sum * 0.2 * 0.2 * 0.2, kept.report.massAfter, 1e-6 * kept.report.massAfter);
  // |det J| of the squash: s(r)^2 (s + r s'(r)) stays within [0.6^3, 0.8^3 * 2]: not extreme.
  EXPECT_GE(kept.report.minVolumeChange, 0.6 * 0.6 * 0.6 * 0.99);
  EXPECT_LE(kept.report.maxVolumeChange, 1.1);
  EXPECT_FALSE(hasExtremeVolumeChange(kept.report));
  EXPECT_EQ(plain.report.maxVolumeChange, 0.0) << "nothing divided without conserveMass";
}

// A squeeze by 1e-4 along z: every density is divided by |det J| = 1e-4, the fog collapses
// into one layer of voxels and its total is far off; the report says so.
TEST(WarpVolume, ReportsExtremeVolumeChangesUnderConserveMass) {
  const FloatGrid::Ptr fog = makeGaussianFog(Vec3(0.1, 0.0, -0.1), 1.0, 0.2);
  const FunctionWarp squeeze([](const Vec3& x) { return Vec3(x.x, x.y, 1e-4 * x.z); });
  WarpVolumeOptions options;
  options.conserveMass = true;
  const auto squeezed = warpVolume(squeeze, *fog, options);
  EXPECT_NEAR(squeezed.report.minVolumeChange, 1e-4, 1e-9);
  EXPECT_NEAR(squeezed.report.maxVolumeChange, 1e-4, 1e-9);
  EXPECT_EQ(squeezed.report.degenerateVolumeChanges, 0u);
  EXPECT_TRUE(hasExtremeVolumeChange(squeezed.report));
  EXPECT_GT(squeezed.report.massAfter / squeezed.report.massBefore, 10.0);
}

TEST(WarpVolume, CountsVoxelsWhereTheInverseDoesNotConverge) {
  const FloatGrid::Ptr fog = makeGaussianFog(Vec3(0.0), 1.0, 0.2);
  // Folds space along x: dx'/dx = 1 + 2.5 cos(3x) changes sign.
  const FunctionWarp fold(
      [](const Vec3& x) { return Vec3(x.x + (2.5 / 3.0) * std::sin(3.0 * x.x), x.y, x.z); });
  WarpVolumeOptions options;
  options.inverse.maxIterations = 10;
  const auto warped = warpVolume(fold, *fog, options);
  EXPECT_GT(warped.report.inverseFailures, 0u);
  EXPECT_LE(warped.report.inverseFailures, warped.report.solvedVoxels);
  for (auto it = warped.grid->cbeginValueOn(); it; ++it) EXPECT_TRUE(std::isfinite(*it));
}

// A C⁰ warp that is invertible everywhere but has kinks: x + Σ_k δ n_k g(n_k·x - o_k), g a
// staircase of period p whose risers are ramps of width ε ≪ p (slope δ/ε): the warp is
// piecewise linear, with pairs of kinks a tiny distance apart (like the sliver tets of
// harmonic coordinates or the node switches of a deformation graph). It is the gradient of the
// strictly convex |x|²/2 + Σ_k δ G(n_k·x - o_k) (G' = g is nondecreasing), hence injective.
FunctionWarp kinkedWarp(double period, double width) {
  return FunctionWarp([period, width](const Vec3& x) {
    const Vec3 n[3] = {glm::normalize(Vec3(1.0, 0.3, 0.2)), glm::normalize(Vec3(0.2, 1.0, -0.4)),
                       glm::normalize(Vec3(-0.3, 0.1, 1.0))};
    const double o[3] = {0.07, -0.11, 0.13};
    const double delta = 0.02;
    Vec3 out = x;
    for (int k = 0; k < 3; ++k) {
      const double u = (glm::dot(n[k], x) - o[k]) / period;
      const double step = std::floor(u);
      const double g = step + std::clamp((u - step) * period / width, 0.0, 1.0);
      out += delta * g * n[k];
    }
    return out;
  });
}

TEST(WarpVolume, LocallyInvertibleWarpWithKinksHasNoInverseFailures) {
  // Voxels of 0.04, steps of half a voxel over ramps of 1/130 and 1/200 voxel: Newton from the
  // seeds stalls at some of the kinks (15 and 11 voxels before the second chance was added).
  const FloatGrid::Ptr sphere = makeSphere(0.8, Vec3(0.05, -0.02, 0.03), 0.04);
  for (const auto& [period, width] : {std::pair{0.11, 3e-4}, std::pair{0.23, 2e-4}}) {
    const FunctionWarp kinked = kinkedWarp(period, width);
    const auto warped = warpVolume(kinked, *sphere);
    EXPECT_GT(warped.report.solvedVoxels, 10000u);
    EXPECT_EQ(warped.report.inverseFailures, 0u) << period << " " << width;
    EXPECT_EQ(warped.report.unmappedVoxels, 0u);
    for (auto it = warped.grid->cbeginValueOn(); it; ++it) EXPECT_TRUE(std::isfinite(*it));
    // Near the surface, the output at the image of an input voxel has the input's value.
    std::size_t checked = 0;
    for (auto it = sphere->cbeginValueOn(); it && checked < 2000; ++it) {
      if (std::abs(*it) > 0.02f) continue;
      const Vec3 y = kinked.apply(worldOf(*sphere, it.getCoord()));
      const openvdb::Vec3d yi = warped.grid->worldToIndex(openvdb::Vec3d(y.x, y.y, y.z));
      const double phi = openvdb::tools::BoxSampler::sample(warped.grid->tree(), yi);
      EXPECT_NEAR(phi, *it, 0.04) << it.getCoord();
      ++checked;
    }
    EXPECT_GT(checked, 100u);
  }
}

TEST(WarpVolume, CountsVoxelsWhereTheWarpIsNotFinite) {
  const FloatGrid::Ptr fog = makeGaussianFog(Vec3(0.0), 1.0, 0.2);
  const FunctionWarp broken([](const Vec3& x) {
    return x.x > 0.5 ? Vec3(std::numeric_limits<double>::quiet_NaN()) : x + Vec3(0.1, 0.0, 0.0);
  });
  const auto warped = warpVolume(broken, *fog);
  EXPECT_GT(warped.report.unmappedVoxels + warped.report.inverseFailures, 0u);
  EXPECT_GT(warped.report.unmappedVoxels, 0u);
  EXPECT_GT(warped.grid->activeVoxelCount(), 0);
  for (auto it = warped.grid->cbeginValueOn(); it; ++it) EXPECT_TRUE(std::isfinite(*it));
}

TEST(WarpVolume, IsBitIdenticalForOneAndTwoThreads) {
  const FloatGrid::Ptr sphere = makeSphere(1.0, Vec3(0.6, 0.1, 0.0), 0.1);
  const FloatGrid::Ptr fog = makeGaussianFog(Vec3(0.1, 0.0, -0.1), 1.0, 0.2);
  TwistOptions p;
  p.rate = 0.8;
  const TwistWarp twist(p);
  WarpVolumeOptions massOptions;
  massOptions.conserveMass = true;
  massOptions.sampler = VolumeSampler::Triquadratic;
  WarpVolumeOptions rebuild;
  rebuild.redistance = LevelSetRedistance::Rebuild;
  WarpedGrid<FloatGrid> ls[2], rb[2], fg[2];
  for (int threads : {1, 2}) {
    const tbb::global_control limit(tbb::global_control::max_allowed_parallelism,
                                    static_cast<std::size_t>(threads));
    ls[threads - 1] = warpVolume(twist, *sphere);
    rb[threads - 1] = warpVolume(twist, *sphere, rebuild);
    fg[threads - 1] = warpVolume(radialSquash(Vec3(0.0)), *fog, massOptions);
  }
  EXPECT_TRUE(test::bitIdentical(*ls[0].grid, *ls[1].grid));
  EXPECT_TRUE(test::bitIdentical(*rb[0].grid, *rb[1].grid));
  EXPECT_TRUE(test::bitIdentical(*fg[0].grid, *fg[1].grid));
  EXPECT_EQ(std::memcmp(&fg[0].report.massAfter, &fg[1].report.massAfter, sizeof(double)), 0);
}

TEST(WarpVolume, DoubleAndVectorGridsAreWarped) {
  openvdb::initialize();
  auto grid = openvdb::DoubleGrid::create(0.0);
  auto vectors = openvdb::Vec3SGrid::create(openvdb::Vec3s(0.0f));
  for (int i = -5; i <= 5; ++i)
    for (int j = -5; j <= 5; ++j)
      for (int k = -5; k <= 5; ++k) {
        grid->tree().setValue(Coord(i, j, k), 1.0 + 0.1 * i);
        vectors->tree().setValue(Coord(i, j, k), openvdb::Vec3s(float(i), float(j), float(k)));
      }
  const AffineWarp shift(glm::translate(Mat4(1.0), Vec3(2.0, 0.0, 0.0)));
  const auto d = warpVolume(shift, *grid);
  const auto v = warpVolume(shift, *vectors);
  EXPECT_EQ(d.grid->activeVoxelCount(), grid->activeVoxelCount());
  EXPECT_DOUBLE_EQ(d.grid->tree().getValue(Coord(7, 0, 0)), 1.5);
  EXPECT_FALSE(d.grid->tree().isValueOn(Coord(-4, 0, 0)));
  EXPECT_EQ(v.grid->tree().getValue(Coord(3, 1, 2)), openvdb::Vec3s(1, 1, 2));
}

// A vec3s grid holding field(world position) on the voxels -6..6 per axis (voxels of 0.25),
// tagged with `type`.
openvdb::Vec3SGrid::Ptr makeVectorField(const std::function<Vec3(const Vec3&)>& field,
                                        openvdb::VecType type) {
  openvdb::initialize();
  auto grid = openvdb::Vec3SGrid::create(openvdb::Vec3s(0.0f));
  grid->setTransform(openvdb::math::Transform::createLinearTransform(0.25));
  grid->setVectorType(type);
  for (int i = -6; i <= 6; ++i)
    for (int j = -6; j <= 6; ++j)
      for (int k = -6; k <= 6; ++k) {
        const Vec3 v = field(worldOf(*grid, Coord(i, j, k)));
        grid->tree().setValue(Coord(i, j, k), openvdb::Vec3s(float(v.x), float(v.y), float(v.z)));
      }
  return grid;
}

// Checks every output voxel whose preimage (by `inverse`) lies in the input's interior, where
// trilinear sampling does not reach the background; returns how many were checked.
std::size_t expectVectors(const openvdb::Vec3SGrid& out,
                          const std::function<Vec3(const Vec3&)>& inverse,
                          const std::function<Vec3(const Vec3& x, const Vec3& y)>& expected,
                          double tolerance) {
  std::size_t checked = 0;
  for (auto it = out.cbeginValueOn(); it; ++it) {
    const Vec3 y = worldOf(out, it.getCoord());
    const Vec3 x = inverse(y);
    if (maxAbs(x) > 4.5 * 0.25) continue;
    const Vec3 want = expected(x, y);
    const Vec3 got((*it)[0], (*it)[1], (*it)[2]);
    EXPECT_LT(glm::length(got - want), tolerance) << it.getCoord();
    ++checked;
  }
  return checked;
}

TEST(WarpVolume, VectorFieldRotatedByARigidWarpComesBackRotated) {
  const Vec3 u(1.0, 0.5, -0.25);
  const Mat4 m = glm::translate(Mat4(1.0), Vec3(0.3, -0.2, 0.1)) *
                 glm::rotate(Mat4(1.0), 0.6, glm::normalize(Vec3(1.0, 2.0, 3.0)));
  const AffineWarp rigid(m);
  const Mat3 r = rigid.linear();
  auto inverse = [&](const Vec3& y) { return glm::transpose(r) * (y - rigid.translation()); };
  // A file that says nothing (VEC_INVARIANT) and an explicit velocity: pushed forward, R u.
  for (const auto type : {openvdb::VEC_INVARIANT, openvdb::VEC_CONTRAVARIANT_RELATIVE,
                          openvdb::VEC_COVARIANT_NORMALIZE}) {
    const auto field = makeVectorField([&](const Vec3&) { return u; }, type);
    const auto w = warpVolume(rigid, *field);
    EXPECT_EQ(w.report.inverseFailures, 0u);
    EXPECT_GT(expectVectors(
                  *w.grid, inverse,
                  [&](const Vec3&, const Vec3&) {
                    return type == openvdb::VEC_COVARIANT_NORMALIZE ? r * glm::normalize(u) : r * u;
                  },
                  1e-5),
              300u)
        << type;
    EXPECT_EQ(w.grid->getVectorType(), type);
  }
  // Keep: resampled only.
  const auto field = makeVectorField([&](const Vec3&) { return u; }, openvdb::VEC_INVARIANT);
  WarpVolumeOptions keep;
  keep.vectors = VectorTransform::Keep;
  const auto kept = warpVolume(rigid, *field, keep);
  EXPECT_EQ(kept.report.vectors, "unchanged");
  EXPECT_GT(expectVectors(
                *kept.grid, inverse, [&](const Vec3&, const Vec3&) { return u; }, 1e-5),
            300u);
}

TEST(WarpVolume, CovariantAndPositionFieldsFollowTheirVecType) {
  // A linear map that is neither rigid nor symmetric: J⁻ᵀ differs from J.
  Mat3 a(1.0);
  a[0] = Vec3(1.4, 0.2, 0.0);
  a[1] = Vec3(0.5, 0.9, 0.1);
  a[2] = Vec3(0.0, -0.3, 1.2);
  Mat4 m(1.0);
  for (int c = 0; c < 3; ++c) m[c] = glm::dvec4(a[c], 0.0);
  m[3] = glm::dvec4(0.1, 0.2, -0.1, 1.0);
  const AffineWarp linear(m);
  const Mat3 aInverse = glm::inverse(a);
  auto inverse = [&](const Vec3& y) { return aInverse * (y - linear.translation()); };
  const Vec3 g(0.3, -1.0, 0.6);

  const auto gradient = makeVectorField([&](const Vec3&) { return g; }, openvdb::VEC_COVARIANT);
  const auto wg = warpVolume(linear, *gradient);
  EXPECT_EQ(wg.report.vectors, "J^-T v");
  EXPECT_GT(expectVectors(
                *wg.grid, inverse,
                [&](const Vec3&, const Vec3&) { return glm::transpose(aInverse) * g; }, 1e-5),
            300u);

  // Normal (whatever the grid says): J⁻ᵀ v with the length of v.
  WarpVolumeOptions normal;
  normal.vectors = VectorTransform::Normal;
  const auto wn = warpVolume(linear, *gradient, normal);
  EXPECT_GT(expectVectors(
                *wn.grid, inverse,
                [&](const Vec3&, const Vec3&) {
                  return glm::normalize(glm::transpose(aInverse) * g) * glm::length(g);
                },
                1e-5),
            300u);

  // Positions (VEC_CONTRAVARIANT_ABSOLUTE): v(x) = x is carried to warp(x), i.e. every output
  // voxel holds its own position, even where sampling is exact only to first order.
  const auto positions =
      makeVectorField([](const Vec3& x) { return x; }, openvdb::VEC_CONTRAVARIANT_ABSOLUTE);
  const auto wp = warpVolume(linear, *positions);
  EXPECT_EQ(wp.report.vectors, "warp(v)");
  EXPECT_GT(expectVectors(
                *wp.grid, inverse, [](const Vec3&, const Vec3& y) { return y; }, 1e-5),
            300u);
}

TEST(WarpVolume, VectorsFollowANonlinearShearThroughItsFiniteDifferenceJacobian) {
  // F(x) = (x + 0.3 sin(4y), y, z) with the default (central-difference) Jacobian: J v for a
  // velocity, and J⁻ᵀ of the gradient of x₀ is the gradient of its warped copy,
  // ∇(y₀ - 0.3 sin(4y₁)) = (1, -1.2 cos(4y₁), 0).
  const FunctionWarp shear(
      [](const Vec3& x) { return Vec3(x.x + 0.3 * std::sin(4.0 * x.y), x.y, x.z); });
  auto inverse = [](const Vec3& y) { return Vec3(y.x - 0.3 * std::sin(4.0 * y.y), y.y, y.z); };
  const auto velocity =
      makeVectorField([](const Vec3&) { return Vec3(0.0, 1.0, 0.0); }, openvdb::VEC_INVARIANT);
  const auto wv = warpVolume(shear, *velocity);
  EXPECT_EQ(wv.report.inverseFailures, 0u);
  EXPECT_EQ(wv.report.vectors, "J v");
  EXPECT_GT(
      expectVectors(
          *wv.grid, inverse,
          [](const Vec3& x, const Vec3&) { return Vec3(1.2 * std::cos(4.0 * x.y), 1.0, 0.0); },
          1e-5),
      300u);
  const auto gradient =
      makeVectorField([](const Vec3&) { return Vec3(1.0, 0.0, 0.0); }, openvdb::VEC_COVARIANT);
  const auto wg = warpVolume(shear, *gradient);
  EXPECT_GT(
      expectVectors(
          *wg.grid, inverse,
          [](const Vec3& x, const Vec3&) { return Vec3(1.0, -1.2 * std::cos(4.0 * x.y), 0.0); },
          1e-5),
      300u);
}

TEST(WarpVolume, ImagesBeyondTheIndexRangeAreRefusedNamingTheGrid) {
  // A plain translation by 5e7 at voxel size 0.1 lands at index 5e8..: fine. By 5e8 it lands
  // beyond what 32-bit coordinates hold, which used to give an empty grid and exit 0.
  const auto grid = makeSphere(1.0, Vec3(0.0), 0.1);
  const auto near = warpVolume(AffineWarp(glm::translate(Mat4(1.0), Vec3(5e7, 0, 0))), *grid);
  EXPECT_NEAR(double(near.report.outputActiveVoxels), double(near.report.inputActiveVoxels),
              0.01 * double(near.report.inputActiveVoxels));
  try {
    warpVolume(AffineWarp(glm::translate(Mat4(1.0), Vec3(5e8, 0, 0))), *grid);
    FAIL() << "expected InvalidInput";
  } catch (const InvalidInput& e) {
    EXPECT_NE(std::string(e.what()).find("'sphere'"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("32-bit"), std::string::npos) << e.what();
  }
}

TEST(WarpVolume, SparseGridFarFromATwistAxisFailsFastNamingTheGrid) {
  // Two small spheres 1e6 apart, twisted about the z axis through the first: at the second,
  // one voxel's corners land 1e5 voxels apart, so its image box alone has 1e10 voxels. That
  // used to be allocated (std::bad_alloc after minutes); it must be a quick InvalidInput.
  auto grid = makeSphere(1.0, Vec3(0.0), 0.1);
  openvdb::tools::csgUnion(*grid, *makeSphere(1.0, Vec3(1e6, 0.0, 0.0), 0.1));
  TwistOptions p;
  p.rate = 0.5;
  const TwistWarp twist(p);
  try {
    warpVolume(twist, *grid);
    FAIL() << "expected InvalidInput";
  } catch (const InvalidInput& e) {
    EXPECT_NE(std::string(e.what()).find("'sphere'"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("not smooth at the scale"), std::string::npos);
  }
  // The same grid twisted about the x axis through both is rigid near each sphere: its cost
  // follows the active voxels, not the 1e7-voxel bounding box.
  TwistOptions alongX;
  alongX.axis = Vec3(1.0, 0.0, 0.0);
  alongX.rate = 0.5;
  const auto w = warpVolume(TwistWarp(alongX), *grid);
  EXPECT_EQ(w.report.inverseFailures, 0u);
  EXPECT_NEAR(double(w.report.outputActiveVoxels), double(w.report.inputActiveVoxels),
              0.1 * double(w.report.inputActiveVoxels));
  EXPECT_LT(w.report.solvedVoxels, 20 * w.report.inputActiveVoxels);
}

TEST(WarpVolume, ProgressReportsAndCancels) {
  const FloatGrid::Ptr fog = makeGaussianFog(Vec3(0.0), 1.0, 0.2);
  WarpVolumeOptions options;
  double last = -1.0;
  options.progress = [&](std::string_view stage, double fraction) {
    EXPECT_EQ(stage, "warp volume");
    last = fraction;
    return true;
  };
  warpVolume(IdentityWarp(), *fog, options);
  EXPECT_EQ(last, 1.0);
  options.progress = [](std::string_view, double fraction) { return fraction < 0.3; };
  EXPECT_THROW(warpVolume(IdentityWarp(), *fog, options), Cancelled);
}

TEST(WarpVolume, CachedDisplacementFieldStaysWithinItsErrorBound) {
  const double voxel = 0.1, rate = 0.6;
  const FloatGrid::Ptr sphere = makeSphere(1.0, Vec3(0.7, 0.0, 0.0), voxel);
  TwistOptions p;
  p.rate = rate;
  const TwistWarp twist(p);
  WarpVolumeOptions options;
  options.redistance = LevelSetRedistance::None;  // compare the resampled values
  const auto exact = warpVolume(twist, *sphere, options);
  options.cacheSpacing = 2.0;
  const auto cached = warpVolume(twist, *sphere, options);

  // The trilinear bound h² θ² r / 8 with r the largest distance from the axis over the
  // lattice: the band reaches 2.0 from the axis, the seeding cells 0.4 more, the lattice
  // another 2 voxels + h and one lattice cell: r < 3.2.
  const double h = options.cacheSpacing * voxel;
  const double bound = h * h * rate * rate * 3.2 / 8.0;
  EXPECT_GT(cached.report.cacheError, 0.0);
  EXPECT_LE(cached.report.cacheError, bound);
  // Values of a distance field move by at most the position error times |J⁻¹| (< 2.5 here).
  auto acc = exact.grid->getConstAccessor();
  std::size_t compared = 0;
  for (auto it = cached.grid->cbeginValueOn(); it; ++it) {
    float ref;
    if (!acc.probeValue(it.getCoord(), ref)) continue;
    EXPECT_NEAR(*it, ref, 2.5 * bound + 1e-5) << it.getCoord();
    ++compared;
  }
  EXPECT_GT(compared, 0.95 * double(exact.grid->activeVoxelCount()));
  EXPECT_EQ(cached.report.inverseFailures, 0u);
}

TEST(WarpVolume, RejectsUnsupportedTransformsAndOptions) {
  openvdb::initialize();
  const FloatGrid::Ptr fog = makeGaussianFog(Vec3(0.0), 0.5, 0.2);
  WarpVolumeOptions bad;
  bad.seedSpacing = 0;
  EXPECT_THROW(warpVolume(IdentityWarp(), *fog, bad), InvalidInput);

  auto frustum = FloatGrid::create(0.0f);
  frustum->setName("frustum");
  frustum->setTransform(openvdb::math::Transform::createFrustumTransform(
      openvdb::BBoxd(openvdb::Vec3d(0), openvdb::Vec3d(10)), 0.5, 2.0, 0.1));
  frustum->tree().setValue(Coord(1, 1, 1), 1.0f);
  try {
    warpVolume(IdentityWarp(), *frustum);
    ADD_FAILURE() << "no exception";
  } catch (const InvalidInput& e) {
    EXPECT_NE(std::string(e.what()).find("frustum"), std::string::npos) << e.what();
  }

  const FloatGrid::Ptr sphere = makeSphere(1.0, Vec3(0.0), 0.1);
  openvdb::math::Mat4d stretch(openvdb::math::Mat4d::identity());
  stretch(0, 0) = 0.1;
  stretch(1, 1) = 0.2;
  stretch(2, 2) = 0.1;
  sphere->setTransform(openvdb::math::Transform::createLinearTransform(stretch));
  EXPECT_THROW(warpVolume(IdentityWarp(), *sphere), InvalidInput);
}

TEST(WarpVolume, FogWithNonCubicVoxelsIsWarped) {
  auto fog = makeGaussianFog(Vec3(0.0), 1.0, 0.2);
  openvdb::math::Mat4d stretch(openvdb::math::Mat4d::identity());
  stretch(0, 0) = 0.2;
  stretch(1, 1) = 0.3;
  stretch(2, 2) = 0.2;
  fog->setTransform(openvdb::math::Transform::createLinearTransform(stretch));
  const AffineWarp shift(glm::translate(Mat4(1.0), Vec3(0.6, 0.9, 0.0)));  // 3 voxels each
  const auto warped = warpVolume(shift, *fog);
  auto acc = warped.grid->getConstAccessor();
  for (auto it = fog->cbeginValueOn(); it; ++it)
    EXPECT_NEAR(acc.getValue(it.getCoord() + Coord(3, 3, 0)), *it, 1e-5);
}

}  // namespace
}  // namespace spacewarp
