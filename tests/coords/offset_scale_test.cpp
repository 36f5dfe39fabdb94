// Cage coordinates far from the world origin and at any size. Coordinates are invariant under
// similarities, so a cage moved by up to 1e8 and scaled by 1e-3 … 1e3 must give the weights of
// the original cage at the correspondingly moved points, and keep every property relative to
// its size.
//
// The bound: a placed coordinate carries an absolute round-off of ε·(|offset| + size), so the
// input itself is only known to the relative resolution r = ε·(|offset| + size) / size of the
// cage's size (test::placementResolution: ≈ 1e-8 for a unit cage at 1e8, ≈ 2e-5 for a 1e-3
// cage there), and no method can do better than r; 1e-9 at 1e8 is out of reach in double.
// Each method is tested at 1e-11 + K·r, K measured with a margin.

#include <cmath>
#include <functional>
#include <limits>
#include <memory>
#include <ostream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include <spacewarp/coords/cage.h>
#include <spacewarp/coords/green.h>
#include <spacewarp/coords/mean_value.h>
#include <spacewarp/coords/properties.h>
#include "coords_test_shapes.h"
#include "placement.h"
#ifdef SPACEWARP_HAVE_HARMONIC
#include <spacewarp/coords/harmonic.h>
#endif

namespace spacewarp {
namespace {

using test::place;
using test::Placement;

using Factory = std::function<std::shared_ptr<const Coordinates>(std::shared_ptr<const Cage>)>;

struct Method {
  std::string name;
  Factory make;
  double k;  // the tolerance's multiple of the resolution r (see the file comment)
  // Added to the tolerance of the comparison with the cage at the origin: the harmonic
  // coordinates are solved on a TetGen mesh, and TetGen's Delaunay refinement is not stable
  // under round-off (a relative perturbation of 1e-13 of its input gives another mesh), so
  // the placed cage gets another mesh than the cage at the origin, and weights that differ by
  // the discretisation error (0.013–0.022 measured at 3000 tets; the old world-unit solve was
  // off by 0.3 at 1e8). Their properties hold to K·r on any mesh.
  double meshTolerance;
  bool interpolates;  // Lagrange property and linear on faces (not Green)
};

std::vector<Method> methods() {
  std::vector<Method> all = {
      {"mvc", [](auto cage) { return std::make_shared<MeanValueCoordinates>(cage); }, 100.0, 0.0,
       true},
      {"green", [](auto cage) { return std::make_shared<GreenCoordinates>(cage); }, 100.0, 0.0,
       false},
  };
#ifdef SPACEWARP_HAVE_HARMONIC
  all.push_back({"harmonic",
                 [](auto cage) {
                   HarmonicOptions options;
                   options.targetTetCount = 3000;
                   return std::make_shared<HarmonicCoordinates>(cage, options);
                 },
                 100.0, 0.05, true});
#endif
  return all;
}

struct Case {
  Method method;
  Placement placement;
};
void PrintTo(const Case& c, std::ostream* os) {
  *os << c.method.name << " offset " << c.placement.offset << " scale " << c.placement.scale;
}

// A star cage with its vertices moved off every symmetric position (a generic shape: no
// cospherical or coplanar vertex sets that TetGen could resolve either way).
PolygonSoup genericStar() {
  PolygonSoup soup = test::star();
  for (std::size_t i = 0; i < soup.positions.size(); ++i) {
    const double t = static_cast<double>(i);
    soup.positions[i] += 0.05 * Vec3(std::sin(1.3 * t + 0.2), std::cos(2.1 * t), std::sin(0.7 * t));
  }
  return soup;
}

class OffsetScale : public ::testing::TestWithParam<Case> {};

TEST_P(OffsetScale, WeightsMatchTheCageAtTheOriginAndPropertiesHold) {
  const Method& method = GetParam().method;
  const Placement& at = GetParam().placement;
  const PolygonSoup base = genericStar();
  auto baseCage = std::make_shared<const Cage>(base, "star");
  PolygonSoup placedSoup = base;
  for (Vec3& p : placedSoup.positions) p = place(p, at);
  auto placedCage = std::make_shared<const Cage>(placedSoup, "placed star");

  const double resolution = test::placementResolution(at, placedCage->diagonal());
  const double tolerance = 1e-11 + method.k * resolution;

  // The cage's geometry does not depend on where it is.
  EXPECT_NEAR(placedCage->volume() / (at.scale * at.scale * at.scale), baseCage->volume(),
              1e3 * resolution * baseCage->volume());

  const std::vector<Vec3> samples = interiorSamples(*baseCage, 40, 7);
  std::vector<Vec3> placedSamples;
  for (const Vec3& x : samples) placedSamples.push_back(place(x, at));

  const auto reference = method.make(baseCage);
  const auto placed = method.make(placedCage);
  EXPECT_LE(test::placedWeightError(*reference, *placed, samples, at),
            tolerance + method.meshTolerance)
      << "resolution " << resolution;

  const PropertyReport report = measureProperties(*placed, *placedCage, placedSamples);
  EXPECT_LE(report.partitionOfUnity, tolerance);
  EXPECT_LE(report.linearReproduction, tolerance);
  EXPECT_LE(report.similarityReproduction, tolerance);
  if (method.interpolates) {
    EXPECT_LE(report.lagrange, tolerance);
    EXPECT_LE(report.faceInterpolation, tolerance);
  }
}

std::vector<Case> cases() {
  std::vector<Case> all;
  for (const Method& method : methods())
    for (const Placement& at : test::placements()) all.push_back({method, at});
  return all;
}

INSTANTIATE_TEST_SUITE_P(Cages, OffsetScale, ::testing::ValuesIn(cases()),
                         [](const ::testing::TestParamInfo<Case>& info) {
                           return info.param.method.name + "_" +
                                  test::placementName(info.param.placement);
                         });

}  // namespace
}  // namespace spacewarp
