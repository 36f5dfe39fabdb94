#include "apps/view/view_server.h"

#include <algorithm>
#include <atomic>
#include <cctype>
#include <charconv>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <functional>
#include <map>
#include <mutex>
#include <sstream>
#include <stdexcept>
#include <thread>

#include <arpa/inet.h>
#include <httplib.h>

#include <spacewarp/core/errors.h>
#include <spacewarp/core/io/atomic_file.h>
#include "apps/heat_map.h"

namespace spacewarp::view {

namespace {

void fail(httplib::Response& res, int status, const std::string& message) {
  res.status = status;
  res.set_content(nlohmann::json{{"error", printable(message)}}.dump(), "application/json");
}

void sendJson(httplib::Response& res, const nlohmann::json& body) {
  res.set_content(body.dump(), "application/json");
}

// The values as little-endian float32, written straight into the response body.
template <typename Fill>
void sendBinary(httplib::Response& res, std::size_t bytes, Fill&& fill) {
  res.body.resize(bytes);
  fill(res.body.data());
  res.set_header("Content-Type", "application/octet-stream");
}

// Positions relative to the session's origin (subtracted in double), so that float32 keeps
// the precision of the model's size however far it is from the world origin.
void positionsInto(std::span<const Vec3> positions, const Vec3& origin, char* out) {
  for (std::size_t i = 0; i < positions.size(); ++i) {
    const Vec3 p = positions[i] - origin;
    const float xyz[3] = {static_cast<float>(p.x), static_cast<float>(p.y),
                          static_cast<float>(p.z)};
    std::memcpy(out + 12 * i, xyz, 12);
  }
}

// Bad query numbers are 400s: a parameter that is missing, not a whole number/finite number, or
// has trailing text.
struct BadRequest : std::runtime_error {
  using std::runtime_error::runtime_error;
};

// A body over its endpoint's limit: 413.
struct TooLarge : std::runtime_error {
  using std::runtime_error::runtime_error;
};

std::string overLimit(const std::string& path, std::size_t limit) {
  return path + ": the body is over the limit of " + std::to_string(limit) + " bytes";
}

// The body, read through httplib's content reader whatever its content type or transfer
// encoding (chunked bodies carry no Content-Length to screen): reading stops as soon as the body
// passes `limit`.
std::string readBody(const httplib::Request& req, const httplib::ContentReader& reader,
                     std::size_t limit) {
  std::string body;
  bool over = false;
  reader([&](const char* data, std::size_t size) {
    if (size > limit - body.size()) return !(over = true);
    body.append(data, size);
    return true;
  });
  if (over) throw TooLarge(overLimit(req.path, limit));
  return body;
}

std::string param(const httplib::Request& req, const std::string& name, const char* fallback) {
  if (req.has_param(name.c_str())) return req.get_param_value(name.c_str());
  if (fallback) return fallback;
  throw BadRequest("missing query parameter '" + name + "'");
}

long long integerParam(const httplib::Request& req, const std::string& name, const char* fallback,
                       long long lo, long long hi) {
  const std::string text = param(req, name, fallback);
  long long value = 0;
  const auto [end, error] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (error != std::errc() || end != text.data() + text.size() || value < lo || value > hi)
    throw BadRequest("'" + name + "' must be a whole number in [" + std::to_string(lo) + ", " +
                     std::to_string(hi) + "], not '" + text + "'");
  return value;
}

double numberParam(const httplib::Request& req, const std::string& name) {
  const std::string text = param(req, name, nullptr);
  double value = 0.0;
  const auto [end, error] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (error != std::errc() || end != text.data() + text.size() || !std::isfinite(value))
    throw BadRequest("'" + name + "' must be a finite number, not '" + text + "'");
  return value;
}

nlohmann::json jsonBody(const httplib::Request& req, const httplib::ContentReader& reader) {
  nlohmann::json body = nlohmann::json::parse(readBody(req, reader, kMaxJsonBody), nullptr, false);
  if (body.is_discarded() || !body.is_object()) throw BadRequest("the body is not a JSON object");
  return body;
}

// The longest name (method, "what") a request may give: the longest the API knows is 8.
constexpr std::size_t kMaxName = 64;

// body[key] as a name: a string of at most kMaxName characters, none of them control characters
// (a NUL would cut the message that echoes it). Refusals echo at most kMaxName characters.
std::string nameField(const nlohmann::json& body, const std::string& key, const char* expected) {
  const auto it = body.find(key);
  if (it == body.end() || !it->is_string())
    throw BadRequest("the body needs \"" + key + "\": " + expected);
  const std::string name = it->get<std::string>();
  const bool control = std::any_of(name.begin(), name.end(), [](char c) {
    return static_cast<unsigned char>(c) < 0x20 || c == 0x7f;
  });
  if (control || name.size() > kMaxName)
    throw BadRequest("\"" + key + "\" '" + printable(name.substr(0, kMaxName)) +
                     (name.size() > kMaxName ? "...' is too long" : "' holds a control character") +
                     ": " + expected);
  return name;
}

// A PNG's frame, not only its signature: the IHDR chunk first (13 bytes, a width and height in
// [1, 2^31), a valid bit depth and colour type) and the IEND chunk last.
bool isPng(const std::string& body) {
  static constexpr char kSignature[] = "\x89PNG\r\n\x1a\n";
  static constexpr char kIhdr[] = "\0\0\0\x0dIHDR";
  static constexpr char kIend[] = "\0\0\0\0IEND\xae\x42\x60\x82";
  if (body.size() < 8 + 25 + 12 || std::memcmp(body.data(), kSignature, 8) != 0 ||
      std::memcmp(body.data() + 8, kIhdr, 8) != 0 ||
      std::memcmp(body.data() + body.size() - 12, kIend, 12) != 0)
    return false;
  const auto byte = [&](std::size_t i) { return static_cast<unsigned char>(body[i]); };
  const auto u32 = [&](std::size_t i) {
    return std::uint32_t(byte(i)) << 24 | std::uint32_t(byte(i + 1)) << 16 |
           std::uint32_t(byte(i + 2)) << 8 | std::uint32_t(byte(i + 3));
  };
  const std::uint32_t width = u32(16), height = u32(20);
  const unsigned depth = byte(24), colour = byte(25);
  const bool depthOk = depth == 1 || depth == 2 || depth == 4 || depth == 8 || depth == 16;
  const bool colourOk = colour == 0 || colour == 2 || colour == 3 || colour == 4 || colour == 6;
  return width > 0 && height > 0 && width < (1u << 31) && height < (1u << 31) && depthOk &&
         colourOk && byte(26) == 0 && byte(27) == 0 && byte(28) <= 1;
}

std::string contentType(const std::filesystem::path& path) {
  static const std::map<std::string, std::string> types = {{".html", "text/html; charset=utf-8"},
                                                           {".js", "text/javascript"},
                                                           {".mjs", "text/javascript"},
                                                           {".css", "text/css"},
                                                           {".json", "application/json"},
                                                           {".png", "image/png"},
                                                           {".svg", "image/svg+xml"},
                                                           {".ico", "image/x-icon"},
                                                           {".wasm", "application/wasm"},
                                                           {".map", "application/json"},
                                                           {".txt", "text/plain; charset=utf-8"}};
  const auto it = types.find(path.extension().string());
  return it == types.end() ? "application/octet-stream" : it->second;
}

std::string lowercase(std::string text) {
  for (char& c : text) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return text;
}

// Whether the name part of a Host header is an IP literal (v4 or bracketed v6): the browser
// connected to that address, so no DNS name can have been rebound onto it.
bool isIpLiteral(const std::string& name) {
  if (name.size() > 2 && name.front() == '[' && name.back() == ']') return true;
  in_addr address{};
  return ::inet_pton(AF_INET, name.c_str(), &address) == 1;
}

bool isDirectory(const std::filesystem::path& dir) {
  std::error_code error;
  return !dir.empty() && std::filesystem::is_regular_file(dir / "index.html", error);
}

}  // namespace

std::filesystem::path findWebDir(const std::filesystem::path& given) {
  if (!given.empty()) return isDirectory(given) ? given : std::filesystem::path();
  if (const char* env = std::getenv("SPACEWARP_WEB_DIR"); env && *env)
    return isDirectory(env) ? std::filesystem::path(env) : std::filesystem::path();
#ifdef SPACEWARP_BUILD_WEB_DIR
  if (isDirectory(SPACEWARP_BUILD_WEB_DIR)) return SPACEWARP_BUILD_WEB_DIR;
#endif
#ifdef SPACEWARP_INSTALLED_WEB_DIR
  if (isDirectory(SPACEWARP_INSTALLED_WEB_DIR)) return SPACEWARP_INSTALLED_WEB_DIR;
#endif
  return {};
}

void checkSaveDir(const std::filesystem::path& dir, const std::string& what) {
  std::error_code error;
  if (!std::filesystem::is_directory(dir, error))
    throw IoError(what + " " + dir.string() + ": not a folder");
}

bool isLoopbackHost(const std::string& host) {
  const std::string name = lowercase(host);
  return name == "127.0.0.1" || name == "localhost" || name == "::1" || name == "[::1]";
}

std::string missingPageMessage() {
  return "view: the viewer page is not built (no index.html in --web-dir, $SPACEWARP_WEB_DIR or "
         "the build's web/dist): install Node.js and npm (apt-get install nodejs npm) and "
         "rebuild";
}

struct ViewServer::Impl {
  ViewServerOptions options;
  std::filesystem::path saveDir, webDir;  // absolute, canonical
  std::string modelStem;
  std::size_t poseBytes = 0;  // the controls never change count: read without the mutex
  std::mutex mutex;           // guards the session
  ViewSession session;
  httplib::Server server;
  int port = 0;
  std::atomic<bool> listening{false}, stopRequested{false};
  // The API's routes and their verb (GET routes also answer HEAD), from routes()' tables.
  std::map<std::string, std::string, std::less<>> apiVerbs;
  bool checkHost = true;

