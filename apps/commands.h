#pragma once
// The subcommands of the spacewarp tool, one file each (apps/<name>_command.cpp). Each adds
// its options to the app and returns the work to run once the command line has parsed.

#include <functional>

#include <CLI/CLI.hpp>

#include "apps/cli_context.h"

namespace spacewarp::cli {

struct Command {
  CLI::App* app = nullptr;    ///< the subcommand, to ask whether it was given
  std::function<void()> run;  ///< its work, called after parsing with --threads in effect
};

Command addInfoCommand(CLI::App& app, const CliContext& context);
Command addDeformCommand(CLI::App& app, const CliContext& context);
Command addWeightsCommand(CLI::App& app, const CliContext& context);
Command addCompareCommand(CLI::App& app, const CliContext& context);
Command addDemoCommand(CLI::App& app, const CliContext& context);

}  // namespace spacewarp::cli
