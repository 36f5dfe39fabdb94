// spacewarp demo DIR: the README's main job. Builds procedural inputs (a detailed polygon
// soup, a point cloud, and controls around them: a cage, a lattice, handles), deforms them
// with every method through rigs written next to them (exactly as `spacewarp deform --rig`
// would), and compares the cage coordinate functions on a slice.

#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <map>
#include <numbers>
#include <stdexcept>
#include <string>
#include <utility>

#include <spacewarp/coords/cage.h>
#include <spacewarp/core/errors.h>
#include <spacewarp/core/io/mesh_io.h>
#include <spacewarp/core/primitives.h>
#include <spacewarp/rig/cage_rig.h>
#include <spacewarp/rig/rig.h>
#include "apps/commands.h"
#include "apps/compare.h"
#include "apps/edit_command.h"
#include "apps/jobs.h"
#include "apps/volume_command.h"

namespace spacewarp::cli {

namespace {

namespace fs = std::filesystem;
using nlohmann::json;

json points(std::span<const Vec3> ps) {
  json array = json::array();
  for (const Vec3& p : ps) array.push_back({p.x, p.y, p.z});
  return array;
}

// The pose every control-based method is given: the bar sways sideways and turns, more
// towards the top (z = 2), so all their results can be compared with each other.
Vec3 sway(const Vec3& p) {
  const double t = std::clamp((p.z + 2.25) / 4.5, 0.0, 1.0);  // 0 at the bottom, 1 at the top
  const double angle = 0.6 * t;
  return Vec3(std::cos(angle) * p.x - std::sin(angle) * p.y + 0.8 * t * t,
              std::sin(angle) * p.x + std::cos(angle) * p.y, p.z);
}

// The procedural inputs every rig deforms: a detailed bar (polygon soup), a point cloud in the
// same box and, where volumes are supported, the bar's level set.
struct DemoInputs {
  PolygonSoup bar;
  PointSet cloud;
  std::vector<std::string> files;  // file names in the demo folder
};

// The controls around the inputs, all posed by sway().
struct DemoControls {
  PolygonSoup cage;            // pinched (concave), quads
  PolygonSoup convexCage;      // the box unpinched, quads
  PolygonSoup simplicialCage;  // a capped hexagonal antiprism, triangles
  Vec3 boxLo, boxHi;           // the lattice's box
  std::array<int, 3> resolution{3, 3, 5};
  std::vector<Vec3> lattice;  // posed control points
  std::vector<Vec3> handles, targets;
};

const Vec3 kBarLo(-0.5, -0.5, -2.0), kBarHi(0.5, 0.5, 2.0);

DemoInputs writeInputs(const fs::path& dir) {
  DemoInputs inputs;
  inputs.bar = makeBoxSurface(kBarLo, kBarHi, {24, 24, 96});
  inputs.cloud = makeRandomPoints(kBarLo, kBarHi, 20000, 7);
  PolygonSoup cloudSoup;
  static_cast<PointSet&>(cloudSoup) = inputs.cloud;
  writeSoup(inputs.bar, dir / "bar.obj");
  writeSoup(cloudSoup, dir / "cloud.ply");
  inputs.files = {"bar.obj", "cloud.ply"};
  if (volumesSupported()) {
    writeMeshLevelSet(inputs.bar, 0.04, dir / "bar.vdb");  // the bar's level set, 0.04 voxels
    inputs.files.push_back("bar.vdb");
  }
  return inputs;
}

// Writes NAME.obj and its pose by sway(), NAME_pose.obj.
void writePosed(PolygonSoup soup, const fs::path& dir, const std::string& name) {
  writeSoup(soup, dir / (name + ".obj"));
  for (Vec3& p : soup.positions) p = sway(p);
  writeSoup(soup, dir / (name + "_pose.obj"));
}

DemoControls writeControls(const fs::path& dir) {
  DemoControls controls;
  // A cage around the bar with a pinched waist (so it is concave, where coordinate functions
  // differ most), and its swayed pose. It clears the volume's narrow band (3 voxels of 0.04)
  // everywhere, so every voxel is warped by the cage's interior coordinates.
  PolygonSoup& cage = controls.cage;
  cage = makeBoxSurface(kBarLo - 0.2, kBarHi + 0.2, {1, 1, 4});
  for (Vec3& p : cage.positions)
    if (std::abs(p.z) < 1e-9) p.x *= 0.9, p.y *= 0.9;
  writePosed(cage, dir, "cage");
  // The same box unpinched and undivided (every vertex a corner), for wachspress, which needs a
  // convex cage.
  controls.convexCage = makeBoxSurface(kBarLo - 0.2, kBarHi + 0.2, {1, 1, 1});
  writePosed(controls.convexCage, dir, "convex_cage");
  // discrete-harmonic needs a convex cage of triangles (a box's quads are refused): two rings of
  // six vertices on the ellipsoid (x² + y²)/1.4² + z²/3.5² = 1 at z = ±1.75, the upper turned by
  // 30°, joined by a band of triangles and capped by apexes at z = ±3.5: 14 vertices, 24
  // triangles (the points' convex hull, no two faces coplanar). Its faces clear the bar by 0.19.
  // With the rings, its interpolation of the sway along the bar is closer than a bipyramid's
  // (max |x' − sway(x)| over the bar 0.14 against 0.42).
  PolygonSoup& simplicial = controls.simplicialCage;
  const double pi = std::numbers::pi, radius = 1.4 * std::sin(pi / 3.0), height = 3.5;
  for (int ring = 0; ring < 2; ++ring)
    for (int i = 0; i < 6; ++i) {
      const double azimuth = pi / 3.0 * i + (ring == 1 ? pi / 6.0 : 0.0);
      simplicial.positions.emplace_back(radius * std::cos(azimuth), radius * std::sin(azimuth),
                                        ring == 1 ? height / 2.0 : -height / 2.0);
    }
  simplicial.positions.emplace_back(0.0, 0.0, -height);  // 12
  simplicial.positions.emplace_back(0.0, 0.0, height);   // 13
  for (std::uint32_t i = 0; i < 6; ++i) {
    const std::uint32_t next = (i + 1) % 6;  // lower ring i..next, upper ring 6 + i in between
    simplicial.addPolygon({12, next, i});
    simplicial.addPolygon({i, next, 6 + i});
    simplicial.addPolygon({next, 6 + next, 6 + i});
    simplicial.addPolygon({13, 6 + i, 6 + next});
  }
  writePosed(simplicial, dir, "simplicial_cage");

  // A Bernstein lattice around the cage and handles at the cage's vertices, swayed alike.
  controls.boxLo = kBarLo - 0.25;
  controls.boxHi = kBarHi + 0.25;
  const std::array<int, 3>& resolution = controls.resolution;
  for (int k = 0; k < resolution[2]; ++k)
    for (int j = 0; j < resolution[1]; ++j)
      for (int i = 0; i < resolution[0]; ++i)
        controls.lattice.push_back(
            sway(controls.boxLo + (controls.boxHi - controls.boxLo) *
                                      Vec3(i / (resolution[0] - 1.0), j / (resolution[1] - 1.0),
                                           k / (resolution[2] - 1.0))));
  controls.handles.assign(cage.positions.begin(), cage.positions.end());
  for (const Vec3& h : controls.handles) controls.targets.push_back(sway(h));
  return controls;
}

// One rig per method, by name: the analytic warps, the lattice, the handle-based warps and
// every cage method.
std::map<std::string, json> demoRigs(const DemoControls& controls) {
  const double pi = std::numbers::pi;
  const Vec3 boxLo = controls.boxLo, boxHi = controls.boxHi;
  std::map<std::string, json> rigs = {
      {"twist",
       {{"method", "twist"}, {"origin", {0, 0, 0}}, {"axis", {0, 0, 1}}, {"rate", pi / 4}}},
      {"bend",
       {{"method", "bend"},
        {"origin", {0, 0, -2}},
        {"axis", {0, 0, 1}},
        {"direction", {1, 0, 0}},
        {"rate", pi / 4}}},
      {"taper",
       {{"method", "taper"},
        {"origin", {0, 0, 0}},
        {"axis", {0, 0, 1}},
        {"rate", 0.2},
        {"limits", {-2, 2}}}},
      {"ffd",
       {{"method", "ffd"},
        {"basis", "bernstein"},
        {"origin", {boxLo.x, boxLo.y, boxLo.z}},
        {"size", {boxHi.x - boxLo.x, boxHi.y - boxLo.y, boxHi.z - boxLo.z}},
        {"resolution", controls.resolution},
        {"controlPoints", points(controls.lattice)}}},
      {"rbf",
       {{"method", "rbf"},
        {"centers", points(controls.handles)},
        {"targets", points(controls.targets)}}},
      {"mls",
       {{"method", "mls"},
        {"mode", "rigid"},
        {"handles", points(controls.handles)},
        {"targets", points(controls.targets)}}},
      {"idw",
       {{"method", "idw"},
        {"handles", points(controls.handles)},
        {"targets", points(controls.targets)}}},
      // Two brushes composed: the top pulled sideways, the bottom twisted.
      {"kelvinlet",
       {{"method", "compose"},
        {"warps",
         {{{"method", "kelvinlet"},
           {"brush", "grab"},
           {"center", {0, 0, 1.5}},
           {"radius", 1.0},
           {"displacement", {0.5, 0, 0}}},
          {{"method", "kelvinlet"},
           {"brush", "twist"},
           {"center", {0, 0, -1.5}},
           {"radius", 1.0},
           {"axis", {0, 0, 1}},
           {"angle", pi / 3}}}}}},
      {"graph",
       {{"method", "graph"},
        {"spacing", 0.5},
        {"handles", points(controls.handles)},
        {"targets", points(controls.targets)}}},
  };
  // A wire along the bar's axis, swayed; the bar and its level set's narrow band lie within the
  // inner radius, so each slice follows the wire rigidly, and the wide drop-off band beyond
  // does not fold space (the volume's backward mapping finds every preimage).
  std::vector<Vec3> axis, swayedAxis;
  for (int k = 0; k <= 8; ++k) {
    axis.emplace_back(0.0, 0.0, -2.25 + 4.5 * k / 8.0);
    swayedAxis.push_back(sway(axis.back()));
  }
  rigs["wires"] = {{"method", "wires"},
                   {"wires",
                    {{{"rest", points(axis)},
                      {"deformed", points(swayedAxis)},
                      {"curve", "catmull-rom"},
                      {"radius", 2.5},
                      {"innerRadius", 0.9}}}}};
  // Skinning: the bar twisted by 170° about its axis between two bones at its ends, by linear
  // blending (its middle collapses: the candy-wrapper effect) and by dual quaternions (it keeps
  // its girth). Two handles per end, one bone each, so that the default (RBF) coordinates of
  // the four handles are their barycentric coordinates: each end's weight is linear along z.
  const double c = std::cos(170.0 * pi / 180.0), s = std::sin(170.0 * pi / 180.0);
  const json rest = {{1, 0, 0, 0}, {0, 1, 0, 0}, {0, 0, 1, 0}, {0, 0, 0, 1}};
  const json twisted = {{c, -s, 0, 0}, {s, c, 0, 0}, {0, 0, 1, 0}, {0, 0, 0, 1}};
  for (const std::string mode : {"lbs", "dqs"}) {
    rigs["skinning-" + mode] = {
        {"method", "skinning"},
        {"mode", mode},
        {"bones", {rest, rest, twisted, twisted}},
        {"handles",
         {{-0.3, 0, kBarLo.z}, {0.3, 0, kBarLo.z}, {0, -0.3, kBarHi.z}, {0, 0.3, kBarHi.z}}}};
  }
  // Each cage method on the first of these cages that it takes: the pinched cage, the convex
  // box (wachspress), the capped antiprism (discrete-harmonic, which needs triangle faces).
  const std::pair<const char*, const PolygonSoup*> cages[] = {
      {"cage", &controls.cage},
      {"convex_cage", &controls.convexCage},
      {"simplicial_cage", &controls.simplicialCage}};
  for (const std::string& method : cageMethods()) {
    for (const auto& [name, soup] : cages) {
      try {
        checkCageMethodApplies(method, Cage(*soup, std::string(name) + ".obj"));
      } catch (const InvalidInput&) {
        continue;
      }
      rigs[method] = {{"method", method},
                      {"cage", std::string(name) + ".obj"},
                      {"pose", std::string(name) + "_pose.obj"}};
      break;
    }
    if (!rigs.count(method)) throw std::logic_error("demo: no cage of the demo takes " + method);
  }
  // The volume's inverse is seeded from a coarse lattice that may reach past the cage: the
  // methods defined inside only take the nearest cage point's coordinates there. 100k tets are
  // plenty for this cage (the default aims at detailed cages like the armadillo's).
  for (const char* method : {"harmonic", "wachspress", "discrete-harmonic"})
    if (rigs.count(method)) rigs[method]["outside"] = "nearest";
  if (rigs.count("harmonic")) rigs["harmonic"]["tets"] = 100000;
  // MLS weighted by distances inside the bar (which needs OpenVDB): handles on four lines along
  // the bar, inside it. The bar is convex, so this is close to "mls"; the fingers show the
  // difference (demoFingers).
  if (volumesSupported()) {
    std::vector<Vec3> handles, targets;
    for (const double z : {-1.8, 0.0, 1.8})
      for (const Vec3 corner :
           {Vec3(-0.3, -0.3, z), Vec3(0.3, -0.3, z), Vec3(0.3, 0.3, z), Vec3(-0.3, 0.3, z)})
        handles.push_back(corner);
    for (const Vec3& h : handles) targets.push_back(sway(h));
    rigs["mls-inside"] = {{"method", "mls"},
                          {"distance", "inside"},
                          {"model", "bar.obj"},
                          {"handles", points(handles)},
                          {"targets", points(targets)}};
  }
  return rigs;
}

// Writes each rig next to the inputs and deforms every input with it, printing the command
// that reproduces each result.
void deformWithEveryRig(const fs::path& dir, const std::map<std::string, json>& rigs,
                        const std::vector<std::string>& inputs, const CliContext& context) {
  for (const auto& [name, rig] : rigs) {
    const fs::path rigPath = dir / (name + ".json");
    writeJsonFile(rig, rigPath);
    const auto warp = loadRigFile(rigPath, context).warp;
    for (const std::string& input : inputs) {
      const fs::path in = dir / input;
      const fs::path out = dir / (in.stem().string() + "_" + name + in.extension().string());
      if (isVolumePath(in)) {
        CliContext quietVolumes = context;  // one line per result is enough
        quietVolumes.quiet = true;
        deformVolumeFile(*warp, in, out, {}, quietVolumes);
      } else {
        deformSoupFile(*warp, in, out, false, context);
      }
      context.say("spacewarp deform --rig " + rigPath.string() + " " + in.string() + " -o " +
                  out.string());
    }
  }
}

// Two fingers on a palm (a U, 1.25 wide, 0.25 thick) whose left fingertip is pulled towards the
// right finger, by MLS with Euclidean distances (the right finger follows) and with distances
// inside the model (it stays): fingers_mls-fingers.obj and fingers_mls-fingers-inside.obj.
void demoFingers(const fs::path& dir, const CliContext& context) {
  std::vector<glm::ivec3> cells;
  for (int x = 0; x <= 4; ++x) cells.emplace_back(x, 0, 0);
  for (int y = 1; y <= 4; ++y) {
    cells.emplace_back(0, y, 0);
    cells.emplace_back(4, y, 0);
  }
  const double cell = 0.25;
  writeSoup(makeBlocksSurface(cells, Vec3(0.0), cell), dir / "fingers.obj");
  const std::vector<Vec3> handles = {{0.5, 4.5, 0.5}, {0.5, 0.5, 0.5}, {2.5, 0.5, 0.8},
                                     {4.5, 0.5, 0.5}, {4.5, 2.5, 0.5}, {4.5, 4.5, 0.5}};
  std::vector<Vec3> scaled, targets;
  for (const Vec3& h : handles) scaled.push_back(h * cell);
  targets = scaled;
  targets[0].x += 1.5 * cell;
  const json euclidean = {
      {"method", "mls"}, {"handles", points(scaled)}, {"targets", points(targets)}};
  json inside = euclidean;
  inside["distance"] = "inside";
  inside["model"] = "fingers.obj";
  deformWithEveryRig(dir, {{"mls-fingers", euclidean}, {"mls-fingers-inside", inside}},
                     {"fingers.obj"}, context);
}

// The affine map that sway() applies at height z (a turn about the axis and a shift).
Mat4 swayAt(double z) {
  const Vec3 origin = sway(Vec3(0.0, 0.0, z));
  Mat4 m(1.0);
  m[0] = glm::dvec4(sway(Vec3(1.0, 0.0, z)) - origin, 0.0);
  m[1] = glm::dvec4(sway(Vec3(0.0, 1.0, z)) - origin, 0.0);
  m[3] = glm::dvec4(origin - Vec3(0.0, 0.0, z), 1.0);
  return m;
}

// Surface editing of the bar: its caps are the handles, each moved as sway() moves it, so the
// edits compare with the space deformations; ARAP on the surface, and ARAP in the subspace of
// the cage (which also writes the posed cage, for `spacewarp deform --method mvc`).
void editTheBar(const fs::path& dir, const PolygonSoup& bar, const CliContext& context) {
  json handles = json::array();
  for (const double z : {kBarLo.z, kBarHi.z}) {
    std::vector<std::uint32_t> cap;
    for (std::size_t v = 0; v < bar.size(); ++v)
      if (bar.positions[v].z == z) cap.push_back(static_cast<std::uint32_t>(v));
    const Mat4 m = swayAt(z);
    json rows = json::array();
    for (int r = 0; r < 4; ++r) rows.push_back({m[0][r], m[1][r], m[2][r], m[3][r]});
    handles.push_back({{"vertices", cap}, {"matrix", rows}});
  }
  const fs::path handlesPath = dir / "edit_handles.json";
  writeJsonFile({{"handles", handles}}, handlesPath);
  CliContext quietEdits = context;  // one line per result, as for the rigs
  quietEdits.quiet = true;
  for (const std::string method : {"arap", "cage-arap"}) {
    EditRequest request;
    request.method = method;
    request.handles = handlesPath.string();
    request.model = (dir / "bar.obj").string();
    request.output = (dir / ("bar_" + method + ".obj")).string();
    std::string cage;
    if (method == "cage-arap") {
      request.cage = (dir / "cage.obj").string();
      request.cageOut = (dir / "cage_pose_cage-arap.obj").string();
      cage = " --cage " + request.cage + " --cage-out " + request.cageOut;
    }
    runEdit(request, quietEdits);
    context.say("spacewarp edit --method " + method + cage + " --handles " + request.handles + " " +
                request.model + " -o " + request.output);
  }
}

// The coordinate functions of one vertex of the waist, on the diagonal plane x = y through
// the bar's axis and that vertex.
void compareWaistVertex(const fs::path& dir, const PolygonSoup& cage, const CliContext& context) {
  CompareRequest request;
  request.cage = dir / "cage.obj";
  request.planePoint = Vec3(0.0);
  request.planeNormal = Vec3(1.0, -1.0, 0.0);
  request.control = 0;
  for (std::size_t v = 0; v < cage.positions.size(); ++v) {
    const Vec3& p = cage.positions[v];
    if (std::abs(p.z) < 1e-9 && p.x > 0.0 && p.y > 0.0) request.control = v;
  }
  request.resolution = 400;
  request.output = dir / "compare";
  runComparison(request, context);
  context.say("spacewarp compare --cage " + request.cage.string() +
              " --point 0,0,0 --normal 1,-1,0 --control " + std::to_string(request.control) +
              " --resolution 400 -o " + request.output.string());
}

void runDemo(const fs::path& dir, const CliContext& context) {
  const auto start = std::chrono::steady_clock::now();
  createOutputFolder(dir / "compare");
  const DemoInputs inputs = writeInputs(dir);
  const DemoControls controls = writeControls(dir);
  const std::map<std::string, json> rigs = demoRigs(controls);
  deformWithEveryRig(dir, rigs, inputs.files, context);
  if (volumesSupported()) demoFingers(dir, context);
  editTheBar(dir, inputs.bar, context);
  compareWaistVertex(dir, controls.cage, context);

  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  char summary[160];
  std::snprintf(summary, sizeof summary,
                "demo: %zu-vertex bar, %zu-point cloud%s deformed by %zu rigs in %.1f s",
                inputs.bar.size(), inputs.cloud.size(),
                volumesSupported() ? " and level-set volume" : "", rigs.size(), seconds);
  context.say(summary);
  context.say("look at: " + dir.string() + " (bar_<method>.obj, cloud_<method>.ply" +
              (volumesSupported() ? ", bar_<method>.vdb" : "") +
              "; edits bar_arap.obj, bar_cage-arap.obj) and " +
              (dir / "compare" / "report.md").string() + " with compare.png");
  context.say("pose it in the browser: spacewarp view " + (dir / "bar.obj").string() + " --cage " +
              (dir / "cage.obj").string() + " --save-dir " + dir.string());
}

}  // namespace

Command addDemoCommand(CLI::App& app, const CliContext& context) {
  auto dir = std::make_shared<std::string>("out/demo");
  CLI::App* demo = app.add_subcommand(
      "demo", "Deform built-in example geometry with every method and compare the coordinates");
  demo->add_option("DIR", *dir, "output folder")->capture_default_str();
  return {demo, [dir, &context] { runDemo(*dir, context); }};
}

}  // namespace spacewarp::cli
