// Whole archives (rig/warp_archive.h): the header, and each class's save -> load round trip,
// compared bit for bit (same doubles, same code paths), never within a tolerance.

#include <spacewarp/rig/warp_archive.h>

#include <unistd.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <limits>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <spacewarp/coords/green.h>
#include <spacewarp/coords/mean_value.h>
#include <spacewarp/core/bend.h>
#include <spacewarp/core/combinators.h>
#include <spacewarp/core/coordinate_warp.h>
#include <spacewarp/core/errors.h>
#include <spacewarp/core/io/mesh_io.h>
#include <spacewarp/core/taper.h>
#include <spacewarp/core/twist.h>
#include <spacewarp/ffd/lattice_coordinates.h>
#include <spacewarp/ffd/lattice_fit.h>
#include <spacewarp/ffd/lattice_warp.h>
#include <spacewarp/rbf/detail/rbf_system.h>
#include <spacewarp/rbf/rbf_coordinates.h>
#include <spacewarp/rbf/rbf_warp.h>
#include <spacewarp/rig/rig.h>
#ifdef SPACEWARP_HAVE_HARMONIC
#include <spacewarp/coords/detail/harmonic_file.h>
#include <spacewarp/coords/harmonic.h>
#include <spacewarp/coords/harmonic_warp.h>
#endif

#include "coords/coords_test_shapes.h"

#include "rig/archive_test_util.h"
#include "test_util.h"

