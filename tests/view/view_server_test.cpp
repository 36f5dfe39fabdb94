#include "apps/view/view_server.h"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <atomic>
#include <cmath>
#include <cstring>
#include <fstream>
#include <sstream>
#include <thread>

#include <gtest/gtest.h>
#include <httplib.h>

#include <spacewarp/core/primitives.h>
#include "apps/heat_map.h"
#include "view_test_util.h"

namespace spacewarp::test {
namespace {

using view::ViewSession;

// Sends `request` as raw bytes on a new connection; returns what the server answers until it
// closes (or nothing when `closeEarly`: the connection is closed right after sending).
std::string rawRequest(int port, const std::string& request, bool closeEarly = false) {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_port = htons(static_cast<std::uint16_t>(port));
  address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  if (::connect(fd, reinterpret_cast<sockaddr*>(&address), sizeof address) != 0) {
    ::close(fd);
    return "connect failed";
  }
  for (std::size_t sent = 0; sent < request.size();) {
    const ssize_t n = ::send(fd, request.data() + sent, request.size() - sent, MSG_NOSIGNAL);
    if (n <= 0) break;
    sent += static_cast<std::size_t>(n);
  }
  std::string answer;
  if (!closeEarly) {
    char buffer[4096];
    for (ssize_t n; (n = ::recv(fd, buffer, sizeof buffer, 0)) > 0;) answer.append(buffer, n);
  }
  ::close(fd);
  return answer;
}

// Sends a chunked POST of up to `total` bytes in 1 MiB chunks; returns the bytes of body sent
// before the server stopped taking them, and its answer (empty when it cut the connection).
std::pair<std::size_t, std::string> chunkedPost(int port, const std::string& path,
                                                const std::string& type, std::size_t total) {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  timeval timeout{5, 0};
  ::setsockopt(fd, SOL_SOCKET, SO_SNDTIMEO, &timeout, sizeof timeout);
  ::setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &timeout, sizeof timeout);
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_port = htons(static_cast<std::uint16_t>(port));
  address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  if (::connect(fd, reinterpret_cast<sockaddr*>(&address), sizeof address) != 0) {
    ::close(fd);
    return {0, "connect failed"};
  }
  const auto sendAll = [fd](const std::string& bytes) {
    for (std::size_t sent = 0; sent < bytes.size();) {
      const ssize_t n = ::send(fd, bytes.data() + sent, bytes.size() - sent, MSG_NOSIGNAL);
      if (n <= 0) return false;
      sent += static_cast<std::size_t>(n);
    }
    return true;
  };
  sendAll("POST " + path + " HTTP/1.1\r\nHost: 127.0.0.1:" + std::to_string(port) +
          "\r\nContent-Type: " + type + "\r\nTransfer-Encoding: chunked\r\n\r\n");
  const std::size_t chunk = 1 << 20;
  std::string piece = "100000\r\n" + std::string(chunk, 'x') + "\r\n";
  piece.replace(8, 8, "\x89PNG\r\n\x1a\n");
  std::size_t sent = 0;
  while (sent < total && sendAll(piece)) sent += chunk;
  if (sent >= total) sendAll("0\r\n\r\n");
  std::string answer;
  char buffer[4096];
  for (ssize_t n; (n = ::recv(fd, buffer, sizeof buffer, 0)) > 0;) answer.append(buffer, n);
  ::close(fd);
  return {sent, answer};
}

// A PNG's frame around `padding` bytes: the signature, an IHDR chunk (1 × 1, RGB, 8 bits), the
// padding as a chunk's bytes, and the IEND chunk; the server checks the frame, not the pixels.
std::string pngFrame(std::size_t padding) {
  return std::string("\x89PNG\r\n\x1a\n", 8) +
         std::string("\0\0\0\x0dIHDR\0\0\0\x01\0\0\0\x01\x08\x02\0\0\0\x90\x77\x53\xde", 25) +
         std::string(padding, 'x') + std::string("\0\0\0\0IEND\xae\x42\x60\x82", 12);
}

std::string poseBody(std::span<const Vec3> pose) {
  std::string body(24 * pose.size(), '\0');
  for (std::size_t i = 0; i < pose.size(); ++i) {
    const double xyz[3] = {pose[i].x, pose[i].y, pose[i].z};
    std::memcpy(body.data() + 24 * i, xyz, 24);
  }
  return body;
}

std::vector<float> floats(const std::string& body) {
  std::vector<float> out(body.size() / 4);
  std::memcpy(out.data(), body.data(), 4 * out.size());
  return out;
}

// The API's origin for a model: its bounding-box centre.
Vec3 originOf(std::span<const Vec3> model) {
  const BoundingBox box = boundingBox(model);
  return 0.5 * (box.min + box.max);
}

// The float32 positions the API should answer for `positions` of `model`: relative to its
// origin.
std::vector<float> asFloats(std::span<const Vec3> positions, std::span<const Vec3> model) {
  const Vec3 origin = originOf(model);
  std::vector<float> out;
  for (const Vec3& p : positions)
    for (int c = 0; c < 3; ++c) out.push_back(static_cast<float>(p[c] - origin[c]));
  return out;
}

// A server over model.obj in cage.obj on a free port, serving page/ and saving into saves/.
class ViewServerTest : public ViewFixture {
 protected:
  void SetUp() override {
    ViewFixture::SetUp();
    std::filesystem::create_directories(dir_ / "page" / "assets");
    write("page/index.html", "<html>viewer</html>");
    write("page/assets/app.js", "console.log(1)");
    write("page/.secret", "hidden");
    write("outside.txt", "outside the page");
    std::filesystem::create_symlink(dir_ / "outside.txt", dir_ / "page" / "link.txt");
    std::filesystem::create_directories(dir_ / "saves");
    start(cageSession());
  }
  void TearDown() override {
    stop();
    ViewFixture::TearDown();
  }

