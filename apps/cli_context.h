#pragma once
// What every subcommand shares: the options every subcommand takes (--threads, --quiet) and
// the terminal progress display built on the library's progress callback.

#include <string>

#include "core/progress.h"

namespace spacewarp::cli {

/// Exit codes (DESIGN.md).
enum ExitCode { kOk = 0, kOther = 1, kUsage = 2, kBadInput = 3, kNumerical = 4 };

struct CliContext {
  int threads = 0;     ///< worker threads; 0 = every core
  bool quiet = false;  ///< no progress display and no informational output

  /// A progress display on stderr ("stage  42%") when stderr is a terminal and not quiet;
  /// a null callback (no display) otherwise, so piped output stays clean.
  ProgressCallback progress() const;

  /// Prints one informational line on stdout unless quiet.
  void say(const std::string& line) const;
};

}  // namespace spacewarp::cli
