// spacewarp deform (--rig RIG | --method M --cage C --pose P) INPUT -o OUTPUT: warps a soup,
// a point cloud or (by extension) an OpenVDB volume.

#include <algorithm>
#include <charconv>
#include <chrono>
#include <filesystem>
#include <limits>
#include <optional>

#include <spacewarp/core/deform_stream.h>
#include <spacewarp/core/io/mesh_io.h>
#include <spacewarp/core/io/ply_stream.h>
#include <spacewarp/rig/rig.h>
#include "apps/cage_options.h"
#include "apps/commands.h"
#include "apps/file_kinds.h"
#include "apps/jobs.h"
#include "apps/volume_command.h"

namespace spacewarp::cli {

namespace {

struct DeformArgs {
  std::string rig, input, output, method, cage, pose;
  bool ascii = false;
  std::string chunkText;                     // --chunk-points as given, parsed into chunkPoints
  std::optional<std::uint64_t> chunkPoints;  // none: automatic; 0: never stream
  CageMethodOptions cageOptions;
  VolumeCliOptions volumeOptions;
};

// --rig, or --method with --cage and --pose: where the warp comes from.
void addWarpOptions(CLI::App* cmd, DeformArgs& args) {
  std::string methodList;
  for (const std::string& m : cageMethods()) methodList += (methodList.empty() ? "" : "|") + m;
  auto* rigOption =
      cmd->add_option("--rig", args.rig, "JSON rig file (see README.md for every method's keys)");
  auto* methodOption =
      cmd->add_option("--method", args.method,
                      "cage coordinates (" + methodList + "), with --cage and --pose")
          ->check(CLI::IsMember(cageMethods()));
  auto* cageOption = cmd->add_option("--cage", args.cage, "rest cage (closed mesh)");
  auto* poseOption = cmd->add_option("--pose", args.pose, "posed cage, same vertex order");
  rigOption->excludes(methodOption);
  methodOption->needs(cageOption, poseOption);
  cageOption->needs(methodOption);
  poseOption->needs(methodOption);
  addCageMethodOptions(cmd, args.cageOptions);
}

// Binary PLY inputs at least this large are streamed (deformFileStreaming) when --chunk-points
// is not given: the in-memory path holds about 5 times a float-xyz file's size (positions in
// double, the warped copy, the output buffer), so past a few hundred MB it is streaming that
// keeps a deform within a small machine's memory. Below it, both paths take about the same time.
constexpr std::uintmax_t kStreamBytes = std::uintmax_t{256} << 20;

// --chunk-points N: a whole number of points, 0 up to 2^64 - 1.
std::optional<std::uint64_t> chunkCount(const std::string& text) {
  std::uint64_t n = 0;
  const char* end = text.data() + text.size();
  const auto [stop, error] = std::from_chars(text.data(), end, n);
  if (text.empty() || error != std::errc() || stop != end) return std::nullopt;
  return n;
}

// Whether to stream: binary PLY in and PLY out (other outputs and ASCII PLY input are read
// whole, see --chunk-points), forced by --chunk-points N or automatic above kStreamBytes.
bool streams(const DeformArgs& args) {
  if (args.chunkPoints == std::uint64_t{0} || formatFromPath(args.output) != FileFormat::Ply)
    return false;
  if (!isStreamablePly(args.input)) return false;
  if (args.chunkPoints) return true;
  std::error_code error;
  const std::uintmax_t bytes = std::filesystem::file_size(args.input, error);
  return !error && bytes >= kStreamBytes;
}

void runDeform(const DeformArgs& args, const CliContext& context) {
  const auto start = std::chrono::steady_clock::now();
  const ProgressCallback progress = context.progress();
  const bool volume = fileKind(args.input) == FileKind::Volume;
  // The input is checked (a volume), read (a soup) or its header read (a streamed PLY) before
  // the rig, whose solve may be the longest part of the work.
  PolygonSoup soup;
  const bool streamed = !volume && streams(args);
  if (volume) {
    checkVolumeFile(args.input);
  } else if (!streamed) {
    if (args.chunkPoints.value_or(0) > 0) {
      context.warn(args.input +
                   ": read whole, --chunk-points ignored: only a binary PLY regular file (not "
                   "ASCII, not a pipe) streams");
    }
    soup = readSoup(args.input);
  }
  const Rig rig = args.rig.empty()
                      ? cageRig(args.method, args.cage, args.pose, args.cageOptions, progress)
                      : loadRigFile(args.rig, context);
  std::string what;
  if (volume) {
    const VolumeSummary s =
        deformVolumeFile(*rig.warp, args.input, args.output, args.volumeOptions, context);
    what = counted(s.grids, "grid") + " (" + counted(s.activeVoxels, "active voxel");
    if (s.points > 0) what += ", " + counted(s.points, "point");
    what += ", " + counted(s.inverseFailures, "inverse failure") + ")";
  } else if (streamed) {
    StreamDeformOptions options;
    // Past the size_t range a chunk is all the rows anyway (deformFileStreaming clamps it).
    if (args.chunkPoints) {
      options.chunkPoints = static_cast<std::size_t>(
          std::min<std::uint64_t>(*args.chunkPoints, std::numeric_limits<std::size_t>::max()));
    }
    options.ascii = args.ascii;
    options.progress = progress;
    const StreamDeformReport r = deformFileStreaming(*rig.warp, args.input, args.output, options);
    PolygonSoup notKept;
    notKept.notKept = r.notKept;
    warnNotKept(args.input, notKept, context);
    warnSingularNormals(args.input, r.singularNormals, r.points, context);
    what = counted(r.points, "point");
    if (r.faces > 0) what += " (" + counted(r.faces, "face") + ")";
    what += ", streamed in " + counted(r.chunks, "chunk");
  } else {
    deformSoup(*rig.warp, soup, args.input, args.output, args.ascii, context);
    what = counted(soup.size(), "point");
    if (soup.polygonCount() > 0) what += " (" + counted(soup.polygonCount(), "face") + ")";
  }
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  context.say(summaryLine("deformed", what, seconds, args.output, context.warnings()));
}

}  // namespace

Command addDeformCommand(CLI::App& app, const CliContext& context) {
  auto args = std::make_shared<DeformArgs>();
  CLI::App* cmd = app.add_subcommand(
      "deform",
      "Warp a polygon soup or point cloud (OBJ, OFF, PLY) or a volume (VDB) with the warp a rig "
      "describes");
  addWarpOptions(cmd, *args);
  cmd->add_option("INPUT", args->input,
                  "input file; its kind and format follow its extension (.obj, .off, .ply: soup "
                  "or point cloud; .vdb: volume)")
      ->required();
  cmd->add_option("-o,--output", args->output,
                  "output file, of the input's kind (a soup or cloud converts to any of .obj, "
                  ".off, .ply; a volume is written as .vdb); may be the input itself")
      ->required();
  auto* asciiOption =
      cmd->add_flag("--ascii", args->ascii, "write PLY as ASCII rather than binary little-endian");
  auto* chunkOption =
      cmd->add_option(
             "--chunk-points", args->chunkText,
             "stream a binary PLY input: read, warp and write N points at a time (output "
             "identical; memory grows with N, about 200 MB for 1048576 float-xyz points, three "
             "chunks being in flight); 0 = never stream. Without it, binary PLY inputs of 256 MiB "
             "(268435456 bytes) or more stream in chunks of 1048576 points. Only a binary PLY "
             "regular file streams, to .ply output only; an ASCII PLY or a pipe is read whole, "
             "with a warning")
          ->check(CLI::Validator(
              [](std::string& value) -> std::string {
                if (chunkCount(value)) return {};
                return "'" + value + "' is not a non-negative integer below 2^64";
              },
              "N"))
          ->type_name("UINT");
  const std::vector<CLI::Option*> volumeOptions =
      optionsAddedBy(cmd, [&] { addVolumeOptions(cmd, args->volumeOptions); });
  for (CLI::Option* option : volumeOptions) option->group("Options of volume (.vdb) input");

  // Everything the command line alone decides is checked here, before any file is read or
  // any rig is solved: options that do not apply are usage errors, not silently ignored.
  cmd->callback([args, cmd, asciiOption, chunkOption, volumeOptions] {
    if (args->rig.empty() && args->method.empty()) throw CLI::RequiredError("--rig or --method");
    checkConversion(args->input, args->output);
    checkCageMethodOptions(*cmd, args->method);
    if (fileKind(args->input) != FileKind::Volume)
      rejectGiven(volumeOptions, "applies to volume (.vdb) input only, not to " + args->input);
    if (fileKind(args->output) == FileKind::Volume ||
        formatFromPath(args->output) != FileFormat::Ply)
      rejectGiven({asciiOption}, "applies to .ply output only, not to " + args->output);
    if (fileKind(args->input) == FileKind::Volume || formatFromPath(args->input) != FileFormat::Ply)
      rejectGiven({chunkOption}, "applies to .ply input only, not to " + args->input);
    if (fileKind(args->output) == FileKind::Volume ||
        formatFromPath(args->output) != FileFormat::Ply)
      rejectGiven({chunkOption}, "applies to .ply output only, not to " + args->output);
    if (chunkOption->count() > 0) args->chunkPoints = chunkCount(args->chunkText);
  });
  return {cmd, [args, &context] { runDeform(*args, context); }};
}

}  // namespace spacewarp::cli
