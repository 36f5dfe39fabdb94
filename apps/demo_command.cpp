// spacewarp demo DIR: the README's main job on built-in example geometry.

#include <cmath>
#include <map>
#include <numbers>

#include "apps/commands.h"
#include "apps/jobs.h"
#include "apps/rig.h"
#include "core/io/mesh_io.h"
#include "core/primitives.h"

namespace spacewarp::cli {

namespace {

namespace fs = std::filesystem;

// A subdivided bar and a point cloud in the same box, twisted, bent, tapered and deformed by
// a posed cage (mean-value and Green coordinates) through rigs written next to them, exactly
// as `spacewarp deform --rig` would do it.
void runDemo(const fs::path& dir, const CliContext& context) {
  fs::create_directories(dir);
  const Vec3 lo(-0.5, -0.5, -2.0), hi(0.5, 0.5, 2.0);
  const PolygonSoup bar = makeBoxSurface(lo, hi, {8, 8, 32});
  const PointSet cloud = makeRandomPoints(lo, hi, 20000, 7);
  PolygonSoup cloudSoup;
  static_cast<PointSet&>(cloudSoup) = cloud;
  writeSoup(bar, dir / "bar.obj");
  writeSoup(cloudSoup, dir / "cloud.ply");

  const double pi = std::numbers::pi;
  std::map<std::string, nlohmann::json> rigs = {
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
  };
  // A cage around the bar, posed by swaying its rings sideways, for the cage methods.
  const PolygonSoup cage = makeBoxSurface(lo - 0.1, hi + 0.1, {1, 1, 4});
  PolygonSoup pose = cage;
  for (Vec3& p : pose.positions) {
    const double t = (p.z - lo.z + 0.1) / (hi.z - lo.z + 0.2);  // 0 at the bottom, 1 at the top
    const double angle = 0.6 * t;
    p = Vec3(std::cos(angle) * p.x - std::sin(angle) * p.y + 0.8 * t * t,
             std::sin(angle) * p.x + std::cos(angle) * p.y, p.z);
  }
  writeSoup(cage, dir / "cage.obj");
  writeSoup(pose, dir / "cage_pose.obj");
  rigs["mvc"] = {{"method", "mvc"}, {"cage", "cage.obj"}, {"pose", "cage_pose.obj"}};
  rigs["green"] = {{"method", "green"}, {"cage", "cage.obj"}, {"pose", "cage_pose.obj"}};

  for (const auto& [name, rig] : rigs) {
    const fs::path rigPath = dir / (name + ".json");
    writeJsonFile(rig, rigPath);
    const auto warp = loadRig(rigPath).warp;
    for (const char* input : {"bar.obj", "cloud.ply"}) {
      const fs::path in = dir / input;
      const fs::path out = dir / (in.stem().string() + "_" + name + in.extension().string());
      deformSoupFile(*warp, in, out, false, context.progress());
      context.say("spacewarp deform --rig " + rigPath.string() + " " + in.string() + " -o " +
                  out.string());
    }
  }
  context.say("demo: wrote " + std::to_string(bar.size()) + "-vertex bar and " +
              std::to_string(cloud.size()) + "-point cloud, " + std::to_string(rigs.size()) +
              " rigs, to " + dir.string());
}

}  // namespace

Command addDemoCommand(CLI::App& app, const CliContext& context) {
  auto dir = std::make_shared<std::string>("out/demo");
  CLI::App* demo =
      app.add_subcommand("demo", "Twist, bend, taper and cage-deform built-in example geometry");
  demo->add_option("DIR", *dir, "output folder")->capture_default_str();
  return {demo, [dir, &context] { runDemo(*dir, context); }};
}

}  // namespace spacewarp::cli
