// spacewarp info FILE: what a file holds. Soups and point clouds: counts and the bounding box;
// volumes (.vdb): every grid's class, type, voxel size, active voxels and box, and metadata;
// rigs (.json): the method, its controls and what it will do.

#include <cstdio>
#include <map>

#include <spacewarp/core/io/mesh_io.h>
#include "apps/commands.h"
#include "apps/file_kinds.h"
#include "apps/rig_info.h"
#include "apps/volume_command.h"

namespace spacewarp::cli {

namespace {

void printSoupInfo(const std::filesystem::path& path) {
  const PolygonSoup soup = readSoup(path);
  std::map<std::size_t, std::size_t> sizes;
  for (std::size_t p = 0; p < soup.polygonCount(); ++p) ++sizes[soup.polygon(p).size()];
  const BoundingBox box = boundingBox(soup.positions);

  std::printf("file:       %s\n", path.string().c_str());
  std::printf("vertices:   %zu\n", soup.size());
  std::printf("polygons:   %zu", soup.polygonCount());
  for (const auto& [n, count] : sizes) std::printf("  (%zu with %zu sides)", count, n);
  std::printf("\nnormals:    %s\n", soup.hasNormals() ? "per vertex" : "none");
  for (const VertexAttribute& a : soup.attributes) std::printf("attribute:  %s\n", a.name.c_str());
  if (!box.empty()) {
    std::printf("bbox min:   %.17g %.17g %.17g\n", box.min.x, box.min.y, box.min.z);
    std::printf("bbox max:   %.17g %.17g %.17g\n", box.max.x, box.max.y, box.max.z);
    std::printf("diagonal:   %.17g\n", box.diagonal());
  }
}

void printInfo(const std::filesystem::path& path, const CliContext& context) {
  if (lowerExtension(path) == ".json")
    printRigInfo(path);
  else if (fileKind(path) == FileKind::Volume)
    printVolumeInfo(path, context);
  else
    printSoupInfo(path);
}

}  // namespace

Command addInfoCommand(CLI::App& app, const CliContext& context) {
  auto path = std::make_shared<std::string>();
  CLI::App* info = app.add_subcommand(
      "info",
      "Describe a file: a soup or point cloud (counts, bounding box), a volume (grids, types, "
      "voxel size, active voxels, metadata) or a rig (method, controls, what it will do)");
  info->add_option("FILE", *path, "OBJ, OFF, PLY, VDB or JSON rig file")->required();
  return {info, [path, &context] { printInfo(*path, context); }};
}

}  // namespace spacewarp::cli
