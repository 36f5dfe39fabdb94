// spacewarp inverse --rig RIG INPUT -o OUTPUT: moves the points of a soup or point cloud to
// their preimages under the rig's warp, so that `deform` with the same rig gives them back.

#include <chrono>
#include <cmath>
#include <cstdio>
#include <string>

#include <spacewarp/core/deform.h>
#include <spacewarp/core/errors.h>
#include <spacewarp/core/inverse.h>
#include <spacewarp/core/io/mesh_io.h>
#include <spacewarp/rig/rig.h>
#include "apps/commands.h"
#include "apps/file_kinds.h"
#include "apps/jobs.h"

namespace spacewarp::cli {

namespace {

struct InverseArgs {
  std::string rig, input, output;
  bool ascii = false;
  InverseOptions options;
};

}  // namespace

Command addInverseCommand(CLI::App& app, const CliContext& context) {
  auto args = std::make_shared<InverseArgs>();
  const InverseOptions defaults;

  CLI::App* cmd = app.add_subcommand(
      "inverse",
      "Move the points of a polygon soup or point cloud (OBJ, OFF, PLY) to their preimages under "
      "a rig's warp: the inverse of deform");
  cmd->add_option("--rig", args->rig, "JSON rig file (see README.md for every method's keys)")
      ->required();
  cmd->add_option("INPUT", args->input,
                  "input soup or point cloud (.obj, .off, .ply); its points are the warped ones")
      ->required();
  cmd->add_option("-o,--output", args->output,
                  "output file (.obj, .off, .ply: any of them, whatever the input's format); "
                  "may be the input itself")
      ->required();
  cmd->add_flag("--ascii", args->ascii, "write PLY as ASCII rather than binary little-endian");
  char tolerance[32];
  std::snprintf(tolerance, sizeof tolerance, "%g", defaults.tolerance);
  cmd->add_option("--tolerance", args->options.tolerance,
                  std::string("a point has converged when |warp(x) - y| <= this × the input's "
                              "bounding-box diagonal (default ") +
                      tolerance + ")")
      ->check(kFinitePositive);
  cmd->add_option("--max-iterations", args->options.maxIterations,
                  "Newton steps at most per point before the continuation fallback, which takes "
                  "up to 32 times this (default " +
                      std::to_string(defaults.maxIterations) + ")")
      ->check(CLI::Range(1, 1000000));

  cmd->callback([args] {
    if (fileKind(args->input) == FileKind::Volume)
      throw CLI::ValidationError(
          args->input +
          ": inverse maps the points of soups and point clouds; a volume is resampled by "
          "deform, which solves the inverse for each output voxel itself");
    checkConversion(args->input, args->output);
    if (formatFromPath(args->output) != FileFormat::Ply && args->ascii)
      throw CLI::ValidationError("--ascii applies to .ply output only, not to " + args->output);
  });

  return {cmd, [args, &context] {
            const auto start = std::chrono::steady_clock::now();
            formatFromPath(args->output);
            PolygonSoup soup = readSoup(args->input);
            const Rig rig = loadRigFile(args->rig, context);
            // The tolerance is relative to the input's scale, not to each point's distance from
            // the origin (points near it would otherwise be held to a tolerance below rounding).
            InverseOptions options = args->options;
            const double diagonal = boundingBox(soup.positions).diagonal();
            if (diagonal > 0.0 && std::isfinite(diagonal)) options.lengthScale = diagonal;
            const InverseDeformReport report = namingFile(args->input, [&] {
              return deformInverse(*rig.warp, soup, options, context.progress());
            });
            writeSoupFile(soup, args->output, args->ascii, context);
            warnNotKept(args->input, soup, context);
            warnSingularNormals(args->input, report.singularNormals, soup.size(), context);
            std::string what = counted(soup.size(), "point") + " (";
            if (soup.polygonCount() > 0) what += counted(soup.polygonCount(), "face") + "; ";
            char residual[32];
            std::snprintf(residual, sizeof residual, "%.3g", report.maxResidual);
            what += groupDigits(report.closedForm) + " by the closed form, " +
                    groupDigits(report.iterative) + " iterative";
            if (report.continuation > 0)
              what += " (" + groupDigits(report.continuation) + " with continuation)";
            what += ", worst residual " + std::string(residual) + ")";
            const double seconds =
                std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
            context.say(summaryLine("inverted", what, seconds, args->output, context.warnings()));
          }};
}

}  // namespace spacewarp::cli
