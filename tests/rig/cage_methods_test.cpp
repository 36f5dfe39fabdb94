// The polygon and convex cage methods (qmvc, qgc, wachspress, discrete-harmonic) through every
// name-based entry point: rig/cage_rig.h (the factories, the column counts and the checks known
// before the coordinates are made), the rig JSON of rig/rig.h, and the archive of
// rig/warp_archive.h (bit-identical round trips, as every other Coordinates).

#include <spacewarp/rig/cage_rig.h>

#include <unistd.h>

#include <filesystem>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <spacewarp/coords/discrete_harmonic.h>
#include <spacewarp/coords/quad_green.h>
#include <spacewarp/coords/quad_mean_value.h>
#include <spacewarp/coords/wachspress.h>
#include <spacewarp/core/errors.h>
#include <spacewarp/core/io/mesh_io.h>
#include <spacewarp/core/primitives.h>
#include <spacewarp/rig/rig.h>
#include <spacewarp/rig/warp_archive.h>

#include "coords/convex_test_shapes.h"
#include "coords/coords_test_shapes.h"

#include "rig/archive_test_util.h"
#include "test_util.h"

namespace spacewarp {
namespace {

using ::testing::HasSubstr;

const char* const kNewMethods[] = {"qmvc", "qgc", "wachspress", "discrete-harmonic"};

// The pinched box (concave, planar quads) with its bottom quad cut into two triangles and one
// top vertex lifted, so that its top quad is not planar: triangles, planar and non-planar quads.
std::shared_ptr<const Cage> triQuadCage() {
  PolygonSoup soup = test::pinchedBox(0.6);
  PolygonSoup mixed;
  mixed.positions = soup.positions;
  mixed.positions[9].z += 0.2;
  mixed.addPolygon({3, 2, 1});
  mixed.addPolygon({3, 1, 0});
  for (std::size_t f = 1; f < soup.polygonCount(); ++f) {
    const auto begin = soup.faceIndices.begin() + soup.faceOffsets[f];
    const auto end = soup.faceIndices.begin() + soup.faceOffsets[f + 1];
    mixed.addPolygon(std::vector<std::uint32_t>(begin, end));
  }
  return std::make_shared<const Cage>(mixed, "tri-quad");
}

// Convex, six quads: wachspress takes it, discrete-harmonic (triangles only) does not.
std::shared_ptr<const Cage> cube() {
  return std::make_shared<const Cage>(makeBoxSurface(Vec3(-1.0), Vec3(1.0), {1, 1, 1}), "cube");
}

// Convex, eight triangles (|x| + |y| + |z| <= 3, around the cube [-0.9, 0.9]^3 of test points):
// both convex methods take it.
std::shared_ptr<const Cage> octahedron() {
  PolygonSoup soup = test::octahedron();
  for (Vec3& p : soup.positions) p *= 3.0;
  return std::make_shared<const Cage>(soup, "octahedron");
}

std::vector<Vec3> posedOf(std::span<const Vec3> rest) {
  std::vector<Vec3> posed(rest.begin(), rest.end());
  for (std::size_t i = 0; i < posed.size(); ++i) {
    const double t = static_cast<double>(i);
    posed[i] += 0.2 * Vec3(std::sin(t), std::cos(3.0 * t), std::sin(2.0 * t));
  }
  return posed;
}

// The cage each method is tested on: the concave tri-quad cage, the cube for wachspress, the
// octahedron for discrete-harmonic.
std::shared_ptr<const Cage> cageFor(const std::string& method) {
  if (method == "wachspress") return cube();
  return method == "discrete-harmonic" ? octahedron() : triQuadCage();
}

TEST(CageMethods, TheNewMethodsAreListedByName) {
  const std::vector<std::string> methods = cageMethods();
  for (const char* name : kNewMethods)
    EXPECT_NE(std::find(methods.begin(), methods.end(), name), methods.end()) << name;
  EXPECT_TRUE(std::is_sorted(methods.begin(), methods.end()));
}

// compare sizes its memory check by the columns before it makes the coordinates: they must be
// the coordinates' own columnCount() (qgc: V + triangles + 4 quads; green: V + triangles).
TEST(CageMethods, ColumnsKnownBeforehandAreTheCoordinatesColumns) {
  CageMethodOptions options;
  options.harmonicTets = 2000;
  for (const auto& cage : {triQuadCage(), cube(), octahedron()}) {
    for (const std::string& method : cageMethods()) {
      try {
        checkCageMethodApplies(method, *cage);
      } catch (const InvalidInput&) {
        continue;  // the convex methods on the concave cage, discrete-harmonic on quads: below
      }
      const auto coordinates = cageCoordinates(method, cage, options);
      EXPECT_EQ(cageCoordinatesColumns(method, *cage), coordinates->columnCount())
          << method << " on " << cage->name();
      EXPECT_GT(cageCoordinatesMemory(method, *cage, options), 0.0) << method;
    }
  }
  // The tri-quad cage: 12 vertices, 2 triangles and 9 quads.
  EXPECT_EQ(cageCoordinatesColumns("qgc", *triQuadCage()), 12u + 2u + 4u * 9u);
}

TEST(CageMethods, ConvexMethodsRefuseAConcaveCageNamingItAndAnEdge) {
  // Planar faces, reflex edges around the waist (the tri-quad cage's lifted vertex would be
  // refused first for its non-planar face).
  const auto concave = std::make_shared<const Cage>(test::pinchedBox(0.6), "pinched");
  for (const char* method : {"wachspress", "discrete-harmonic"}) {
    const std::string message =
        test::messageOf<InvalidInput>([&] { checkCageMethodApplies(method, *concave); });
    EXPECT_THAT(message, HasSubstr("pinched")) << method;
    EXPECT_THAT(message, HasSubstr("edge")) << method;
    EXPECT_THROW(cageCoordinates(method, concave), InvalidInput) << method;
    EXPECT_NO_THROW(checkCageMethodApplies(method, *octahedron())) << method;
  }
  for (const char* method : {"mvc", "green", "qmvc", "qgc"}) {
    EXPECT_NO_THROW(checkCageMethodApplies(method, *concave)) << method;
    EXPECT_NO_THROW(checkCageMethodApplies(method, *triQuadCage())) << method;
  }
}

// qmvc and qgc refuse a quad whose bilinear patch folds over (a planar dart) by their CLI names,
// so that compare leaves them out of its default set instead of failing.
TEST(CageMethods, QuadMethodsRefuseAFoldedQuadNamingIt) {
  const auto dart = std::make_shared<const Cage>(test::dartPrism(), "dart");
  for (const char* method : {"qmvc", "qgc"}) {
    const std::string message =
        test::messageOf<InvalidInput>([&] { checkCageMethodApplies(method, *dart); });
    EXPECT_THAT(message,
                HasSubstr(std::string("dart: ") + method + ": face 0 (vertices 3, 2, 1, 0)"));
    EXPECT_THAT(message, HasSubstr("split it into triangles"));
    EXPECT_THROW(cageCoordinates(method, dart), InvalidInput) << method;
  }
  EXPECT_NO_THROW(checkCageMethodApplies("mvc", *dart));
}

// discrete-harmonic takes convex cages of triangles only (polygon faces give its closed form
// poles): the check made before the coordinates (compare's default set, the viewer, checkRig)
// refuses the cube as the constructor does, naming the cage and a quad face; wachspress takes it.
TEST(CageMethods, DiscreteHarmonicRefusesAConvexCageOfQuadsNamingTheFace) {
  const std::string message =
      test::messageOf<InvalidInput>([&] { checkCageMethodApplies("discrete-harmonic", *cube()); });
  EXPECT_THAT(message, HasSubstr("cube"));
  EXPECT_THAT(message, HasSubstr("quad"));
  EXPECT_THAT(message, HasSubstr("triangle faces"));
  // The constructor's refusal, after its own name in place of the method's.
  EXPECT_THAT(test::messageOf<InvalidInput>([&] { cageCoordinates("discrete-harmonic", cube()); }),
              HasSubstr(message.substr(message.find(": "))));
  EXPECT_NO_THROW(checkCageMethodApplies("wachspress", *cube()));
  // The cube's faces cut into triangles merge back into quads: still refused.
  const Cage split(test::triangulated(makeBoxSurface(Vec3(-1.0), Vec3(1.0), {1, 1, 1})), "split");
  EXPECT_THAT(
      test::messageOf<InvalidInput>([&] { checkCageMethodApplies("discrete-harmonic", split); }),
      HasSubstr("coplanar"));
}

TEST(CageMethods, QuadGreenRefusesALargerPolygonNamingTheFace) {
  const Cage prism(test::lPrism(), "l-prism");  // face 0 is a hexagon
  const std::string message =
      test::messageOf<InvalidInput>([&] { checkCageMethodApplies("qgc", prism); });
  EXPECT_THAT(message, HasSubstr("l-prism"));
  EXPECT_THAT(message, HasSubstr("face 0"));
  EXPECT_NO_THROW(checkCageMethodApplies("qmvc", prism));
}

TEST(CageMethods, OutsideOptionReachesTheConvexCoordinates) {
  CageMethodOptions options;
  options.outside = "nearest";
  const auto w = std::dynamic_pointer_cast<const WachspressCoordinates>(
      cageCoordinates("wachspress", cube(), options));
  ASSERT_NE(w, nullptr);
  EXPECT_EQ(w->options().outside, ConvexOutsidePolicy::NearestPoint);
  const auto d = std::dynamic_pointer_cast<const DiscreteHarmonicCoordinates>(
      cageCoordinates("discrete-harmonic", octahedron()));
  ASSERT_NE(d, nullptr);
  EXPECT_EQ(d->options().outside, ConvexOutsidePolicy::Throw);
  options.outside = "sometimes";
  EXPECT_THROW(cageCoordinates("wachspress", cube(), options), InvalidInput);
}

// Every new Coordinates, and its warp, saves and loads bit-identically (convex ones with both
// outside policies; points inside the cube, and so inside the octahedron, where outside points
// are refused).
TEST(CageMethods, ArchivesRoundTripBitIdentically) {
  std::vector<std::shared_ptr<const Coordinates>> all = {
      std::make_shared<const QuadMeanValueCoordinates>(triQuadCage(), QuadMeanValueOptions{1e-12}),
      std::make_shared<const QuadGreenCoordinates>(triQuadCage()),
  };
  for (const auto outside : {ConvexOutsidePolicy::Throw, ConvexOutsidePolicy::NearestPoint}) {
    all.push_back(
        std::make_shared<const WachspressCoordinates>(cube(), WachspressOptions{1e-13, outside}));
    all.push_back(std::make_shared<const DiscreteHarmonicCoordinates>(
        octahedron(), DiscreteHarmonicOptions{1e-13, outside}));
  }
  std::mt19937 rng(20);
  const std::vector<Vec3> inside = test::randomPoints(rng, 200, -0.9, 0.9);
  for (const auto& c : all) {
    EXPECT_TRUE(test::coordinatesRoundTrip(c, inside)) << saveCoordinates(*c).substr(0, 40);
    const auto warp = makeWarp(c, posedOf(c->restControlPoints()));
    EXPECT_TRUE(test::warpRoundTrips(*warp, inside));
  }
  // The options come back: another snap tolerance is another archive.
  const auto a = std::make_shared<const WachspressCoordinates>(cube());
  const auto b = std::make_shared<const WachspressCoordinates>(cube(), WachspressOptions{1e-13});
  EXPECT_NE(saveCoordinates(*a), saveCoordinates(*b));
}

// A rig by name gives the same warp, bit for bit, as the library's class posed by hand.
class CageMethodRigs : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = std::filesystem::temp_directory_path() /
           ("spacewarp_cage_methods_" + std::to_string(::getpid()));
    std::filesystem::create_directories(dir_);
    for (const auto& [name, cage] :
         {std::pair{"tri-quad", triQuadCage()}, {"cube", cube()}, {"octahedron", octahedron()}}) {
      PolygonSoup soup;
      soup.positions.assign(cage->vertices().begin(), cage->vertices().end());
      for (std::size_t f = 0; f < cage->faceCount(); ++f) {
        const auto face = cage->face(f);
        soup.addPolygon(std::vector<std::uint32_t>(face.begin(), face.end()));
      }
      writeSoup(soup, dir_ / (std::string(name) + ".obj"));
      soup.positions = posedOf(soup.positions);
      writeSoup(soup, dir_ / (std::string(name) + "_posed.obj"));
    }
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }

