// The viewer's pose -> positions time, as the page sees it: POST /api/pose to a ViewServer on
// localhost (the deform, float32 output into the response, HTTP on loopback), for the Armadillo
// (15k vertices) with every cage method and for generated 1M- and 5M-point clouds with MVC.
// The server's own deform time (X-Spacewarp-Deform-Ms) is the counter deform_ms.

#include <unistd.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <memory>
#include <string>
#include <thread>

#include <benchmark/benchmark.h>

#include <spacewarp/core/io/mesh_io.h>
#include <spacewarp/core/primitives.h>

#include "apps/view/view_server.h"

// After spacewarp's headers: <httplib.h> pulls in glibc's <resolv.h>, whose `_res` macro breaks
// Eigen's.
#include <httplib.h>

namespace {

using namespace spacewarp;

struct Running {
  std::filesystem::path dir;
  std::unique_ptr<view::ViewServer> server;
  std::thread thread;
  std::vector<Vec3> rest;
  int port = 0;
  ~Running() {
    if (server) server->stop();
    if (thread.joinable()) thread.join();
    std::filesystem::remove_all(dir);
  }
};

std::unique_ptr<Running> serve(view::ViewSession session) {
  auto r = std::make_unique<Running>();
  r->rest.assign(session.restControls().begin(), session.restControls().end());
  r->dir = std::filesystem::temp_directory_path() /
           ("spacewarp_view_bench_" + std::to_string(::getpid()));
  std::filesystem::create_directories(r->dir);
  std::ofstream(r->dir / "index.html") << "<html></html>";
  view::ViewServerOptions options;
  options.port = 0;
  options.webDir = r->dir;
  options.saveDir = r->dir;
  r->server = std::make_unique<view::ViewServer>(std::move(session), options);
  r->port = r->server->bind();
  r->thread = std::thread([s = r->server.get()] { s->listen(); });
  return r;
}

void posePositions(benchmark::State& state, Running& r) {
  httplib::Client client("127.0.0.1", r.port);
  client.set_read_timeout(600);
  std::string body(24 * r.rest.size(), '\0');
  double deformMs = 0.0;
  std::size_t bytes = 0;
  int k = 0;
  for (auto _ : state) {
    // A new pose each time: a sway of growing amplitude.
    const double t = 0.02 * (++k % 10);
    for (std::size_t i = 0; i < r.rest.size(); ++i) {
      const Vec3& p = r.rest[i];
      const double xyz[3] = {p.x + t * p.y, p.y, p.z + t * p.x};
      std::memcpy(body.data() + 24 * i, xyz, 24);
    }
    const auto answer = client.Post("/api/pose", body, "application/octet-stream");
    if (!answer || answer->status != 200) {
      state.SkipWithError("the pose failed");
      return;
    }
    deformMs += std::stod(answer->get_header_value("X-Spacewarp-Deform-Ms"));
    bytes += answer->body.size();
  }
  state.counters["deform_ms"] = benchmark::Counter(deformMs, benchmark::Counter::kAvgIterations);
  state.SetBytesProcessed(static_cast<int64_t>(bytes));
}

const std::filesystem::path kArmadillo =
    std::filesystem::path(SPACEWARP_SOURCE_DIR) / "../shared/data/ju2005-armadillo";

void BM_ViewPoseArmadillo(benchmark::State& state, const std::string& method) {
  if (!std::filesystem::exists(kArmadillo / "bounding_mesh.obj")) {
    state.SkipWithError("no shared data");
    return;
  }
  view::ViewSessionOptions options;
  options.method = method;
  auto r = serve(view::ViewSession::withCage(kArmadillo / "armadilloman.obj",
                                             kArmadillo / "bounding_mesh.obj", options));
  posePositions(state, *r);
}

void BM_ViewPoseCloudMvc(benchmark::State& state) {
  const auto n = static_cast<std::size_t>(state.range(0));
  const auto dir = std::filesystem::temp_directory_path() /
                   ("spacewarp_view_bench_cloud_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  writeSoup(makeBoxSurface(Vec3(-1, -1, -1.5), Vec3(1, 1, 1.5), glm::ivec3(1, 1, 2)),
            dir / "cage.obj");
  {
    PolygonSoup cloud;
    static_cast<PointSet&>(cloud) =
        makeRandomPoints(Vec3(-0.9, -0.9, -1.4), Vec3(0.9, 0.9, 1.4), n);
    writeSoup(cloud, dir / "cloud.ply");
  }
  auto r = serve(view::ViewSession::withCage(dir / "cloud.ply", dir / "cage.obj"));
  std::filesystem::remove_all(dir);
  posePositions(state, *r);
}

}  // namespace

#ifdef SPACEWARP_HAVE_HARMONIC
BENCHMARK_CAPTURE(BM_ViewPoseArmadillo, harmonic, std::string("harmonic"))
    ->Unit(benchmark::kMillisecond);
#endif
BENCHMARK_CAPTURE(BM_ViewPoseArmadillo, mvc, std::string("mvc"))->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_ViewPoseArmadillo, green, std::string("green"))->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_ViewPoseArmadillo, ffd, std::string("ffd"))->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_ViewPoseArmadillo, rbf, std::string("rbf"))->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_ViewPoseArmadillo, idw, std::string("idw"))->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_ViewPoseArmadillo, mls, std::string("mls"))->Unit(benchmark::kMillisecond);
BENCHMARK(BM_ViewPoseCloudMvc)
    ->Arg(1'000'000)
    ->Arg(5'000'000)
    ->Unit(benchmark::kMillisecond)
    ->Iterations(5);
