// spacewarp edit --method laplacian|bilaplacian|arap|cage-arap --handles HANDLES.json MODEL -o
// OUT: surface-based editing (surface/): the model is welded into a triangle mesh, the handle
// regions are moved and the rest of the surface follows by the chosen method; the output is the
// input soup with its positions (and normals) replaced.

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <memory>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include <spacewarp/coords/cage.h>
#include <spacewarp/core/errors.h>
#include <spacewarp/core/io/mesh_io.h>
#include <spacewarp/rig/cage_rig.h>
#include <spacewarp/rig/handles_file.h>
#include <spacewarp/rig/rig.h>
#include <spacewarp/surface/arap.h>
#include <spacewarp/surface/cage_arap.h>
#include <spacewarp/surface/handles.h>
#include <spacewarp/surface/laplacian_editing.h>
#include <spacewarp/surface/surface_mesh.h>
#include "apps/cage_options.h"
#include "apps/commands.h"
#include "apps/edit_command.h"
#include "apps/file_kinds.h"
#include "apps/jobs.h"

namespace spacewarp::cli {

namespace {

using nlohmann::json;
namespace fs = std::filesystem;

using EditArgs = EditRequest;

// "1 vertex", "452 vertices", "3 handle vertices" (counted() only adds an s).
std::string countedVertices(std::size_t n, const std::string& kind = "") {
  return groupDigits(n) + " " + kind + (n == 1 ? "vertex" : "vertices");
}

// --- HANDLES.json -------------------------------------------------------------------------

// The library's messages name regions "handle region 2" and start with the function's name;
// the file's user knows them as handles[2].
std::string inFileTerms(std::string what) {
  for (const char* prefix : {"resolveHandles: ", "mapConstraints: "})
    if (what.starts_with(prefix)) what.erase(0, std::string(prefix).size());
  // "handle region 12" -> "handles[12]" (by hand: <regex> trips GCC 12's -Wmaybe-uninitialized
  // in sanitizer builds).
  const std::string from = "handle region ";
  for (std::size_t at = what.find(from); at != std::string::npos; at = what.find(from, at)) {
    std::size_t end = at + from.size();
    while (end < what.size() && std::isdigit(static_cast<unsigned char>(what[end]))) ++end;
    if (end == at + from.size()) {
      at = end;
      continue;
    }
    what.replace(at, end - at,
                 "handles[" + what.substr(at + from.size(), end - at - from.size()) + "]");
  }
  return what;
}

// The constraints of the handles file on the welded mesh's vertices.
VertexConstraints readConstraints(const std::string& path, const PolygonSoup& soup,
                                  const SurfaceMesh& mesh) {
  const std::string where = printable(path);
  const std::vector<HandleRegion> regions = readHandlesFile(path, soup.size());
  try {
    const VertexConstraints onSoup = resolveHandles(regions, soup.positions);
    const double tolerance = 1e-9 * boundingBox(soup.positions).diagonal();
    return mapConstraints(onSoup, mesh.soupToMesh, tolerance);
  } catch (const InvalidInput& e) {
    throw InvalidInput(where + ": " + inFileTerms(e.what()));
  }
}

// --- the model -----------------------------------------------------------------------------

// The first soup vertex welded into each mesh vertex: how messages name mesh vertices (the
// user knows the file's order).
std::vector<std::uint32_t> firstSoupVertex(const SurfaceMesh& mesh) {
  std::vector<std::uint32_t> first(mesh.vertexCount(), ~std::uint32_t{0});
  for (std::size_t v = mesh.soupToMesh.size(); v-- > 0;)
    first[mesh.soupToMesh[v]] = static_cast<std::uint32_t>(v);
  return first;
}

// "vertices 3, 17, 40 and 5 more" (soup indices, sorted).
std::string someVertices(std::vector<std::uint32_t> soupVertices, std::size_t shown = 5) {
  std::sort(soupVertices.begin(), soupVertices.end());
  std::string list;
  for (std::size_t k = 0; k < std::min(shown, soupVertices.size()); ++k)
    list += (k ? ", " : "") + std::to_string(soupVertices[k]);
  if (soupVertices.size() > shown)
    list += " and " + groupDigits(soupVertices.size() - shown) + " more";
  return list;
}

// One warning per kind of trouble that weldSoup() reported; none is fatal.
void warnAboutTheMesh(const std::string& model, const SurfaceMesh& mesh,
                      const CliContext& context) {
  const MeshReport& report = mesh.report;
  const std::vector<std::uint32_t> soupOf = firstSoupVertex(mesh);
  if (!report.nonManifoldEdges.empty()) {
    const auto& e = report.nonManifoldEdges.front();
    context.warn(model + ": " + counted(report.nonManifoldEdges.size(), "non-manifold edge") +
                 " (more than two faces), the first between vertices " +
                 std::to_string(soupOf[e[0]]) + " and " + std::to_string(soupOf[e[1]]) +
                 "; the methods still run, but the result there may crease");
  }
  if (!report.nonManifoldVertices.empty()) {
    context.warn(model + ": " +
                 countedVertices(report.nonManifoldVertices.size(), "non-manifold ") +
                 " (faces touching at a point), the first vertex " +
                 std::to_string(soupOf[report.nonManifoldVertices.front()]) +
                 "; the methods still run, but the result there may crease");
  }
  if (const std::size_t dropped = report.droppedPolygons.size(); dropped > 0) {
    context.warn(
        model + ": " + counted(dropped, "face") + " collapsed by welding (the first: face " +
        std::to_string(report.droppedPolygons.front()) + ") " + (dropped == 1 ? "takes" : "take") +
        " no part in the edit; written, moved with their vertices");
  }
  if (const std::size_t flat = report.degenerateTriangles.size(); flat > 0) {
    context.warn(model + ": " + counted(flat, "triangle") + " without area (the first: of face " +
                 std::to_string(mesh.triangleToPolygon[report.degenerateTriangles.front()]) + ") " +
                 (flat == 1 ? "takes" : "take") +
                 " no part in the edit; a vertex only on such triangles stays in place");
  }
}

// Vertices that no handle reaches through the surface (components without a constrained
// vertex, isolated points): the linear and ARAP energies cannot place them, so they stay.
void warnHeld(const std::string& model, const SurfaceMesh& mesh,
              std::span<const std::uint32_t> held, const CliContext& context) {
  if (held.empty()) return;
  const std::vector<std::uint32_t> soupOf = firstSoupVertex(mesh);
  std::set<std::uint32_t> parts;
  std::vector<std::uint32_t> soupVertices;
  std::size_t isolated = 0;  // of the held ones (an isolated handle vertex is not held)
  const auto& all = mesh.report.isolatedVertices;
  for (const std::uint32_t v : held) {
    parts.insert(mesh.vertexComponent[v]);
    soupVertices.push_back(soupOf[v]);
    isolated += std::binary_search(all.begin(), all.end(), v);
  }
  context.warn(model + ": " + countedVertices(held.size(), "") + " in " +
               counted(parts.size(), "part") +
               " of the surface that no handle reaches stay in place (" +
               (isolated == 0 ? std::string() : countedVertices(isolated, "isolated ") + "; ") +
               "vertices " + someVertices(soupVertices) + ")");
}

// --- the methods ---------------------------------------------------------------------------

// Prints one informational line on stderr unless quiet (the solve's report, as the graph
// rig's; stdout keeps the summary line).
void note(const CliContext& context, const std::string& line) {
  if (context.quiet) return;
  std::fflush(stdout);
  std::fprintf(stderr, "spacewarp: %s\n", line.c_str());
}

std::string energyLine(const std::vector<double>& energies) {
  char text[96];
  std::snprintf(text, sizeof text, "energy %.4g -> %.4g", energies.front(), energies.back());
  return text;
}

// The ARAP-type report: iterations, energies, convergence (a warning when not converged, as the
// deformation graph's: the result is still the best found and is written). With --tolerance 0
// every iteration was asked for, so running them all is no surprise.
void reportIterations(const std::string& name, int iterations, const std::vector<double>& energies,
                      bool converged, bool startedRigid, const EditArgs& args,
                      const CliContext& context) {
  const std::string line = name + ": " + counted(std::size_t(iterations), "iteration") + ", " +
                           energyLine(energies) +
                           (startedRigid ? " (from the handles' rigid motion)" : "");
  if (converged) {
    note(context, line + ", converged");
  } else if (args.tolerance == 0.0) {
    note(context, line + " (--tolerance 0: every iteration run)");
  } else {
    context.warn(name + " did not converge in " + counted(std::size_t(iterations), "iteration") +
                 " (" + energyLine(energies) +
                 "); the result is written; raise --iterations or --tolerance");
  }
}

// The options of the edit, from the command line.
SurfaceEditOptions editOptions(const EditArgs& args) {
  SurfaceEditOptions o;
  o.method = args.method == "laplacian"     ? SurfaceEditMethod::Laplacian
             : args.method == "bilaplacian" ? SurfaceEditMethod::BiLaplacian
             : args.method == "arap"        ? SurfaceEditMethod::Arap
                                            : SurfaceEditMethod::CageArap;
  const ArapEnergy energy =
      args.energy == "spokes" ? ArapEnergy::Spokes : ArapEnergy::SpokesAndRims;
  o.arap.energy = o.cageArap.energy = energy;
  if (args.iterations > 0) o.arap.maxIterations = o.cageArap.maxIterations = args.iterations;
  if (args.acceleration >= 0)
    o.arap.accelerationWindow = o.cageArap.accelerationWindow = args.acceleration;
  if (args.tolerance >= 0.0)
    o.arap.relativeTolerance = o.cageArap.relativeTolerance = args.tolerance;
  o.cageArap.rotationClusters = args.clusters;
  o.cageArap.handleWeight = args.handleWeight;
  o.cageArap.reachTolerance = args.reachTolerance;
  return o;
}

// `normalTerms`: set when the cage coordinates have columns besides the vertices' (Green's face
// normals), which cage-arap keeps at rest.
SurfaceEdit editWith(const EditArgs& args, const SurfaceMesh& mesh, const VertexConstraints& c,
                     const CliContext& context, bool& normalTerms) {
  const ProgressCallback progress = context.progress();
  SurfaceEditOptions options = editOptions(args);
  std::string controls;  // cage-arap: the coordinates of the cage or of the lattice
  if (options.method == SurfaceEditMethod::CageArap) {
    if (args.lattice.empty()) {
      auto cage = std::make_shared<const Cage>(Cage::fromFile(args.cage));
      options.coordinates = namingFile(args.cage, [&] {
        return cageCoordinates(args.coordinates, cage, args.cageOptions, progress);
      });
      normalTerms = options.coordinates->columnCount() > options.coordinates->controlPointCount();
      controls =
          args.coordinates + " coordinates of " + countedVertices(cage->vertexCount(), "cage ");
    } else {
      const json rig = readRigFile(args.lattice);
      if (!rig.is_object() || rig.value("method", json()) != "ffd")
        throw InvalidInput(printable(args.lattice) +
                           ": --lattice takes an ffd rig (\"method\": \"ffd\")");
      options.coordinates = loadRigFile(args.lattice, context).coordinates;
      controls =
          "the lattice's " + counted(options.coordinates->controlPointCount(), "control point");
    }
  }
  SurfaceEdit edit = namingFile(args.model, [&] { return editMesh(mesh, c, options, progress); });
  warnHeld(args.model, mesh, edit.heldVertices, context);
  if (edit.arapReport) {
    const ArapReport& r = *edit.arapReport;
    reportIterations("arap", r.iterations, r.energies, r.converged, r.startedRigid, args, context);
  }
  if (edit.cageArapReport) {
    const CageArapReport& r = *edit.cageArapReport;
    char residual[64];
    std::snprintf(residual, sizeof residual, "max handle residual %.3g", r.maxResidual);
    note(context, "cage-arap: " + counted(edit.clusterCount, "rotation cluster") + ", " + controls +
                      ", " + residual);
    reportIterations("cage-arap", r.iterations, r.energies, r.converged, r.startedRigid, args,
                     context);
    if (!r.unreached.empty()) {
      const std::vector<std::uint32_t> soupOf = firstSoupVertex(mesh);
      std::vector<std::uint32_t> unreached;
      for (const std::uint32_t v : r.unreached) unreached.push_back(soupOf[v]);
      char tolerance[32];
      std::snprintf(tolerance, sizeof tolerance, "%g", args.reachTolerance);
      context.warn(args.model + ": " + countedVertices(unreached.size(), "handle ") +
                   " left farther than --reach-tolerance " + tolerance +
                   " of the model's size from their targets (" + residual + "): vertices " +
                   someVertices(unreached) + "; the " +
                   (args.lattice.empty() ? "cage" : "lattice") +
                   " cannot carry them there rigidly (raise --handle-weight, or refine it)");
    }
  }
  return edit;
}

// The posed lattice: the ffd rig with its control points replaced (the fit's keys, if it had
// them, removed), so that `deform --rig` carries the edit.
void writePosedLattice(const EditArgs& args, std::span<const Vec3> posed) {
  json rig = readRigFile(args.lattice);
  rig.erase("constraints");
  rig.erase("smoothness");
  json points = json::array();
  for (const Vec3& p : posed) points.push_back({p.x, p.y, p.z});
  rig["controlPoints"] = std::move(points);
  writeJsonFile(rig, args.latticeOut);
}

// The posed cage: the rest cage file's soup (faces, attributes) with the cage vertices moved.
void writePosedCage(const EditArgs& args, PolygonSoup cage, std::span<const Vec3> posed,
                    const CliContext& context) {
  if (cage.positions.size() != posed.size())
    throw InvalidInput(args.cage + ": the cage has " + std::to_string(cage.positions.size()) +
                       " vertices but its coordinates " + std::to_string(posed.size()) +
                       " control points");
  std::copy(posed.begin(), posed.end(), cage.positions.begin());
  cage.normals.clear();  // a posed cage's normals would be stale
  cage.cornerNormals = {};
  writeSoupFile(cage, args.cageOut, false, context);
}

// Outputs are checked before the work: a folder that does not exist would otherwise be found
// only when the result is ready to be written.
void checkOutputFolders(std::initializer_list<std::string> outputs) {
  for (const std::string& output : outputs) {
    if (output.empty()) continue;
    const fs::path folder = fs::path(output).parent_path();
    std::error_code error;
    if (!folder.empty() && !fs::is_directory(folder, error))
      throw IoError(printable(output) + ": cannot write: the folder " + printable(folder.string()) +
                    " does not exist");
  }
}

}  // namespace

void runEdit(const EditArgs& args, const CliContext& context) {
  const auto start = std::chrono::steady_clock::now();
  formatFromPath(args.output);
  if (!args.cageOut.empty()) formatFromPath(args.cageOut);
  checkOutputFolders({args.output, args.cageOut, args.latticeOut});
  // The rest cage as read now: the posed one is written from it, even when -o replaces the
  // cage's file.
  const PolygonSoup restCage = args.cageOut.empty() ? PolygonSoup{} : readSoup(args.cage);
  PolygonSoup soup = readSoup(args.model);
  WeldOptions weld;
  weld.relativeTolerance = args.weldTolerance;
  const SurfaceMesh mesh = namingFile(args.model, [&] { return weldSoup(soup, weld); });
  if (mesh.triangles.empty())
    throw InvalidInput(args.model +
                       ": has no triangle to edit (welding collapsed every one of its " +
                       counted(soup.polygonCount(), "face") + ")");
  // The handles are checked before any warning, so that a refused run prints one line.
  const VertexConstraints constraints = readConstraints(args.handles, soup, mesh);
  warnAboutTheMesh(args.model, mesh, context);

  bool normalTerms = false;
  const SurfaceEdit edited = editWith(args, mesh, constraints, context, normalTerms);
  applyEdit(soup, mesh, edited.positions);
  if (normalTerms)
    context.warn("--coordinates " + args.coordinates +
                 ": cage-arap moves the vertex terms only (the face normals' terms stay at "
                 "rest), so it does not reproduce rotations exactly; mvc and harmonic do");
  writeSoupFile(soup, args.output, args.ascii, context);
  if (!args.latticeOut.empty()) writePosedLattice(args, edited.controlPoints);
  if (!args.cageOut.empty()) {
    writePosedCage(args, restCage, edited.controlPoints, context);
    // The edit keeps Green's face-normal columns at rest; a Green deform of the posed cage
    // recomputes them from it.
    if (normalTerms)
      context.warn("--cage-out " + args.cageOut + ": with --coordinates " + args.coordinates +
                   ", `deform --method " + args.coordinates +
                   "` of this pose does not reproduce the edit exactly (the edit keeps the face "
                   "normals' terms at rest)");
  }
  warnNotKept(args.model, soup, context);

  const std::string what =
      countedVertices(mesh.vertexCount(), "") + " (" + counted(mesh.triangles.size(), "triangle") +
      ", " + countedVertices(constraints.vertices.size(), "handle ") + ") by " + args.method;
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  std::string output = args.output;
  if (!args.cageOut.empty()) output += " and " + args.cageOut;
  if (!args.latticeOut.empty()) output += " and " + args.latticeOut;
  context.say(summaryLine("edited", what, seconds, output, context.warnings()));
}

namespace {

const CLI::Validator kHandleWeight(
    [](std::string& value) -> std::string {
      double t = 0.0;
      if (CLI::detail::lexical_cast(value, t) && t > 0.0 && t <= 1e6) return {};
      return "'" + value + "' is not a number > 0 and at most 1e6";
    },
    "NUMBER in (0, 1e6]");

const CLI::Validator kCount(
    [](std::string& value) -> std::string {
      long long n = 0;
      if (CLI::detail::lexical_cast(value, n) && n >= 0) return {};
      return "'" + value + "' is not a whole number >= 0";
    },
    "COUNT");

}  // namespace

Command addEditCommand(CLI::App& app, const CliContext& context) {
  auto args = std::make_shared<EditArgs>();
  const ArapOptions arap;
  const CageArapOptions cageArap;
  char text[256];

  CLI::App* cmd = app.add_subcommand(
      "edit",
      "Edit a surface (OBJ, OFF, PLY mesh) by moving handle regions: Laplacian, bi-Laplacian, "
      "as-rigid-as-possible, or ARAP in a cage's subspace");
  cmd->add_option("--method", args->method,
                  "laplacian | bilaplacian (linear: follow translations, not rotations) | arap | "
                  "cage-arap (ARAP through a cage's coordinates, with --cage)")
      ->check(CLI::IsMember({"laplacian", "bilaplacian", "arap", "cage-arap"}))
      ->required();
  cmd->add_option("--handles", args->handles,
                  "JSON file {\"handles\": [{\"vertices\": [i, ...], \"matrix\": [4 rows of 4]} or "
                  "{\"vertices\": [...], \"targets\": [[x, y, z], ...]}, ...]}; indices in the "
                  "model's file order")
      ->required();
  cmd->add_option("MODEL", args->model, "the surface to edit (.obj, .off, .ply)")->required();
  cmd->add_option("-o,--output", args->output,
                  "output file (.obj, .off, .ply): the model with its vertices moved")
      ->required();
  auto* asciiOption =
      cmd->add_flag("--ascii", args->ascii, "write PLY as ASCII rather than binary little-endian");
  std::snprintf(text, sizeof text,
                "vertices closer than this × the model's bounding-box diagonal are welded into "
                "one (default %g)",
                args->weldTolerance);
  cmd->add_option("--weld-tolerance", args->weldTolerance, text)->check(kFiniteNonNegative);

  const std::vector<CLI::Option*> iterative = optionsAddedBy(cmd, [&] {
    cmd->add_option("--iterations", args->iterations,
                    "arap, cage-arap: at most this many local/global iterations (default " +
                        std::to_string(arap.maxIterations) + " for arap, " +
                        std::to_string(cageArap.maxIterations) + " for cage-arap)")
        ->check(CLI::Range(1, 1000000));
    std::snprintf(text, sizeof text,
                  "arap, cage-arap: stop when an iteration lowers the energy by less than this "
                  "fraction (default %g for arap, %g for cage-arap; 0 runs every iteration)",
                  arap.relativeTolerance, cageArap.relativeTolerance);
    cmd->add_option("--tolerance", args->tolerance, text)->check(kFiniteNonNegative);
    cmd->add_option("--acceleration", args->acceleration,
                    "arap, cage-arap: Anderson acceleration over the last M iterations (default " +
                        std::to_string(arap.accelerationWindow) +
                        "; 0: the plain local/global iteration)")
        ->check(CLI::Range(0, 50));
    cmd->add_option("--energy", args->energy,
                    "arap, cage-arap: the edges each vertex's rotation acts on: "
                    "spokes-and-rims (its triangles' edges; bounded below with obtuse triangles; "
                    "default) | spokes (its one-ring edges, Sorkine and Alexa 2007)")
        ->check(CLI::IsMember({"spokes-and-rims", "spokes"}));
  });
  for (CLI::Option* option : iterative) option->group("Options of --method arap and cage-arap");

  const std::vector<CLI::Option*> cageOnly = optionsAddedBy(cmd, [&] {
    cmd->add_option("--cage", args->cage, "cage-arap: the cage (closed mesh) around the model");
    std::string coordinateList;
    for (const std::string& m : cageMethods())
      coordinateList += (coordinateList.empty() ? "" : "|") + m;
    cmd->add_option("--coordinates", args->coordinates,
                    "cage-arap: the cage coordinates (" + coordinateList + "; default mvc)")
        ->check(CLI::IsMember(cageMethods()));
    cmd->add_option("--cage-out", args->cageOut,
                    "cage-arap: also write the posed cage (the rest cage's faces), for `spacewarp "
                    "deform --method mvc --cage CAGE --pose POSED` of clouds and volumes");
    cmd->add_option("--lattice", args->lattice,
                    "cage-arap: instead of --cage, an ffd rig (JSON) whose lattice's coordinates "
                    "carry the model (its pose is ignored: the edit starts at rest)");
    cmd->add_option("--lattice-out", args->latticeOut,
                    "cage-arap with --lattice: also write the ffd rig with the posed control "
                    "points, for `spacewarp deform --rig`");
    cmd->add_option("--clusters", args->clusters,
                    "cage-arap: rotation clusters (default 0: 4 per cage vertex, at least 64, at "
                    "most the vertex count)")
        ->check(kCount);
    std::snprintf(text, sizeof text,
                  "cage-arap: weight of the handles against rigidity, relative to the mesh's "
                  "stiffness (default %g, at most 1e6)",
                  cageArap.handleWeight);
    cmd->add_option("--handle-weight", args->handleWeight, text)->check(kHandleWeight);
    std::snprintf(text, sizeof text,
                  "cage-arap: warn about handle vertices farther than this × the model's "
                  "bounding-box diagonal from their targets (default %g)",
                  cageArap.reachTolerance);
    cmd->add_option("--reach-tolerance", args->reachTolerance, text)->check(kFiniteNonNegative);
  });
  for (CLI::Option* option : cageOnly) option->group("Options of --method cage-arap");
  const std::vector<CLI::Option*> harmonic =
      optionsAddedBy(cmd, [&] { addCageMethodOptions(cmd, args->cageOptions); });
  for (CLI::Option* option : harmonic)
    option->group(
        "Options of --method cage-arap --coordinates harmonic (--outside: also wachspress, "
        "discrete-harmonic)");
  CLI::Option* cageOption = cageOnly.front();

  cmd->callback([args, cmd, asciiOption, iterative, harmonic, cageOnly, cageOption] {
    if (fileKind(args->model) == FileKind::Volume)
      throw CLI::ValidationError(args->model + ": edit takes a surface mesh (.obj, .off, .ply)");
    checkConversion(args->model, args->output);
    if (formatFromPath(args->output) != FileFormat::Ply)
      rejectGiven({asciiOption}, "applies to .ply output only, not to " + args->output);
    const std::string method = "--method " + args->method;
    if (args->method != "arap" && args->method != "cage-arap")
      rejectGiven(iterative, "applies to --method arap and cage-arap only, not to " + method);
    if (args->method != "cage-arap") {
      rejectGiven(cageOnly, "applies to --method cage-arap only, not to " + method);
      rejectGiven(harmonic, "applies to --method cage-arap with --coordinates that take it only");
      return;
    }
    if (!args->lattice.empty()) {
      if (cageOption->count() > 0)
        throw CLI::ValidationError("--lattice and --cage: give one, the controls of cage-arap");
      for (CLI::Option* option : cageOnly)
        if (option->count() > 0 &&
            (option->get_name() == "--coordinates" || option->get_name() == "--cage-out"))
          throw CLI::ValidationError(option->get_name() + " applies to --cage, not to --lattice");
      rejectGiven(harmonic, "applies to --cage with --coordinates that take it, not to --lattice");
      if (!args->latticeOut.empty() && lowerExtension(args->latticeOut) != ".json")
        throw CLI::ValidationError("--lattice-out " + args->latticeOut +
                                   ": the posed lattice is an ffd rig, written as .json");
      return;
    }
    if (cageOption->count() == 0)
      throw CLI::RequiredError("--cage (or --lattice; --method cage-arap needs its controls)");
    if (!args->latticeOut.empty())
      throw CLI::ValidationError("--lattice-out applies to --lattice, not to --cage");
    checkCageMethodOptions(*cmd, args->coordinates, "--coordinates");
    if (!args->cageOut.empty()) {
      checkConversion(args->cage, args->cageOut);
      std::error_code error;
      if (fs::weakly_canonical(fs::absolute(args->output), error) ==
          fs::weakly_canonical(fs::absolute(args->cageOut), error))
        throw CLI::ValidationError("-o and --cage-out name the same file, " + args->output +
                                   ": give the edited model and the posed cage a file each");
    }
  });
  return {cmd, [args, &context] { runEdit(*args, context); }};
}

}  // namespace spacewarp::cli
