// spacewarp view: serves a model, its controls and every method that can drive them to the
// browser page of web/ (apps/view/view_server.h), until Ctrl-C or SIGTERM, which end it with
// exit code 0 once the requests in flight are done.

#include <signal.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <chrono>
#include <cstdio>
#include <memory>
#include <system_error>
#include <thread>

#include <spacewarp/core/errors.h>
#include <spacewarp/core/io/atomic_file.h>
#include "apps/commands.h"
#include "apps/view/view_server.h"

namespace spacewarp::cli {

namespace {

struct ViewArgs {
  std::string model, cage, rig, method, host = "127.0.0.1", saveDir = ".", webDir;
  int port = 8080;
  std::filesystem::path page;  // found at parse time
  bool hostGiven = false;
};

// The server being run, for the signal thread; null while loading.
std::atomic<view::ViewServer*> running{nullptr};
std::atomic<bool> stopped{false};  // the signal thread is done with the server

int wakeFds[2] = {-1, -1};  // the signal handler's pipe to the stopping thread

extern "C" void onViewSignal(int) {
  const char c = 1;
  [[maybe_unused]] const ssize_t n = ::write(wakeFds[1], &c, 1);  // async-signal-safe
}

// SIGINT, SIGTERM and SIGHUP (whichever thread they reach: OpenBLAS starts threads of its own
// before main) wake one thread through a pipe: it stops the server, which returns from listen()
// once the requests in flight are answered. While the model loads there is nothing to finish:
// the process ends at once (no output is being written).
void handleSignalsInThread() {
  if (::pipe(wakeFds) != 0) throw std::system_error(errno, std::generic_category(), "pipe");
  struct sigaction action {};
  action.sa_handler = onViewSignal;
  sigemptyset(&action.sa_mask);
  for (const int signal : {SIGINT, SIGTERM, SIGHUP}) {
    struct sigaction previous {};
    // A signal ignored by whoever started us (nohup, a background job) stays ignored.
    if (sigaction(signal, nullptr, &previous) == 0 && previous.sa_handler == SIG_IGN) continue;
    sigaction(signal, &action, nullptr);
  }
  std::thread([] {
    char c = 0;
    while (::read(wakeFds[0], &c, 1) < 0 && errno == EINTR) {
    }
    view::ViewServer* server = running.load();
    if (!server) {
      removeAtomicTemporaries();
      _exit(kOk);
    }
    server->stop();
    stopped.store(true);
  }).detach();
}

void runView(const ViewArgs& args, const CliContext& context) {
  handleSignalsInThread();
  view::checkSaveDir(args.saveDir, "--save-dir");
  view::ViewSessionOptions options;
  options.method = args.method;
  view::ViewSession session =
      !args.rig.empty()    ? view::ViewSession::withRig(args.model, args.rig, options)
      : !args.cage.empty() ? view::ViewSession::withCage(args.model, args.cage, options)
                           : throw InvalidInput("view: give --cage or --rig");
  view::ViewServerOptions serverOptions;
  serverOptions.host = args.host;
  serverOptions.port = args.port;
  serverOptions.checkHost = !args.hostGiven;
  serverOptions.saveDir = args.saveDir;
  serverOptions.webDir = args.page;
  view::ViewServer server(std::move(session), serverOptions);
  server.bind();
  if (args.hostGiven && !view::isLoopbackHost(args.host))
    context.warn("view: --host " + args.host +
                 ": the viewer is reachable from the network, and saves into " + args.saveDir);
  std::printf("spacewarp view: %s (Ctrl-C to stop)\n", server.url().c_str());
  std::fflush(stdout);
  running.store(&server);
  server.listen();
  // The signal thread may still be inside stop(): the server outlives that.
  for (int i = 0; i < 1000 && !stopped.load(); ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
}

}  // namespace

Command addViewCommand(CLI::App& app, const CliContext& context) {
  auto args = std::make_shared<ViewArgs>();
  CLI::App* cmd = app.add_subcommand(
      "view",
      "show a model and its controls in the browser: drag the controls, switch methods, "
      "see weights and folds, save the pose as a rig");
  cmd->add_option("MODEL", args->model, "the model: an OBJ, OFF or PLY soup or point cloud")
      ->required();
  auto* cage = cmd->add_option("--cage", args->cage, "a cage around the model (OBJ, OFF, PLY)");
  auto* rig = cmd->add_option("--rig", args->rig, "a rig file whose controls to pose");
  cage->excludes(rig);
  cmd->add_option("--method", args->method,
                  "the first method (default: the rig's, or mvc with a cage)");
  cmd->add_option("--port", args->port, "the port to listen on; 0 = any free port")
      ->check(CLI::Range(0, 65535))
      ->capture_default_str();
  auto* host = cmd->add_option("--host", args->host,
                               "the address to listen on; anything but 127.0.0.1 makes the viewer "
                               "reachable from the network")
                   ->capture_default_str();
  cmd->add_option("--save-dir", args->saveDir, "where saves and screenshots go")
      ->capture_default_str();
  cmd->add_option("--web-dir", args->webDir,
                  "the page's folder (default: $SPACEWARP_WEB_DIR, the build's web/dist, the "
                  "installed copy)");
  cmd->callback([args, cage, rig, host] {
    if (cage->count() == 0 && rig->count() == 0) throw CLI::RequiredError("--cage or --rig");
    args->hostGiven = host->count() > 0;
    args->page = view::findWebDir(args->webDir);
    if (args->page.empty()) throw CLI::ValidationError(view::missingPageMessage());
  });
  return {cmd, [args, &context] { runView(*args, context); }};
}

}  // namespace spacewarp::cli
