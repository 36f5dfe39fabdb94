#include "apps/volume_command.h"

#include <iostream>
#include <string>
#include <system_error>

#include "core/errors.h"
#include "core/io/atomic_file.h"

#ifdef SPACEWARP_WITH_OPENVDB
#include <openvdb/io/Archive.h>
#include <openvdb/io/File.h>
#include <openvdb/openvdb.h>
#include <openvdb/tools/MeshToVolume.h>

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

struct VdbContent {
  openvdb::GridPtrVec grids;
  openvdb::MetaMap::Ptr metadata;
};

VdbContent readVdb(const std::filesystem::path& path) {
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) throw IoError(path.string() + ": no such file");
  if (std::filesystem::is_directory(path, ec)) throw IoError(path.string() + ": is a directory");
  VdbContent content;
  try {
    openvdb::io::File file(path.string());
    file.open(/*delayLoad=*/false);
    content.grids = *file.getGrids();
    content.metadata = file.getMetadata();
    file.close();
  } catch (const openvdb::Exception& e) {
    throw IoError(path.string() + ": not a readable OpenVDB file (" + e.what() + ")");
  } catch (const std::ios_base::failure& e) {
    throw IoError(path.string() + ": cannot be read (" + e.what() + ")");
  }
  if (!content.metadata) content.metadata = std::make_shared<openvdb::MetaMap>();
  return content;
}

// OpenVDB's own file writer (io::File) opens the file itself and checks no write; this writes
// the same seekable format (with grid offsets, for delayed loading) to the stream of the one
// atomic-write path instead.
class VdbArchive : public openvdb::io::Archive {
 public:
  void writeTo(std::ostream& out, const openvdb::GridCPtrVec& grids,
               const openvdb::MetaMap& metadata) const {
    write(out, grids, /*seekable=*/true, metadata);
  }
};

void writeVdbAtomically(const std::filesystem::path& path, const openvdb::GridCPtrVec& grids,
                        const openvdb::MetaMap& metadata) {
  try {
    writeFileAtomically(path,
                        [&](std::ostream& out) { VdbArchive().writeTo(out, grids, metadata); });
  } catch (const openvdb::Exception& e) {
    throw IoError(path.string() + ": cannot be written (" + e.what() + ")");
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
  const VdbContent content = readVdb(input);

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