  Impl(ViewSession s, ViewServerOptions o) : options(std::move(o)), session(std::move(s)) {
    saveDir = std::filesystem::absolute(options.saveDir).lexically_normal();
    if (!options.webDir.empty()) webDir = std::filesystem::weakly_canonical(options.webDir);
    modelStem = session.modelPath().stem().string();
    // Listening on loopback only: the Host check costs nothing and stops DNS rebinding.
    checkHost = options.checkHost || isLoopbackHost(options.host);
    poseBytes = 24 * session.restControls().size();
  }

  // "name" of "name:PORT" (lowercase) when the port is this server's; empty otherwise.
  std::string nameAtOurPort(const std::string& hostAndPort) const {
    const std::size_t colon = hostAndPort.rfind(':');
    if (colon == std::string::npos || hostAndPort.substr(colon + 1) != std::to_string(port))
      return {};
    return lowercase(hostAndPort.substr(0, colon));
  }

  bool hostAllowed(const std::string& host) const {
    if (!checkHost) return true;
    return isLoopbackHost(nameAtOurPort(host));
  }

  // The server's own origins: the loopback names at its port, the --host address, and (for a
  // wildcard --host, whose addresses are not known) the Host when it is an IP literal — never a
  // DNS name taken from the request, which a rebinding attacker controls.
  bool originAllowed(const std::string& origin, const std::string& host) const {
    if (!lowercase(origin).starts_with("http://")) return false;
    const std::string name = nameAtOurPort(origin.substr(7));
    if (name.empty()) return false;
    if (isLoopbackHost(name)) return true;
    const std::string listen = lowercase(options.host);
    if (name == listen || name == "[" + listen + "]") return true;
    const bool wildcard = listen == "0.0.0.0" || listen == "::" || listen.empty();
    return wildcard && isIpLiteral(name) && name == nameAtOurPort(host);
  }

