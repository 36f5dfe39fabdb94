// Volume benchmarks: a sphere level set of radius 50 with voxels of 0.5 (about 750k active
// voxels) twisted by warpVolume() and, as the baseline measured in the same run, by OpenVDB's
// own non-affine GridResampler with a transformer that maps through the closed-form inverse
// twist. Also a mean-value cage warp of the same grid, exact and cached as a displacement
// field. Items are input active voxels. Then two small spheres far apart (sparse volumes).
// Last, reading the sphere's file with readVdbFile (bounds-checked stream, checked chunks)
// against openvdb::io::File in the same run.

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include <unistd.h>

#include <benchmark/benchmark.h>
#include <openvdb/io/File.h>
#include <openvdb/openvdb.h>
#include <openvdb/tools/Composite.h>
#include <openvdb/tools/LevelSetSphere.h>

#include <spacewarp/coords/cage.h>
#include <spacewarp/coords/mean_value.h>
#include <spacewarp/core/coordinate_warp.h>
#include <spacewarp/core/primitives.h>
#include <spacewarp/core/twist.h>
#include <spacewarp/volume/read_vdb.h>
#include <spacewarp/volume/warp_volume.h>

namespace {

using namespace spacewarp;

constexpr double kVoxel = 0.5;

const openvdb::FloatGrid& sphere() {
  static const openvdb::FloatGrid::Ptr grid = [] {
    openvdb::initialize();
    return openvdb::tools::createLevelSetSphere<openvdb::FloatGrid>(50.0f, openvdb::Vec3f(0.0f),
                                                                    float(kVoxel), 3.0f);
  }();
  return *grid;
}

// A twist about the z axis through (10, 0, 0), 0.01 rad per world unit: 1 rad over the sphere.
TwistOptions twistParams() {
  TwistOptions p;
  p.origin = Vec3(10.0, 0.0, 0.0);
  p.rate = 0.01;
  return p;
}

const TwistWarp& twist() {
  static const TwistWarp warp(twistParams());
  return warp;
}

}  // namespace

// bench/volume_bench_openvdb.cpp (a C++17 file): OpenVDB's GridResampler with the twist and
// its closed-form inverse as a non-affine transformer; returns the output's active voxels.
std::size_t openVdbTwistResample(const openvdb::FloatGrid& grid, const openvdb::Vec3d& origin,
                                 double rate, double voxel);

namespace {

// Mean seconds per iteration of each benchmark, for the summary.
std::map<std::string, double>& seconds() {
  static std::map<std::string, double> s;
  return s;
}

void finish(benchmark::State& state, const std::string& name, double total,
            std::size_t outputVoxels) {
  const auto inputVoxels = static_cast<double>(sphere().activeVoxelCount());
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations() * inputVoxels));
  state.counters["in_voxels"] = inputVoxels;
  state.counters["out_voxels"] = static_cast<double>(outputVoxels);
  seconds()[name] = total / static_cast<double>(state.iterations());
}