  void start(ViewSession session, view::ViewServerOptions options = {}) {
    options.port = 0;
    if (options.webDir.empty()) options.webDir = dir_ / "page";
    if (options.saveDir == ".") options.saveDir = dir_ / "saves";
    server_ = std::make_unique<view::ViewServer>(std::move(session), options);
    port_ = server_->bind();
    thread_ = std::thread([this] { server_->listen(); });
  }
  void stop() {
    if (server_) server_->stop();
    if (thread_.joinable()) thread_.join();
    server_.reset();
  }

  httplib::Client client() {
    httplib::Client c("127.0.0.1", port_);
    c.set_read_timeout(60);
    return c;
  }

  // The response must be a one-line JSON error with this status.
  static void expectError(const httplib::Result& r, int status) {
    ASSERT_TRUE(r) << "no response";
    EXPECT_EQ(r->status, status) << r->body;
    const nlohmann::json body = nlohmann::json::parse(r->body, nullptr, false);
    ASSERT_TRUE(body.is_object() && body.contains("error")) << r->body;
    EXPECT_EQ(r->body.find('\n'), std::string::npos);
    EXPECT_FALSE(body["error"].get<std::string>().empty());
  }

  std::unique_ptr<view::ViewServer> server_;
  std::thread thread_;
  int port_ = 0;
};

TEST_F(ViewServerTest, SceneDescribesTheModelControlsAndMethods) {
  const auto r = client().Get("/api/scene");
  ASSERT_TRUE(r);
  ASSERT_EQ(r->status, 200);
  const nlohmann::json scene = nlohmann::json::parse(r->body);
  EXPECT_EQ(scene["model"]["vertexCount"], model_.positions.size());
  EXPECT_EQ(scene["model"]["kind"], "soup");
  EXPECT_EQ(scene["model"]["triangleCount"], 2 * model_.polygonCount());  // quads, fanned
  EXPECT_EQ(scene["controls"]["kind"], "cage");
  EXPECT_EQ(scene["controls"]["count"], 12);
  EXPECT_EQ(scene["controls"]["rest"].size(), 12u);
  EXPECT_EQ(scene["controls"]["pose"], scene["controls"]["rest"]);
  EXPECT_EQ(scene["controls"]["faces"].size(), 10u);
  EXPECT_EQ(scene["method"], "mvc");
  EXPECT_TRUE(scene["hasWeights"]);
  EXPECT_EQ(scene["saveDir"], (dir_ / "saves").string());
  EXPECT_GE(scene["methods"].size(), 6u);
  EXPECT_EQ(scene["model"]["bounds"][0][0], -0.6);
  EXPECT_EQ(scene["model"]["bounds"][1][2], 1.2);
  const Vec3 origin = originOf(model_.positions);
  EXPECT_EQ(scene["origin"], nlohmann::json({origin.x, origin.y, origin.z}));
}

TEST_F(ViewServerTest, AFarModelKeepsFloat32PrecisionOfItsSize) {
  // The model and cage 1e6 away: float32 world coordinates there are 0.06 apart, coarser than
  // the model's 0.2 spacing allows to draw; positions relative to the origin stay exact.
  const Vec3 far(1e6, -2e6, 1e6);
  PolygonSoup model = model_, cage = readSoup(dir_ / "cage.obj");
  for (Vec3& p : model.positions) p += far;
  for (Vec3& p : cage.positions) p += far;
  writeSoup(model, dir_ / "far_model.obj");
  writeSoup(cage, dir_ / "far_cage.obj");
  const auto session = [&] {
    return ViewSession::withCage(dir_ / "far_model.obj", dir_ / "far_cage.obj", {});
  };
  stop();
  start(session());
  httplib::Client c = client();
  const nlohmann::json scene = nlohmann::json::parse(c.Get("/api/scene")->body);
  const Vec3 origin(scene["origin"][0], scene["origin"][1], scene["origin"][2]);
  EXPECT_LT(glm::length(origin - far), 1.0);
  // Relative float32 + the double origin: the positions to float32 precision of the size.
  const auto world = [&](const std::vector<float>& xyz) {
    std::vector<Vec3> out;
    for (std::size_t i = 0; i + 2 < xyz.size(); i += 3)
      out.push_back(origin + Vec3(xyz[i], xyz[i + 1], xyz[i + 2]));
    return out;
  };
  const std::string body = c.Get("/api/model")->body;
  const std::size_t n = model.positions.size();
  EXPECT_LT(relativeGap(world(floats(body.substr(8, 12 * n))), model.positions, model.positions),
            1e-6);
  ViewSession reference = session();
  std::vector<Vec3> pose;
  for (std::size_t i = 0; i < reference.restControls().size(); ++i)
    pose.push_back(reference.restControls()[i] + Vec3(0.1, 0.0, 0.05 * double(i)));
  reference.setPose(pose);
  const auto r = c.Post("/api/pose", poseBody(pose), "application/octet-stream");
  ASSERT_EQ(r->status, 200);
  EXPECT_LT(relativeGap(world(floats(r->body)), reference.positions(), model.positions), 1e-6);
  EXPECT_LT(relativeGap(world(floats(c.Get("/api/positions")->body)), reference.positions(),
                        model.positions),
            1e-6);
}

TEST_F(ViewServerTest, ModelIsTheRestPositionsAndFannedTriangles) {
  const auto r = client().Get("/api/model");
  ASSERT_TRUE(r);
  std::uint32_t n = 0, t = 0;
  std::memcpy(&n, r->body.data(), 4);
  std::memcpy(&t, r->body.data() + 4, 4);
  ASSERT_EQ(n, model_.positions.size());
  ASSERT_EQ(r->body.size(), 8 + 12 * std::size_t(n) + 12 * std::size_t(t));
  const std::vector<float> xyz = floats(r->body.substr(8, 12 * n));
  EXPECT_EQ(xyz, asFloats(model_.positions, model_.positions));
  std::vector<std::uint32_t> tris(3 * t);
  std::memcpy(tris.data(), r->body.data() + 8 + 12 * n, 12 * t);
  for (const std::uint32_t i : tris) ASSERT_LT(i, n);
}

TEST_F(ViewServerTest, PoseAnswersTheSessionsPositionsAndKeepsThePose) {
  ViewSession reference = cageSession();
  const std::vector<Vec3> pose = sway(reference.restControls());
  reference.setPose(pose);
  auto c = client();
  const auto r = c.Post("/api/pose", poseBody(pose), "application/octet-stream");
  ASSERT_TRUE(r);
  ASSERT_EQ(r->status, 200) << r->body;
  EXPECT_EQ(floats(r->body), asFloats(reference.positions(), model_.positions));
  ASSERT_TRUE(r->has_header("X-Spacewarp-Deform-Ms"));
  EXPECT_GE(std::stod(r->get_header_value("X-Spacewarp-Deform-Ms")), 0.0);
  const auto again = c.Get("/api/positions");
  ASSERT_TRUE(again);
  EXPECT_EQ(again->body, r->body);
  const nlohmann::json scene = nlohmann::json::parse(c.Get("/api/scene")->body);
  EXPECT_EQ(scene["controls"]["pose"][5][0], pose[5].x);
}

TEST_F(ViewServerTest, MethodSwitchBindsOnceAndKeepsThePose) {
  auto c = client();
  ViewSession reference = cageSession("green");
  const std::vector<Vec3> pose = sway(reference.restControls());
  reference.setPose(pose);
  ASSERT_EQ(c.Post("/api/pose", poseBody(pose), "application/octet-stream")->status, 200);
  const auto r = c.Post("/api/method", R"({"method": "green"})", "application/json");
  ASSERT_TRUE(r);
  ASSERT_EQ(r->status, 200) << r->body;
  const nlohmann::json body = nlohmann::json::parse(r->body);
  EXPECT_EQ(body["method"], "green");
  EXPECT_TRUE(body["hasWeights"]);
  EXPECT_GE(body["bindMs"].get<double>(), 0.0);
  EXPECT_EQ(floats(c.Get("/api/positions")->body),
            asFloats(reference.positions(), model_.positions));
  const nlohmann::json mls = nlohmann::json::parse(
      c.Post("/api/method", R"({"method": "mls"})", "application/json")->body);
  EXPECT_FALSE(mls["hasWeights"]);
  expectError(c.Get("/api/weights?control=0"), 409);
  expectError(c.Get("/api/slice?control=0&axis=z&value=0"), 409);
  expectError(c.Post("/api/method", R"({"method": "nope"})", "application/json"), 400);
  expectError(c.Post("/api/method", R"({"mode": "mvc"})", "application/json"), 400);
  expectError(c.Post("/api/method", "not json", "application/json"), 400);
}

TEST_F(ViewServerTest, WeightsSumToOneOverTheControls) {
  auto c = client();
  std::vector<double> sum(model_.positions.size(), 0.0);
  for (int i = 0; i < 12; ++i) {
    const auto r = c.Get("/api/weights?control=" + std::to_string(i));
    ASSERT_TRUE(r);
    ASSERT_EQ(r->body.size(), 4 * sum.size());
    const std::vector<float> w = floats(r->body);
    for (std::size_t k = 0; k < sum.size(); ++k) sum[k] += w[k];
  }
  for (const double s : sum) ASSERT_NEAR(s, 1.0, 1e-5);
  expectError(c.Get("/api/weights?control=12"), 400);
  expectError(c.Get("/api/weights?control=-1"), 400);
  expectError(c.Get("/api/weights?control=1x"), 400);
  expectError(c.Get("/api/weights"), 400);
}

TEST_F(ViewServerTest, SliceHasItsPlaneInTheHeaders) {
  auto c = client();
  const auto r = c.Get("/api/slice?control=2&axis=y&value=0.1&resolution=5");
  ASSERT_TRUE(r);
  ASSERT_EQ(r->status, 200) << r->body;
  EXPECT_EQ(r->body.size(), 4u * 25);
  std::istringstream origin(r->get_header_value("X-Spacewarp-Slice-Origin"));
  double x = 0, y = 0, z = 0;
  origin >> x >> y >> z;
  EXPECT_EQ(y, 0.1);
  EXPECT_FALSE(r->get_header_value("X-Spacewarp-Slice-U").empty());
  EXPECT_FALSE(r->get_header_value("X-Spacewarp-Slice-V").empty());
  EXPECT_EQ(c.Get("/api/slice?control=2&axis=z&value=0")->body.size(), 4u * 256 * 256);
  expectError(c.Get("/api/slice?control=2&axis=w&value=0"), 400);
  expectError(c.Get("/api/slice?control=2&axis=x&value=nan"), 400);
  expectError(c.Get("/api/slice?control=2&axis=x&value=1e999"), 400);
  expectError(c.Get("/api/slice?control=2&axis=x&value=0&resolution=1"), 400);
  expectError(c.Get("/api/slice?control=2&axis=x&value=0&resolution=1025"), 400);
}

TEST_F(ViewServerTest, ColormapIsComparesColourScale) {
  const auto r = client().Get("/api/colormap?min=-0.25&max=1.5&n=8");
  ASSERT_TRUE(r);
  const nlohmann::json body = nlohmann::json::parse(r->body);
  ASSERT_EQ(body["colors"].size(), 8u);
  const cli::ColourScale scale{-0.25, 1.5};
  for (int i = 0; i < 8; ++i) {
    const cli::Rgb c = scale(-0.25 + 1.75 * i / 7);
    EXPECT_EQ(body["colors"][i], nlohmann::json({c.r, c.g, c.b})) << i;
  }
  EXPECT_EQ(body["outside"], nlohmann::json({cli::kOutside.r, cli::kOutside.g, cli::kOutside.b}));
  auto c = client();
  expectError(c.Get("/api/colormap?min=0.5&max=1&n=8"), 400);
  expectError(c.Get("/api/colormap?min=-1&max=1&n=1"), 400);
  expectError(c.Get("/api/colormap?min=-1&max=1&n=4097"), 400);
  expectError(c.Get("/api/colormap?min=-1&max=inf&n=4"), 400);
}

TEST_F(ViewServerTest, FoldsFollowThePose) {
  auto c = client();
  ViewSession reference = cageSession();
  EXPECT_EQ(c.Get("/api/folds")->body, std::string(model_.positions.size(), '\0'));
  ASSERT_EQ(
      c.Post("/api/pose", poseBody(mirror(reference.restControls())), "application/octet-stream")
          ->status,
      200);
  EXPECT_EQ(c.Get("/api/folds")->body, std::string(model_.positions.size(), '\1'));
}

TEST_F(ViewServerTest, SavesWriteThePoseRigAndModel) {
  auto c = client();
  ViewSession reference = cageSession();
  const std::vector<Vec3> pose = sway(reference.restControls());
  reference.setPose(pose);
  ASSERT_EQ(c.Post("/api/pose", poseBody(pose), "application/octet-stream")->status, 200);
  const auto rig = c.Post("/api/save", R"({"what": "rig"})", "application/json");
  ASSERT_EQ(rig->status, 200) << rig->body;
  const nlohmann::json paths = nlohmann::json::parse(rig->body)["paths"];
  ASSERT_EQ(paths.size(), 2u);
  EXPECT_EQ(paths[0], (dir_ / "saves" / "model_pose.obj").string());
  EXPECT_EQ(paths[1], (dir_ / "saves" / "model_rig.json").string());
  EXPECT_LT(relativeGap(deformedByRig(paths[1].get<std::string>()), reference.positions(),
                        model_.positions),
            1e-12);
  const auto model = c.Post("/api/save", R"({"what": "model"})", "application/json");
  ASSERT_EQ(model->status, 200) << model->body;
  EXPECT_EQ(readSoup(dir_ / "saves" / "model_deformed.obj").positions.size(),
            model_.positions.size());
  expectError(c.Post("/api/save", R"({"what": "everything"})", "application/json"), 400);
}

TEST_F(ViewServerTest, AFailingSaveIsA500AndLeavesNoFile) {
  stop();
  view::ViewServerOptions options;
  options.saveDir = dir_ / "missing" / "folder";  // (root ignores read-only folders)
  start(cageSession(), options);
  auto c = client();
  for (const char* what : {"pose", "rig", "model"})
    expectError(
        c.Post("/api/save", std::string(R"({"what": ")") + what + "\"}", "application/json"), 500);
  expectError(c.Post("/api/screenshot", pngFrame(4), "image/png"), 500);
  EXPECT_FALSE(std::filesystem::exists(dir_ / "missing"));
  // The server goes on serving.
  EXPECT_EQ(c.Get("/api/scene")->status, 200);
}

TEST_F(ViewServerTest, ScreenshotsArePngsOnly) {
  auto c = client();
  const std::string png = pngFrame(1000);
  const auto r = c.Post("/api/screenshot", png, "image/png");
  ASSERT_EQ(r->status, 200) << r->body;
  EXPECT_EQ(nlohmann::json::parse(r->body)["paths"][0],
            (dir_ / "saves" / "model_view.png").string());
  std::ifstream in(dir_ / "saves" / "model_view.png", std::ios::binary);
  EXPECT_EQ(std::string(std::istreambuf_iterator<char>(in), {}), png);
  expectError(c.Post("/api/screenshot", "GIF89a....", "image/png"), 400);
  // The signature alone is not a PNG: the IHDR and IEND chunks are checked too.
  expectError(c.Post("/api/screenshot", std::string("\x89PNG\r\n\x1a\ngarbage", 15), "image/png"),
              400);
  std::string noIend = pngFrame(1000);
  noIend.resize(noIend.size() - 12);
  expectError(c.Post("/api/screenshot", noIend, "image/png"), 400);
  std::string zeroWidth = pngFrame(10);
  zeroWidth[19] = '\0';
  expectError(c.Post("/api/screenshot", zeroWidth, "image/png"), 400);
  // Refused from its Content-Length, before the body is read (a client still sending it then
  // sees the connection close, so the request goes without its body here).
  const std::string answer = rawRequest(
      port_, "POST /api/screenshot HTTP/1.1\r\nHost: 127.0.0.1:" + std::to_string(port_) +
                 "\r\nContent-Type: image/png\r\nContent-Length: " +
                 std::to_string(view::kMaxScreenshot + 1) + "\r\nConnection: close\r\n\r\n");
  EXPECT_TRUE(answer.starts_with("HTTP/1.1 413")) << answer.substr(0, 40);
  EXPECT_NE(answer.find("{\"error\":"), std::string::npos);
}

TEST_F(ViewServerTest, RefusesForeignHostsAndOrigins) {
  auto c = client();
  expectError(c.Get("/api/scene", {{"Host", "evil.example:" + std::to_string(port_)}}), 403);
  expectError(c.Get("/", {{"Host", "127.0.0.1:1"}}), 403);
  EXPECT_EQ(c.Get("/api/scene", {{"Host", "localhost:" + std::to_string(port_)}})->status, 200);
  EXPECT_EQ(c.Get("/api/scene", {{"Host", "[::1]:" + std::to_string(port_)}})->status, 200);
  const std::string body = R"({"method": "green"})";
  expectError(c.Post("/api/method", {{"Origin", "http://evil.example"}}, body, "application/json"),
              403);
  EXPECT_EQ(c.Post("/api/method", {{"Origin", "http://127.0.0.1:" + std::to_string(port_)}}, body,
                   "application/json")
                ->status,
            200);
  // Host names are case-insensitive; two Host headers are refused whatever their order.
  EXPECT_EQ(c.Get("/api/scene", {{"Host", "LOCALHOST:" + std::to_string(port_)}})->status, 200);
  const std::string good = "Host: 127.0.0.1:" + std::to_string(port_) + "\r\n";
  const std::string evil = "Host: evil.example:" + std::to_string(port_) + "\r\n";
  for (const std::string& hosts : {good + evil, evil + good})
    EXPECT_TRUE(
        rawRequest(port_, "GET /api/scene HTTP/1.1\r\n" + hosts + "Connection: close\r\n\r\n")
            .starts_with("HTTP/1.1 403"));
  // An explicit loopback host keeps the check even when asked to drop it.
  for (const std::string host : {"127.0.0.1", "localhost"}) {
    stop();
    view::ViewServerOptions options;
    options.host = host;
    options.checkHost = false;
    start(cageSession(), options);
    expectError(client().Get("/api/scene", {{"Host", "evil.example:" + std::to_string(port_)}}),
                403);
  }
  // A network host turns the Host check off, but an Origin is still compared with the server's
  // own origins, not with the request's Host.
  stop();
  view::ViewServerOptions options;
  options.host = "0.0.0.0";
  options.checkHost = false;
  start(cageSession(), options);
  const std::string p = std::to_string(port_);
  EXPECT_EQ(client().Get("/api/scene", {{"Host", "viewer.lan:8080"}})->status, 200);
  expectError(client().Post("/api/method",
                            {{"Host", "evil.example:" + p}, {"Origin", "http://evil.example:" + p}},
                            body, "application/json"),
              403);
  EXPECT_EQ(
      client()
          .Post("/api/method", {{"Host", "127.0.0.1:" + p}, {"Origin", "http://127.0.0.1:" + p}},
                body, "application/json")
          ->status,
      200);
}

TEST_F(ViewServerTest, RefusesBadBodiesAndPoses) {
  auto c = client();
  const ViewSession reference = cageSession();
  const std::vector<Vec3> rest(reference.restControls().begin(), reference.restControls().end());
  std::vector<Vec3> pose = sway(rest);
  expectError(c.Post("/api/pose", poseBody(pose).substr(0, 24 * 11), "application/octet-stream"),
              400);
  expectError(c.Post("/api/pose", poseBody(pose) + "12345678", "application/octet-stream"), 413);
  pose[3].z = std::nan("");
  expectError(c.Post("/api/pose", poseBody(pose), "application/octet-stream"), 400);
  pose[3].z = INFINITY;
  expectError(c.Post("/api/pose", poseBody(pose), "application/octet-stream"), 400);
  expectError(c.Post("/api/method", std::string(view::kMaxJsonBody + 1, ' '), "application/json"),
              413);
  // The refused poses were not kept.
  EXPECT_EQ(c.Get("/api/positions")->body, client().Get("/api/positions")->body);
  EXPECT_EQ(floats(c.Get("/api/positions")->body), asFloats(model_.positions, model_.positions));
}

TEST_F(ViewServerTest, ChunkedBodiesStopAtTheirLimit) {
  // 128 MiB chunked at a 32 MiB screenshot limit, and at the pose's and JSON's limits: the server
  // stops reading once past the limit (the sender is blocked or cut off long before the end).
  for (const auto& [path, type] :
       {std::pair<std::string, std::string>{"/api/screenshot", "image/png"},
        {"/api/pose", "application/octet-stream"},
        {"/api/method", "application/json"}}) {
    SCOPED_TRACE(path);
    const auto [sent, answer] = chunkedPost(port_, path, type, std::size_t(128) << 20);
    EXPECT_LT(sent, std::size_t(64) << 20);
    if (!answer.empty()) {
      EXPECT_TRUE(answer.starts_with("HTTP/1.1 413")) << answer.substr(0, 40);
    }
    EXPECT_FALSE(std::filesystem::exists(dir_ / "saves" / "model_view.png"));
  }
  EXPECT_EQ(client().Get("/api/scene")->status, 200);
}

TEST_F(ViewServerTest, BodyLimitsHoldForAnyContentType) {
  auto c = client();
  // A JSON body of 9 KiB sent as a form (curl -d's default type) is under the 64 KiB JSON limit.
  const std::string padded = R"({"method": "green"})" + std::string(9 * 1024, ' ');
  EXPECT_EQ(c.Post("/api/method", padded, "application/x-www-form-urlencoded")->status, 200);
  const std::string png = pngFrame(100 * 1024);
  EXPECT_EQ(c.Post("/api/screenshot", png, "application/x-www-form-urlencoded")->status, 200);
  expectError(c.Post("/api/method", std::string(view::kMaxJsonBody + 1, ' '),
                     "application/x-www-form-urlencoded"),
              413);
  // Content-Length: negative, twice, or with a chunked encoding: 400.
  const std::string host = "Host: 127.0.0.1:" + std::to_string(port_) + "\r\n";
  for (const std::string& lengths :
       {std::string("Content-Length: -5\r\n"),
        std::string("Content-Length: 19\r\nContent-Length: 5\r\n"),
        std::string("Content-Length: 19\r\nTransfer-Encoding: chunked\r\n")}) {
    SCOPED_TRACE(lengths);
    const std::string answer =
        rawRequest(port_, "POST /api/method HTTP/1.1\r\n" + host +
                              "Content-Type: application/json\r\nConnection: close\r\n" + lengths +
                              "\r\n" + R"({"method": "green"})");
    EXPECT_TRUE(answer.starts_with("HTTP/1.1 400")) << answer.substr(0, 40);
  }
}

TEST_F(ViewServerTest, SlowClientsLeaveWorkersForTheOthers) {
  // 32 connections that send half a request line and then nothing (slowloris) would hold every
  // worker of a small pool for the read timeout; a normal request is still answered before the
  // client's own timeout, which is shorter than the server's.
  std::vector<int> slow;
  for (int i = 0; i < 32; ++i) {
    const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in address{};
    address.sin_family = AF_INET;
    address.sin_port = htons(static_cast<std::uint16_t>(port_));
    address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    ASSERT_EQ(::connect(fd, reinterpret_cast<sockaddr*>(&address), sizeof address), 0);
    ASSERT_GT(::send(fd, "GET /api/scene HTTP/1.1\r\nHo", 27, MSG_NOSIGNAL), 0);
    slow.push_back(fd);
  }
  httplib::Client c("127.0.0.1", port_);
  c.set_read_timeout(view::kSocketTimeoutSeconds - 1);
  c.set_connection_timeout(view::kSocketTimeoutSeconds - 1);
  const auto r = c.Get("/api/scene");
  for (const int fd : slow) ::close(fd);
  ASSERT_TRUE(r) << "no answer while slow clients hold connections";
  EXPECT_EQ(r->status, 200);
}

TEST_F(ViewServerTest, PosesGoOnWhileASliceIsComputed) {
  // A 1024² slice of Green coordinates takes many pose times. It runs outside the session's lock,
  // so poses sent meanwhile are answered throughout: the longest wait between two pose answers
  // is a small part of the slice's time (under the lock it would be most of it). A ratio, not a
  // time limit.
  using Clock = std::chrono::steady_clock;
  auto c = client();
  ASSERT_EQ(c.Post("/api/method", R"({"method": "green"})", "application/json")->status, 200);
  const ViewSession reference = cageSession();
  const std::vector<Vec3> rest(reference.restControls().begin(), reference.restControls().end());
  std::atomic<bool> sliceDone{false};
  const Clock::time_point sliceStart = Clock::now();
  std::thread slicer([&] {
    const auto r = client().Get("/api/slice?control=0&axis=z&value=0.1&resolution=1024");
    EXPECT_EQ(r->status, 200);
    EXPECT_EQ(r->body.size(), 4u * 1024 * 1024);
    sliceDone = true;
  });
  Clock::duration longestWait{};
  Clock::time_point last = sliceStart;
  for (int i = 0; !sliceDone; ++i) {
    const auto r =
        c.Post("/api/pose", poseBody(sway(rest, 0.001 * (i % 100))), "application/octet-stream");
    ASSERT_EQ(r->status, 200);
    const Clock::time_point now = Clock::now();
    if (!sliceDone) longestWait = std::max(longestWait, now - last);
    last = now;
  }
  slicer.join();
  const Clock::duration sliceTime = Clock::now() - sliceStart;
  EXPECT_LT(longestWait, sliceTime / 4);
}

TEST_F(ViewServerTest, RefusesPosesThatOverflowAndKeepsThePrevious) {
  // Finite controls at 1e200 overflow Green's positions (squared lengths): refused, naming the
  // first vertex, and the previous pose and its positions are kept.
  auto c = client();
  ASSERT_EQ(c.Post("/api/method", R"({"method": "green"})", "application/json")->status, 200);
  const ViewSession reference = cageSession();
  const std::vector<Vec3> rest(reference.restControls().begin(), reference.restControls().end());
  const auto kept = c.Post("/api/pose", poseBody(sway(rest)), "application/octet-stream");
  ASSERT_EQ(kept->status, 200);
  std::vector<Vec3> huge = sway(rest);
  for (Vec3& p : huge) p *= 1e200;
  const auto r = c.Post("/api/pose", poseBody(huge), "application/octet-stream");
  expectError(r, 400);
  EXPECT_NE(r->body.find("vertex 0"), std::string::npos) << r->body;
  EXPECT_EQ(c.Get("/api/positions")->body, kept->body);
  const nlohmann::json scene = nlohmann::json::parse(c.Get("/api/scene")->body);
  EXPECT_EQ(scene["controls"]["pose"], nlohmann::json::parse(jsonOf(sway(rest))));
}

TEST_F(ViewServerTest, ExtremeQueriesAndOddBodiesAreClear400s) {
  auto c = client();
  // The colour map's ends at ±1e308 (hi − lo overflows) are the scale's own end colours.
  const auto map = c.Get("/api/colormap?min=-1e308&max=1e308&n=4096");
  ASSERT_EQ(map->status, 200);
  const nlohmann::json colors = nlohmann::json::parse(map->body)["colors"];
  const cli::ColourScale scale{-1e308, 1e308};
  const cli::Rgb first = scale(-1e308), last = scale(1e308);
  EXPECT_EQ(colors[0], nlohmann::json({first.r, first.g, first.b}));
  EXPECT_EQ(colors[4095], nlohmann::json({last.r, last.g, last.b}));
  EXPECT_NE(colors[0], colors[2047]);
  for (const int i : {1, 1024, 2047, 2048, 3000}) {
    const double t = i / 4095.0;
    const cli::Rgb expected = scale(-1e308 * (1 - t) + 1e308 * t);
    EXPECT_EQ(colors[i], nlohmann::json({expected.r, expected.g, expected.b})) << i;
  }
  // A slice plane far outside the cage: cells without weights are NaN, not a 500.
  const auto far = c.Get("/api/slice?control=0&axis=z&value=1e308&resolution=4");
  ASSERT_TRUE(far);
  EXPECT_EQ(far->status, 200) << far->body;
  // JSON of the wrong type, NUL and huge names: one clear line, the name cut to 64 characters.
  const auto array = c.Post("/api/save", R"({"what": ["pose"]})", "application/json");
  expectError(array, 400);
  EXPECT_EQ(array->body.find("json.exception"), std::string::npos) << array->body;
  const auto nul = c.Post("/api/method", R"({"method": "mvc\u0000x"})", "application/json");
  expectError(nul, 400);
  EXPECT_NE(nul->body.find("control character"), std::string::npos) << nul->body;
  const auto longName = c.Post("/api/method", R"({"method": ")" + std::string(60000, 'm') + "\"}",
                               "application/json");
  expectError(longName, 400);
  EXPECT_LT(longName->body.size(), 300u);
}

