// spacewarp compare --cage CAGE [--methods a,b,...] (--slice AXIS=VALUE | --point X,Y,Z
// --normal X,Y,Z) [--control I] [--resolution N] -o DIR
//
// A method that fails is a warning on stderr (even with --quiet: it is not information but a
// missing result) and a "failed" entry in the reports; the exit code stays 0 while at least
// one method succeeded, since the others' comparison is still worth having. When every method
// fails the reports are still written (they hold the reasons) and the exit code is 4.

#include <algorithm>
#include <charconv>

#include <spacewarp/core/errors.h>
#include "apps/cage_options.h"
#include "apps/commands.h"
#include "apps/compare.h"

namespace spacewarp::cli {

namespace {

struct CompareArgs {
  CompareRequest request;
  std::string cage, methods, slice, output;
  std::vector<double> point, normal;
};

// "z=0.25" → axis 2, 0.25, and ""; otherwise what is wrong with `text`, the axis or the value.
std::string parseSlice(const std::string& text, int& axis, double& value) {
  const std::string axes = "xyz";
  const auto found = text.size() < 2 || text[1] != '=' ? std::string::npos : axes.find(text[0]);
  if (found == std::string::npos) return "expected AXIS=VALUE with AXIS x, y or z";
  axis = static_cast<int>(found);
  const char* end = text.data() + text.size();
  const auto result = std::from_chars(text.data() + 2, end, value);
  if (result.ec != std::errc() || result.ptr != end || !std::isfinite(value))
    return "the VALUE of AXIS=VALUE must be a finite number, not '" + text.substr(2) + "'";
  return "";
}

std::vector<std::string> split(const std::string& list) {
  std::vector<std::string> parts;
  if (list.empty()) return parts;  // no --methods: every method
  std::size_t start = 0;
  while (start <= list.size()) {
    const std::size_t comma = std::min(list.find(',', start), list.size());
    parts.push_back(list.substr(start, comma - start));  // "" for ",," : reported as unknown
    start = comma + 1;
  }
  return parts;
}

// The --methods check: known names, none twice. `known` is the comma-separated list.
std::string checkMethodList(const std::string& list, const std::string& known) {
  const auto names = split(list);
  if (list.empty()) return "expected a comma-separated list of methods";
  for (std::size_t k = 0; k < names.size(); ++k) {
    if (("," + known + ",").find("," + names[k] + ",") == std::string::npos)
      return "unknown method '" + names[k] + "' (one of: " + known + ")";
    // Twice the same panel is a typo, not a comparison: say so rather than guess.
    if (std::find(names.begin(), names.begin() + k, names[k]) != names.begin() + k)
      return "method '" + names[k] + "' is listed twice";
  }
  return {};
}

// --slice, or --point with --normal: the plane of the images.
void addPlaneOptions(CLI::App* cmd, CompareArgs& args) {
  auto* sliceOption =
      cmd->add_option("--slice", args.slice, "axis-aligned plane, e.g. z=0.5 (world units)")
          ->check([](const std::string& text) -> std::string {
            int axis;
            double value;
            return parseSlice(text, axis, value);
          });
  auto* pointOption = cmd->add_option("--point", args.point, "a point of the plane: X,Y,Z")
                          ->delimiter(',')
                          ->expected(3);
  auto* normalOption = cmd->add_option("--normal", args.normal, "the plane's normal: X,Y,Z")
                           ->delimiter(',')
                           ->expected(3);
  sliceOption->excludes(pointOption)->excludes(normalOption);
  pointOption->needs(normalOption);
  normalOption->needs(pointOption);
}

// The request the parsed options describe.
CompareRequest compareRequest(const CompareArgs& args) {
  CompareRequest request = args.request;
  request.cage = args.cage;
  request.methods = split(args.methods);
  request.output = args.output;
  if (!args.slice.empty()) {
    int axis = 0;
    double value = 0.0;
    parseSlice(args.slice, axis, value);
    request.planeNormal = Vec3(0.0);
    request.planeNormal[axis] = 1.0;
    request.planePoint = Vec3(0.0);
    request.planePoint[axis] = value;
  } else {
    request.planePoint = Vec3(args.point[0], args.point[1], args.point[2]);
    request.planeNormal = Vec3(args.normal[0], args.normal[1], args.normal[2]);
  }
  return request;
}

void runCompare(const CompareArgs& args, const CliContext& context) {
  const CompareRequest request = compareRequest(args);
  const nlohmann::json report = runComparison(request, context);
  const std::size_t failed = report["failedMethods"].size();
  if (failed == report["methods"].size())
    throw SolverError("compare: every method failed; the reasons are in " +
                      (request.output / "report.md").string());
  context.say("compare: wrote " + std::to_string(report["methods"].size()) + " heat maps (" +
              std::to_string(failed) + " failed), compare.png, report.md and report.json to " +
              request.output.string());
}

}  // namespace

Command addCompareCommand(CLI::App& app, const CliContext& context) {
  auto args = std::make_shared<CompareArgs>();
  std::string known;
  for (const std::string& m : compareMethods()) known += (known.empty() ? "" : ",") + m;

  CLI::App* cmd = app.add_subcommand(
      "compare",
      "Heat maps of one control's coordinate function on a slice, per method, and a report of "
      "their properties");
  cmd->add_option("--cage", args->cage, "rest cage (closed mesh)")->required();
  cmd->add_option("--methods", args->methods,
                  "comma-separated methods (default: all of " + known + ")")
      ->check([known](const std::string& list) { return checkMethodList(list, known); });
  addPlaneOptions(cmd, *args);
  cmd->add_option("--control", args->request.control, "cage vertex whose function is drawn")
      ->check(CLI::NonNegativeNumber)  // before the conversion to an unsigned index wraps -1
      ->capture_default_str();
  cmd->add_option("--resolution", args->request.resolution,
                  "pixels along the longer side of each image")
      ->check(CLI::Range(8, 8192))
      ->capture_default_str();
  cmd->add_option("--samples", args->request.samples,
                  "random interior points for the property figures")
      ->check(CLI::Range(1, 10000000))
      ->capture_default_str();
  addCageMethodOptions(cmd, args->request.cageOptions);
  cmd->add_option("-o,--output", args->output, "output folder")->required();
  cmd->callback([args, cmd] {
    if (args->slice.empty() && args->point.empty())
      throw CLI::RequiredError("--slice or --point and --normal");
    // As deform: a method's options without that method among the methods would not be read.
    if (!args->methods.empty()) checkCageMethodOptions(*cmd, args->methods, "--methods");
  });
  return {cmd, [args, &context] { runCompare(*args, context); }};
}

}  // namespace spacewarp::cli