template <typename F>
double timed(F&& f) {
  const auto t0 = std::chrono::steady_clock::now();
  f();
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

void BM_VolumeTwistWarpVolume(benchmark::State& state) {
  const auto& grid = sphere();
  WarpVolumeOptions options;
  options.redistance = static_cast<LevelSetRedistance>(state.range(0));
  std::size_t out = 0, failures = 0;
  int maxIterations = 0;
  double total = 0.0;
  for (auto _ : state) {
    total += timed([&] {
      const auto r = warpVolume(twist(), grid, options);
      out = r.report.outputActiveVoxels;
      failures = r.report.inverseFailures;
      maxIterations = r.report.maxNewtonIterations;
    });
  }
  finish(state, "twist" + std::to_string(state.range(0)), total, out);
  state.counters["failures"] = static_cast<double>(failures);
  state.counters["max_newton"] = maxIterations;
}
BENCHMARK(BM_VolumeTwistWarpVolume)
    ->ArgName("redistance")  // 0 Normalize (default), 1 Rebuild, 2 None
    ->Arg(0)
    ->Arg(1)
    ->Arg(2)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

void BM_VolumeTwistOpenVdbGridResampler(benchmark::State& state) {
  const auto& grid = sphere();
  std::size_t out = 0;
  double total = 0.0;
  for (auto _ : state) {
    total += timed([&] {
      const TwistOptions p = twistParams();
      out = openVdbTwistResample(grid, openvdb::Vec3d(p.origin.x, p.origin.y, p.origin.z), p.rate,
                                 kVoxel);
    });
  }
  finish(state, "openvdb", total, out);
}
BENCHMARK(BM_VolumeTwistOpenVdbGridResampler)->Unit(benchmark::kMillisecond)->UseRealTime();

// A 2 x 2 x 2 box cage around the sphere (26 vertices, 48 triangles), its top face pushed
// sideways and outwards.
const CoordinateWarp& cageWarp() {
  static const std::unique_ptr<CoordinateWarp> warp = [] {
    const PolygonSoup box = makeBoxSurface(Vec3(-60.0), Vec3(60.0), {2, 2, 2});
    auto cage = std::make_shared<const Cage>(box, "bench cage");
    auto coords = std::make_shared<const MeanValueCoordinates>(cage);
    std::vector<Vec3> posed(cage->vertices().begin(), cage->vertices().end());
    for (Vec3& v : posed) {
      const double t = (v.z + 60.0) / 120.0;
      v += Vec3(15.0 * t, 0.0, 10.0 * t * t);
    }
    return std::make_unique<CoordinateWarp>(coords, posed);
  }();
  return *warp;
}

void BM_VolumeMeanValueCage(benchmark::State& state) {
  const auto& grid = sphere();
  WarpVolumeOptions options;
  options.cacheSpacing = static_cast<double>(state.range(0));
  std::size_t out = 0;
  double total = 0.0, cacheError = 0.0;
  for (auto _ : state) {
    total += timed([&] {
      const auto r = warpVolume(cageWarp(), grid, options);
      out = r.report.outputActiveVoxels;
      cacheError = r.report.cacheError;
    });
  }
  finish(state, "mvc_cache" + std::to_string(state.range(0)), total, out);
  state.counters["cache_error_voxels"] = cacheError / kVoxel;
}
BENCHMARK(BM_VolumeMeanValueCage)
    ->ArgName("cacheSpacing")
    ->Arg(0)
    ->Arg(4)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

// Sparse volumes: two level-set spheres of radius 1 (voxels of 0.1, about 8k active voxels
// together) `distance` world units apart along x, warped by a mean-value cage around both (a
// long box whose far end is pushed sideways) and by a twist about the x axis through both.
// Cost and memory must follow the active voxels, not the bounding box of everything.
const openvdb::FloatGrid& sparseSpheres(double distance) {
  static std::map<double, openvdb::FloatGrid::Ptr> grids;
  auto& grid = grids[distance];
  if (!grid) {
    openvdb::initialize();
    grid = openvdb::tools::createLevelSetSphere<openvdb::FloatGrid>(1.0f, openvdb::Vec3f(0.0f),
                                                                    0.1f, 3.0f);
    auto far = openvdb::tools::createLevelSetSphere<openvdb::FloatGrid>(
        1.0f, openvdb::Vec3f(float(distance), 0.0f, 0.0f), 0.1f, 3.0f);
    openvdb::tools::csgUnion(*grid, *far);
  }
  return *grid;
}

const CoordinateWarp& sparseCageWarp(double distance) {
  static std::map<double, std::unique_ptr<CoordinateWarp>> warps;
  auto& warp = warps[distance];
  if (!warp) {
    const PolygonSoup box = makeBoxSurface(Vec3(-3.0), Vec3(distance + 3.0, 3.0, 3.0), {1, 1, 1});
    auto cage = std::make_shared<const Cage>(box, "sparse bench cage");
    auto coords = std::make_shared<const MeanValueCoordinates>(cage);
    std::vector<Vec3> posed(cage->vertices().begin(), cage->vertices().end());
    for (Vec3& v : posed)
      if (v.x > 0.0) v += Vec3(0.0, 0.5, 0.2);
    warp = std::make_unique<CoordinateWarp>(coords, posed);
  }
  return *warp;
}

void BM_VolumeSparseSpheres(benchmark::State& state) {
  const double distance = std::pow(10.0, static_cast<double>(state.range(1)));
  const auto& grid = sparseSpheres(distance);
  TwistOptions twistAlongX;
  twistAlongX.axis = Vec3(1.0, 0.0, 0.0);
  twistAlongX.rate = 0.5;
  const TwistWarp twistX(twistAlongX);
  const Warp& warp = state.range(0) == 0 ? static_cast<const Warp&>(sparseCageWarp(distance))
                                         : static_cast<const Warp&>(twistX);
  std::size_t out = 0, failures = 0;
  for (auto _ : state) {
    const auto r = warpVolume(warp, grid);
    out = r.report.outputActiveVoxels;
    failures = r.report.inverseFailures;
  }
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations() * grid.activeVoxelCount()));
  state.counters["in_voxels"] = static_cast<double>(grid.activeVoxelCount());
  state.counters["out_voxels"] = static_cast<double>(out);
  state.counters["failures"] = static_cast<double>(failures);
}
BENCHMARK(BM_VolumeSparseSpheres)
    ->ArgNames({"twist", "log10_distance"})  // warp 0: mean-value cage, 1: twist about x
    ->Args({0, 5})
    ->Args({0, 6})
    ->Args({1, 6})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