  // Refusals decided from the request line and headers alone, before any body is read.
  httplib::Server::HandlerResponse screen(const httplib::Request& req, httplib::Response& res) {
    using R = httplib::Server::HandlerResponse;
    const std::string host = req.get_header_value("Host");
    if (req.get_header_value_count("Host") > 1 || !hostAllowed(host)) {
      fail(res, 403, "refused: Host '" + host + "' is not this viewer's address");
      return R::Handled;
    }
    const bool get = req.method == "GET" || req.method == "HEAD";
    if (req.method == "POST" && req.has_header("Origin") &&
        !originAllowed(req.get_header_value("Origin"), host)) {
      fail(res, 403,
           "refused: Origin '" + req.get_header_value("Origin") + "' is not this viewer's origin");
      return R::Handled;
    }
    if (req.path.starts_with("/api/") || req.path == "/api") {
      const auto route = apiVerbs.find(req.path);
      if (route == apiVerbs.end()) {
        fail(res, 404, "no API route " + req.path);
        return R::Handled;
      }
      if (!(route->second == "GET" ? get : req.method == route->second)) {
        res.set_header("Allow", route->second == "GET" ? "GET, HEAD" : route->second);
        fail(res, 405, req.method + " " + req.path + ": use " + route->second);
        return R::Handled;
      }
      const std::size_t lengths = req.get_header_value_count("Content-Length");
      if (lengths > 1 || (lengths == 1 && req.has_header("Transfer-Encoding"))) {
        fail(res, 400,
             "refused: two body lengths (Content-Length twice or with Transfer-Encoding)");
        return R::Handled;
      }
      if (req.method == "POST" && lengths == 1) {
        const std::string text = req.get_header_value("Content-Length");
        std::size_t length = 0;
        const auto [end, error] = std::from_chars(text.data(), text.data() + text.size(), length);
        if (error == std::errc::result_out_of_range)
          length = SIZE_MAX;
        else if (error != std::errc() || end != text.data() + text.size()) {
          fail(res, 400, "refused: Content-Length '" + text + "' is not a byte count");
          return R::Handled;
        }
        const std::size_t limit = bodyLimit(req.path);
        if (length > limit) {
          fail(res, 413, overLimit(req.path, limit));
          return R::Handled;
        }
      }
      return R::Unhandled;
    }
    if (!get) {
      res.set_header("Allow", "GET, HEAD");
      fail(res, 405, req.method + " " + req.path + ": static files answer GET only");
      return R::Handled;
    }
    return R::Unhandled;
  }

