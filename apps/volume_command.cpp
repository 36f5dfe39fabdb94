#include "apps/volume_command.h"

#include <unistd.h>

#include <iostream>
#include <string>
#include <system_error>

#include "core/errors.h"

#ifdef SPACEWARP_WITH_OPENVDB
#include <openvdb/io/File.h>
#include <openvdb/openvdb.h>
#include <openvdb/tools/MeshToVolume.h>

#include "core/volume/read_vdb.h"
#include "core/volume/warp_grid.h"
#include "core/volume/warp_points.h"
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

void deformVolumeFile(const Warp&, const std::filesystem::path& input, const std::filesystem::path&,
                      const VolumeCliOptions&, const CliContext&) {
  throw InvalidInput(input.string() + ": volumes are not supported by this build");
}

#else

namespace {

// Writes to a temporary beside `path` and renames it; the temporary is removed on failure.
void writeVdbAtomically(const std::filesystem::path& path, const openvdb::GridCPtrVec& grids,
                        const openvdb::MetaMap& metadata) {
  const std::filesystem::path dir = path.has_parent_path() ? path.parent_path() : ".";
  const std::filesystem::path temp =
      dir / ("." + path.filename().string() + ".tmp" + std::to_string(::getpid()));
  try {
    openvdb::io::File file(temp.string());
    file.write(grids, metadata);
    file.close();
    std::filesystem::rename(temp, path);
  } catch (const openvdb::Exception& e) {
    std::error_code ec;
    std::filesystem::remove(temp, ec);
    throw IoError(path.string() + ": cannot be written (" + e.what() + ")");
  } catch (const std::filesystem::filesystem_error& e) {
    std::error_code ec;
    std::filesystem::remove(temp, ec);
    throw IoError(path.string() + ": cannot be written (" + e.what() + ")");
  } catch (...) {
    std::error_code ec;
    std::filesystem::remove(temp, ec);
    throw;
  }
}

}  // namespace

bool volumesSupported() { return true; }

void writeMeshLevelSet(const PolygonSoup& closed, double voxelSize,
                       const std::filesystem::path& path) {
  openvdb::initialize();
  const auto transform = openvdb::math::Transform::createLinearTransform(voxelSize);
  std::vector<openvdb::Vec3s> points;
  for (const Vec3& p : closed.positions)
    points.emplace_back(p.x, p.y, p.z);  // world space: meshToLevelSet applies the transform
  std::vector<openvdb::Vec3I> triangles;
  std::vector<openvdb::Vec4I> quads;
  for (std::size_t f = 0; f < closed.polygonCount(); ++f) {
    const auto poly = closed.polygon(f);
    if (poly.size() == 4) {
      quads.emplace_back(poly[0], poly[1], poly[2], poly[3]);
    } else {
      for (std::size_t k = 1; k + 1 < poly.size(); ++k)
        triangles.emplace_back(poly[0], poly[k], poly[k + 1]);
    }
  }
  auto grid = openvdb::tools::meshToLevelSet<openvdb::FloatGrid>(*transform, points, triangles,
                                                                 quads, 3.0f);
  grid->setName("surface");
  writeVdbAtomically(path, {grid}, openvdb::MetaMap());
}

void deformVolumeFile(const Warp& warp, const std::filesystem::path& input,
                      const std::filesystem::path& output, const VolumeCliOptions& options,
                      const CliContext& context) {
  openvdb::initialize();
  const VdbFile content = readVdbFile(input);

  std::string found;
  std::size_t supported = 0;
  for (const openvdb::GridBase::Ptr& grid : content.grids) {
    if (isWarpableGrid(*grid)) ++supported;
    found += (found.empty() ? "" : ", ") + ("'" + grid->getName() + "' (" + grid->type() + ")");
  }
  if (supported == 0) {
    throw InvalidInput(input.string() +
                       ": no supported grid (float, double, vec3s or point data grids); found " +
                       (found.empty() ? std::string("no grids") : found));
  }

  WarpVolumeOptions volumeOptions;
  volumeOptions.sampler =
      options.sampler == "triquadratic" ? VolumeSampler::Triquadratic : VolumeSampler::Trilinear;
  volumeOptions.conserveMass = options.conserveMass;
  volumeOptions.vectors = options.vectors == "push"     ? VectorTransform::Push
                          : options.vectors == "normal" ? VectorTransform::Normal
                          : options.vectors == "keep"   ? VectorTransform::Keep
                                                        : VectorTransform::Auto;
  volumeOptions.progress = context.progress();

  openvdb::GridCPtrVec warped;
  for (const openvdb::GridBase::Ptr& grid : content.grids) {
    const std::string name = "'" + grid->getName() + "'";
    if (!isWarpableGrid(*grid)) {
      std::cerr << "warning: " << input.string() << ": grid " << name << " of type " << grid->type()
                << " is not supported and is left out\n";
      continue;
    }
    WarpedGrid<openvdb::GridBase> result;
    try {
      result = warpGrid(warp, *grid, volumeOptions);
    } catch (const InvalidInput& e) {
      throw InvalidInput(input.string() + ": " + e.what());
    }
    const WarpVolumeReport& r = result.report;
    if (r.inverseFailures > 0) {
      std::cerr
          << "warning: " << input.string() << ": grid " << name << ": the inverse warp "
          << "did not converge at " << r.inverseFailures << " of " << r.solvedVoxels
          << " voxels, which are left inactive (the warp folds space or is not invertible there)\n";
    }
    if (r.vectorFailures > 0) {
      std::cerr << "warning: " << input.string() << ": grid " << name << ": " << r.vectorFailures
                << " vectors could not be transformed (" << r.vectors
                << " with a singular Jacobian) and are left inactive\n";
    }
    if (r.unmappedVoxels > 0) {
      std::cerr << "warning: " << input.string() << ": grid " << name << ": " << r.unmappedVoxels
                << " input voxels could not be mapped (the warp is not finite or singular "
                   "there) and are missing from the output\n";
    }
    std::string line;
    if (grid->isType<openvdb::points::PointDataGrid>()) {
      line = "grid " + name + ": " + std::to_string(r.points) + " points moved";
    } else {
      line = "grid " + name + ": " + std::to_string(r.inputActiveVoxels) + " -> " +
             std::to_string(r.outputActiveVoxels) + " active voxels, at most " +
             std::to_string(r.maxNewtonIterations) + " Newton iterations";
      if (!r.vectors.empty()) line += ", vectors " + r.vectors;
      if (r.massBefore != 0.0) {
        line += ", mass " + std::to_string(r.massBefore) + " -> " + std::to_string(r.massAfter);
      }
    }
    context.say(line);
    warped.push_back(result.grid);
  }
  writeVdbAtomically(output, warped, *content.metadata);
}

#endif

}  // namespace spacewarp::cli