/// The sphere in a temporary VDB file (OpenVDB's default Blosc compression), removed at exit.
class SphereFile {
 public:
  SphereFile()
      : path_(std::filesystem::temp_directory_path() /
              ("spacewarp_bench_sphere_" + std::to_string(::getpid()) + ".vdb")) {
    openvdb::io::File file(path_.string());
    file.write({sphere().deepCopy()});
    file.close();
  }
  ~SphereFile() {
    std::error_code ignored;
    std::filesystem::remove(path_, ignored);
  }
  SphereFile(const SphereFile&) = delete;
  SphereFile& operator=(const SphereFile&) = delete;
  const std::filesystem::path& path() const { return path_; }

 private:
  std::filesystem::path path_;
};

const std::filesystem::path& sphereFile() {
  static const SphereFile file;
  return file.path();
}

void BM_VolumeReadVdbFile(benchmark::State& state) {
  const auto& path = sphereFile();
  std::size_t voxels = 0;
  for (auto _ : state) {
    if (state.range(0) == 0) {
      const VdbFile content = readVdbFile(path);
      voxels = content.grids.at(0)->activeVoxelCount();
    } else {
      openvdb::io::File file(path.string());
      file.open(/*delayLoad=*/false);
      voxels = file.getGrids()->at(0)->activeVoxelCount();
    }
  }
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations() * voxels));
  state.SetBytesProcessed(
      static_cast<std::int64_t>(state.iterations() * std::filesystem::file_size(path)));
}
BENCHMARK(BM_VolumeReadVdbFile)
    ->ArgName("openvdb_io_file")  // 0: readVdbFile, 1: openvdb::io::File (baseline)
    ->Arg(0)
    ->Arg(1)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

}  // namespace

void printVolumeSummary() {
  const auto& s = seconds();
  const auto ours = s.find("twist0");
  const auto theirs = s.find("openvdb");
  if (ours == s.end() || theirs == s.end()) return;
  std::printf(
      "volume: twisted sphere, warpVolume %.3f s vs OpenVDB GridResampler %.3f s "
      "(ratio %.2f)\n",
      ours->second, theirs->second, ours->second / theirs->second);
}