  // Takes a job from the session under the lock (`take` checks the request and snapshots what
  // the job reads) and runs it without the lock, so that poses are answered meanwhile.
  template <typename Take>
  auto unlocked(Take take) {
    decltype(take()) job;
    {
      const std::lock_guard lock(mutex);
      job = take();
    }
    return job();
  }

  // The README's body limit of a POST route, whatever the content type.
  std::size_t bodyLimit(const std::string& path) const {
    return path == "/api/screenshot" ? kMaxScreenshot
           : path == "/api/pose"     ? poseBytes
                                     : kMaxJsonBody;
  }

  // Runs `run`, turning the typed errors into their statuses.
  template <typename Run>
  static void answerErrors(httplib::Response& res, Run&& run) {
    try {
      run();
    } catch (const TooLarge& e) {
      // The rest of the body is never read: the connection cannot carry another request.
      res.set_header("Connection", "close");
      fail(res, 413, e.what());
    } catch (const BadRequest& e) {
      fail(res, 400, e.what());
    } catch (const Refused& e) {
      fail(res, 403, e.what());
    } catch (const NotAvailable& e) {
      fail(res, 409, e.what());
    } catch (const InvalidInput& e) {
      fail(res, 400, e.what());
    } catch (const IoError& e) {
      fail(res, 500, e.what());
    } catch (const SolverError& e) {
      fail(res, 500, std::string("numerical failure: ") + e.what());
    } catch (const std::exception& e) {
      fail(res, 500, e.what());
    }
  }

