#pragma once
// The command-line options of the cage methods (rig/cage_rig.h's CageMethodOptions).

#include <string>

#include <CLI/CLI.hpp>

#include <spacewarp/rig/cage_rig.h>

namespace spacewarp::cli {

/// Adds the cage methods' options to a subcommand that takes --method.
void addCageMethodOptions(CLI::App* command, CageMethodOptions& options);

/// Throws a usage error (exit 2) naming the first option of addCageMethodOptions given on
/// `command` that `method` does not use (--outside: harmonic, wachspress, discrete-harmonic; the
/// others: harmonic); `method` "" stands for a rig, whose keys set them, and a comma-separated
/// list (compare's --methods) uses an option if any of its methods does. `flag`: the option that
/// named the method(s), for the message.
void checkCageMethodOptions(const CLI::App& command, const std::string& method,
                            const std::string& flag = "--method");

}  // namespace spacewarp::cli
