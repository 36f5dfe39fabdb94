// spacewarp.warp_volume in bricks (volume/warp_volume_bricks.h), for spacewarp.dask: the plan on
// the driver, one brick on a worker (a picklable result), and the merge back on the driver.

#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>

#include <filesystem>
#include <memory>
#include <mutex>
#include <string>
#include <utility>
#include <vector>

#include <spacewarp/core/errors.h>
#include <spacewarp/core/warp.h>

#ifdef SPACEWARP_WITH_OPENVDB
#include <openvdb/openvdb.h>
#include <openvdb/tools/LevelSetSphere.h>
#include <openvdb/tools/LevelSetUtil.h>

#include <spacewarp/volume/read_vdb.h>
#include <spacewarp/volume/warp_grid.h>
#include <spacewarp/volume/warp_volume_bricks.h>
#include <spacewarp/volume/write_vdb.h>
#endif

#include "common.h"
#include "volume.h"

namespace spacewarp::python {

using namespace pybind11::literals;

#ifdef SPACEWARP_WITH_OPENVDB
namespace {

using openvdb::Coord;
using openvdb::CoordBBox;

/// One grid of the input file: bricked (float, double, vec3s), or warped whole on the driver
/// (point data grids, grids with no brick), or left out (unsupported types).
struct PlannedGrid {
  openvdb::GridBase::Ptr input;
  bool warpable = false;
  bool bricked = false;
  bool clip = true;  // a clipped read finds the grid by its name (false for duplicate names)
  VolumeBrickPlan plan;
};

/// The plan of a whole file, kept on the driver.
struct FilePlan {
  std::filesystem::path input;
  VdbFile content;
  WarpVolumeOptions options;
  std::vector<PlannedGrid> grids;
};

/// A brick as plain Python values, which pickle: (grid index, grid name, clipped read, rigid,
/// output min, output max, input min, input max, cells (k, 3) int32).
py::tuple brickTuple(std::size_t gridIndex, const PlannedGrid& g, const VolumeBrick& b) {
  const auto triple = [](const Coord& c) { return py::make_tuple(c.x(), c.y(), c.z()); };
  py::array_t<std::int32_t> cells(
      std::vector<py::ssize_t>{static_cast<py::ssize_t>(b.cells.size()), 3});
  auto* out = cells.mutable_data();
  for (std::size_t i = 0; i < b.cells.size(); ++i)
    for (int a = 0; a < 3; ++a) out[3 * i + a] = b.cells[i][a];
  return py::make_tuple(gridIndex, g.input->getName(), g.clip, g.plan.rigid, triple(b.output.min()),
                        triple(b.output.max()), triple(b.input.min()), triple(b.input.max()),
                        cells);
}

Coord coordOf(py::handle t) {
  const auto v = t.cast<std::vector<int>>();
  if (v.size() != 3) throw InvalidInput("brick: a coordinate must have 3 entries");
  return {v[0], v[1], v[2]};
}

struct BrickSpec {
  std::size_t gridIndex = 0;
  std::string name;
  bool clip = true, rigid = true;
  VolumeBrick brick;
};

BrickSpec brickFromTuple(const py::tuple& t) {
  if (t.size() != 9) throw InvalidInput("brick: expected a 9-tuple from plan_volume_bricks");
  BrickSpec s;
  s.gridIndex = t[0].cast<std::size_t>();
  s.name = t[1].cast<std::string>();
  s.clip = t[2].cast<bool>();
  s.rigid = t[3].cast<bool>();
  s.brick.output = CoordBBox(coordOf(t[4]), coordOf(t[5]));
  s.brick.input = CoordBBox(coordOf(t[6]), coordOf(t[7]));
  const auto cells =
      py::array_t<std::int32_t, py::array::c_style | py::array::forcecast>::ensure(t[8]);
  if (!cells || cells.ndim() != 2 || cells.shape(1) != 3)
    throw InvalidInput("brick: cells must have shape (k, 3)");
  for (py::ssize_t i = 0; i < cells.shape(0); ++i)
    s.brick.cells.emplace_back(cells.at(i, 0), cells.at(i, 1), cells.at(i, 2));
  return s;
}

/// What a worker sends back: the brick's grid (OpenVDB stream bytes) and its report.
struct BrickResult {
  std::size_t gridIndex = 0;
  std::string grid;
  WarpVolumeReport report;
  std::size_t haloMisses = 0;  ///< of the clipped read; the brick was then warped again whole
};

py::tuple resultState(const BrickResult& r) {
  const WarpVolumeReport& p = r.report;
  return py::make_tuple(
      r.gridIndex, py::bytes(r.grid), r.haloMisses,
      py::make_tuple(p.solvedVoxels, p.inverseFailures, p.vectorFailures, p.totalNewtonIterations,
                     p.maxNewtonIterations, p.massAfter, p.minVolumeChange, p.maxVolumeChange,
                     p.degenerateVolumeChanges, p.vectors));
}

BrickResult resultFromState(const py::tuple& t) {
  if (t.size() != 4) throw InvalidInput("VolumeBrickResult: bad pickled state");
  BrickResult r;
  r.gridIndex = t[0].cast<std::size_t>();
  r.grid = t[1].cast<std::string>();
  r.haloMisses = t[2].cast<std::size_t>();
  const auto p = t[3].cast<py::tuple>();
  if (p.size() != 10) throw InvalidInput("VolumeBrickResult: bad pickled report");
  WarpVolumeReport& q = r.report;
  q.solvedVoxels = p[0].cast<std::size_t>();
  q.inverseFailures = p[1].cast<std::size_t>();
  q.vectorFailures = p[2].cast<std::size_t>();
  q.totalNewtonIterations = p[3].cast<std::size_t>();
  q.maxNewtonIterations = p[4].cast<int>();
  q.massAfter = p[5].cast<double>();
  q.minVolumeChange = p[6].cast<double>();
  q.maxVolumeChange = p[7].cast<double>();
  q.degenerateVolumeChanges = p[8].cast<std::size_t>();
  q.vectors = p[9].cast<std::string>();
  return r;
}

FilePlan planFile(const Warp& warp, const std::filesystem::path& input,
                  const WarpVolumeOptions& options, const VolumeBrickOptions& brickOptions) {
  FilePlan f;
  f.input = input;
  f.options = options;
  f.content = readVdbFile(input);
  checkWarpableGrids(f.content.grids, input.string());
  for (const openvdb::GridBase::Ptr& grid : f.content.grids) {
    PlannedGrid g;
    g.input = grid;
    g.warpable = isWarpableGrid(*grid);
    for (const openvdb::GridBase::Ptr& other : f.content.grids)
      if (other != grid && other->getName() == grid->getName()) g.clip = false;
    g.bricked = g.warpable && !grid->isType<openvdb::points::PointDataGrid>();
    if (g.bricked) {
      g.plan = namingFile(input.string(),
                          [&] { return planVolumeBricks(warp, *grid, options, brickOptions); });
      g.bricked = !g.plan.bricks.empty();
    }
    f.grids.push_back(std::move(g));
  }
  return f;
}

/// The last VDB file a brick read whole in this process, kept for the next bricks of the same
/// file (a worker warps many): reading it costs about as much as a clipped read (OpenVDB
/// decompresses every leaf buffer it passes), so one read per worker beats one per brick.
std::shared_ptr<const VdbFile> wholeFile(const std::filesystem::path& path) {
  static std::mutex mutex;
  static std::filesystem::path cachedPath;
  static std::filesystem::file_time_type cachedTime;
  static std::uintmax_t cachedSize = 0;
  static std::shared_ptr<const VdbFile> cached;
  std::error_code ec;
  const auto time = std::filesystem::last_write_time(path, ec);
  const auto size = std::filesystem::file_size(path, ec);
  const std::lock_guard<std::mutex> lock(mutex);
  if (!cached || ec || path != cachedPath || time != cachedTime || size != cachedSize) {
    cached.reset();  // the old file's grids go before the new file's come
    cached = std::make_shared<const VdbFile>(readVdbFile(path));
    cachedPath = path;
    cachedTime = time;
    cachedSize = size;
  }
  return cached;
}

BrickResult warpBrick(const Warp& warp, const std::filesystem::path& input, const BrickSpec& s,
                      const WarpVolumeOptions& options, bool clip) {
  BrickResult r;
  r.gridIndex = s.gridIndex;
  WarpedBrick warped;
  if (s.clip && clip) {
    const openvdb::GridBase::Ptr clipped = readVdbGridRegion(input, s.name, s.brick.input);
    warped = namingFile(input.string(), [&] {
      return warpVolumeBrick(warp, *clipped, options, s.brick, s.rigid, true);
    });
    r.haloMisses = warped.haloMisses;
  }
  if (!(s.clip && clip) || warped.haloMisses > 0) {
    // The whole grid: asked for, or a preimage left the brick's input box, or the grid has no
    // unique name.
    const std::shared_ptr<const VdbFile> content = wholeFile(input);
    if (s.gridIndex >= content->grids.size())
      throw InvalidInput(input.string() + ": the file has fewer grids than the plan's");
    warped = namingFile(input.string(), [&] {
      return warpVolumeBrick(warp, *content->grids[s.gridIndex], options, s.brick, s.rigid, false);
    });
  }
  r.grid = gridToBytes(*warped.grid);
  r.report = warped.report;
  return r;
}

py::list mergeFile(const FilePlan& f, const Warp& warp, const std::vector<BrickResult>& results,
                   const std::filesystem::path& output) {
  std::vector<std::pair<std::string, WarpedGrid<openvdb::GridBase>>> merged;
  std::vector<std::string> skipped;
  withoutGil([&] {
    std::vector<std::vector<WarpedBrick>> bricks(f.grids.size());
    for (const BrickResult& r : results) {
      if (r.gridIndex >= f.grids.size() || !f.grids[r.gridIndex].bricked)
        throw InvalidInput("merge: a brick result does not belong to this plan");
      bricks[r.gridIndex].push_back({gridFromBytes(r.grid), r.report, r.haloMisses});
    }
    openvdb::GridCPtrVec warped;
    for (std::size_t i = 0; i < f.grids.size(); ++i) {
      const PlannedGrid& g = f.grids[i];
      if (!g.warpable) {
        skipped.push_back(f.input.string() + ": grid '" + g.input->getName() + "' of type " +
                          g.input->type() + " is not supported and is left out");
        continue;
      }
      if (g.bricked && bricks[i].size() != g.plan.bricks.size())
        throw InvalidInput("merge: grid '" + g.input->getName() + "' has " +
                           std::to_string(g.plan.bricks.size()) + " bricks but " +
                           std::to_string(bricks[i].size()) + " results");
      merged.emplace_back(
          g.input->type(), namingFile(f.input.string(), [&] {
            if (!g.bricked) return warpGrid(warp, *g.input, f.options);
            double background = 0.0;
            if (const auto* s = dynamic_cast<const openvdb::FloatGrid*>(g.input.get()))
              background = s->background();
            if (const auto* d = dynamic_cast<const openvdb::DoubleGrid*>(g.input.get()))
              background = d->background();
            return mergeVolumeBricks(bricks[i], g.plan, background, f.options);
          }));
      warped.push_back(merged.back().second.grid);
    }
    writeVdbFile(output, warped, *f.content.metadata);
  });
  warnAll(skipped);
  py::list reports;
  for (const auto& [type, result] : merged) {
    const std::string name = result.grid->getName();
    warnLosses(f.input.string() + ": grid '" + name + "'", result.report);
    reports.append(reportDict(name, type, result.report));
  }
  return reports;
}

/// Test and benchmark data: a sphere as a float level set, the same as a double fog volume and
/// its gradient as a vec3s grid, in one file.
void writeSphereVolumes(const std::filesystem::path& path, double radius, double voxelSize,
                        const Vec3& center, double halfWidth) {
  openvdb::initialize();
  auto levelSet = openvdb::tools::createLevelSetSphere<openvdb::FloatGrid>(
      static_cast<float>(radius), openvdb::Vec3f(float(center.x), float(center.y), float(center.z)),
      static_cast<float>(voxelSize), static_cast<float>(halfWidth));
  levelSet->setName("surface");
  auto fogFloat = levelSet->deepCopy();
  openvdb::tools::sdfToFogVolume(*fogFloat);
  auto fog = openvdb::DoubleGrid::create(0.0);
  fog->setTransform(levelSet->transform().copy());
  fog->setName("density");
  {
    auto acc = fog->getAccessor();
    for (auto it = fogFloat->cbeginValueOn(); it; ++it)
      if (it.isVoxelValue()) acc.setValue(it.getCoord(), static_cast<double>(*it) * 0.5 + 0.25);
  }
  auto field = openvdb::Vec3SGrid::create(openvdb::Vec3s(0.0f));
  field->setTransform(levelSet->transform().copy());
  field->setName("velocity");
  {
    auto acc = field->getAccessor();
    for (auto it = levelSet->cbeginValueOn(); it; ++it) {
      const openvdb::Vec3d p = levelSet->indexToWorld(it.getCoord());
      acc.setValue(it.getCoord(), openvdb::Vec3s(float(-p.y()), float(p.x()), 0.25f));
    }
  }
  writeVdbFile(path, {levelSet, fog, field}, openvdb::MetaMap());
}

}  // namespace
#endif

void bindVolumeBricks(py::module_& m) {
#ifdef SPACEWARP_WITH_OPENVDB
  py::class_<BrickResult>(m, "VolumeBrickResult",
                          R"(A warped brick (OpenVDB stream bytes and its counts); pickles.)")
      .def_property_readonly(
          "halo_misses", [](const BrickResult& r) { return r.haloMisses; },
          R"(Voxels whose preimage left the brick's clipped input; the brick
was then warped again from the whole grid.)")
      .def_property_readonly(
          "size", [](const BrickResult& r) { return r.grid.size(); }, "Bytes of the brick's grid.")
      .def(py::pickle([](const BrickResult& r) { return resultState(r); },
                      [](const py::tuple& t) { return resultFromState(t); }));

  py::class_<FilePlan>(m, "VolumeBrickPlan", R"(The plan of spacewarp.dask.warp_volume for one
VDB file (made by plan_volume_bricks, kept by the caller): its bricks, and the merge.)")
      .def_property_readonly(
          "bricks",
          [](const FilePlan& f) {
            py::list out;
            for (std::size_t i = 0; i < f.grids.size(); ++i)
              if (f.grids[i].bricked)
                for (const VolumeBrick& b : f.grids[i].plan.bricks)
                  out.append(brickTuple(i, f.grids[i], b));
            return out;
          },
          R"(The bricks of every grid, in order: plain tuples (grid index, grid name, clipped
read, rigid, output min, output max, input min, input max, cells (k, 3) int32; boxes in index
space, inclusive) to pass to warp_volume_brick.)")
      .def(
          "merge",
          [](const FilePlan& f, const Warp& warp, const std::vector<BrickResult>& results,
             const std::filesystem::path& output) { return mergeFile(f, warp, results, output); },
          "warp"_a, "results"_a, "output"_a,
          R"(Merges the results of warp_volume_brick (one per brick, any order), warps the grids
that are not bricked (point data grids) here, re-distances level sets once over each merged
grid, and writes every grid to `output` atomically, as spacewarp.warp_volume does. Returns one
report dict per grid.)");