  template <typename Handler>
  static httplib::Server::Handler guarded(Handler handler) {
    return [handler](const httplib::Request& req, httplib::Response& res) {
      answerErrors(res, [&] { handler(req, res); });
    };
  }

  // A POST handler, given the content reader: the body is read under the route's limit.
  template <typename Handler>
  static httplib::Server::HandlerWithContentReader guardedPost(Handler handler) {
    return [handler](const httplib::Request& req, httplib::Response& res,
                     const httplib::ContentReader& reader) {
      answerErrors(res, [&] { handler(req, res, reader); });
    };
  }

  void serveFile(const httplib::Request& req, httplib::Response& res) {
    if (webDir.empty()) return fail(res, 404, "no page folder");
    std::string rel = req.path == "/" ? "/index.html" : req.path;
    if (rel.empty() || rel[0] != '/') return fail(res, 400, "bad path");
    rel.erase(0, 1);
    std::filesystem::path path = webDir;
    std::size_t start = 0;
    while (start <= rel.size()) {
      const std::size_t stop = std::min(rel.find('/', start), rel.size());
      const std::string segment = rel.substr(start, stop - start);
      // No empty segments (an absolute path "//etc"), no "." or "..", no dotfiles, no
      // backslashes or NULs.
      if (segment.empty() || segment[0] == '.' || segment.find('\\') != std::string::npos ||
          segment.find('\0') != std::string::npos)
        return fail(res, 403, "refused: path '" + req.path + "'");
      path /= segment;
      start = stop + 1;
    }
    std::error_code error;
    const std::filesystem::path real = std::filesystem::weakly_canonical(path, error);
    const std::string root = webDir.string() + "/";
    if (error || !real.string().starts_with(root))
      return fail(res, 403, "refused: '" + req.path + "' leads out of the page folder");
    if (!std::filesystem::is_regular_file(real, error))
      return fail(res, 404, "no file " + req.path);
    std::ifstream in(real, std::ios::binary);
    std::ostringstream body;
    body << in.rdbuf();
    if (!in && !in.eof()) return fail(res, 500, "cannot read " + req.path);
    res.set_content(body.str(), contentType(real));
    res.set_header("Cache-Control", "no-cache");
  }

  // GET /api/scene
  void scene(const httplib::Request&, httplib::Response& res) {
    nlohmann::json scene;
    {
      const std::lock_guard lock(mutex);
      scene = session.sceneJson();
    }
    scene["saveDir"] = saveDir.string();
    sendJson(res, scene);
  }

  // GET /api/model
  void model(const httplib::Request&, httplib::Response& res) {
    const std::lock_guard lock(mutex);
    const auto rest = std::span<const Vec3>(session.model().positions);
    const std::vector<std::uint32_t>& tris = session.triangles();
    const auto n = static_cast<std::uint32_t>(rest.size());
    const auto t = static_cast<std::uint32_t>(tris.size() / 3);
    sendBinary(res, 8 + 12 * std::size_t(n) + 4 * tris.size(), [&](char* out) {
      std::memcpy(out, &n, 4);
      std::memcpy(out + 4, &t, 4);
      positionsInto(rest, session.origin(), out + 8);
      std::memcpy(out + 8 + 12 * std::size_t(n), tris.data(), 4 * tris.size());
    });
  }

