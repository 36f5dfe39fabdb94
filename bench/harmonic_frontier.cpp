// One point of the harmonic set-up's accuracy-versus-time frontier (bench/harmonic_frontier.py
// drives it and compares with Blender's Mesh Deform): solves the harmonic coordinates of a cage
// at a given resolution, binds a model's vertices (their weight rows), deforms them by a posed
// cage, and writes the deformed vertices (raw little-endian f64, x y z per vertex, in the model's
// order) to a file. Prints one JSON line: the time of every stage (tetrahedralise, factorise,
// solve with the non-negativity projection, bind), the mesh's size and how many mesh vertices
// the projection changed.
//
// harmonic_frontier CAGE.obj POSED.obj MODEL.obj OUT.f64 [--tets N | --precision P] [--ratio Q]

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include <spacewarp/coords/cage.h>
#include <spacewarp/coords/harmonic.h>
#include <spacewarp/core/io/mesh_io.h>

namespace {

using namespace spacewarp;
using Clock = std::chrono::steady_clock;

double seconds(Clock::time_point from) {
  return std::chrono::duration<double>(Clock::now() - from).count();
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 5) {
    std::fprintf(stderr,
                 "usage: harmonic_frontier CAGE.obj POSED.obj MODEL.obj OUT.f64 [--tets N | "
                 "--precision P]\n");
    return 2;
  }
  try {
    auto cage = std::make_shared<const Cage>(Cage::fromFile(argv[1]));
    const std::vector<Vec3> posed = readSoup(argv[2]).positions;
    const std::vector<Vec3> model = readSoup(argv[3]).positions;
    HarmonicOptions options;
    options.outside = HarmonicOutsidePolicy::NearestPoint;
    for (int i = 5; i + 1 < argc; i += 2) {
      const std::string key = argv[i];
      if (key == "--tets")
        options.targetTetCount = std::stoul(argv[i + 1]);
      else if (key == "--precision")
        options.targetTetCount = harmonicPrecisionTets(std::stod(argv[i + 1]));
      else if (key == "--ratio")
        options.radiusEdgeRatio = std::stod(argv[i + 1]);
      else if (key == "--raw")
        options.nonNegative = std::string(argv[i + 1]) == "0";
      else
        throw std::runtime_error("unknown option " + key);
    }
    if (posed.size() != cage->vertexCount()) throw std::runtime_error("the pose's size differs");

    std::map<std::string, double> begin, end;
    const Clock::time_point t0 = Clock::now();
    const ProgressCallback progress = [&](std::string_view stage, double fraction) {
      const double t = seconds(t0);
      const std::string name(stage);
      if (!begin.count(name)) begin[name] = t;
      if (fraction == 1.0) end[name] = t;
      return true;
    };
    const auto harmonic = std::make_shared<const HarmonicCoordinates>(cage, options, progress);
    const double solved = seconds(t0);
    const std::size_t k = cage->vertexCount();
    std::vector<double> rows(model.size() * k);
    const Clock::time_point bindStart = Clock::now();
    harmonic->weightsBatch(model, rows);
    const double bind = seconds(bindStart);

    std::vector<double> out(model.size() * 3, 0.0);
    for (std::size_t i = 0; i < model.size(); ++i) {
      Vec3 p(0.0);
      for (std::size_t c = 0; c < k; ++c) p += rows[i * k + c] * posed[c];
      out[3 * i] = p.x;
      out[3 * i + 1] = p.y;
      out[3 * i + 2] = p.z;
    }
    std::ofstream file(argv[4], std::ios::binary);
    file.write(reinterpret_cast<const char*>(out.data()),
               static_cast<std::streamsize>(out.size() * sizeof(double)));
    if (!file) throw std::runtime_error(std::string("cannot write ") + argv[4]);

    // Rows with an entry at or below zero: with --raw 1 (no projection), the rows the projection
    // would change; with it, those it clamped (a lower bound of those it changed).
    std::size_t projected = 0;
    const std::span<const double> values = harmonic->vertexValues();
    for (std::size_t v = 0; v < harmonic->mesh().vertices.size(); ++v) {
      if (harmonic->mesh().boundaryTriangle[v] >= 0) continue;
      for (std::size_t c = 0; c < k; ++c) {
        if (options.nonNegative ? values[v * k + c] <= 0.0 : values[v * k + c] < 0.0) {
          ++projected;
          break;
        }
      }
    }
    std::printf("{\"tets\": %zu, \"mesh_vertices\": %zu, \"projected_rows\": %zu",
                harmonic->mesh().tets.size(), harmonic->mesh().vertices.size(), projected);
    for (const auto& [stage, t] : end)
      std::printf(", \"%s_s\": %.4f", stage.c_str(), t - begin[stage]);
    std::printf(", \"solve_total_s\": %.4f, \"bind_s\": %.4f, \"setup_s\": %.4f}\n", solved, bind,
                solved + bind);
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "harmonic_frontier: %s\n", e.what());
    return 1;
  }
}