namespace spacewarp {
namespace {

using ::testing::HasSubstr;

TwistWarp someTwist() {
  TwistOptions o;
  o.origin = {0.1, -0.2, 0.3};
  o.axis = {0.3, 1.0, -0.2};
  o.rate = 1.7;
  o.lo = -0.4;
  o.hi = 0.9;
  return TwistWarp(o);
}

TEST(WarpArchive, TwistRoundTripsBitIdentically) {
  const TwistWarp twist = someTwist();
  const std::shared_ptr<const Warp> loaded = loadWarp(saveWarp(twist));
  ASSERT_NE(dynamic_cast<const TwistWarp*>(loaded.get()), nullptr);
  EXPECT_TRUE(test::sameWarp(twist, *loaded));
  EXPECT_EQ(saveWarp(*loaded), saveWarp(twist));
}

TEST(WarpArchive, TheHeaderIsCheckedNamingMagicAndVersion) {
  const std::string bytes = saveWarp(someTwist());
  EXPECT_THAT(test::messageOf<InvalidInput>([&] { loadWarp("{\"method\": \"twist\"}"); }),
              HasSubstr("not a spacewarp archive: it does not start with \"spacewarp-archive\""));
  EXPECT_THAT(test::messageOf<InvalidInput>([&] { loadWarp(""); }),
              HasSubstr("not a spacewarp archive"));
  std::string otherVersion = bytes;
  // Version 1 stored compositions nested two by two; version 2 stores them as a list.
  for (const char version : {'\x07', '\x01'}) {
    otherVersion[8 + kArchiveMagic.size()] = version;  // the version's low byte
    EXPECT_THAT(test::messageOf<InvalidInput>([&] { loadWarp(otherVersion); }),
                HasSubstr("format version " + std::to_string(version) +
                          ", but this build reads version " + std::to_string(kArchiveVersion)));
  }
}

TEST(WarpArchive, TrailingBytesAreRefused) {
  EXPECT_THAT(test::messageOf<InvalidInput>([&] { loadWarp(saveWarp(someTwist()) + "xy"); }),
              HasSubstr("2 bytes after the end of the object"));
}

TEST(WarpArchive, EveryTruncationIsRefusedWithInvalidInput) {
  const std::string bytes = saveWarp(someTwist());
  for (std::size_t n = 0; n < bytes.size(); ++n)
    EXPECT_THROW(loadWarp(std::string_view(bytes).substr(0, n)), InvalidInput) << n;
}

TEST(WarpArchive, ParametersAreCheckedByTheConstructor) {
  // A NaN rate in an otherwise valid archive: TwistWarp's own refusal.
  std::string bytes = saveWarp(someTwist());
  const std::size_t rateAt = bytes.size() - 3 * sizeof(double);
  const double nan = std::numeric_limits<double>::quiet_NaN();
  std::memcpy(bytes.data() + rateAt, &nan, sizeof nan);
  EXPECT_THAT(test::messageOf<InvalidInput>([&] { loadWarp(bytes); }), HasSubstr("rate"));
}

TEST(WarpArchive, ConstructorRefusalsNameTheArchiveTagAndByteOnce) {
  BendOptions options;
  options.lo = -0.5;
  options.hi = 1.0;
  const BendWarp bend(options);
  const double nan = std::numeric_limits<double>::quiet_NaN();
  std::string bytes = saveWarp(bend);
  std::memcpy(bytes.data() + bytes.size() - 2 * sizeof(double), &nan, sizeof nan);  // lo
  // The header is 29 bytes: the bend's tag starts there.
  const std::string message = test::messageOf<InvalidInput>([&] { loadWarp(bytes); });
  EXPECT_THAT(message, ::testing::StartsWith("warp archive: bend at byte 29: "));
  EXPECT_THAT(message, HasSubstr("NaN"));
  // Nested in a composition: the bend's tag and byte, not one prefix per level.
  const ComposedWarp composed(std::make_shared<const TwistWarp>(someTwist()),
                              std::make_shared<const BendWarp>(bend));
  std::string nested = saveWarp(composed);
  std::memcpy(nested.data() + nested.size() - 2 * sizeof(double), &nan, sizeof nan);
  const std::size_t bendAt = nested.find("bend") - sizeof(std::uint64_t);
  const std::string nestedMessage = test::messageOf<InvalidInput>([&] { loadWarp(nested); });
  EXPECT_THAT(nestedMessage,
              ::testing::StartsWith("warp archive: bend at byte " + std::to_string(bendAt) + ": "));
  EXPECT_EQ(nestedMessage.find("warp archive:", 1), std::string::npos) << nestedMessage;
  // A cage archive: its name is the file it came from, but the archive is what is at fault.
  std::string cage = saveCage(Cage(test::pinchedBox(0.5), "box.obj"));
  const std::uint32_t farVertex = 262150;
  std::memcpy(cage.data() + cage.size() - sizeof farVertex, &farVertex, sizeof farVertex);
  EXPECT_THAT(test::messageOf<InvalidInput>([&] { loadCage(cage); }),
              ::testing::StartsWith("warp archive: cage at byte 29: box.obj: "));
}

// ---- core ----

TEST(WarpArchive, AnalyticWarpsRoundTripBitIdentically) {
  EXPECT_TRUE(test::warpRoundTrips(IdentityWarp()));
  Mat4 m(1.0);
  m[0] = glm::dvec4(1.1, 0.2, -0.3, 0.0);
  m[3] = glm::dvec4(0.5, -1.0, 2.0, 1.0);
  EXPECT_TRUE(test::warpRoundTrips(AffineWarp(m)));
  Mat4 singular(1.0);
  singular[2] = glm::dvec4(0.0);  // no exact inverse: the same "none" after loading
  EXPECT_TRUE(test::warpRoundTrips(AffineWarp(singular)));
  BendOptions bend;
  bend.rate = 0.8;
  bend.lo = -0.5;
  bend.hi = 1.0;
  bend.direction = {0.0, 1.0, 0.0};
  EXPECT_TRUE(test::warpRoundTrips(BendWarp(bend)));
  TaperOptions taper;
  taper.rate = 0.6;  // r = 0 at s = -1/0.6: points there have no exact inverse
  taper.axis = {1.0, 1.0, 0.0};
  EXPECT_TRUE(test::warpRoundTrips(TaperWarp(taper)));
  EXPECT_TRUE(test::warpRoundTrips(someTwist()));
}

TEST(WarpArchive, NestedCompositionsRoundTrip) {
  std::shared_ptr<const Warp> warp = std::make_shared<TwistWarp>(someTwist());
  TaperOptions taper;
  taper.rate = 0.3;
  for (int i = 0; i < 5; ++i) {
    warp = std::make_shared<ComposedWarp>(warp, std::make_shared<TaperWarp>(taper));
    warp = std::make_shared<ComposedWarp>(std::make_shared<IdentityWarp>(), warp);
  }
  EXPECT_TRUE(test::warpRoundTrips(*warp));
}

TEST(WarpArchive, LongCompositionsSaveAsAListAndLoadAsTheSameChain) {
  // Nested 200 deep it would pass the archive's nesting limit; flat it is one level.
  const auto twist = std::make_shared<TwistWarp>(someTwist());
  std::shared_ptr<const Warp> warp = twist;
  for (int i = 0; i < 200; ++i) warp = std::make_shared<ComposedWarp>(warp, twist);
  EXPECT_TRUE(test::warpRoundTrips(*warp));
  const auto loaded = std::dynamic_pointer_cast<const ComposedWarp>(loadWarp(saveWarp(*warp)));
  ASSERT_NE(loaded, nullptr);
  EXPECT_EQ(loaded->stages().size(), 201u);
}

TEST(WarpArchive, ACompositionWithAHostileStageCountIsRefusedBeforeReserving) {
  const auto twist = std::make_shared<TwistWarp>(someTwist());
  std::string bytes = saveWarp(ComposedWarp(twist, twist));
  // The count follows the header and the tag "compose" (8-byte length + 7 characters).
  const std::size_t at = bytes.find("compose") + 7;
  for (const std::uint64_t count : {std::uint64_t{0}, std::uint64_t{1}, ~std::uint64_t{0}}) {
    for (int i = 0; i < 8; ++i) bytes[at + i] = static_cast<char>(count >> (8 * i));
    EXPECT_THAT(test::messageOf<InvalidInput>([&] { loadWarp(bytes); }),
                HasSubstr("a composition of " + std::to_string(count) + " stages (at least 2, " +
                          "at most one per 8 bytes left) (byte " + std::to_string(at) + ")"));
  }
}

// ---- coords ----

std::shared_ptr<const Cage> starCage() {
  return std::make_shared<const Cage>(test::star(), "star");
}

std::vector<Vec3> posedOf(std::span<const Vec3> rest, double amount = 0.2) {
  std::vector<Vec3> posed(rest.begin(), rest.end());
  for (std::size_t i = 0; i < posed.size(); ++i) {
    const double t = static_cast<double>(i);
    posed[i] += amount * Vec3(std::sin(t), std::cos(3.0 * t), std::sin(2.0 * t));
  }
  return posed;
}

TEST(WarpArchive, CageCoordinatesAndTheirWarpsRoundTrip) {
  const auto cage = starCage();
  MeanValueOptions mv;
  mv.snapTolerance = 1e-12;
  const auto mvc = std::make_shared<const MeanValueCoordinates>(cage, mv);
  EXPECT_TRUE(test::coordinatesRoundTrip(mvc, {}, -3.0, 3.0));
  const auto green = std::make_shared<const GreenCoordinates>(cage);
  EXPECT_TRUE(test::coordinatesRoundTrip(green, {}, -3.0, 3.0));
  for (const auto& c :
       {std::shared_ptr<const Coordinates>(mvc), std::shared_ptr<const Coordinates>(green)}) {
    const auto warp = makeWarp(c, posedOf(cage->vertices()));
    ASSERT_NE(dynamic_cast<const CoordinateWarp*>(warp.get()), nullptr);
    EXPECT_TRUE(test::warpRoundTrips(*warp, {}, -3.0, 3.0));
  }
}

TEST(WarpArchive, SharedCoordinatesAreStoredOnceAndLoadShared) {
  const auto cage = starCage();
  const auto mvc = std::make_shared<const MeanValueCoordinates>(cage);
  const auto one = makeWarp(mvc, posedOf(cage->vertices(), 0.1));
  const auto two = makeWarp(mvc, posedOf(cage->vertices(), 0.2));
  const ComposedWarp both(one, two);
  const std::string bytes = saveWarp(both);
  // The second warp refers to the first one's coordinates: the archive holds them once.
  const std::size_t coordinatesSize = saveCoordinates(*mvc).size();
  EXPECT_LT(bytes.size(), saveWarp(*one).size() + saveWarp(*two).size() - coordinatesSize / 2);
  EXPECT_TRUE(test::warpRoundTrips(both, {}, -3.0, 3.0));
  const auto loaded = std::dynamic_pointer_cast<const ComposedWarp>(loadWarp(bytes));
  ASSERT_NE(loaded, nullptr);
  const auto& a = dynamic_cast<const CoordinateWarp&>(*loaded->stages()[0]);
  const auto& b = dynamic_cast<const CoordinateWarp&>(*loaded->stages()[1]);
  EXPECT_EQ(&a.coordinates(), &b.coordinates());
  // The same warp twice is one object too.
  const auto twice =
      std::dynamic_pointer_cast<const ComposedWarp>(loadWarp(saveWarp(ComposedWarp(one, one))));
  EXPECT_EQ(twice->stages()[0], twice->stages()[1]);
}

TEST(WarpArchive, BackReferencesToNothingOrAnotherKindAreRefused) {
  const auto cage = starCage();
  const auto mvc = std::make_shared<const MeanValueCoordinates>(cage);
  const auto one = makeWarp(mvc, posedOf(cage->vertices(), 0.1));
  const std::string bytes = saveWarp(ComposedWarp(one, makeWarp(mvc, posedOf(cage->vertices()))));
  // Objects: 0 the composition, 1 the first warp, 2 its coordinates, 3 the second warp; the
  // back-reference in the second warp is the tag "#" (8-byte length 1, then '#') and 2.
  const std::size_t at = bytes.find(std::string("\x01\0\0\0\0\0\0\0#", 9));
  ASSERT_NE(at, std::string::npos);
  ASSERT_EQ(bytes[at + 9], 2);
  for (const char number : {'\x00', '\x01', '\x03', '\x7f'}) {
    std::string hostile = bytes;
    hostile[at + 9] = number;  // still loading, a warp, still loading, none
    EXPECT_THAT(
        test::messageOf<InvalidInput>([&] { loadWarp(hostile); }),
        HasSubstr("a reference to coordinates number " + std::to_string(number) +
                  ", which is not a coordinates loaded before it (4 objects so far) (byte " +
                  std::to_string(at) + ")"));
  }
}

TEST(WarpArchive, AnArchiveOfAnotherKindIsNamedWithItsLoader) {
  const auto cage = starCage();
  const MeanValueCoordinates mvc(cage);
  EXPECT_THAT(test::messageOf<InvalidInput>([&] { loadWarp(saveCoordinates(mvc)); }),
              HasSubstr("'mean-value' is coordinates (loadCoordinates, "
                        "spacewarp.coordinates_from_bytes), not a warp (byte 29)"));
  EXPECT_THAT(test::messageOf<InvalidInput>([&] { loadCoordinates(saveWarp(someTwist())); }),
              HasSubstr("'twist' is a warp (loadWarp, spacewarp.warp_from_bytes), not "
                        "coordinates"));
  EXPECT_THAT(test::messageOf<InvalidInput>([&] { loadCoordinates(saveCage(*cage)); }),
              HasSubstr("'cage' is a cage (loadCage, spacewarp.cage_from_bytes), not coordinates"));
}

TEST(WarpArchive, ACageIsRebuiltFromItsPolygons) {
  // A quad cage (triangulated and reoriented by the constructor) keeps its polygons: a posed
  // cage with other faces is refused by the loaded one as by the original.
  PolygonSoup box = test::pinchedBox(0.5);
  const auto cage = std::make_shared<const Cage>(box, "box");
  const auto loaded = std::dynamic_pointer_cast<const MeanValueCoordinates>(
      loadCoordinates(saveCoordinates(MeanValueCoordinates(cage))));
  ASSERT_NE(loaded, nullptr);
  EXPECT_EQ(loaded->cage().name(), "box");
  EXPECT_EQ(loaded->cage().triangleCount(), cage->triangleCount());
  EXPECT_EQ(loaded->cage().reorientedCount(), cage->reorientedCount());
  EXPECT_EQ(loaded->cage().volume(), cage->volume());
}

TEST(WarpArchive, CagePolygonsThatOvershootTheirIndicesAreRefused) {
  // Found by fuzz_archive: offsets 0, 100, 3 over 3 indices read past them before this check.
  ArchiveWriter out;
  out.string(kArchiveMagic);
  out.u32(kArchiveVersion);
  out.tag("mean-value");
  out.tag("cage");
  out.string("cage");
  const std::vector<Vec3> vertices{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  out.vec3s(vertices);
  const std::vector<std::uint32_t> offsets{0, 100, 3}, indices{0, 1, 2};
  out.u32s(offsets);
  out.u32s(indices);
  out.f64(1e-14);
  EXPECT_THAT(test::messageOf<InvalidInput>([&] { loadCoordinates(out.bytes()); }),
              HasSubstr("polygon 0 ends past the face index array"));
}

#ifdef SPACEWARP_HAVE_HARMONIC
TEST(WarpArchive, HarmonicCoordinatesAndWarpLoadWithoutSolving) {
  for (const auto outside : {HarmonicOutsidePolicy::Throw, HarmonicOutsidePolicy::NearestPoint}) {
    HarmonicOptions options;
    options.targetTetCount = 3000;
    options.outside = outside;
    const auto harmonic = std::make_shared<const HarmonicCoordinates>(starCage(), options);
    const auto warp = makeWarp(harmonic, posedOf(harmonic->restControlPoints()));
    ASSERT_NE(dynamic_cast<const HarmonicWarp*>(warp.get()), nullptr);
    const std::size_t solves = detail::harmonicSolveCount();
    // Points inside and outside the cage: outside ones are refused (Throw) by both alike.
    EXPECT_TRUE(test::coordinatesRoundTrip(harmonic, {}, -3.0, 3.0));
    EXPECT_TRUE(test::warpRoundTrips(*warp, {}, -3.0, 3.0));
    EXPECT_EQ(detail::harmonicSolveCount(), solves) << "loading solved again";
  }
}

TEST(WarpArchive, ACorruptHarmonicFieldIsRefused) {
  HarmonicOptions options;
  options.targetTetCount = 2000;
  const HarmonicCoordinates harmonic(starCage(), options);
  std::string bytes = saveCoordinates(harmonic);
  bytes[bytes.size() - 9] ^= 1;  // a value bit: the field's checksum no longer matches
  EXPECT_THAT(test::messageOf<InvalidInput>([&] { loadCoordinates(bytes); }),
              HasSubstr("harmonic coordinates: corrupt harmonic coordinate file: checksum"));
}
#endif

// ---- ffd ----

TEST(WarpArchive, LatticesOfEveryBasisAndOutsideModeRoundTrip) {
  for (const auto& [basis, ends] : {std::pair{LatticeBasis::Trilinear, LatticeEnds::Extrapolate},
                                    std::pair{LatticeBasis::Bernstein, LatticeEnds::Extrapolate},
                                    std::pair{LatticeBasis::BSpline, LatticeEnds::Extrapolate},
                                    std::pair{LatticeBasis::BSpline, LatticeEnds::Repeat}}) {
    for (const auto outside :
         {LatticeOutside::Identity, LatticeOutside::Clamp, LatticeOutside::Falloff}) {
      LatticeOptions o;
      o.origin = {-1.0, -1.0, -1.0};
      o.extents = {2.0, 2.5, 1.5};
      o.axes = {glm::normalize(Vec3(1.0, 0.1, 0.0)), glm::normalize(Vec3(-0.1, 1.0, 0.0)),
                Vec3(0.0, 0.0, 1.0)};
      o.resolution = {4, 5, 4};
      o.basis = basis;
      o.ends = ends;
      o.outside = outside;
      o.falloff = 0.3;
      const Lattice lattice(o);
      const auto coordinates = std::make_shared<const LatticeCoordinates>(lattice);
      EXPECT_TRUE(test::coordinatesRoundTrip(coordinates, {}, -3.0, 3.0));
      const auto loaded = std::dynamic_pointer_cast<const LatticeCoordinates>(
          loadCoordinates(saveCoordinates(*coordinates)));
      ASSERT_NE(loaded, nullptr);
      EXPECT_EQ(loaded->lattice().params().ends, ends);
      const auto warp = makeWarp(coordinates, posedOf(lattice.restControlPoints(), 0.1));
      ASSERT_NE(dynamic_cast<const LatticeWarp*>(warp.get()), nullptr);
      EXPECT_TRUE(test::warpRoundTrips(*warp, {}, -3.0, 3.0));
    }
  }
}

// The ends ride in the basis value, so an extrapolate lattice is archived as before (basis 2,
// what builds without ends wrote and read) and a repeat one differs in that value alone (3).
TEST(WarpArchive, LatticeEndsKeepTheVersion2Layout) {
  LatticeOptions o;
  o.resolution = {4, 4, 4};
  o.basis = LatticeBasis::BSpline;
  const std::string extrapolate = saveCoordinates(LatticeCoordinates(Lattice(o)));
  o.ends = LatticeEnds::Repeat;
  const std::string repeat = saveCoordinates(LatticeCoordinates(Lattice(o)));
  ASSERT_EQ(extrapolate.size(), repeat.size());
  std::vector<std::size_t> differ;
  for (std::size_t i = 0; i < repeat.size(); ++i)
    if (extrapolate[i] != repeat[i]) differ.push_back(i);
  ASSERT_EQ(differ.size(), 1u);
  EXPECT_EQ(extrapolate[differ[0]], 2);
  EXPECT_EQ(repeat[differ[0]], 3);
}

TEST(WarpArchive, AFittedLatticeKeepsItsFittedControlPoints) {
  std::mt19937 rng(11);
  const std::vector<Vec3> from = test::randomPoints(rng, 40, -1.0, 1.0);
  std::vector<Vec3> to = from;
  for (Vec3& p : to) p += Vec3(0.1 * p.y, 0.0, 0.05);
  const Lattice lattice = fitLattice(from, 0.1, {4, 4, 4}, LatticeBasis::BSpline);
  const LatticeWarp warp(lattice, fitControlPoints(lattice, from, to).controlPoints);
  const auto loaded = std::dynamic_pointer_cast<const LatticeWarp>(loadWarp(saveWarp(warp)));
  ASSERT_NE(loaded, nullptr);
  EXPECT_EQ(
      test::bytesOf(
          std::vector<Vec3>(loaded->controlPoints().begin(), loaded->controlPoints().end())),
      test::bytesOf(std::vector<Vec3>(warp.controlPoints().begin(), warp.controlPoints().end())));
  EXPECT_TRUE(test::sameWarp(warp, *loaded));
}

TEST(WarpArchive, ALatticeResolutionThatDisagreesWithItsPosedPointsIsRefusedBeforeBuilding) {
  std::mt19937 rng(3);
  const Lattice lattice =
      fitLattice(test::randomPoints(rng, 10, -1.0, 1.0), 0.1, {4, 4, 4}, LatticeBasis::BSpline);
  std::vector<Vec3> posed(lattice.restControlPoints().begin(), lattice.restControlPoints().end());
  std::string bytes = saveWarp(LatticeWarp(lattice, posed));
  // resolution[2] follows the header (29 bytes), the tag (20), origin, axes and extents (120).
  const std::size_t at = 29 + 20 + 120 + 8;
  ASSERT_EQ(bytes[at], 4);
  const std::int32_t huge = 1 << 24;  // 4 x 4 x 2^24 control points: 6.4 GB if built
  std::memcpy(&bytes[at], &huge, 4);
  // The stored 64 posed points are compared first: the message is this check's, not the memory
  // guard's, so nothing was allocated for the resolution.
  const std::size_t posedAt = 29 + 20 + 120 + 12 + 4 + 4 + 8;
  EXPECT_THAT(test::messageOf<InvalidInput>([&] { loadWarp(bytes); }),
              HasSubstr("stores 64 posed control points, but its resolution 4 x 4 x 16777216 "
                        "needs one per control point (byte " +
                        std::to_string(posedAt) + ")"));
}

// ---- rbf ----

TEST(WarpArchive, RbfWarpsAndCoordinatesOfEveryKernelLoadWithoutFitting) {
  std::mt19937 rng(7);
  const std::vector<Vec3> centers = test::randomPoints(rng, 12, -1.0, 1.0);
  const std::vector<Vec3> fixed = test::randomPoints(rng, 5, -1.5, 1.5);
  std::vector<Vec3> targets = centers;
  for (Vec3& t : targets) t += 0.2 * test::randomPoint(rng, -1.0, 1.0);
  for (const auto kernel :
       {RbfKernel::Triharmonic, RbfKernel::Biharmonic, RbfKernel::ThinPlate, RbfKernel::Gaussian,
        RbfKernel::InverseMultiquadric, RbfKernel::WendlandC2}) {
    RbfOptions options;
    options.kernel = kernel;
    options.scale = 0.9;
    options.radius = 2.5;
    options.smoothing = kernel == RbfKernel::ThinPlate ? 1e-3 : 0.0;
    const RbfWarp warp(centers, targets, fixed, options);
    const auto coordinates = std::make_shared<const RbfCoordinates>(centers, fixed, options);
    const std::size_t fits = detail::rbfSystemCount();
    EXPECT_TRUE(test::warpRoundTrips(warp)) << rbfKernelName(kernel);
    const auto loaded = loadCoordinates(saveCoordinates(*coordinates));
    EXPECT_EQ(detail::rbfSystemCount(), fits) << "loading fitted again";
    EXPECT_TRUE(test::sameCoordinates(*coordinates, *loaded)) << rbfKernelName(kernel);
    EXPECT_EQ(saveCoordinates(*loaded), saveCoordinates(*coordinates));
  }
}

TEST(WarpArchive, TamperedRbfStateIsRefused) {
  const std::vector<Vec3> centers{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}, {1, 1, 1}};
  const RbfWarp warp(centers, centers);
  std::string bytes = saveWarp(warp);
  // The translation's last component (the archive's last 8 bytes) made NaN.
  const double nan = std::numeric_limits<double>::quiet_NaN();
  std::memcpy(bytes.data() + bytes.size() - 8, &nan, 8);
  EXPECT_THAT(test::messageOf<InvalidInput>([&] { loadWarp(bytes); }),
              HasSubstr("an RBF warp's state is not finite"));
}

// ---- rigs ----

// A rig built from JSON text, with cage files written to a temporary folder.
class RigArchive : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = std::filesystem::temp_directory_path() /
           ("spacewarp_archive_" + std::to_string(::getpid()));
    std::filesystem::create_directories(dir_);
    PolygonSoup rest = test::star();
    writeSoup(rest, dir_ / "rest.obj");
    PolygonSoup posed = rest;
    posed.positions = posedOf(rest.positions);
    writeSoup(posed, dir_ / "posed.obj");
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }

