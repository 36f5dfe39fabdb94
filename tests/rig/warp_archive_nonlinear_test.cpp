// The warp archive for the warps, coordinates and distances of nonlinear/ and volume/: every
// class saved and loaded gives the very same bits (applyBatch, jacobian, weights) and the same
// refusals; solved state (graph maps, marched distance grids) is taken from the archive, not
// solved again; hostile archives are refused as bad parameters are; every rig method of these
// modules round-trips.

#include <spacewarp/rig/warp_archive.h>

#include <bit>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <spacewarp/core/archive.h>
#include <spacewarp/core/coordinates.h>
#include <spacewarp/core/errors.h>
#include <spacewarp/core/io/mesh_io.h>
#include <spacewarp/core/primitives.h>
#include <spacewarp/nonlinear/deformation_graph.h>
#include <spacewarp/nonlinear/kelvinlet.h>
#include <spacewarp/nonlinear/mls.h>
#include <spacewarp/nonlinear/shepard.h>
#include <spacewarp/nonlinear/skinning.h>
#include <spacewarp/nonlinear/wires.h>
#include <spacewarp/rig/rig.h>
#ifdef SPACEWARP_WITH_OPENVDB
#include <spacewarp/volume/inside_distance.h>
#endif
#include "rig/archive_test_util.h"
#include "test_util.h"

