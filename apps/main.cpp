// The spacewarp command-line tool. Exit codes (DESIGN.md): 0 success, 2 usage, 3 bad input,
// 4 numerical failure, 1 anything else. Outputs are written atomically, so a failure never
// leaves a partial file behind.

#include <charconv>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <numbers>
#include <string>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "apps/cage_methods.h"
#include "apps/rig.h"
#include "core/deform.h"
#include "core/errors.h"
#include "core/io/atomic_file.h"
#include "core/io/mesh_io.h"
#include "core/primitives.h"

namespace fs = std::filesystem;
using namespace spacewarp;

namespace {

enum ExitCode { kOk = 0, kOther = 1, kUsage = 2, kBadInput = 3, kNumerical = 4 };

void printInfo(const fs::path& path) {
  const PolygonSoup soup = readSoup(path);
  std::map<std::size_t, std::size_t> sizes;
  for (std::size_t p = 0; p < soup.polygonCount(); ++p) ++sizes[soup.polygon(p).size()];
  const BoundingBox box = boundingBox(soup.positions);

  std::printf("file:       %s\n", path.string().c_str());
  std::printf("vertices:   %zu\n", soup.size());
  std::printf("polygons:   %zu", soup.polygonCount());
  for (const auto& [n, count] : sizes) std::printf("  (%zu with %zu sides)", count, n);
  std::printf("\nnormals:    %s\n", soup.hasNormals() ? "per vertex" : "none");
  for (const VertexAttribute& a : soup.attributes) std::printf("attribute:  %s\n", a.name.c_str());
  if (!box.empty()) {
    std::printf("bbox min:   %.17g %.17g %.17g\n", box.min.x, box.min.y, box.min.z);
    std::printf("bbox max:   %.17g %.17g %.17g\n", box.max.x, box.max.y, box.max.z);
    std::printf("diagonal:   %.17g\n", box.diagonal());
  }
}

WriteOptions writeOptions(bool ascii) {
  WriteOptions options;
  if (ascii) options.plyEncoding = PlyEncoding::Ascii;
  return options;
}

// Reads INPUT, warps it and writes OUTPUT. The output format is checked before any work.
void deformFile(const Warp& warp, const fs::path& input, const fs::path& output, bool ascii) {
  formatFromPath(output);
  PolygonSoup soup = readSoup(input);
  try {
    deform(warp, soup);
  } catch (const InvalidInput& e) {
    throw InvalidInput(input.string() + ": " + e.what());
  }
  writeSoup(soup, output, writeOptions(ascii));
}

// The coordinate matrix of every point of POINTS as CSV: a header naming the columns, then
// one row per input point in input order, shortest round-trip (full) double precision.
void writeWeights(const Coordinates& coordinates, const fs::path& pointsPath,
                  const fs::path& output) {
  formatFromPath(pointsPath);
  const PolygonSoup points = readSoup(pointsPath);
  const std::size_t m = coordinates.columnCount();
  std::vector<double> rows(points.size() * m);
  coordinates.weightsBatch(points.positions, rows);
  writeFileAtomically(output, [&](std::ostream& out) {
    for (std::size_t c = 0; c < m; ++c) out << (c ? "," : "") << coordinates.columnName(c);
    out << '\n';
    std::string line;
    char buffer[32];
    for (std::size_t i = 0; i < points.size(); ++i) {
      line.clear();
      for (std::size_t c = 0; c < m; ++c) {
        if (c) line += ',';
        const auto result = std::to_chars(buffer, buffer + sizeof buffer, rows[i * m + c]);
        line.append(buffer, result.ptr);
      }
      line += '\n';
      out << line;
    }
  });
}

void writeJson(const nlohmann::json& j, const fs::path& path) {
  writeFileAtomically(path, [&](std::ostream& out) { out << j.dump(2) << '\n'; });
}

// The built-in example: a subdivided bar and a point cloud in the same box, twisted, bent,
// tapered and deformed by a posed cage (mean-value and Green coordinates) through rigs written
// next to them, exactly as `spacewarp deform --rig` would do it.
void runDemo(const fs::path& dir) {
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
    writeJson(rig, rigPath);
    const auto warp = cli::loadRig(rigPath).warp;
    for (const char* input : {"bar.obj", "cloud.ply"}) {
      const fs::path in = dir / input;
      const fs::path out = dir / (in.stem().string() + "_" + name + in.extension().string());
      deformFile(*warp, in, out, false);
      std::printf("spacewarp deform --rig %s %s -o %s\n", rigPath.string().c_str(),
                  in.string().c_str(), out.string().c_str());
    }
  }
  std::printf("demo: wrote %zu-vertex bar and %zu-point cloud, %zu rigs, to %s\n", bar.size(),
              cloud.size(), rigs.size(), dir.string().c_str());
}