  Rig rig(const std::string& text) {
    return rigFromJson(parseRigJson(text, "rig.json"), dir_, "rig.json");
  }

  // The rig's warp, and its coordinates when it has them, round-trip bit-identically.
  void expectRoundTrips(const std::string& text) {
    const Rig r = rig(text);
    EXPECT_TRUE(test::warpRoundTrips(*r.warp, {}, -3.0, 3.0)) << text;
    if (r.coordinates) {
      EXPECT_TRUE(test::coordinatesRoundTrip(r.coordinates, {}, -3.0, 3.0)) << text;
      // The lazy RBF coordinates have fitted now: their archive holds the fit, loaded as is.
      const auto loaded = loadCoordinates(saveCoordinates(*r.coordinates));
      const std::size_t before = detail::rbfSystemCount();
      std::vector<double> row(loaded->columnCount());
      loaded->weights(Vec3(0.1), row);
      EXPECT_EQ(detail::rbfSystemCount(), before) << text;
    }
  }

  std::filesystem::path dir_;
};

TEST_F(RigArchive, EveryRigOfTheLinearAndAnalyticModulesRoundTrips) {
  expectRoundTrips(R"({"method": "twist", "origin": [0, 0, 0], "axis": [0, 1, 0], "rate": 0.7})");
  expectRoundTrips(
      R"({"method": "bend", "origin": [0, 0, 0], "axis": [0, 0, 1], "direction": [1, 0, 0], "rate": 0.4})");
  expectRoundTrips(R"({"method": "taper", "origin": [0, 0, 0], "axis": [0, 0, 1], "rate": 0.2})");
  expectRoundTrips(
      R"({"method": "affine", "matrix": [[1, 0.1, 0, 0.5], [0, 1, 0, 0], [0, 0, 2, 0], [0, 0, 0, 1]]})");
  expectRoundTrips(R"({"method": "mvc", "cage": "rest.obj", "pose": "posed.obj"})");
  expectRoundTrips(R"({"method": "green", "cage": "rest.obj", "pose": "posed.obj"})");
#ifdef SPACEWARP_HAVE_HARMONIC
  expectRoundTrips(
      R"({"method": "harmonic", "cage": "rest.obj", "pose": "posed.obj", "tets": 2000, "outside": "nearest"})");
#endif
  expectRoundTrips(R"({"method": "ffd", "basis": "bspline", "origin": [-1, -1, -1],
      "size": [2, 2, 2], "resolution": [4, 4, 4],
      "constraints": {"from": [[0, 0, 0], [0.5, 0, 0]], "to": [[0.1, 0, 0], [0.5, 0.2, 0]]}})");
  expectRoundTrips(R"({"method": "rbf", "centers": [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]],
      "targets": [[0, 0, 0.1], [1, 0, 0], [0, 1.2, 0], [0, 0, 1]], "fixed": [[2, 2, 2]]})");
  expectRoundTrips(R"({"method": "compose", "warps": [
      {"method": "twist", "origin": [0, 0, 0], "axis": [0, 1, 0], "rate": 0.7},
      {"method": "mvc", "cage": "rest.obj", "pose": "posed.obj"},
      {"method": "rbf", "centers": [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]],
       "targets": [[0, 0, 0.1], [1, 0, 0], [0, 1.2, 0], [0, 0, 1]]}]})");
}

TEST_F(RigArchive, LazyRbfCoordinatesSavedBeforeTheirFitStayLazy) {
  const Rig r = rig(R"({"method": "rbf", "centers": [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]],
      "targets": [[0, 0, 0.1], [1, 0, 0], [0, 1.2, 0], [0, 0, 1]]})");
  const std::size_t fits = detail::rbfSystemCount();
  const auto loaded = loadCoordinates(saveCoordinates(*r.coordinates));  // neither has fitted
  EXPECT_EQ(detail::rbfSystemCount(), fits);
  EXPECT_TRUE(test::sameCoordinates(*r.coordinates, *loaded));  // both fit now, alike
  EXPECT_EQ(detail::rbfSystemCount(), fits + 2);
}

}  // namespace
}  // namespace spacewarp
