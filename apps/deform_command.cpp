// spacewarp deform (--rig RIG | --method M --cage C --pose P) INPUT -o OUTPUT: warps a soup,
// a point cloud or (by extension) an OpenVDB volume.

#include <chrono>

#include <spacewarp/core/io/mesh_io.h>
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

void runDeform(const DeformArgs& args, const CliContext& context) {
  const auto start = std::chrono::steady_clock::now();
  const ProgressCallback progress = context.progress();
  const bool volume = fileKind(args.input) == FileKind::Volume;
  // The input is checked (a volume) or read (a soup) before the rig, whose solve may be the
  // longest part of the work.
  PolygonSoup soup;
  if (volume)
    checkVolumeFile(args.input);
  else
    soup = readSoup(args.input);
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
  const std::vector<CLI::Option*> volumeOptions =
      optionsAddedBy(cmd, [&] { addVolumeOptions(cmd, args->volumeOptions); });
  for (CLI::Option* option : volumeOptions) option->group("Options of volume (.vdb) input");

  // Everything the command line alone decides is checked here, before any file is read or
  // any rig is solved: options that do not apply are usage errors, not silently ignored.
  cmd->callback([args, cmd, asciiOption, volumeOptions] {
    if (args->rig.empty() && args->method.empty()) throw CLI::RequiredError("--rig or --method");
    checkConversion(args->input, args->output);
    checkCageMethodOptions(*cmd, args->method);
    if (fileKind(args->input) != FileKind::Volume)
      rejectGiven(volumeOptions, "applies to volume (.vdb) input only, not to " + args->input);
    if (fileKind(args->output) == FileKind::Volume ||
        formatFromPath(args->output) != FileFormat::Ply)
      rejectGiven({asciiOption}, "applies to .ply output only, not to " + args->output);
  });
  return {cmd, [args, &context] { runDeform(*args, context); }};
}

}  // namespace spacewarp::cli