int run(int argc, char** argv) {
  CLI::App app{"spacewarp: space deformations and cage coordinates"};
  app.require_subcommand(1);

  std::string infoPath;
  CLI::App* info = app.add_subcommand("info", "Print counts and the bounding box of a file");
  info->add_option("FILE", infoPath, "OBJ, OFF or PLY file")->required();

  std::string methodList;
  for (const std::string& m : cli::cageMethods()) methodList += (methodList.empty() ? "" : "|") + m;

  std::string rigPath, input, output, method, cagePath, posePath;
  bool ascii = false;
  CLI::App* deformCmd = app.add_subcommand(
      "deform", "Warp a polygon soup or point cloud (OBJ, OFF, PLY) with the warp a rig describes");
  auto* rigOption = deformCmd->add_option("--rig", rigPath,
                                          "JSON rig file (see README.md for every method's keys)");
  auto* methodOption =
      deformCmd
          ->add_option("--method", method,
                       "cage coordinates (" + methodList + "), with --cage and --pose")
          ->check(CLI::IsMember(cli::cageMethods()));
  auto* cageOption = deformCmd->add_option("--cage", cagePath, "rest cage (closed mesh)");
  auto* poseOption = deformCmd->add_option("--pose", posePath, "posed cage, same vertex order");
  rigOption->excludes(methodOption);
  methodOption->needs(cageOption, poseOption);
  cageOption->needs(methodOption);
  poseOption->needs(methodOption);
  deformCmd->callback([&] {
    if (rigPath.empty() && method.empty()) throw CLI::RequiredError("--rig or --method");
  });
  deformCmd->add_option("INPUT", input, "input file; its format follows its extension")->required();
  deformCmd->add_option("-o,--output", output, "output file; its format follows its extension")
      ->required();
  deformCmd->add_flag("--ascii", ascii, "write PLY as ASCII rather than binary little-endian");

  std::string weightsRig, weightsMethod, weightsCage, weightsPoints, weightsOutput;
  CLI::App* weightsCmd = app.add_subcommand(
      "weights", "Write the coordinate matrix of points (cage, lattice or RBF coordinates) as CSV");
  auto* weightsRigOption = weightsCmd->add_option(
      "--rig", weightsRig, "a rig whose method has coordinates (mvc, green, ...)");
  auto* weightsMethodOption = weightsCmd->add_option("--method", weightsMethod, methodList)
                                  ->check(CLI::IsMember(cli::cageMethods()));
  auto* weightsCageOption =
      weightsCmd->add_option("--cage", weightsCage, "rest cage (closed mesh)");
  weightsRigOption->excludes(weightsMethodOption);
  weightsMethodOption->needs(weightsCageOption);
  weightsCageOption->needs(weightsMethodOption);
  weightsCmd->callback([&] {
    if (weightsRig.empty() && weightsMethod.empty()) throw CLI::RequiredError("--rig or --method");
  });
  weightsCmd->add_option("POINTS", weightsPoints, "points (any supported file; faces ignored)")
      ->required();
  weightsCmd->add_option("-o,--output", weightsOutput, "CSV file")->required();

  std::string demoDir = "out/demo";
  CLI::App* demo =
      app.add_subcommand("demo", "Twist, bend, taper and cage-deform built-in example geometry");
  demo->add_option("DIR", demoDir, "output folder")->capture_default_str();

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int code = app.exit(e);
    return code == 0 ? kOk : kUsage;
  }

  if (info->parsed()) printInfo(infoPath);
  if (deformCmd->parsed()) {
    const cli::Rig rig =
        rigPath.empty() ? cli::cageRig(method, cagePath, posePath) : cli::loadRig(rigPath);
    deformFile(*rig.warp, input, output, ascii);
  }
  if (weightsCmd->parsed()) {
    std::shared_ptr<const Coordinates> coordinates;
    if (weightsRig.empty()) {
      coordinates = cli::cageCoordinates(weightsMethod,
                                         std::make_shared<const Cage>(Cage::fromFile(weightsCage)));
    } else {
      coordinates = cli::loadRig(weightsRig).coordinates;
      if (!coordinates)
        throw InvalidInput(weightsRig + ": this rig's method has no coordinates to export");
    }
    writeWeights(*coordinates, weightsPoints, weightsOutput);
  }
  if (demo->parsed()) runDemo(demoDir);
  return kOk;
}

}  // namespace

int main(int argc, char** argv) {
  try {
    return run(argc, argv);
  } catch (const IoError& e) {
    std::fprintf(stderr, "spacewarp: error: %s\n", e.what());
    return kBadInput;
  } catch (const InvalidInput& e) {
    std::fprintf(stderr, "spacewarp: error: %s\n", e.what());
    return kBadInput;
  } catch (const SolverError& e) {
    std::fprintf(stderr, "spacewarp: numerical failure: %s\n", e.what());
    return kNumerical;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "spacewarp: error: %s\n", e.what());
    return kOther;
  }
}