TEST_F(ViewServerTest, SavesRefuseSymlinksAtTheirNames) {
  // A link planted in the save folder at a save's name would redirect the write out of it.
  write("target.txt", "not to be overwritten");
  for (const char* name :
       {"model_pose.obj", "model_rig.json", "model_deformed.obj", "model_view.png"})
    std::filesystem::create_symlink(dir_ / "target.txt", dir_ / "saves" / name);
  auto c = client();
  for (const char* what : {"pose", "rig", "model"}) {
    SCOPED_TRACE(what);
    const auto r =
        c.Post("/api/save", std::string(R"({"what": ")") + what + "\"}", "application/json");
    expectError(r, 403);
    EXPECT_NE(r->body.find("symbolic link"), std::string::npos) << r->body;
  }
  expectError(c.Post("/api/screenshot", pngFrame(10), "image/png"), 403);
  std::ifstream in(dir_ / "target.txt");
  EXPECT_EQ(std::string(std::istreambuf_iterator<char>(in), {}), "not to be overwritten");
  EXPECT_TRUE(std::filesystem::is_symlink(dir_ / "saves" / "model_view.png"));
}

TEST_F(ViewServerTest, UnknownRoutesAndWrongVerbs) {
  auto c = client();
  expectError(c.Get("/api/nope"), 404);
  expectError(c.Get("/missing.html"), 404);
  expectError(c.Get("/api/pose"), 405);
  expectError(c.Post("/api/scene", "", "application/json"), 405);
  expectError(c.Delete("/index.html"), 405);
  expectError(c.Put("/api/save", "{}", "application/json"), 405);
}

