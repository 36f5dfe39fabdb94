// `spacewarp view` run as a process (SPACEWARP_CLI): the URL line, ports, refusals of bad
// input, signals, and the rig it saves deformed by `spacewarp deform --rig`.

#include <poll.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>
#include <algorithm>

#include <chrono>
#include <cstring>
#include <thread>

#include <gtest/gtest.h>

// Before httplib.h: glibc's <resolv.h>, which it includes, defines a macro `_res` that breaks
// Eigen's headers.
#include "view_test_util.h"

#include <httplib.h>

namespace spacewarp::test {
namespace {

using Clock = std::chrono::steady_clock;

// One `spacewarp view` process: stdout through a pipe (to read the URL line), stderr to a file.
class ViewProcess {
 public:
  ViewProcess(const std::string& args, const std::filesystem::path& errFile) {
    int fds[2];
    if (::pipe(fds) != 0) throw std::runtime_error("pipe");
    pid_ = ::fork();
    if (pid_ == 0) {
      ::dup2(fds[1], 1);
      ::close(fds[0]);
      ::close(fds[1]);
      const std::string cmd =
          "exec " + std::string(SPACEWARP_CLI) + " view " + args + " 2>" + errFile.string();
      ::execl("/bin/sh", "sh", "-c", cmd.c_str(), static_cast<char*>(nullptr));
      ::_exit(127);
    }
    ::close(fds[1]);
    out_ = fds[0];
  }
  ~ViewProcess() {
    if (pid_ > 0 && exitCode_ == kRunning) {
      ::kill(pid_, SIGKILL);
      ::waitpid(pid_, nullptr, 0);
    }
    ::close(out_);
  }

  // The first line on stdout ("" if none comes within `seconds`).
  std::string firstLine(double seconds = 60) {
    std::string line;
    const auto end = Clock::now() + std::chrono::duration<double>(seconds);
    while (Clock::now() < end) {
      pollfd p{out_, POLLIN, 0};
      if (::poll(&p, 1, 100) <= 0) continue;
      char c = 0;
      if (::read(out_, &c, 1) != 1) break;
      if (c == '\n') return line;
      line += c;
    }
    return line;
  }

  // The port of the URL line "spacewarp view: http://127.0.0.1:PORT/ (Ctrl-C to stop)"; 0 if
  // the line is not that.
  int port() {
    const std::string line = firstLine();
    // By hand, not with <regex>: GCC 12 warns falsely inside it under ASan.
    const std::string head = "spacewarp view: http://127.0.0.1:", tail = "/ (Ctrl-C to stop)";
    const bool framed =
        line.size() > head.size() + tail.size() && line.starts_with(head) && line.ends_with(tail);
    const std::string digits =
        framed ? line.substr(head.size(), line.size() - head.size() - tail.size()) : "";
    if (digits.empty() || digits.size() > 5 ||
        !std::all_of(digits.begin(), digits.end(), [](char c) { return c >= '0' && c <= '9'; })) {
      ADD_FAILURE() << "not the URL line: '" << line << "'";
      return 0;
    }
    return std::stoi(digits);
  }

  void signal(int s) { ::kill(pid_, s); }