  Rig rig(const std::string& text) {
    return rigFromJson(parseRigJson(text, "rig.json"), dir_, "rig.json");
  }

  std::filesystem::path dir_;
};

TEST_F(CageMethodRigs, EveryNewMethodByRigEqualsTheLibraryBitForBit) {
  std::mt19937 rng(7);
  const std::vector<Vec3> points = test::randomPoints(rng, 300, -0.9, 0.9);
  for (const std::string method : kNewMethods) {
    const std::string file = cageFor(method)->name();
    const Rig r = rig(R"({"method": ")" + method + R"(", "cage": ")" + file +
                      R"(.obj", "pose": ")" + file + R"(_posed.obj"})");
    ASSERT_NE(r.coordinates, nullptr) << method;
    const auto cage = std::make_shared<const Cage>(Cage::fromFile(dir_ / (file + ".obj")));
    const auto own = cageCoordinates(method, cage);
    EXPECT_EQ(saveCoordinates(*r.coordinates), saveCoordinates(*own)) << method;
    const auto warp = makeWarp(own, cage->posedVerticesFromFile(dir_ / (file + "_posed.obj")));
    std::vector<Vec3> byRig(points.size()), byLibrary(points.size());
    r.warp->applyBatch(points, byRig);
    warp->applyBatch(points, byLibrary);
    for (std::size_t i = 0; i < points.size(); ++i)
      ASSERT_TRUE(test::bitEqual(byRig[i], byLibrary[i])) << method << " point " << i;
  }
}

