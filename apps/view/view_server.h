#pragma once
// The HTTP side of `spacewarp view`: cpp-httplib routes over one ViewSession (guarded by a
// mutex, requests served concurrently by httplib's pool), the refusals that keep a local viewer
// local (Host and Origin checks, size limits), and the page's static files. The API is listed in
// README.md (Viewer).

#include <cstddef>
#include <filesystem>
#include <memory>
#include <string>

#include "apps/view/view_session.h"

namespace spacewarp::view {

/// Options of ViewServer.
struct ViewServerOptions {
  std::string host = "127.0.0.1";  ///< the address to listen on
  int port = 8080;                 ///< 0: any free port
  /// Refuse (403) requests whose Host header is not 127.0.0.1:PORT, localhost:PORT or
  /// [::1]:PORT, against DNS rebinding. Only honoured as false for a host that is not loopback
  /// (--host 0.0.0.0 or a LAN address): a loopback host always keeps the check.
  bool checkHost = true;
  std::filesystem::path saveDir = ".";  ///< where saves and screenshots go
  std::filesystem::path webDir;         ///< the page's folder (index.html); empty: no page
};

/// Body limits (bytes).
inline constexpr std::size_t kMaxJsonBody = 64 * 1024;
inline constexpr std::size_t kMaxScreenshot = 32 * 1024 * 1024;
/// A connection that sends or takes nothing for this long is closed.
inline constexpr int kSocketTimeoutSeconds = 3;
/// Requests served at once (httplib's thread pool).
inline constexpr std::size_t kWorkerThreads = 64;

/// Whether `host` (a --host value) is a loopback address or name: 127.0.0.1, localhost, ::1.
bool isLoopbackHost(const std::string& host);

/// The page's folder: `given` if not empty, else $SPACEWARP_WEB_DIR, else the build tree's
/// web/dist, else the installed share/spacewarp/web; the first that holds index.html. Empty if
/// none does.
std::filesystem::path findWebDir(const std::filesystem::path& given);

/// Throws IoError ("<what> DIR: not a folder") unless `dir` is a folder: the CLI and Python
/// check the save folder before loading anything.
void checkSaveDir(const std::filesystem::path& dir, const std::string& what);

/// The line `spacewarp view` prints when no page is found.
std::string missingPageMessage();

/// Serves one session. Construct, bind(), then listen() (blocks) until stop() from any thread.
class ViewServer {
 public:
  ViewServer(ViewSession session, ViewServerOptions options);
  ~ViewServer();
  ViewServer(const ViewServer&) = delete;
  ViewServer& operator=(const ViewServer&) = delete;

  /// Binds the socket; returns the port (the one chosen when options.port is 0). Throws
  /// std::runtime_error naming the address and port when it cannot (a port in use).
  int bind();
  /// Serves until stop(); requests in flight finish first.
  void listen();
  /// Stops listen(); thread-safe, may be called before listen() starts.
  void stop();
  int port() const;
  /// "http://HOST:PORT/" (IPv6 hosts in brackets).
  std::string url() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace spacewarp::view