namespace spacewarp {
namespace {

using ::testing::HasSubstr;
using ::testing::StartsWith;

bool sameBits(const Vec3& a, const Vec3& b) { return std::memcmp(&a, &b, sizeof a) == 0; }

// Points around [-1.5, 1.5]^3, where the test rigs live.
std::vector<Vec3> probes(std::size_t n = 300, unsigned seed = 7) {
  std::mt19937 rng(seed);
  return test::randomPoints(rng, n, -1.5, 1.5);
}

void expectRoundTrip(const Warp& warp, const std::vector<Vec3>& points = probes()) {
  EXPECT_TRUE(test::warpRoundTrips(warp, points));
}

void expectCoordinatesRoundTrip(std::shared_ptr<const Coordinates> c,
                                const std::vector<Vec3>& points = probes()) {
  EXPECT_TRUE(test::coordinatesRoundTrip(std::move(c), points));
}

// The archive with the f64 of value `from` (its first occurrence after `after`) replaced by `to`.
std::string replaceDouble(std::string bytes, double from, double to, std::size_t after = 0) {
  char f[8], t[8];
  std::memcpy(f, &from, 8);
  std::memcpy(t, &to, 8);
  const std::size_t at = bytes.find(std::string_view(f, 8), after);
  EXPECT_NE(at, std::string::npos);
  if (at != std::string::npos) std::memcpy(bytes.data() + at, t, 8);
  return bytes;
}

std::string loadError(const std::string& bytes) {
  return test::messageOf<InvalidInput>([&] { loadWarp(bytes); });
}

// ---- MLS ----

TEST(WarpArchiveNonlinear, MlsEveryModeRoundTrips) {
  std::mt19937 rng(1);
  const test::HandleRig rig = test::randomHandleRig(rng, 9);
  for (const MlsMode mode : {MlsMode::Affine, MlsMode::Similarity, MlsMode::Rigid}) {
    for (const double alpha : {1.0, 0.75, 2.0}) {
      SCOPED_TRACE(mlsModeName(mode) + " alpha " + std::to_string(alpha));
      MlsOptions options;
      options.mode = mode;
      options.alpha = alpha;
      std::vector<Vec3> points = probes();
      points.push_back(rig.handles[3]);  // the pinned limit fit
      expectRoundTrip(MlsWarp(rig.handles, rig.targets, options), points);
    }
  }
}

TEST(WarpArchiveNonlinear, MlsArchiveIsRefusedAsItsParametersWouldBe) {
  std::mt19937 rng(2);
  const test::HandleRig rig = test::randomHandleRig(rng, 6);
  const std::string bytes = saveWarp(MlsWarp(rig.handles, rig.targets));
  // alpha = 1 becomes -1: the constructor's own message, after the archive's tag and byte.
  const std::string message = loadError(replaceDouble(bytes, 1.0, -1.0));
  EXPECT_THAT(message, HasSubstr("alpha must be finite and > 0"));
  EXPECT_EQ(message, "warp archive: mls at byte 29: " + test::messageOf<InvalidInput>([&] {
                       MlsWarp(rig.handles, rig.targets, MlsOptions{MlsMode::Rigid, -1.0, nullptr});
                     }));
  // A truncated archive names where it ends.
  EXPECT_THAT(loadError(bytes.substr(0, bytes.size() - 3)), StartsWith("warp archive: "));
}

TEST(WarpArchiveNonlinear, MlsAffineCoordinatesRoundTrip) {
  std::mt19937 rng(3);
  const test::HandleRig rig = test::randomHandleRig(rng, 7);
  for (const double alpha : {1.0, 1.5}) {
    const auto coordinates = std::make_shared<const MlsAffineCoordinates>(rig.handles, alpha);
    std::vector<Vec3> points = probes();
    points.push_back(rig.handles[0]);
    expectCoordinatesRoundTrip(coordinates, points);
    // Its warp (CoordinateWarp over the nested coordinates) too.
    expectRoundTrip(*makeWarp(coordinates, rig.targets), points);
  }
}

// ---- deformation graph ----

// A graph over random points with handles moved by an unconverged solve: one Gauss-Newton step.
struct SolvedGraph {
  std::unique_ptr<DeformationGraph> graph;
  std::vector<Vec3> handles, targets;
};

SolvedGraph oneStepGraph() {
  std::mt19937 rng(4);
  const std::vector<Vec3> positions = test::randomPoints(rng, 2000, -1.0, 1.0);
  SolvedGraph g;
  g.graph = std::make_unique<DeformationGraph>(positions, DeformationGraphOptions{0.4, 4});
  const test::HandleRig rig = test::randomHandleRig(rng, 6);
  g.handles = rig.handles;
  g.targets = rig.targets;
  DeformationGraphSolveOptions once;
  once.maxIterations = 1;
  const DeformationGraphReport report = g.graph->solve(g.handles, g.targets, once);
  EXPECT_FALSE(report.converged);
  return g;
}

TEST(WarpArchiveNonlinear, DeformationGraphRoundTripsItsSolvedStateWithoutSolving) {
  SolvedGraph g = oneStepGraph();
  const DeformationGraphWarp warp = g.graph->warp();
  std::vector<Vec3> points = probes();
  points.push_back(Vec3(1e200, 0.0, 0.0));  // out of reach: refused alike
  expectRoundTrip(warp, points);
  // The archive holds no handles or targets, so the loaded warp could only re-solve from
  // nothing; and a converged solve (what re-solving would give) is another warp.
  const std::string bytes = saveWarp(warp);
  for (const Vec3& h : g.handles) {
    char raw[24];
    std::memcpy(raw, &h, sizeof raw);
    EXPECT_EQ(bytes.find(std::string_view(raw, sizeof raw)), std::string::npos);
  }
  g.graph->solve(g.handles, g.targets);
  const Vec3 probe = g.handles[0];
  EXPECT_FALSE(sameBits(g.graph->warp().apply(probe), loadWarp(bytes)->apply(probe)));
}

TEST(WarpArchiveNonlinear, DeformationGraphTakesTheMapsFromTheArchive) {
  SolvedGraph g = oneStepGraph();
  const DeformationGraphWarp warp = g.graph->warp();
  const std::size_t last = g.graph->nodeCount() - 1;
  const Vec3 node = g.graph->nodes()[last];
  const Vec3 t = g.graph->translations()[last];
  // The last translation is the archive's last 24 bytes: moved by 1 along x.
  std::string bytes = saveWarp(warp);
  const Vec3 moved = t + Vec3(1.0, 0.0, 0.0);
  std::memcpy(bytes.data() + bytes.size() - sizeof(Vec3), &moved, sizeof(Vec3));
  const auto loaded = loadWarp(bytes);
  const NodeWeights w = g.graph->weights(node);
  ASSERT_EQ(w.nodes[0], last);
  EXPECT_NEAR(loaded->apply(node).x - warp.apply(node).x, w.weights[0], 1e-12);
  // Far from that node nothing changed, bit for bit.
  const Vec3 far = -node;
  for (const std::uint32_t n : g.graph->weights(far).nodes) ASSERT_NE(n, last);
  EXPECT_TRUE(sameBits(loaded->apply(far), warp.apply(far)));
  // A map that is not finite is refused, naming the node.
  const Vec3 nan(std::nan(""), 0.0, 0.0);
  std::memcpy(bytes.data() + bytes.size() - sizeof(Vec3), &nan, sizeof(Vec3));
  EXPECT_THAT(loadError(bytes),
              HasSubstr("the map of node " + std::to_string(last) + " is not finite"));
}

TEST(WarpArchiveNonlinear, DeformationGraphRefusesABadK) {
  SolvedGraph g = oneStepGraph();
  std::string bytes = saveWarp(g.graph->warp());
  // k is the i32 right after the tag; the header and tag lengths come first, so find it as the
  // first 4-byte 4 after the tag's text.
  const std::size_t tag = bytes.find("deformation-graph");
  ASSERT_NE(tag, std::string::npos);
  const std::size_t at = tag + std::string("deformation-graph").size();
  std::int32_t k = 0;
  std::memcpy(&k, bytes.data() + at, 4);
  ASSERT_EQ(k, 4);
  const std::int32_t huge = 1 << 30;
  std::memcpy(bytes.data() + at, &huge, 4);
  EXPECT_THAT(loadError(bytes), HasSubstr("needs at least k + 1 = 1073741825 nodes"));
}

// ---- wires ----

TEST(WarpArchiveNonlinear, WiresRoundTrip) {
  Wire a;
  a.rest = {{-1.0, 0.0, 0.0}, {0.0, 0.2, 0.0}, {1.0, 0.0, 0.1}};
  a.deformed = {{-1.0, 0.3, 0.0}, {0.0, 0.6, 0.2}, {1.0, 0.2, 0.4}};
  a.radius = 1.2;
  a.innerRadius = 0.2;
  a.scale = 1.3;
  a.curve = WireCurve::CatmullRom;
  Wire b;
  b.rest = {{0.0, -1.0, 0.5}, {0.0, 1.0, 0.5}};
  b.deformed = {{0.2, -1.0, 0.7}, {-0.1, 1.0, 0.4}};
  b.radius = 0.8;
  b.dropoff = WireDropoff::Linear;
  expectRoundTrip(WiresWarp({a}));
  expectRoundTrip(WiresWarp({a, b}, WiresOptions{2.0}));
  // A wire's radius made negative is refused as the constructor refuses it.
  const std::string bytes = saveWarp(WiresWarp({a}));
  EXPECT_THAT(loadError(replaceDouble(bytes, 1.2, -1.2)), HasSubstr("wire 0"));
}

// ---- Kelvinlets ----

TEST(WarpArchiveNonlinear, KelvinletEveryBrushFalloffAndStepsRoundTrips) {
  KelvinletOptions base;
  base.center = Vec3(0.1, -0.2, 0.3);
  base.radius = 0.7;
  base.poisson = 0.3;
  std::vector<KelvinletOptions> brushes;
  KelvinletOptions grab = base;
  grab.displacement = Vec3(0.3, 0.1, -0.2);
  brushes.push_back(grab);
  KelvinletOptions twist = base;
  twist.brush = KelvinletBrush::Twist;
  twist.axis = Vec3(1.0, 2.0, 0.5);
  twist.angle = 0.8;
  brushes.push_back(twist);
  KelvinletOptions scale = base;
  scale.brush = KelvinletBrush::Scale;
  scale.factor = 1.4;
  brushes.push_back(scale);
  KelvinletOptions pinch = base;
  pinch.brush = KelvinletBrush::Pinch;
  pinch.matrix = Mat3(0.0);
  pinch.matrix[0][0] = 0.3;
  pinch.matrix[1][1] = -0.3;
  pinch.matrix[0][1] = pinch.matrix[1][0] = 0.1;
  brushes.push_back(pinch);
  for (KelvinletOptions o : brushes) {
    for (const KelvinletFalloff falloff :
         {KelvinletFalloff::Single, KelvinletFalloff::Bi, KelvinletFalloff::Tri}) {
      for (const int steps : {1, 3}) {
        o.falloff = falloff;
        o.steps = steps;
        SCOPED_TRACE(kelvinletBrushName(o.brush) + " " + kelvinletFalloffName(falloff));
        expectRoundTrip(KelvinletWarp(o), probes(200));
      }
    }
  }
  // steps = 1 made 0 is the constructor's refusal; a brush enumerator past Pinch is the
  // archive's.
  KelvinletOptions odd = grab;
  odd.steps = 7;
  std::string bytes = saveWarp(KelvinletWarp(odd));
  const std::int32_t seven = 7, zero = 0;
  const std::size_t at = bytes.rfind(std::string_view(reinterpret_cast<const char*>(&seven), 4));
  ASSERT_EQ(at, bytes.size() - 4);
  std::string noSteps = bytes;
  std::memcpy(noSteps.data() + at, &zero, 4);
  EXPECT_THAT(loadError(noSteps), HasSubstr("steps must be in 1..10000, not 0"));
  const std::size_t tag = bytes.find("kelvinlet") + std::string("kelvinlet").size();
  bytes[tag] = 4;  // the brush's u32, little-endian
  EXPECT_THAT(loadError(bytes), StartsWith("warp archive: "));
}

// ---- Shepard ----

TEST(WarpArchiveNonlinear, ShepardCoordinatesAndWarpRoundTrip) {
  std::mt19937 rng(5);
  const test::HandleRig rig = test::randomHandleRig(rng, 12);
  for (const ShepardOptions options :
       {ShepardOptions{}, ShepardOptions{1.0, 0.9},
        ShepardOptions{3.0, std::numeric_limits<double>::infinity()}}) {
    const auto coordinates = std::make_shared<const ShepardCoordinates>(rig.handles, options);
    std::vector<Vec3> points = probes();
    points.push_back(rig.handles[2]);
    expectCoordinatesRoundTrip(coordinates, points);
    const auto warp = makeWarp(coordinates, rig.targets);
    ASSERT_TRUE(dynamic_cast<const ShepardWarp*>(warp.get()));
    // With a radius, some probes have no handle in reach: refused alike.
    expectRoundTrip(*warp, points);
  }
}

TEST(WarpArchiveNonlinear, ShepardWarpRefusesDisplacementsThatAreNotFinite) {
  const std::vector<Vec3> handles = {{0.1, 0.0, 0.0}, {1.0, 0.3, 0.0}, {0.0, 1.0, 0.7}};
  const std::vector<Vec3> targets = {{0.3, 1e-17, 0.0}, {1.1, 0.3, 0.2}, {0.0, 1.0 / 3.0, 0.7}};
  expectRoundTrip(ShepardWarp(handles, targets));
  const ShepardWarp warp(handles, targets);
  const double d = targets[2].y - handles[2].y;
  EXPECT_THAT(loadError(replaceDouble(saveWarp(warp), d, std::nan(""))),
              HasSubstr("displacement 2 is not finite"));
}

// ---- skinning ----

std::vector<Mat4> twoBones(double angle) {
  Mat4 turned(test::rotation(Vec3(0.0, 0.0, 1.0), angle));
  turned[3] = glm::dvec4(0.1, 0.2, 0.0, 1.0);
  return {Mat4(1.0), turned};
}

TEST(WarpArchiveNonlinear, SkinningFromModelWeightsRoundTrips) {
  std::mt19937 rng(6);
  const std::vector<Vec3> model = test::randomPoints(rng, 300, -1.0, 1.0);
  std::vector<double> rows;
  for (const Vec3& p : model) {
    const double w = 0.5 + 0.5 * std::tanh(3.0 * p.z);
    rows.push_back(1.0 - w);
    rows.push_back(w);
  }
  const SkinningWeights weights = sparseSkinningWeights(rows, 2);
  for (const SkinningMode mode : {SkinningMode::Linear, SkinningMode::DualQuaternion}) {
    SCOPED_TRACE(skinningModeName(mode));
    const SkinningWarp warp(twoBones(2.5), model, weights, mode);
    std::vector<Vec3> points = probes();
    points.push_back(Vec3(std::nan(""), 0.0, 0.0));  // refused alike
    expectRoundTrip(warp, points);
  }
  // Weights cut short are refused.
  const std::string bytes =
      saveWarp(SkinningWarp(twoBones(1.0), model, weights, SkinningMode::Linear));
  EXPECT_THAT(loadError(bytes.substr(0, bytes.size() - 1)), StartsWith("warp archive: "));
}

TEST(WarpArchiveNonlinear, SkinningFromCoordinatesRoundTrips) {
  const std::vector<Vec3> handles = {{-1.0, 0.0, -1.0}, {1.0, 0.0, 1.0}};
  const auto shepard = std::make_shared<const ShepardCoordinates>(handles);
  for (const SkinningMode mode : {SkinningMode::Linear, SkinningMode::DualQuaternion}) {
    for (const std::size_t influences : {std::size_t{0}, std::size_t{1}}) {
      SCOPED_TRACE(skinningModeName(mode) + " " + std::to_string(influences));
      expectRoundTrip(SkinningWarp(twoBones(2.0), shepard, SkinningOptions{mode, influences}));
    }
  }
  std::mt19937 rng(8);
  const test::HandleRig rig = test::randomHandleRig(rng, 5);
  std::vector<Mat4> bones(5, Mat4(1.0));
  bones[4][3] = glm::dvec4(0.2, 0.0, 0.1, 1.0);
  expectRoundTrip(SkinningWarp(bones, std::make_shared<const MlsAffineCoordinates>(rig.handles)));
}

// ---- distances inside a model ----

#ifdef SPACEWARP_WITH_OPENVDB

// Two fingers on a palm (a U of unit cells), handles at the finger tips and the palm.
struct Fingers {
  PolygonSoup model;
  std::vector<Vec3> handles, targets;
};

Fingers fingers() {
  std::vector<glm::ivec3> cells;
  for (int x = 0; x <= 4; ++x) cells.emplace_back(x, 0, 0);
  for (int y = 1; y <= 4; ++y) {
    cells.emplace_back(0, y, 0);
    cells.emplace_back(4, y, 0);
  }
  const double cell = 0.25;
  Fingers f;
  f.model = makeBlocksSurface(cells, Vec3(0.0), cell);
  for (const Vec3 h : {Vec3(0.5, 4.5, 0.5), Vec3(0.5, 0.5, 0.5), Vec3(2.5, 0.5, 0.8),
                       Vec3(4.5, 0.5, 0.5), Vec3(4.5, 4.5, 0.5)})
    f.handles.push_back(h * cell);
  f.targets = f.handles;
  f.targets[0].x += 1.5 * cell;
  return f;
}

TEST(WarpArchiveNonlinear, MlsWithInsideDistancesRoundTripsWithoutTheModel) {
  const Fingers f = fingers();
  auto distances =
      std::make_shared<const InsideDistances>(f.model, f.handles, InsideDistanceOptions{0.05});
  MlsOptions options;
  options.distances = distances;
  const MlsWarp warp(f.handles, f.targets, options);
  std::mt19937 rng(10);
  std::vector<Vec3> points = test::randomPoints(rng, 400, -0.2, 1.5);
  points.push_back(f.handles[1]);
  points.push_back(Vec3(9.0, -3.0, 2.0));  // outside the grid
  expectRoundTrip(warp, points);
  // The grids are stored as floats: 4 bytes a voxel and handle, and little else.
  const std::array<int, 3> dims = distances->gridSize();
  const std::size_t values = std::size_t(dims[0]) * dims[1] * dims[2] * f.handles.size();
  const std::string bytes = saveWarp(warp);
  EXPECT_GT(bytes.size(), 4 * values);
  EXPECT_LT(bytes.size(), 4 * values + 1024);
}

TEST(WarpArchiveNonlinear, InsideDistancesAloneRoundTripBitIdentically) {
  const Fingers f = fingers();
  const InsideDistances distances(f.model, f.handles, InsideDistanceOptions{0.05});
  const std::string bytes = saveDistances(distances);
  const auto loaded = std::dynamic_pointer_cast<const InsideDistances>(loadDistances(bytes));
  ASSERT_TRUE(loaded);
  EXPECT_EQ(loaded->gridSize(), distances.gridSize());
  EXPECT_EQ(saveDistances(*loaded), bytes);
  std::mt19937 rng(12);
  const std::size_t n = f.handles.size();
  std::vector<double> a(n), b(n);
  for (const Vec3& p : test::randomPoints(rng, 200, -0.2, 1.5)) {
    distances.distances(p, a);
    loaded->distances(p, b);
    for (std::size_t k = 0; k < n; ++k)
      ASSERT_EQ(std::bit_cast<std::uint64_t>(a[k]), std::bit_cast<std::uint64_t>(b[k]));
  }
  EXPECT_THAT(test::messageOf<InvalidInput>([&] { loadWarp(bytes); }),
              HasSubstr("is handle distances (loadDistances, spacewarp.distances_from_bytes)"));
}

TEST(WarpArchiveNonlinear, InsideDistancesAreTakenFromTheArchiveNotMarched) {
  const Fingers f = fingers();
  auto distances =
      std::make_shared<const InsideDistances>(f.model, f.handles, InsideDistanceOptions{0.05});
  MlsOptions options;
  options.distances = distances;
  std::string bytes = saveWarp(MlsWarp(f.handles, f.targets, options));
  // The archive's last float is the last handle's distance at the grid's far corner voxel,
  // which every point beyond that corner reads (plus its way out to it). Raised by 1 there, the
  // loaded distances show it: they are the archive's values, not marched again from a model.
  float last = 0.0f;
  std::memcpy(&last, bytes.data() + bytes.size() - 4, 4);
  const float raised = last + 1.0f;
  std::memcpy(bytes.data() + bytes.size() - 4, &raised, 4);
  const auto loaded = std::dynamic_pointer_cast<const MlsWarp>(loadWarp(bytes));
  ASSERT_TRUE(loaded);
  const HandleDistances& stored = *loaded->options().distances;
  const std::size_t n = f.handles.size();
  std::vector<double> a(n), b(n);
  const Vec3 beyond = boundingBox(f.model.positions).max + Vec3(10.0);
  distances->distances(beyond, a);
  stored.distances(beyond, b);
  for (std::size_t k = 0; k + 1 < n; ++k) EXPECT_EQ(a[k], b[k]) << k;
  EXPECT_NEAR(b[n - 1] - a[n - 1], double(raised) - double(last), 1e-12);
  EXPECT_GT(b[n - 1] - a[n - 1], 0.5);
}

TEST(WarpArchiveNonlinear, InsideDistancesRefuseBadGrids) {
  const Fingers f = fingers();
  MlsOptions options;
  options.distances =
      std::make_shared<const InsideDistances>(f.model, f.handles, InsideDistanceOptions{0.05});
  const std::string bytes = saveWarp(MlsWarp(f.handles, f.targets, options));
  const std::array<int, 3> dims =
      dynamic_cast<const InsideDistances&>(*options.distances).gridSize();
  // A negative distance.
  std::string negative = bytes;
  const float minus = -1.0f;
  std::memcpy(negative.data() + negative.size() - 4, &minus, 4);
  EXPECT_THAT(loadError(negative), HasSubstr("finite and >= 0 expected"));
  // The voxel size made 0.
  EXPECT_THAT(loadError(replaceDouble(bytes, 0.05, 0.0)), HasSubstr("voxel size 0"));
  // A value count that does not match the grid: the grid's x count one larger.
  const std::size_t tag = bytes.find("inside-distances");
  ASSERT_NE(tag, std::string::npos);
  const std::size_t at =
      bytes.find(std::string_view(reinterpret_cast<const char*>(dims.data()), 12), tag);
  ASSERT_NE(at, std::string::npos);
  std::string wrong = bytes;
  const std::int32_t more = dims[0] + 1;
  std::memcpy(wrong.data() + at, &more, 4);
  EXPECT_THAT(loadError(wrong), HasSubstr("values for a grid of"));
  // A huge grid with few values allocates nothing and is refused.
  const std::int32_t huge = 1 << 30;
  for (int a = 0; a < 3; ++a) std::memcpy(wrong.data() + at + 4 * a, &huge, 4);
  EXPECT_THAT(loadError(wrong), HasSubstr("values for a grid of"));
}

#endif  // SPACEWARP_WITH_OPENVDB

// ---- every rig method of these modules ----

std::filesystem::path rigDirectory() {
  const std::filesystem::path dir =
      std::filesystem::temp_directory_path() / "spacewarp_archive_nonlinear_rigs";
  std::filesystem::create_directories(dir);
  return dir;
}

nlohmann::json jsonPoints(const std::vector<Vec3>& points) {
  nlohmann::json a = nlohmann::json::array();
  for (const Vec3& p : points) a.push_back({p.x, p.y, p.z});
  return a;
}

TEST(WarpArchiveNonlinear, EveryRigMethodOfTheseModulesRoundTrips) {
  std::mt19937 rng(11);
  const test::HandleRig rig = test::randomHandleRig(rng, 8);
  const nlohmann::json handles = jsonPoints(rig.handles), targets = jsonPoints(rig.targets);
  const nlohmann::json identity = {{1, 0, 0, 0}, {0, 1, 0, 0}, {0, 0, 1, 0}, {0, 0, 0, 1}};
  const nlohmann::json turned = {{0, -1, 0, 0.1}, {1, 0, 0, 0}, {0, 0, 1, 0}, {0, 0, 0, 1}};
  const nlohmann::json bones = {identity, identity, turned, turned};
  const nlohmann::json fourHandles = {{-1, 0, -1}, {1, 0, -1}, {0, -1, 1}, {0, 1, 1}};
  std::vector<std::pair<std::string, nlohmann::json>> rigs = {
      {"mls", {{"method", "mls"}, {"handles", handles}, {"targets", targets}}},
      {"mls affine",
       {{"method", "mls"}, {"mode", "affine"}, {"handles", handles}, {"targets", targets}}},
      {"idw", {{"method", "idw"}, {"handles", handles}, {"targets", targets}}},
      {"idw local",
       {{"method", "idw"}, {"radius", 1.5}, {"handles", handles}, {"targets", targets}}},
      {"graph",
       {{"method", "graph"}, {"spacing", 0.5}, {"handles", handles}, {"targets", targets}}},
      {"wires",
       {{"method", "wires"},
        {"wires",
         {{{"rest", {{0, 0, -1}, {0, 0, 0}, {0, 0, 1}}},
           {"deformed", {{0, 0, -1}, {0.3, 0, 0}, {0.2, 0.2, 1}}},
           {"curve", "catmull-rom"},
           {"radius", 1.5},
           {"innerRadius", 0.3}}}}}},
      {"kelvinlet",
       {{"method", "kelvinlet"},
        {"brush", "twist"},
        {"center", {0, 0, 0.5}},
        {"radius", 1.0},
        {"axis", {0, 0, 1}},
        {"angle", 1.0},
        {"falloff", "bi"}}},
      {"kelvinlet compose",
       {{"method", "compose"},
        {"warps",
         {{{"method", "kelvinlet"},
           {"brush", "grab"},
           {"center", {0, 0, 1}},
           {"radius", 1.0},
           {"displacement", {0.5, 0, 0}}},
          {{"method", "kelvinlet"},
           {"brush", "scale"},
           {"center", {0, 0, -1}},
           {"radius", 1.0},
           {"factor", 1.3},
           {"steps", 4}}}}}},
  };
  for (const std::string coordinates : {"rbf", "mls-affine", "idw"}) {
    for (const std::string mode : {"lbs", "dqs"}) {
      rigs.push_back({"skinning " + coordinates + " " + mode,
                      {{"method", "skinning"},
                       {"mode", mode},
                       {"bones", bones},
                       {"handles", fourHandles},
                       {"coordinates", coordinates}}});
    }
  }
#ifdef SPACEWARP_WITH_OPENVDB
  const Fingers f = fingers();
  const std::filesystem::path dir = rigDirectory();
  writeSoup(f.model, dir / "fingers.obj");
  rigs.push_back({"mls inside",
                  {{"method", "mls"},
                   {"distance", "inside"},
                   {"model", "fingers.obj"},
                   {"voxelSize", 0.05},
                   {"handles", jsonPoints(f.handles)},
                   {"targets", jsonPoints(f.targets)}}});
#endif
  for (const auto& [name, json] : rigs) {
    SCOPED_TRACE(name);
    const Rig built = rigFromJson(json, rigDirectory(), name);
    expectRoundTrip(*built.warp);
    if (built.coordinates) expectCoordinatesRoundTrip(built.coordinates);
  }
}

}  // namespace
}  // namespace spacewarp
