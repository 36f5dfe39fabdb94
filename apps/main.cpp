// The spacewarp command-line tool. Exit codes (DESIGN.md): 0 success, 2 usage, 3 bad input,
// 4 numerical failure, 1 anything else. Outputs are written atomically, so a failure never
// leaves a partial file behind. Each subcommand lives in apps/<name>_command.cpp.

#include <cstdio>
#include <new>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include <tbb/global_control.h>

#include "apps/commands.h"
#include "core/errors.h"

using namespace spacewarp;
using namespace spacewarp::cli;

namespace {

// The subcommand being run, for the out-of-memory message.
std::string running = "spacewarp";

int run(int argc, char** argv) {
  CLI::App app{"spacewarp: space deformations and cage coordinates"};
  app.require_subcommand(1);
  // --threads and --quiet may be given before or after the subcommand's name.
  app.fallthrough();
  CliContext context;
  app.add_option("--threads", context.threads, "worker threads (0 = every core)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  app.add_flag("-q,--quiet", context.quiet, "no progress display and no informational output");

  const std::vector<Command> commands = {
      addInfoCommand(app, context),    addDeformCommand(app, context),
      addWeightsCommand(app, context), addCompareCommand(app, context),
      addDemoCommand(app, context),
  };

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int code = app.exit(e);
    return code == 0 ? kOk : kUsage;
  }

  std::optional<tbb::global_control> threads;
  if (context.threads > 0)
    threads.emplace(tbb::global_control::max_allowed_parallelism,
                    static_cast<std::size_t>(context.threads));
  for (const Command& command : commands) {
    if (!command.app->parsed()) continue;
    running = "spacewarp " + command.app->get_name();
    command.run();
  }
  return kOk;
}

}  // namespace

int main(int argc, char** argv) {
  try {
    return run(argc, argv);
  } catch (const IoError& e) {
    std::fprintf(stderr, "spacewarp: error: %s\n", printable(e.what()).c_str());
    return kBadInput;
  } catch (const InvalidInput& e) {
    std::fprintf(stderr, "spacewarp: error: %s\n", printable(e.what()).c_str());
    return kBadInput;
  } catch (const SolverError& e) {
    std::fprintf(stderr, "spacewarp: numerical failure: %s\n", printable(e.what()).c_str());
    return kNumerical;
  } catch (const Cancelled& e) {
    std::fprintf(stderr, "spacewarp: %s\n", printable(e.what()).c_str());
    return kOther;
  } catch (const std::bad_alloc&) {
    // The estimates (core/detail/memory_budget.h) catch most jobs too big for the machine
    // before they start; this is the rest: still a clear one-line message and exit 3.
    std::fprintf(stderr,
                 "spacewarp: error: out of memory in '%s': the input is too large for "
                 "the memory available\n",
                 running.c_str());
    return kBadInput;
  } catch (const std::length_error&) {
    std::fprintf(stderr,
                 "spacewarp: error: in '%s': the input asks for an array larger than "
                 "this machine can hold\n",
                 running.c_str());
    return kBadInput;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "spacewarp: error: %s\n", printable(e.what()).c_str());
    return kOther;
  }
}