TEST_F(ViewServerTest, StaticFilesStayInThePageFolder) {
  auto c = client();
  const auto index = c.Get("/");
  ASSERT_EQ(index->status, 200);
  EXPECT_EQ(index->body, "<html>viewer</html>");
  EXPECT_EQ(index->get_header_value("Content-Type"), "text/html; charset=utf-8");
  EXPECT_EQ(c.Get("/assets/app.js")->body, "console.log(1)");
  expectError(c.Get("/.secret"), 403);
  expectError(c.Get("/link.txt"), 403);  // a symlink out of the folder
  // Raw requests: no client normalises these paths.
  for (const std::string path :
       {"/../outside.txt", "/assets/../../outside.txt", "/%2e%2e/outside.txt",
        "/%2E%2E%2Foutside.txt", "//etc/passwd", "/%2Fetc%2Fpasswd"}) {
    SCOPED_TRACE(path);
    const std::string answer =
        rawRequest(port_, "GET " + path + " HTTP/1.1\r\nHost: 127.0.0.1:" + std::to_string(port_) +
                              "\r\nConnection: close\r\n\r\n");
    EXPECT_TRUE(answer.starts_with("HTTP/1.1 403")) << answer.substr(0, 40);
    EXPECT_EQ(answer.find("outside the page"), std::string::npos);
    EXPECT_EQ(answer.find("root:"), std::string::npos);
  }
}

