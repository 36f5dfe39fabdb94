// spacewarp deform (--rig RIG | --method M --cage C --pose P) INPUT -o OUTPUT: warps a soup,
// a point cloud or (by extension) an OpenVDB volume.

#include "apps/cage_methods.h"
#include "apps/commands.h"
#include "apps/jobs.h"
#include "apps/rig.h"
#include "apps/volume_command.h"

namespace spacewarp::cli {

namespace {

struct DeformArgs {
  std::string rig, input, output, method, cage, pose;
  bool ascii = false;
  CageMethodOptions cageOptions;
  VolumeCliOptions volumeOptions;
};

}  // namespace

Command addDeformCommand(CLI::App& app, const CliContext& context) {
  auto args = std::make_shared<DeformArgs>();
  std::string methodList;
  for (const std::string& m : cageMethods()) methodList += (methodList.empty() ? "" : "|") + m;

  CLI::App* cmd = app.add_subcommand(
      "deform",
      "Warp a polygon soup or point cloud (OBJ, OFF, PLY) or a volume (VDB) with the warp a rig "
      "describes");
  auto* rigOption =
      cmd->add_option("--rig", args->rig, "JSON rig file (see README.md for every method's keys)");
  auto* methodOption =
      cmd->add_option("--method", args->method,
                      "cage coordinates (" + methodList + "), with --cage and --pose")
          ->check(CLI::IsMember(cageMethods()));
  auto* cageOption = cmd->add_option("--cage", args->cage, "rest cage (closed mesh)");
  auto* poseOption = cmd->add_option("--pose", args->pose, "posed cage, same vertex order");
  rigOption->excludes(methodOption);
  methodOption->needs(cageOption, poseOption);
  cageOption->needs(methodOption);
  poseOption->needs(methodOption);
  addCageMethodOptions(cmd, args->cageOptions);
  cmd->add_option("INPUT", args->input, "input file; its format follows its extension")->required();
  cmd->add_option("-o,--output", args->output, "output file; its format follows its extension")
      ->required();
  cmd->add_flag("--ascii", args->ascii, "write PLY as ASCII rather than binary little-endian");
  addVolumeOptions(cmd, args->volumeOptions);
  cmd->callback([args] {
    if (args->rig.empty() && args->method.empty()) throw CLI::RequiredError("--rig or --method");
  });

  return {cmd, [args, &context] {
            const ProgressCallback progress = context.progress();
            const Rig rig = args->rig.empty() ? cageRig(args->method, args->cage, args->pose,
                                                        args->cageOptions, progress)
                                              : loadRig(args->rig);
            if (isVolumePath(args->input)) {
              deformVolumeFile(*rig.warp, args->input, args->output, args->volumeOptions, context);
            } else {
              deformSoupFile(*rig.warp, args->input, args->output, args->ascii, progress);
            }
          }};
}

}  // namespace spacewarp::cli