  // POST /api/pose
  void pose(const httplib::Request& req, httplib::Response& res,
            const httplib::ContentReader& reader) {
    const std::string body = readBody(req, reader, poseBytes);
    const std::lock_guard lock(mutex);
    const std::size_t m = session.restControls().size();
    if (body.size() != 24 * m)
      throw BadRequest("a pose is " + std::to_string(24 * m) + " bytes (" + std::to_string(m) +
                       " controls × 3 float64), not " + std::to_string(body.size()));
    std::vector<Vec3> pose(m);
    for (std::size_t i = 0; i < m; ++i) {
      double xyz[3];
      std::memcpy(xyz, body.data() + 24 * i, 24);
      pose[i] = Vec3(xyz[0], xyz[1], xyz[2]);
    }
    const double ms = session.setPose(pose);
    const auto positions = session.positions();
    sendBinary(res, 12 * positions.size(),
               [&](char* out) { positionsInto(positions, session.origin(), out); });
    res.set_header("X-Spacewarp-Deform-Ms", std::to_string(ms));
  }

  // POST /api/method
  void method(const httplib::Request& req, httplib::Response& res,
              const httplib::ContentReader& reader) {
    const std::string method = nameField(jsonBody(req, reader), "method", "a method's name");
    const std::lock_guard lock(mutex);
    const double ms = session.setMethod(method);
    sendJson(res,
             {{"method", session.method()}, {"hasWeights", session.hasWeights()}, {"bindMs", ms}});
  }

  // GET /api/positions
  void positions(const httplib::Request&, httplib::Response& res) {
    const std::lock_guard lock(mutex);
    const auto positions = session.positions();
    sendBinary(res, 12 * positions.size(),
               [&](char* out) { positionsInto(positions, session.origin(), out); });
  }

  // GET /api/weights
  void weights(const httplib::Request& req, httplib::Response& res) {
    const auto control =
        static_cast<std::size_t>(integerParam(req, "control", nullptr, 0, 1LL << 40));
    const std::vector<double> w = unlocked([&] { return session.weightsJob(control); });
    sendBinary(res, 4 * w.size(), [&](char* out) {
      for (std::size_t i = 0; i < w.size(); ++i) {
        const auto f = static_cast<float>(w[i]);
        std::memcpy(out + 4 * i, &f, 4);
      }
    });
  }

  // GET /api/slice
  void slice(const httplib::Request& req, httplib::Response& res) {
    const auto control =
        static_cast<std::size_t>(integerParam(req, "control", nullptr, 0, 1LL << 40));
    const std::string axisName = param(req, "axis", nullptr);
    const int axis = axisName == "x" ? 0 : axisName == "y" ? 1 : axisName == "z" ? 2 : -1;
    if (axis < 0) throw BadRequest("'axis' must be x, y or z, not '" + axisName + "'");
    const double value = numberParam(req, "value");
    const int r = static_cast<int>(integerParam(req, "resolution", "256", 2, 1024));
    const ViewSession::Slice slice =
        unlocked([&] { return session.sliceJob(control, axis, value, r); });
    const auto vec = [](const Vec3& v) {
      char text[96];
      std::snprintf(text, sizeof text, "%.17g %.17g %.17g", v.x, v.y, v.z);
      return std::string(text);
    };
    res.set_header("X-Spacewarp-Slice-Origin", vec(slice.origin));
    res.set_header("X-Spacewarp-Slice-U", vec(slice.u));
    res.set_header("X-Spacewarp-Slice-V", vec(slice.v));
    sendBinary(res, 4 * slice.values.size(), [&](char* out) {
      for (std::size_t i = 0; i < slice.values.size(); ++i) {
        const auto f = static_cast<float>(slice.values[i]);
        std::memcpy(out + 4 * i, &f, 4);
      }
    });
  }

