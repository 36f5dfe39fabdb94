// spacewarp.view and spacewarp.Viewer: the viewer's server (apps/view/view_server.h) on a
// background thread of the Python process, as `spacewarp view` runs it.

#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>

#include <memory>
#include <optional>
#include <string>
#include <thread>

#include <spacewarp/core/errors.h>
#include "apps/view/view_server.h"
#include "common.h"

namespace spacewarp::python {

namespace {

class Viewer {
 public:
  Viewer(view::ViewSession session, const view::ViewServerOptions& options)
      : server_(std::make_unique<view::ViewServer>(std::move(session), options)) {
    server_->bind();
    url_ = server_->url();
    thread_ = std::thread([this] { server_->listen(); });
  }
  ~Viewer() { stop(); }
  Viewer(const Viewer&) = delete;
  Viewer& operator=(const Viewer&) = delete;

  const std::string& url() const { return url_; }
  int port() const { return server_->port(); }
  void stop() {
    if (!server_) return;
    server_->stop();
    if (thread_.joinable()) thread_.join();
  }

 private:
  std::unique_ptr<view::ViewServer> server_;
  std::thread thread_;
  std::string url_;
};

}  // namespace

void bindView(py::module_& m) {
  using namespace pybind11::literals;
  py::class_<Viewer>(m, "Viewer",
                     R"(A running viewer (spacewarp.view): `url` is the page's address, `stop()`
ends it (requests in flight finish first); also a context manager that stops on exit.)")
      .def_property_readonly("url", &Viewer::url, "\"http://HOST:PORT/\", the page's address.")
      .def_property_readonly("port", &Viewer::port, "The port listened on.")
      .def("stop", &Viewer::stop, py::call_guard<py::gil_scoped_release>(),
           "Stops serving; a second call does nothing.")
      .def(
          "__enter__", [](Viewer& v) -> Viewer& { return v; }, py::return_value_policy::reference)
      .def(
          "__exit__",
          [](Viewer& v, py::handle, py::handle, py::handle) {
            py::gil_scoped_release release;
            v.stop();
          },
          "exc_type"_a, "exc"_a, "traceback"_a);

  m.def(
      "view",
      [](const std::filesystem::path& model, std::optional<std::filesystem::path> cage,
         std::optional<std::filesystem::path> rig, std::optional<std::string> method, int port,
         const std::string& host, const std::filesystem::path& saveDir,
         std::optional<std::filesystem::path> webDir) {
        if (cage.has_value() == rig.has_value())
          throw InvalidInput("spacewarp.view: give one of cage and rig");
        if (port < 0 || port > 65535)
          throw InvalidInput("spacewarp.view: port must be in 0..65535, not " +
                             std::to_string(port));
        view::checkSaveDir(saveDir, "spacewarp.view: save_dir");
        py::gil_scoped_release release;
        view::ViewServerOptions options;
        options.host = host;
        options.port = port;
        options.checkHost = view::isLoopbackHost(host);  // a network host turns it off
        options.saveDir = saveDir;
        options.webDir = view::findWebDir(webDir.value_or(""));
        if (options.webDir.empty()) throw IoError(view::missingPageMessage());
        view::ViewSessionOptions sessionOptions;
        sessionOptions.method = method.value_or("");
        view::ViewSession session = cage ? view::ViewSession::withCage(model, *cage, sessionOptions)
                                         : view::ViewSession::withRig(model, *rig, sessionOptions);
        return std::make_unique<Viewer>(std::move(session), options);
      },
      R"(Serves `model` (an OBJ/OFF/PLY soup or point cloud) with its controls — a `cage` file or
a `rig` file — to the viewer page, from a background thread, as `spacewarp view` does; returns
a Viewer (its `url`, `stop()`, a context manager). `method`: the first method (default: the
rig's, or "mvc" with a cage); `port` 0 picks a free port; `host` other than 127.0.0.1 makes the
viewer reachable from the network; saves go to `save_dir`; `web_dir`: the page's folder
(default: $SPACEWARP_WEB_DIR, the build's web/dist, the installed copy). Raises IoError when no
page is found or a file cannot be read, InvalidInput for bad input, RuntimeError when the port
is in use.)",
      "model"_a, "cage"_a = py::none(), "rig"_a = py::none(), "method"_a = py::none(), "port"_a = 0,
      "host"_a = "127.0.0.1", "save_dir"_a = ".", "web_dir"_a = py::none());
}

}  // namespace spacewarp::python