TEST_F(CageMethodRigs, OutsideKeyIsTakenByTheConvexMethodsOnly) {
  const Rig r = rig(
      R"({"method": "wachspress", "cage": "cube.obj", "pose": "cube_posed.obj", "outside": "nearest"})");
  const auto& w = dynamic_cast<const WachspressCoordinates&>(*r.coordinates);
  EXPECT_EQ(w.options().outside, ConvexOutsidePolicy::NearestPoint);
  EXPECT_THAT(
      test::messageOf<InvalidInput>([&] {
        rig(R"({"method": "discrete-harmonic", "cage": "octahedron.obj", "pose": "octahedron_posed.obj", "outside": "far"})");
      }),
      HasSubstr("outside"));
  EXPECT_THAT(
      test::messageOf<InvalidInput>([&] {
        rig(R"({"method": "qmvc", "cage": "tri-quad.obj", "pose": "tri-quad_posed.obj", "outside": "nearest"})");
      }),
      HasSubstr("outside"));
  // Checking a rig (no coordinates made) already refuses a concave cage for wachspress.
  EXPECT_THAT(
      test::messageOf<InvalidInput>([&] {
        checkRig(
            parseRigJson(
                R"({"method": "wachspress", "cage": "tri-quad.obj", "pose": "tri-quad_posed.obj"})",
                "rig.json"),
            dir_, "rig.json");
      }),
      HasSubstr("tri-quad.obj"));
  // ... and the cube of quads for discrete-harmonic, naming the file and the face.
  const std::string quads = test::messageOf<InvalidInput>([&] {
    checkRig(parseRigJson(
                 R"({"method": "discrete-harmonic", "cage": "cube.obj", "pose": "cube_posed.obj"})",
                 "rig.json"),
             dir_, "rig.json");
  });
  EXPECT_THAT(quads, HasSubstr("cube.obj"));
  EXPECT_THAT(quads, HasSubstr("triangle faces"));
}

}  // namespace
}  // namespace spacewarp
