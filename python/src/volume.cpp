// Volumes: VDB files warped grid by grid, and dense NumPy blocks warped as OpenVDB grids.

#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>

#include <algorithm>

#include <spacewarp/core/errors.h>
#include <spacewarp/core/warp.h>

#ifdef SPACEWARP_WITH_OPENVDB
#include <openvdb/openvdb.h>
#include <openvdb/points/PointDataGrid.h>
#include <openvdb/tools/Dense.h>
#include <openvdb/tools/Prune.h>

#include <spacewarp/volume/read_vdb.h>
#include <spacewarp/volume/warp_grid.h>
#include <spacewarp/volume/write_vdb.h>
#endif

#include "common.h"
#include "volume.h"

namespace spacewarp::python {

using namespace pybind11::literals;

#ifdef SPACEWARP_WITH_OPENVDB

namespace {

template <class E>
E choice(const std::string& value, const char* option,
         std::initializer_list<std::pair<const char*, E>> choices) {
  std::string names;
  for (const auto& [name, e] : choices) {
    if (value == name) return e;
    names += (names.empty() ? "'" : ", '") + std::string(name) + "'";
  }
  throw InvalidInput(std::string(option) + " must be one of " + names + ", not '" + value + "'");
}

}  // namespace

WarpVolumeOptions volumeOptions(const std::string& sampler, bool conserveMass,
                                const std::string& vectors, const std::string& redistance,
                                int seedSpacing, double cacheSpacing) {
  WarpVolumeOptions o;
  o.sampler = choice<VolumeSampler>(
      sampler, "sampler",
      {{"trilinear", VolumeSampler::Trilinear}, {"triquadratic", VolumeSampler::Triquadratic}});
  o.conserveMass = conserveMass;
  o.vectors = choice<VectorTransform>(vectors, "vectors",
                                      {{"auto", VectorTransform::Auto},
                                       {"push", VectorTransform::Push},
                                       {"normal", VectorTransform::Normal},
                                       {"keep", VectorTransform::Keep}});
  o.redistance = choice<LevelSetRedistance>(redistance, "redistance",
                                            {{"normalize", LevelSetRedistance::Normalize},
                                             {"rebuild", LevelSetRedistance::Rebuild},
                                             {"none", LevelSetRedistance::None}});
  o.seedSpacing = seedSpacing;
  o.cacheSpacing = cacheSpacing;
  return o;
}

py::dict reportDict(const std::string& name, const std::string& type, const WarpVolumeReport& r) {
  return py::dict(
      "grid"_a = name, "type"_a = type, "input_active_voxels"_a = r.inputActiveVoxels,
      "output_active_voxels"_a = r.outputActiveVoxels, "solved_voxels"_a = r.solvedVoxels,
      "inverse_failures"_a = r.inverseFailures, "unmapped_voxels"_a = r.unmappedVoxels,
      "max_newton_iterations"_a = r.maxNewtonIterations, "mass_before"_a = r.massBefore,
      "mass_after"_a = r.massAfter, "redistanced"_a = r.redistanced, "cache_error"_a = r.cacheError,
      "vectors"_a = r.vectors, "vector_failures"_a = r.vectorFailures, "points"_a = r.points);
}

void warnLosses(const std::string& where, const WarpVolumeReport& r) {
  std::vector<std::string> lines;
  if (r.inverseFailures > 0)
    lines.push_back(where + ": the inverse did not converge at " +
                    std::to_string(r.inverseFailures) + " voxels, left inactive");
  if (r.vectorFailures > 0)
    lines.push_back(where + ": " + std::to_string(r.vectorFailures) +
                    " vectors not transformed, left inactive");
  if (r.unmappedVoxels > 0)
    lines.push_back(where + ": " + std::to_string(r.unmappedVoxels) +
                    " input voxels could not be mapped");
  warnAll(lines);
}

namespace {

py::list warpVolumeFile(const Warp& warp, const std::filesystem::path& input,
                        const std::filesystem::path& output, WarpVolumeOptions options,
                        const py::object& progress) {
  std::vector<std::pair<std::string, WarpedGrid<openvdb::GridBase>>> results;
  std::vector<std::string> skipped;
  runCancellable(progress, [&](const ProgressCallback& callback) {
    options.progress = callback;
    const VdbFile content = readVdbFile(input);
    checkWarpableGrids(content.grids, input.string());
    if (options.conserveMass &&
        std::none_of(content.grids.begin(), content.grids.end(),
                     [](const openvdb::GridBase::Ptr& g) { return isFogVolume(*g); }))
      skipped.push_back(
          input.string() +
          ": conserve_mass: no grid is a fog volume, so there is no mass to conserve");
    openvdb::GridCPtrVec warped;
    for (const openvdb::GridBase::Ptr& grid : content.grids) {
      if (!isWarpableGrid(*grid)) {
        skipped.push_back(input.string() + ": grid '" + grid->getName() + "' of type " +
                          grid->type() + " is not supported and is left out");
        continue;
      }
      results.emplace_back(
          grid->type(), namingFile(input.string(), [&] { return warpGrid(warp, *grid, options); }));
      warped.push_back(results.back().second.grid);
    }
    writeVdbFile(output, warped, *content.metadata);
  });
  warnAll(skipped);
  py::list reports;
  for (const auto& [type, result] : results) {
    const std::string name = result.grid->getName();
    warnLosses(input.string() + ": grid '" + name + "'", result.report);
    reports.append(reportDict(name, type, result.report));
  }
  return reports;
}

/// A dense block as a grid of T, warped, and back: (values, origin of the output block).
template <class GridT>
py::tuple warpDenseAs(const Warp& warp, const py::array& values, double voxelSize,
                      const Vec3& origin, double background, bool levelSet,
                      WarpVolumeOptions options, const py::object& progress) {
  using ValueT = typename GridT::ValueType;
  const auto in = py::array_t<ValueT, py::array::c_style | py::array::forcecast>::ensure(values);
  if (!in || in.ndim() != 3 || in.size() == 0)
    throw InvalidInput("values must be a non-empty 3-dimensional array (nx, ny, nz)");
  // OpenVDB's transforms need scales well inside the range of double.
  if (!(voxelSize >= 1e-100 && voxelSize <= 1e100))
    throw InvalidInput("voxel_size must be in [1e-100, 1e100] world units, not " +
                       std::to_string(voxelSize));
  if (!isFinite(origin)) throw InvalidInput("origin is not finite");
  if (!std::isfinite(background)) throw InvalidInput("background is not finite");
  for (py::ssize_t i = 0; i < in.size(); ++i) {
    if (!std::isfinite(double(in.data()[i]))) {
      const py::ssize_t nz = in.shape(2), ny = in.shape(1);
      throw InvalidInput("values[" + std::to_string(i / (ny * nz)) + ", " +
                         std::to_string(i / nz % ny) + ", " + std::to_string(i % nz) +
                         "] is not finite");
    }
  }
  py::array_t<ValueT> out;
  Vec3 outOrigin(0.0);
  runCancellable(progress, [&](const ProgressCallback& callback) {
    openvdb::initialize();
    options.progress = callback;
    const openvdb::CoordBBox box(
        openvdb::Coord(0),
        openvdb::Coord(static_cast<int>(in.shape(0)) - 1, static_cast<int>(in.shape(1)) - 1,
                       static_cast<int>(in.shape(2)) - 1));
    // LayoutZYX: z varies fastest, as in a C-ordered (nx, ny, nz) array.
    const openvdb::tools::Dense<const ValueT, openvdb::tools::LayoutZYX> dense(box, in.data());
    auto grid = GridT::create(static_cast<ValueT>(background));
    grid->setTransform(openvdb::math::Transform::createLinearTransform(voxelSize));
    grid->transform().postTranslate(openvdb::Vec3d(origin.x, origin.y, origin.z));
    openvdb::tools::copyFromDense(dense, *grid,
                                  ValueT(0));  // tolerance 0: exactly background is off
    if (levelSet) {
      // A narrow band: voxels at or beyond the background distance, inside (negative) too,
      // are inactive, and uniform regions become tiles of -background or +background.
      grid->setGridClass(openvdb::GRID_LEVEL_SET);
      for (auto voxel = grid->beginValueOn(); voxel; ++voxel)
        if (std::abs(double(*voxel)) >= std::abs(background)) voxel.setValueOff();
      openvdb::tools::pruneLevelSet(grid->tree());
    }
    typename GridT::Ptr warped;
    try {
      warped = warpVolume(warp, *grid, options).grid;
    } catch (const openvdb::Exception& e) {
      throw InvalidInput(std::string("warp_dense: ") + e.what());
    }
    const openvdb::CoordBBox active = warped->evalActiveVoxelBoundingBox();
    const openvdb::Coord size = active.empty() ? openvdb::Coord(0) : active.dim();
    {
      const py::gil_scoped_acquire gil;
      out = py::array_t<ValueT>(std::vector<py::ssize_t>{size.x(), size.y(), size.z()});
    }
    if (!active.empty()) {
      openvdb::tools::Dense<ValueT, openvdb::tools::LayoutZYX> result(active, out.mutable_data());
      openvdb::tools::copyToDense(*warped, result);
      const openvdb::Vec3d o = warped->indexToWorld(active.min());
      outOrigin = Vec3(o.x(), o.y(), o.z());
    }
  });
  return py::make_tuple(out, copyPoints(std::span<const Vec3>(&outOrigin, 1)).attr("reshape")(3));
}

}  // namespace

#endif

namespace {

void bindVolumeFunctions(py::module_& m) {
#ifdef SPACEWARP_WITH_OPENVDB
  m.def(
      "warp_volume",
      [](const Warp& warp, const std::filesystem::path& input, const std::filesystem::path& output,
         const std::string& sampler, bool conserveMass, const std::string& vectors,
         const std::string& redistance, int seedSpacing, double cacheSpacing,
         const py::object& progress) {
        return warpVolumeFile(
            warp, input, output,
            volumeOptions(sampler, conserveMass, vectors, redistance, seedSpacing, cacheSpacing),
            progress);
      },
      "warp"_a, "input"_a, "output"_a, py::kw_only(), "sampler"_a = "trilinear",
      "conserve_mass"_a = false, "vectors"_a = "auto", "redistance"_a = "normalize",
      "seed_spacing"_a = 4, "cache_spacing"_a = 0.0, "progress"_a = py::none(),
      R"(Warps every grid of the VDB file `input` (float, double, vec3s grids: level sets, fog
volumes, fields; point data grids) by `warp` and writes them atomically to `output`, as
`spacewarp deform` does. sampler: "trilinear" or "triquadratic"; conserve_mass (fog volumes);
vectors: "auto", "push", "normal", "keep"; redistance (level sets): "normalize", "rebuild",
"none"; seed_spacing: seeding cells in voxels; cache_spacing: a displacement cache lattice in
voxels (0: the exact warp). Returns one dict per grid written (active voxels, inverse failures,
mass, ...). Voxels lost are warnings; on any error nothing is written.)");
  m.def(
      "warp_dense",
      [](const Warp& warp, const py::array& values, double voxelSize, py::handle origin,
         double background, bool levelSet, const std::string& sampler, bool conserveMass,
         const py::object& progress) {
        const WarpVolumeOptions options =
            volumeOptions(sampler, conserveMass, "auto", "normalize", 4, 0.0);
        const Vec3 o = toVec3(origin, "origin");
        if (values.dtype().is(py::dtype::of<float>()))
          return warpDenseAs<openvdb::FloatGrid>(warp, values, voxelSize, o, background, levelSet,
                                                 options, progress);
        return warpDenseAs<openvdb::DoubleGrid>(warp, values, voxelSize, o, background, levelSet,
                                                options, progress);
      },
      "warp"_a, "values"_a, py::kw_only(), "voxel_size"_a = 1.0,
      "origin"_a = py::make_tuple(0, 0, 0), "background"_a = 0.0, "level_set"_a = false,
      "sampler"_a = "trilinear", "conserve_mass"_a = false, "progress"_a = py::none(),
      R"(Warps a dense block of voxel values (nx, ny, nz) (float32 stays float32, anything else
is float64): voxel (i, j, k) is centered at origin + voxel_size * (i, j, k), world units; values
equal to `background` are inactive. level_set: the values are signed distances (re-distanced
after the warp). Returns (values, origin): the output's active bounding block and the world
position of its voxel (0, 0, 0). For grids of pyopenvdb, copy them to and from dense arrays
(copyToArray / copyFromArray), or go through files with warp_volume.)");
#endif
  m.attr("has_volumes") =
#ifdef SPACEWARP_WITH_OPENVDB
      true;
#else
      false;
#endif
}

}  // namespace

void bindVolume(py::module_& m) {
  bindVolumeFunctions(m);
  bindVolumeBricks(m);
}

}  // namespace spacewarp::python
