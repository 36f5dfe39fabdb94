// The spacewarp command-line tool. Exit codes (DESIGN.md): 0 success, 2 usage, 3 bad input
// (including a file that cannot be read or written: a full disk, a file size limit; and a job
// too large for the memory: refused up front, or one line "out of memory while ..." however the
// memory ran out, apps/out_of_memory.h), 4 numerical failure, 1 anything else; a run
// interrupted by SIGINT, SIGTERM or SIGHUP removes
// the temporaries of the outputs it was writing and ends by that signal, which the shell
// reports as 130, 143 or 129 (128 + the signal's number). Outputs are written atomically
// (core/io/atomic_file.h), so a failure or an interruption never leaves a partial file behind
// and keeps the previous output. Each subcommand lives in apps/<name>_command.cpp.

#include <signal.h>

#include <charconv>
#include <cstdio>
#include <new>
#include <optional>
#include <stdexcept>
#include <string>
#include <system_error>
#include <vector>

#include <tbb/global_control.h>
#include <tbb/info.h>

#include <spacewarp/core/detail/simd.h>
#include <spacewarp/core/errors.h>
#include <spacewarp/core/io/atomic_file.h>
#include "apps/commands.h"
#include "apps/out_of_memory.h"

using namespace spacewarp;
using namespace spacewarp::cli;

namespace {

constexpr int kInterruptingSignals[] = {SIGINT, SIGTERM, SIGHUP};

// Only async-signal-safe calls. The signal is re-raised with its default action rather than
// turned into an exit code, so that a shell running a loop of commands sees the interruption
// and stops (and reports 128 + the signal's number).
extern "C" void onInterrupt(int signal) {
  removeAtomicTemporaries();
  struct sigaction defaultAction {};
  defaultAction.sa_handler = SIG_DFL;
  sigemptyset(&defaultAction.sa_mask);
  sigaction(signal, &defaultAction, nullptr);
  raise(signal);  // pending: the signal is blocked while its handler runs
  sigset_t unblock;
  sigemptyset(&unblock);
  sigaddset(&unblock, signal);
  sigprocmask(SIG_UNBLOCK, &unblock, nullptr);  // delivered here, ending the process
  _exit(128 + signal);                          // not reached
}

void installSignalHandling() {
  struct sigaction action {};
  action.sa_handler = onInterrupt;
  sigemptyset(&action.sa_mask);
  for (const int signal : kInterruptingSignals) sigaddset(&action.sa_mask, signal);
  for (const int signal : kInterruptingSignals) {
    struct sigaction previous {};
    // A signal ignored by whoever started us (nohup, a background job) stays ignored.
    if (sigaction(signal, nullptr, &previous) == 0 && previous.sa_handler == SIG_IGN) continue;
    sigaction(signal, &action, nullptr);
  }
  // Past a file size limit (ulimit -f) a write then fails with EFBIG and is reported (exit 3,
  // temporary removed) instead of the process being killed with the temporary left behind.
  struct sigaction ignore {};
  ignore.sa_handler = SIG_IGN;
  sigemptyset(&ignore.sa_mask);
  sigaction(SIGXFSZ, &ignore, nullptr);
}

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

// The first word of the command line that is not an option (nor --threads' value) when it names
// no command ("spacewarp frob"): CLI11 would only say that a subcommand is required. "" otherwise.
std::string unknownCommand(int argc, char** argv, const std::vector<Command>& commands) {
  for (int i = 1; i < argc; ++i) {
    const std::string word = argv[i];
    if (word == "--threads") {
      ++i;
      continue;
    }
    if (word.starts_with('-')) continue;
    for (const Command& command : commands)
      if (command.app->get_name() == word) return "";
    return word;
  }
  return "";
}

// The subcommand being run, for the messages.
std::string running = "spacewarp";

int run(int argc, char** argv) {
  setActivity("running 'spacewarp'");
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
      addEditCommand(app, context),    addInverseCommand(app, context),
      addWeightsCommand(app, context), addCompareCommand(app, context),
      addDemoCommand(app, context),    addViewCommand(app, context),
  };
  // --threads and --quiet may be given before or after the subcommand's name; declaring them
  // on every subcommand too (same variables) also lists them in its --help.
  for (const Command& command : commands) addGlobalOptions(*command.app, context, cores);

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    if (const std::string word = unknownCommand(argc, argv, commands); !word.empty()) {
      std::string names;
      for (const Command& command : commands)
        names += (names.empty() ? "" : ", ") + command.app->get_name();
      std::cerr << "spacewarp: error: unknown command '" << printable(word) << "' (one of " << names
                << "; see --help)\n";
      return kUsage;
    }
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
  // A bad SPACEWARP_SIMD is the environment's fault, not an input file's: a usage error now,
  // before a command reads anything (the kernels would otherwise report it with a file's name).
  try {
    (void)detail::simd::activePath();
  } catch (const InvalidInput& e) {
    std::fprintf(stderr, "spacewarp: error: %s\n", printable(e.what()).c_str());
    return kUsage;
  }
  for (const Command& command : commands) {
    if (!command.app->parsed()) continue;
    running = "spacewarp " + command.app->get_name();
    setActivity("running '" + running + "'");
    command.run();
  }
  return kOk;
}

// run()'s exit code, with every exception it throws reported in one line.
int exitCode(int argc, char** argv) {
  try {
    return run(argc, argv);
  } catch (const OutOfMemory& e) {  // a SolverError: TetGen or CHOLMOD ran out of memory
    return reportOutOfMemory(printable(e.what()).c_str());
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
    // before they start; this is the rest: still a clear one-line message and exit 3. (Those
    // that no handler can catch end the same way: apps/out_of_memory.h.)
    return reportOutOfMemory();
  } catch (const std::system_error& e) {
    // std::thread's failure to start a thread, when memory (for its stack) ran out.
    if (isOutOfResources(e.code())) return reportOutOfMemory(printable(e.what()).c_str());
    std::fprintf(stderr, "spacewarp: error: %s\n", printable(e.what()).c_str());
    return kOther;
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

}  // namespace

int main(int argc, char** argv) {
  installSignalHandling();
  const int code = exitCode(argc, argv);
  // Static destructors and the libraries' finalisers run after this.
  setActivity("exiting");
  return code;
}
