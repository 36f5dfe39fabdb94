// spacewarp weights (--rig RIG | --method M --cage C) POINTS -o OUT.csv|OUT.npy: the
// coordinate matrix of a set of points.

#include <spacewarp/core/errors.h>
#include <spacewarp/rig/rig.h>
#include "apps/cage_options.h"
#include "apps/commands.h"
#include "apps/jobs.h"

namespace spacewarp::cli {

namespace {

struct WeightsArgs {
  std::string rig, method, cage, points, output;
  CageMethodOptions cageOptions;
};

}  // namespace

Command addWeightsCommand(CLI::App& app, const CliContext& context) {
  auto args = std::make_shared<WeightsArgs>();
  std::string methodList;
  for (const std::string& m : cageMethods()) methodList += (methodList.empty() ? "" : "|") + m;

  CLI::App* cmd = app.add_subcommand(
      "weights",
      "Write the coordinate matrix of points (cage, lattice or RBF coordinates) as CSV or .npy");
  auto* rigOption =
      cmd->add_option("--rig", args->rig, "a rig whose method has coordinates (mvc, green, ...)");
  auto* methodOption =
      cmd->add_option("--method", args->method, methodList)->check(CLI::IsMember(cageMethods()));
  auto* cageOption = cmd->add_option("--cage", args->cage, "rest cage (closed mesh)");
  rigOption->excludes(methodOption);
  methodOption->needs(cageOption);
  cageOption->needs(methodOption);
  addCageMethodOptions(cmd, args->cageOptions);
  cmd->callback([args, cmd] {
    if (args->rig.empty() && args->method.empty()) throw CLI::RequiredError("--rig or --method");
    checkCageMethodOptions(*cmd, args->method);
  });
  cmd->add_option("POINTS", args->points, "points (any supported file; faces ignored)")->required();
  cmd->add_option("-o,--output", args->output,
                  "CSV (header + one row per point) or NumPy .npy (float64, points × columns)")
      ->required();

  return {cmd, [args, &context] {
            std::shared_ptr<const Coordinates> coordinates;
            if (args->rig.empty()) {
              auto cage = std::make_shared<const Cage>(Cage::fromFile(args->cage));
              coordinates = namingFile(args->cage, [&] {
                return cageCoordinates(args->method, cage, args->cageOptions, context.progress());
              });
            } else {
              coordinates = loadRigFile(args->rig, context).coordinates;
              if (!coordinates)
                throw InvalidInput(args->rig + ": this rig's method has no coordinates to export");
            }
            writeWeightsFile(*coordinates, args->points, args->output);
          }};
}

}  // namespace spacewarp::cli