  // GET /api/colormap
  void colormap(const httplib::Request& req, httplib::Response& res) {
    const double lo = numberParam(req, "min"), hi = numberParam(req, "max");
    const auto n = static_cast<int>(integerParam(req, "n", nullptr, 2, 4096));
    if (!(lo <= 0.0 && 0.0 <= hi)) throw BadRequest("the colour map needs min <= 0 <= max");
    const cli::ColourScale scale{lo, hi};
    nlohmann::json colors = nlohmann::json::array();
    for (int i = 0; i < n; ++i) {
      // a + (b - a) t as the API says, unless b - a overflows (±1e308): then the
      // weighted ends.
      const double t = double(i) / (n - 1);
      const double value =
          std::isfinite(hi - lo) ? lo + (hi - lo) * i / (n - 1) : lo * (1.0 - t) + hi * t;
      const cli::Rgb c = scale(value);
      colors.push_back({c.r, c.g, c.b});
    }
    sendJson(res, {{"colors", colors},
                   {"outside", {cli::kOutside.r, cli::kOutside.g, cli::kOutside.b}}});
  }

  // GET /api/folds
  void folds(const httplib::Request&, httplib::Response& res) {
    const std::vector<std::uint8_t> folds = unlocked([&] { return session.foldsJob(); });
    sendBinary(res, folds.size(), [&](char* out) { std::memcpy(out, folds.data(), folds.size()); });
  }

  // POST /api/save
  void save(const httplib::Request& req, httplib::Response& res,
            const httplib::ContentReader& reader) {
    const std::string what =
        nameField(jsonBody(req, reader), "what", "\"pose\", \"rig\" or \"model\"");
    std::vector<std::filesystem::path> paths;
    std::function<std::filesystem::path()> writeModel;
    {
      const std::lock_guard lock(mutex);
      if (what == "pose") {
        paths.push_back(session.writePose(saveDir));
      } else if (what == "rig") {
        paths = session.writeRig(saveDir);
      } else if (what == "model") {
        writeModel = session.writeModelJob(saveDir);
      } else {
        throw BadRequest("\"what\" must be \"pose\", \"rig\" or \"model\"");
      }
    }
    if (writeModel) paths.push_back(writeModel());  // without the lock
    nlohmann::json list = nlohmann::json::array();
    for (const auto& p : paths) list.push_back(p.string());
    sendJson(res, {{"paths", list}});
  }

  // POST /api/screenshot
  void screenshot(const httplib::Request& req, httplib::Response& res,
                  const httplib::ContentReader& reader) {
    const std::string body = readBody(req, reader, kMaxScreenshot);
    if (!isPng(body)) throw BadRequest("the body is not a PNG image");
    const std::filesystem::path path = savePath(saveDir, modelStem + "_view.png");
    writeFileAtomically(path, [&](std::ostream& out) {
      out.write(body.data(), static_cast<std::streamsize>(body.size()));
    });
    sendJson(res, {{"paths", {path.string()}}});
  }

  using GetHandler = void (Impl::*)(const httplib::Request&, httplib::Response&);
  using PostHandler = void (Impl::*)(const httplib::Request&, httplib::Response&,
                                     const httplib::ContentReader&);

