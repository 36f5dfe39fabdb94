#pragma once
// What every subcommand shares: the options every subcommand takes (--threads, --quiet),
// the terminal progress display built on the library's progress callback, and the lines the
// tool prints (information, warnings).

#include <cstddef>
#include <string>

#include <spacewarp/core/progress.h>

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

  /// Prints "spacewarp: warning: <line>" on stderr, even when quiet, and counts it for the
  /// summary a command prints at its end.
  void warn(const std::string& line) const;

  /// The number of warn() calls so far.
  std::size_t warnings() const { return warnings_; }

 private:
  mutable std::size_t warnings_ = 0;  // commands get the context as const; warnings only count
};

/// `n` with thousands separators ("10,000"), for the lines people read.
std::string groupDigits(std::size_t n);

/// "1 point", "10,000 points": `n` grouped, then `noun`, plural unless n is 1.
std::string counted(std::size_t n, const std::string& noun);

/// The line a command ends with: "<verb> <what> in 0.12 s -> <output>[, 1 warning]", e.g.
/// "deformed 10,000 points (7,800 faces) in 0.12 s -> out.ply, 1 warning".
std::string summaryLine(const std::string& verb, const std::string& what, double seconds,
                        const std::string& output, std::size_t warnings);

}  // namespace spacewarp::cli
