#pragma once
// The subcommands of the spacewarp tool, one file each (apps/<name>_command.cpp). Each adds
// its options to the app and returns the work to run once the command line has parsed.

#include <cmath>
#include <cstddef>
#include <functional>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "apps/cli_context.h"

namespace spacewarp::cli {

struct Command {
  CLI::App* app = nullptr;    ///< the subcommand, to ask whether it was given
  std::function<void()> run;  ///< its work, called after parsing with --threads in effect
};

/// The options that `add` adds to `command`, in order (to group them and to check afterwards
/// which were given).
inline std::vector<CLI::Option*> optionsAddedBy(CLI::App* command,
                                                const std::function<void()>& add) {
  const std::size_t before = command->get_options().size();
  add();
  std::vector<CLI::Option*> all = command->get_options();
  return {all.begin() + static_cast<std::ptrdiff_t>(before), all.end()};
}

/// Throws a usage error (exit 2) naming the first of `options` that was given: "--x <why>".
inline void rejectGiven(const std::vector<CLI::Option*>& options, const std::string& why) {
  for (const CLI::Option* option : options)
    if (option->count() > 0) throw CLI::ValidationError(option->get_name() + " " + why);
}

/// Finite numbers above 0 and from 0 (CLI11's PositiveNumber and NonNegativeNumber let "nan"
/// through).
inline const CLI::Validator kFinitePositive(
    [](std::string& value) -> std::string {
      double t = 0.0;
      if (CLI::detail::lexical_cast(value, t) && std::isfinite(t) && t > 0.0) return {};
      return "'" + value + "' is not a finite number > 0";
    },
    "NUMBER > 0");
inline const CLI::Validator kFiniteNonNegative(
    [](std::string& value) -> std::string {
      double t = 0.0;
      if (CLI::detail::lexical_cast(value, t) && std::isfinite(t) && t >= 0.0) return {};
      return "'" + value + "' is not a finite number >= 0";
    },
    "NUMBER >= 0");

Command addInfoCommand(CLI::App& app, const CliContext& context);
Command addDeformCommand(CLI::App& app, const CliContext& context);
Command addEditCommand(CLI::App& app, const CliContext& context);
Command addInverseCommand(CLI::App& app, const CliContext& context);
Command addWeightsCommand(CLI::App& app, const CliContext& context);
Command addCompareCommand(CLI::App& app, const CliContext& context);
Command addDemoCommand(CLI::App& app, const CliContext& context);
Command addViewCommand(CLI::App& app, const CliContext& context);

}  // namespace spacewarp::cli