TEST_F(ViewServerTest, ClientsThatDisconnectLeaveTheServerServing) {
  const std::string host = "Host: 127.0.0.1:" + std::to_string(port_) + "\r\n";
  // Half a pose, then the connection closes.
  rawRequest(port_,
             "POST /api/pose HTTP/1.1\r\n" + host +
                 "Content-Type: application/octet-stream\r\nContent-Length: 288\r\n\r\n" +
                 std::string(100, '\0'),
             true);
  // A request whose answer is never read.
  rawRequest(port_, "GET /api/model HTTP/1.1\r\n" + host + "\r\n", true);
  const auto r = client().Get("/api/scene");
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 200);
}

TEST_F(ViewServerTest, ConcurrentPosersEachGetTheirOwnPose) {
  ViewSession reference = cageSession();
  const std::vector<Vec3> rest(reference.restControls().begin(), reference.restControls().end());
  constexpr int kThreads = 4, kPoses = 8;
  std::vector<std::vector<float>> expected;
  for (int k = 0; k < kThreads * kPoses; ++k) {
    reference.setPose(sway(rest, 0.05 * k));
    expected.push_back(asFloats(reference.positions(), model_.positions));
  }
  std::vector<int> mismatches(kThreads, 0);
  std::vector<std::thread> threads;
  for (int t = 0; t < kThreads; ++t)
    threads.emplace_back([&, t] {
      auto c = client();
      for (int p = 0; p < kPoses; ++p) {
        const int k = t * kPoses + p;
        const auto r =
            c.Post("/api/pose", poseBody(sway(rest, 0.05 * k)), "application/octet-stream");
        if (!r || r->status != 200 || floats(r->body) != expected[k]) ++mismatches[t];
      }
    });
  for (std::thread& t : threads) t.join();
  EXPECT_EQ(mismatches, std::vector<int>(kThreads, 0));
}

// 5M points: the answer (60 MB) is abandoned unread; the server goes on.
TEST_F(ViewServerTest, AClientThatLeavesBeforeA5MPointAnswerLeavesTheServerServing) {
  stop();
  PolygonSoup cloud;
  static_cast<PointSet&>(cloud) = makeRandomPoints(Vec3(-1), Vec3(1), 5'000'000, 7);
  writeSoup(cloud, dir_ / "big.ply");
  write("twist.json",
        R"({"method": "twist", "origin": [0, 0, 0], "axis": [0, 0, 1], "rate": 0.5})");
  start(ViewSession::withRig(dir_ / "big.ply", dir_ / "twist.json"));
  const std::string host = "Host: 127.0.0.1:" + std::to_string(port_) + "\r\n";
  for (int i = 0; i < 3; ++i)
    rawRequest(port_, "GET /api/positions HTTP/1.1\r\n" + host + "\r\n", true);
  const auto r = client().Get("/api/positions");
  ASSERT_TRUE(r);
  EXPECT_EQ(r->body.size(), 12u * 5'000'000);
}

}  // namespace
}  // namespace spacewarp::test