  // The exit code, waiting at most `seconds` (-1: still running or killed by a signal).
  int wait(double seconds) {
    const auto end = Clock::now() + std::chrono::duration<double>(seconds);
    while (Clock::now() < end) {
      int status = 0;
      if (::waitpid(pid_, &status, WNOHANG) == pid_) {
        exitCode_ = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
        return exitCode_;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    return -1;
  }

 private:
  static constexpr int kRunning = -1000;
  pid_t pid_ = -1;
  int out_ = -1;
  int exitCode_ = kRunning;
};

class ViewCliTest : public ViewFixture {
 protected:
  void SetUp() override {
    ViewFixture::SetUp();
    std::filesystem::create_directories(dir_ / "page");
    std::filesystem::create_directories(dir_ / "saves");
    write("page/index.html", "<html>viewer</html>");
  }

  std::string args(const std::string& extra = "") const {
    return (dir_ / "model.obj").string() + " --cage " + (dir_ / "cage.obj").string() +
           " --web-dir " + (dir_ / "page").string() + " --save-dir " + (dir_ / "saves").string() +
           " " + extra;
  }

  // Runs the CLI to its end: exit code, stderr.
  std::pair<int, std::string> run(const std::string& commandLine) {
    const std::string cmd = std::string(SPACEWARP_CLI) + " " + commandLine + " >/dev/null 2>" +
                            (dir_ / "err.txt").string();
    const int status = std::system(cmd.c_str());
    std::ifstream in(dir_ / "err.txt");
    return {WIFEXITED(status) ? WEXITSTATUS(status) : -1,
            std::string(std::istreambuf_iterator<char>(in), {})};
  }

  std::string err() const {
    std::ifstream in(dir_ / "err.txt");
    return std::string(std::istreambuf_iterator<char>(in), {});
  }
};

TEST_F(ViewCliTest, PrintsTheUrlServesAndEndsWithCtrlC) {
  ViewProcess view(args("--port 0"), dir_ / "err.txt");
  const int port = view.port();
  ASSERT_GT(port, 0);
  httplib::Client client("127.0.0.1", port);
  const auto scene = client.Get("/api/scene");
  ASSERT_TRUE(scene);
  EXPECT_EQ(scene->status, 200);
  EXPECT_EQ(client.Get("/")->body, "<html>viewer</html>");
  view.signal(SIGINT);
  EXPECT_EQ(view.wait(5), 0) << err();
}

TEST_F(ViewCliTest, SigtermEndsWithExit0AndNoTemporaries) {
  ViewProcess view(args("--port 0 --method green"), dir_ / "err.txt");
  const int port = view.port();
  ASSERT_GT(port, 0);
  httplib::Client client("127.0.0.1", port);
  ASSERT_EQ(client.Post("/api/save", R"({"what": "rig"})", "application/json")->status, 200);
  view.signal(SIGTERM);
  EXPECT_EQ(view.wait(5), 0) << err();
  for (const auto& entry : std::filesystem::directory_iterator(dir_ / "saves"))
    EXPECT_NE(entry.path().filename().string()[0], '.') << entry.path();
  EXPECT_TRUE(std::filesystem::exists(dir_ / "saves" / "model_rig.json"));
}

TEST_F(ViewCliTest, APortInUseIsExit1NamingIt) {
  httplib::Server occupant;
  const int port = occupant.bind_to_any_port("127.0.0.1");
  ASSERT_GT(port, 0);
  const auto [code, message] = run("view " + args("--port " + std::to_string(port)));
  EXPECT_EQ(code, 1) << message;
  EXPECT_NE(message.find(std::to_string(port)), std::string::npos) << message;
  EXPECT_EQ(std::ranges::count(message, '\n'), 1) << message;
}

TEST_F(ViewCliTest, AMissingPageIsExit2SayingHowToGetIt) {
  std::filesystem::create_directories(dir_ / "empty");
  const auto [code, message] =
      run("view " + (dir_ / "model.obj").string() + " --cage " + (dir_ / "cage.obj").string() +
          " --web-dir " + (dir_ / "empty").string());
  EXPECT_EQ(code, 2) << message;
  EXPECT_NE(message.find("apt-get install nodejs npm"), std::string::npos) << message;
  EXPECT_EQ(std::ranges::count(message, '\n'), 1) << message;
}

TEST_F(ViewCliTest, BadInputIsExit3NamingTheFile) {
  write("broken.obj", "v 0 0 0\nf 1 2 3\n");
  auto [code, message] =
      run("view " + (dir_ / "missing.obj").string() + " --cage " + (dir_ / "cage.obj").string() +
          " --web-dir " + (dir_ / "page").string());
  EXPECT_EQ(code, 3) << message;
  EXPECT_NE(message.find("missing.obj"), std::string::npos) << message;
  std::tie(code, message) =
      run("view " + (dir_ / "model.obj").string() + " --cage " + (dir_ / "broken.obj").string() +
          " --web-dir " + (dir_ / "page").string());
  EXPECT_EQ(code, 3) << message;
  EXPECT_NE(message.find("broken.obj"), std::string::npos) << message;
  // Usage errors: no controls, both kinds of controls, a bad port.
  EXPECT_EQ(
      run("view " + (dir_ / "model.obj").string() + " --web-dir " + (dir_ / "page").string()).first,
      2);
  EXPECT_EQ(run("view " + args("--rig " + (dir_ / "x.json").string())).first, 2);
  EXPECT_EQ(run("view " + args("--port 70000")).first, 2);
}

TEST_F(ViewCliTest, AnotherHostIsAWarning) {
  ViewProcess view(args("--port 0 --host 127.0.0.1"), dir_ / "err.txt");
  ASSERT_GT(view.port(), 0);
  view.signal(SIGTERM);
  EXPECT_EQ(view.wait(5), 0);
  ViewProcess open(args("--port 0 --host 0.0.0.0"), dir_ / "err.txt");
  EXPECT_NE(open.firstLine().find("http://0.0.0.0:"), std::string::npos);
  open.signal(SIGTERM);
  EXPECT_EQ(open.wait(5), 0);
  EXPECT_NE(err().find("warning: view: --host 0.0.0.0: the viewer is reachable from the network"),
            std::string::npos)
      << err();
}

// What the server shows, saved as a rig, is what `spacewarp deform --rig` computes.
TEST_F(ViewCliTest, DeformOfTheSavedRigGivesTheServersPositions) {
  ViewProcess view(args("--port 0"), dir_ / "err.txt");
  const int port = view.port();
  ASSERT_GT(port, 0);
  httplib::Client client("127.0.0.1", port);
  client.set_read_timeout(120);
  for (const std::string method : {"mvc", "green", "ffd", "rbf", "idw", "mls"}) {
    SCOPED_TRACE(method);
    ASSERT_EQ(
        client.Post("/api/method", R"({"method": ")" + method + "\"}", "application/json")->status,
        200);
    view::ViewSession reference = cageSession(method);
    const std::vector<Vec3> pose = sway(reference.restControls());
    reference.setPose(pose);
    std::string body(24 * pose.size(), '\0');
    std::memcpy(body.data(), pose.data(), body.size());  // glm::dvec3 is 3 packed doubles
    const auto posed = client.Post("/api/pose", body, "application/octet-stream");
    ASSERT_EQ(posed->status, 200) << posed->body;
    ASSERT_EQ(client.Post("/api/save", R"({"what": "rig"})", "application/json")->status, 200);
    const auto [code, message] =
        run("deform --rig " + (dir_ / "saves" / "model_rig.json").string() + " " +
            (dir_ / "model.obj").string() + " -o " + (dir_ / "out.obj").string());
    ASSERT_EQ(code, 0) << message;
    const PolygonSoup out = readSoup(dir_ / "out.obj");
    EXPECT_LT(relativeGap(out.positions, reference.positions(), model_.positions), 1e-12);
    // The server's float32 answer is the rounding of those positions.
    std::vector<float> expected;
    for (const Vec3& p : out.positions)
      for (int c = 0; c < 3; ++c) expected.push_back(static_cast<float>(p[c]));
    std::vector<float> got(posed->body.size() / 4);
    std::memcpy(got.data(), posed->body.data(), posed->body.size());
    ASSERT_EQ(got.size(), expected.size());
    std::size_t differ = 0;
    for (std::size_t i = 0; i < got.size(); ++i)
      differ += std::abs(got[i] - expected[i]) > 1e-6f * std::max(1.0f, std::abs(expected[i]));
    EXPECT_EQ(differ, 0u);
  }
  view.signal(SIGTERM);
  EXPECT_EQ(view.wait(5), 0);
}

}  // namespace
}  // namespace spacewarp::test
