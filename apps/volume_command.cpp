#include "apps/volume_command.h"

#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <iostream>
#include <string>
#include <system_error>

#include <spacewarp/core/errors.h>
#include <spacewarp/core/io/atomic_file.h>

#ifdef SPACEWARP_WITH_OPENVDB
#include <openvdb/io/File.h>
#include <openvdb/openvdb.h>
#include <openvdb/points/PointCount.h>
#include <openvdb/points/PointDataGrid.h>

#include <spacewarp/volume/mesh_level_set.h>
#include <spacewarp/volume/read_vdb.h>
#include <spacewarp/volume/warp_grid.h>
#include <spacewarp/volume/warp_points.h>
#include <spacewarp/volume/write_vdb.h>
#include "apps/openvdb_messages.h"
#endif

namespace spacewarp::cli {

void addVolumeOptions(CLI::App* command, VolumeCliOptions& options) {
  command
      ->add_option("--sampler", options.sampler,
                   "volumes: how values are read at the preimage of each voxel (default "
                   "trilinear)")
      ->check(CLI::IsMember({"trilinear", "triquadratic"}));
  command->add_flag("--conserve-mass", options.conserveMass,
                    "fog volumes: scale densities by 1/|det J| so that the total is kept");
  command
      ->add_option("--vectors", options.vectors,
                   "vector grids: how vectors follow the warp: auto (by the grid's vector type; "
                   "J v when it says nothing), push (J v), normal (J^-T v, length kept) or keep "
                   "(default auto)")
      ->check(CLI::IsMember({"auto", "push", "normal", "keep"}));
}

bool isVolumePath(const std::filesystem::path& path) { return path.extension() == ".vdb"; }

#ifndef SPACEWARP_WITH_OPENVDB

bool volumesSupported() { return false; }

void writeMeshLevelSet(const PolygonSoup&, double, const std::filesystem::path& path) {
  throw InvalidInput(path.string() + ": volumes are not supported by this build");
}

void checkVolumeFile(const std::filesystem::path& path) {
  throw InvalidInput(path.string() + ": volumes are not supported by this build");
}

void printVolumeInfo(const std::filesystem::path& path, const CliContext&) {
  checkVolumeFile(path);
}

VolumeSummary deformVolumeFile(const Warp&, const std::filesystem::path& input,
                               const std::filesystem::path&, const VolumeCliOptions&,
                               const CliContext&) {
  checkVolumeFile(input);
  return {};
}

#else

bool volumesSupported() { return true; }

void writeMeshLevelSet(const PolygonSoup& closed, double voxelSize,
                       const std::filesystem::path& path) {
  auto grid = meshLevelSet(closed, voxelSize);
  grid->setName("surface");
  writeVdbFile(path, {grid}, openvdb::MetaMap());
}

/// Prints what OpenVDB logged about `file` as warnings of the tool.
void warnAbout(const std::filesystem::path& file, OpenVdbMessages& messages,
               const CliContext& context) {
  for (const std::string& message : messages.take()) context.warn(file.string() + ": " + message);
}

void checkVolumeFile(const std::filesystem::path& path) {
  // What OpenVDB says about the header is said again when deformVolumeFile reads the file.
  const OpenVdbMessages dropped;
  readVdbFile(path, /*headerOnly=*/true);
}

namespace {

// "2.5e-06", "0.5", "1.23e+04": three significant digits, for the lines people read.
std::string shortNumber(double value) {
  char text[32];
  std::snprintf(text, sizeof text, "%.3g", value);
  return text;
}

WarpVolumeOptions warpVolumeOptions(const VolumeCliOptions& options, const CliContext& context) {
  WarpVolumeOptions volumeOptions;
  volumeOptions.sampler =
      options.sampler == "triquadratic" ? VolumeSampler::Triquadratic : VolumeSampler::Trilinear;
  volumeOptions.conserveMass = options.conserveMass;
  volumeOptions.vectors = options.vectors == "push"     ? VectorTransform::Push
                          : options.vectors == "normal" ? VectorTransform::Normal
                          : options.vectors == "keep"   ? VectorTransform::Keep
                                                        : VectorTransform::Auto;
  volumeOptions.progress = context.progress();
  return volumeOptions;
}

// The warnings of one grid's report: voxels or vectors lost, and mass that --conserve-mass
// could not keep. `grid` is "'name'".
void warnAboutReport(const std::filesystem::path& input, const std::string& grid,
                     const WarpVolumeReport& r, const CliContext& context) {
  const std::string where = input.string() + ": grid " + grid + ": ";
  if (r.inverseFailures > 0) {
    context.warn(where + "the inverse warp did not converge at " +
                 std::to_string(r.inverseFailures) + " of " + std::to_string(r.solvedVoxels) +
                 " voxels, which are left inactive (the warp folds space or is not invertible "
                 "there)");
  }
  if (r.vectorFailures > 0) {
    context.warn(where + std::to_string(r.vectorFailures) + " vectors could not be transformed (" +
                 r.vectors + " with a singular Jacobian) and are left inactive");
  }
  if (hasExtremeVolumeChange(r)) {
    // The densities were divided by |det J|: near a collapse the total is far off.
    std::string range;
    if (r.maxVolumeChange > 0.0)
      range = "by factors from " + shortNumber(r.minVolumeChange) + " to " +
              shortNumber(r.maxVolumeChange);
    if (r.degenerateVolumeChanges > 0)
      range += (range.empty() ? "" : ", and ") + std::string("by 0 or a non-finite factor at ") +
               counted(r.degenerateVolumeChanges, "voxel") + " (left out)";
    context.warn(where + "--conserve-mass: the warp changes volumes (|det J|) " + range +
                 "; densities divided by such factors do not conserve the mass where space is "
                 "squeezed below the voxel size (mass " +
                 shortNumber(r.massBefore) + " -> " + shortNumber(r.massAfter) + ")");
  }
  if (r.unmappedVoxels > 0) {
    context.warn(where + std::to_string(r.unmappedVoxels) +
                 " input voxels could not be mapped (the warp is not finite or singular there) "
                 "and are missing from the output");
  }
}

// The line that says what became of one grid.
std::string gridLine(const openvdb::GridBase& grid, const std::string& name,
                     const WarpVolumeReport& r) {
  if (grid.isType<openvdb::points::PointDataGrid>())
    return "grid " + name + ": " + std::to_string(r.points) + " points moved";
  std::string line = "grid " + name + ": " + std::to_string(r.inputActiveVoxels) + " -> " +
                     std::to_string(r.outputActiveVoxels) + " active voxels, at most " +
                     std::to_string(r.maxNewtonIterations) + " Newton iterations";
  if (!r.vectors.empty()) line += ", vectors " + r.vectors;
  if (r.massBefore != 0.0)
    line += ", mass " + std::to_string(r.massBefore) + " -> " + std::to_string(r.massAfter);
  return line;
}

}  // namespace

VolumeSummary deformVolumeFile(const Warp& warp, const std::filesystem::path& input,
                               const std::filesystem::path& output, const VolumeCliOptions& options,
                               const CliContext& context) {
  OpenVdbMessages messages;
  const VdbFile content = readVdbFile(input);
  warnAbout(input, messages, context);
  checkWarpableGrids(content.grids, input.string());
  const WarpVolumeOptions volumeOptions = warpVolumeOptions(options, context);
  const auto isFog = [](const openvdb::GridBase::Ptr& g) { return isFogVolume(*g); };
  if (options.conserveMass && std::none_of(content.grids.begin(), content.grids.end(), isFog)) {
    context.warn(input.string() + ": --conserve-mass: no grid is a fog volume (a float or double " +
                 "grid that is not a level set), so there is no mass to conserve");
  }

  openvdb::GridCPtrVec warped;
  VolumeSummary summary;
  for (const openvdb::GridBase::Ptr& grid : content.grids) {
    const std::string name = "'" + grid->getName() + "'";
    if (!isWarpableGrid(*grid)) {
      context.warn(input.string() + ": grid " + name + " of type " + grid->type() +
                   " is not supported and is left out");
      continue;
    }
    WarpedGrid<openvdb::GridBase> result;
    try {
      result = warpGrid(warp, *grid, volumeOptions);
    } catch (const InvalidInput& e) {
      throw InvalidInput(input.string() + ": " + e.what());
    }
    const WarpVolumeReport& r = result.report;
    warnAboutReport(input, name, r, context);
    context.say(gridLine(*grid, name, r));
    warped.push_back(result.grid);
    ++summary.grids;
    summary.points += r.points;
    summary.inverseFailures += r.inverseFailures;
    if (!grid->isType<openvdb::points::PointDataGrid>())
      summary.activeVoxels += r.outputActiveVoxels;
  }
  warnAbout(input, messages, context);
  writeVdbFile(output, warped, *content.metadata);
  warnAbout(output, messages, context);
  return summary;
}

namespace {

void printMetadata(const char* indent, const openvdb::MetaMap& meta) {
  for (auto it = meta.beginMeta(); it != meta.endMeta(); ++it) {
    // Shown on lines of their own.
    if (it->first == openvdb::GridBase::META_GRID_NAME ||
        it->first == openvdb::GridBase::META_GRID_CLASS)
      continue;
    std::printf("%s%s = %s (%s)\n", indent, it->first.c_str(), it->second->str().c_str(),
                it->second->typeName().c_str());
  }
}

const char* className(openvdb::GridClass c) {
  switch (c) {
    case openvdb::GRID_LEVEL_SET:
      return "level set";
    case openvdb::GRID_FOG_VOLUME:
      return "fog volume";
    case openvdb::GRID_STAGGERED:
      return "staggered";
    default:
      return "unknown";
  }
}

}  // namespace

void printVolumeInfo(const std::filesystem::path& path, const CliContext& context) {
  OpenVdbMessages messages;
  const VdbFile content = readVdbFile(path);
  warnAbout(path, messages, context);
  std::printf("file:       %s\n", path.string().c_str());
  std::printf("grids:      %zu\n", content.grids.size());
  printMetadata("metadata:   ", *content.metadata);
  for (const openvdb::GridBase::Ptr& grid : content.grids) {
    std::printf("grid '%s':\n", grid->getName().c_str());
    std::printf("  class:          %s\n", className(grid->getGridClass()));
    std::printf("  value type:     %s (%s)\n", grid->valueType().c_str(), grid->type().c_str());
    const openvdb::Vec3d voxel = grid->voxelSize();
    std::printf("  voxel size:     %.17g %.17g %.17g%s\n", voxel.x(), voxel.y(), voxel.z(),
                grid->transform().isLinear() ? "" : " (at the origin; non-linear transform)");
    std::printf("  active voxels:  %s\n", groupDigits(grid->activeVoxelCount()).c_str());
    if (const auto points = openvdb::gridConstPtrCast<openvdb::points::PointDataGrid>(grid))
      std::printf("  points:         %s\n",
                  groupDigits(openvdb::points::pointCount(points->constTree())).c_str());
    const openvdb::CoordBBox box = grid->evalActiveVoxelBoundingBox();
    if (!box.empty()) {
      const openvdb::Coord lo = box.min(), hi = box.max();
      std::printf("  active index box: [%d %d %d] .. [%d %d %d]\n", lo.x(), lo.y(), lo.z(), hi.x(),
                  hi.y(), hi.z());
      // World box of the active voxels' extents (voxel centers +- half a voxel).
      const openvdb::BBoxd world =
          grid->transform().indexToWorld(openvdb::BBoxd(lo.asVec3d() - 0.5, hi.asVec3d() + 0.5));
      std::printf("  active world box: [%.17g %.17g %.17g] .. [%.17g %.17g %.17g]\n",
                  world.min().x(), world.min().y(), world.min().z(), world.max().x(),
                  world.max().y(), world.max().z());
    }
    printMetadata("  metadata:       ", *grid);
  }
}

#endif

}  // namespace spacewarp::cli