  m.def(
      "plan_volume_bricks",
      [](const Warp& warp, const std::filesystem::path& input, int brick, int halo,
         const std::string& sampler, bool conserveMass, const std::string& vectors,
         const std::string& redistance, int seedSpacing) {
        const WarpVolumeOptions options =
            volumeOptions(sampler, conserveMass, vectors, redistance, seedSpacing, 0.0);
        FilePlan plan;
        withoutGil([&] { plan = planFile(warp, input, options, {brick, halo}); });
        return plan;
      },
      "warp"_a, "input"_a, py::kw_only(), "brick"_a = 64, "halo"_a = 4, "sampler"_a = "trilinear",
      "conserve_mass"_a = false, "vectors"_a = "auto", "redistance"_a = "normalize",
      "seed_spacing"_a = 4,
      R"(Plans warping the VDB file `input` by `warp` in bricks of `brick` output voxels per
edge (rounded up to a multiple of 8): reads the file, evaluates the warp at the seeding cells
of each float, double and vec3s grid and lists the bricks their images reach, each with the
cells that reach it and the input box (index space, those cells widened by `halo` + 4 voxels) it
reads. Options as spacewarp.warp_volume (no cache_spacing). Used by spacewarp.dask.)");

  m.def(
      "warp_volume_brick",
      [](const Warp& warp, const std::filesystem::path& input, const py::tuple& brick, bool clip,
         const std::string& sampler, bool conserveMass, const std::string& vectors,
         const std::string& redistance, int seedSpacing) {
        const WarpVolumeOptions options =
            volumeOptions(sampler, conserveMass, vectors, redistance, seedSpacing, 0.0);
        const BrickSpec spec = brickFromTuple(brick);
        BrickResult result;
        withoutGil([&] { result = warpBrick(warp, input, spec, options, clip); });
        return result;
      },
      "warp"_a, "input"_a, "brick"_a, py::kw_only(), "clip"_a = false, "sampler"_a = "trilinear",
      "conserve_mass"_a = false, "vectors"_a = "auto", "redistance"_a = "normalize",
      "seed_spacing"_a = 4,
      R"(Warps one brick of VolumeBrickPlan.bricks (same warp, input and options as the plan):
resamples the brick's output voxels from its seeding cells and returns a VolumeBrickResult for
VolumeBrickPlan.merge. The input: read whole once per process and kept for the next bricks of
the same file (clip False, the default), or only the brick's input box of its grid (clip True:
OpenVDB's clipped read, whose cost is close to a whole read since every compressed leaf buffer
is passed; the whole grid when a preimage leaves that box).)");
  m.def(
      "_write_sphere_volumes",
      [](const std::filesystem::path& path, double radius, double voxelSize, py::handle center,
         double halfWidth) {
        const Vec3 c = toVec3(center, "center");
        withoutGil([&] { writeSphereVolumes(path, radius, voxelSize, c, halfWidth); });
      },
      "path"_a, py::kw_only(), "radius"_a = 1.0, "voxel_size"_a = 0.1,
      "center"_a = py::make_tuple(0, 0, 0), "half_width"_a = 3.0,
      R"(Test and benchmark data: writes a VDB file with a sphere (radius, center in world
units) as a float level set 'surface' (half_width voxels of band), the same as a double fog
volume 'density' and a rotating vec3s field 'velocity' on the band.)");
#else
  (void)m;
#endif
}

}  // namespace spacewarp::python