  // The server's settings and its routes: one handler per endpoint above.
  void routes() {
    server.set_pre_routing_handler(
        [this](const httplib::Request& req, httplib::Response& res) { return screen(req, res); });
    server.set_error_handler(httplib::Server::HandlerWithResponse(
        [](const httplib::Request& req, httplib::Response& res) {
          if (!res.body.empty()) return httplib::Server::HandlerResponse::Unhandled;
          std::string what = res.status == 413   ? "the body is too large"
                             : res.status == 404 ? "not found: " + req.path
                                                 : "bad request";
          fail(res, res.status, what);
          return httplib::Server::HandlerResponse::Handled;
        }));
    // SO_REUSEADDR (a restart binds at once past TIME_WAIT) but not httplib's SO_REUSEPORT,
    // with which a second viewer on the same port would share the first one's connections
    // instead of failing.
    server.set_socket_options([](socket_t sock) {
      int yes = 1;
      ::setsockopt(sock, SOL_SOCKET, SO_REUSEADDR, &yes, sizeof yes);
    });
    server.set_payload_max_length(kMaxScreenshot);
    server.set_keep_alive_timeout(1);  // idle connections do not hold stop() up for long
    // Connections that send their headers or body slowly (or not at all) each hold a worker:
    // short socket timeouts free them, and a pool larger than a browser's few connections leaves
    // workers free for the page while some are held (the pool's threads sleep when idle).
    // httplib's keep-alive count (5) is kept small on purpose: after a 413 the rest of a chunked
    // body is read as (bad) requests until the connection's count runs out.
    server.set_read_timeout(kSocketTimeoutSeconds);
    server.set_write_timeout(kSocketTimeoutSeconds);
    server.new_task_queue = [] { return new httplib::ThreadPool(kWorkerThreads); };

    for (const auto& [path, handler] : std::initializer_list<std::pair<const char*, GetHandler>>{
             {"/api/scene", &Impl::scene},
             {"/api/model", &Impl::model},
             {"/api/positions", &Impl::positions},
             {"/api/weights", &Impl::weights},
             {"/api/slice", &Impl::slice},
             {"/api/colormap", &Impl::colormap},
             {"/api/folds", &Impl::folds},
             {".*", &Impl::serveFile}}) {  // last: httplib tries the patterns in order
      if (std::string_view(path).starts_with("/api/")) apiVerbs.emplace(path, "GET");
      server.Get(path,
                 guarded([this, handler](const httplib::Request& req, httplib::Response& res) {
                   (this->*handler)(req, res);
                 }));
    }
    for (const auto& [path, handler] : std::initializer_list<std::pair<const char*, PostHandler>>{
             {"/api/pose", &Impl::pose},
             {"/api/method", &Impl::method},
             {"/api/save", &Impl::save},
             {"/api/screenshot", &Impl::screenshot}}) {
      apiVerbs.emplace(path, "POST");
      server.Post(path,
                  guardedPost([this, handler](const httplib::Request& req, httplib::Response& res,
                                              const httplib::ContentReader& reader) {
                    (this->*handler)(req, res, reader);
                  }));
    }
  }
};

ViewServer::ViewServer(ViewSession session, ViewServerOptions options)
    : impl_(std::make_unique<Impl>(std::move(session), std::move(options))) {
  impl_->routes();
}

ViewServer::~ViewServer() { stop(); }

int ViewServer::bind() {
  const ViewServerOptions& o = impl_->options;
  if (o.port == 0) {
    impl_->port = impl_->server.bind_to_any_port(o.host);
    if (impl_->port < 0)
      throw std::runtime_error("view: cannot listen on " + o.host + " (any port)");
  } else {
    if (!impl_->server.bind_to_port(o.host, o.port))
      throw std::runtime_error("view: cannot listen on " + o.host + ":" + std::to_string(o.port) +
                               ": port " + std::to_string(o.port) +
                               " is in use (or not allowed); choose another with --port");
    impl_->port = o.port;
  }
  return impl_->port;
}

void ViewServer::listen() {
  impl_->listening = true;
  if (!impl_->stopRequested) impl_->server.listen_after_bind();
  impl_->listening = false;
}

void ViewServer::stop() {
  if (!impl_) return;
  impl_->stopRequested = true;
  // httplib's stop() is lost while listen() is starting (before it runs): repeat until listen()
  // has returned.
  while (impl_->listening) {
    impl_->server.stop();
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
}

int ViewServer::port() const { return impl_->port; }

std::string ViewServer::url() const {
  const std::string& host = impl_->options.host;
  const bool v6 = host.find(':') != std::string::npos;
  return "http://" + (v6 ? "[" + host + "]" : host) + ":" + std::to_string(impl_->port) + "/";
}

}  // namespace spacewarp::view
