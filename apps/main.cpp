// The spacewarp command-line tool. Exit codes (DESIGN.md): 0 success, 2 usage, 3 bad input,
// 4 numerical failure, 1 anything else. Outputs are written atomically, so a failure never
// leaves a partial file behind. Each subcommand lives in apps/<name>_command.cpp.

#include <charconv>
#include <cstdio>
#include <optional>
#include <string>
#include <system_error>
#include <vector>

#include <tbb/global_control.h>
#include <tbb/info.h>

#include "apps/commands.h"
#include "core/errors.h"

using namespace spacewarp;
using namespace spacewarp::cli;

namespace {

// --threads: a whole number from 0 (every core) up; the message names the useful range.
CLI::Validator threadCount(int cores) {
  const std::string range = "0 (every core) or 1.." + std::to_string(cores);
  return CLI::Validator(
      [range](std::string& value) -> std::string {
        int n = -1;
        const char* end = value.data() + value.size();
        const auto [stop, error] = std::from_chars(value.data(), end, n);
        if (error == std::errc() && stop == end && n >= 0) return {};
        return "'" + value + "' is not a thread count: give " + range;
      },
      "0.." + std::to_string(cores));
}

// The options every subcommand takes, on `app` or on one subcommand.
void addGlobalOptions(CLI::App& app, CliContext& context, int cores) {
  app.add_option("--threads", context.threads,
                 "worker threads: 0 = every core (" + std::to_string(cores) + " here), 1.." +
                     std::to_string(cores) + " limits them; results do not depend on it")
      ->check(threadCount(cores))
      ->capture_default_str();
  app.add_flag("-q,--quiet", context.quiet,
               "no progress display, no informational output (warnings and errors remain)");
}

int run(int argc, char** argv) {
  CLI::App app{"spacewarp: space deformations and cage coordinates"};
  app.require_subcommand(1);
  app.set_version_flag("--version", std::string("spacewarp ") + SPACEWARP_VERSION,
                       "print the version and exit");
  // Usage errors in one line, like every other error.
  app.failure_message([](const CLI::App*, const CLI::Error& e) {
    return std::string("spacewarp: error: ") + e.what() + " (see --help)\n";
  });
  CliContext context;
  const int cores = tbb::info::default_concurrency();
  addGlobalOptions(app, context, cores);

  const std::vector<Command> commands = {
      addInfoCommand(app, context),    addDeformCommand(app, context),
      addWeightsCommand(app, context), addCompareCommand(app, context),
      addDemoCommand(app, context),
  };
  // --threads and --quiet may be given before or after the subcommand's name; declaring them
  // on every subcommand too (same variables) also lists them in its --help.
  for (const Command& command : commands) addGlobalOptions(*command.app, context, cores);

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int code = app.exit(e);
    return code == 0 ? kOk : kUsage;
  }

  if (context.threads > cores)
    context.warn("--threads " + std::to_string(context.threads) + ": at most " +
                 std::to_string(cores) + " threads can run here; using " + std::to_string(cores));
  std::optional<tbb::global_control> threads;
  if (context.threads > 0)
    threads.emplace(tbb::global_control::max_allowed_parallelism,
                    static_cast<std::size_t>(context.threads));
  for (const Command& command : commands)
    if (command.app->parsed()) command.run();
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
  } catch (const Cancelled& e) {
    std::fprintf(stderr, "spacewarp: %s\n", e.what());
    return kOther;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "spacewarp: error: %s\n", e.what());
    return kOther;
  }
}
