#include "apps/file_kinds.h"

#include <algorithm>
#include <cctype>

#include <CLI/CLI.hpp>

#include <spacewarp/core/errors.h>

namespace spacewarp::cli {

std::string lowerExtension(const std::filesystem::path& path) {
  std::string extension = path.extension().string();
  std::transform(extension.begin(), extension.end(), extension.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return extension;
}

FileKind fileKind(const std::filesystem::path& path) {
  const std::string extension = lowerExtension(path);
  if (extension == ".obj" || extension == ".off" || extension == ".ply") return FileKind::Geometry;
  if (extension == ".vdb") return FileKind::Volume;
  const std::string expected = "(expected .obj, .off, .ply or .vdb)";
  if (extension.empty()) throw IoError(path.string() + ": no file extension " + expected);
  throw IoError(path.string() + ": unknown file extension '" + path.extension().string() + "' " +
                expected);
}

void checkConversion(const std::filesystem::path& input, const std::filesystem::path& output) {
  const FileKind in = fileKind(input), out = fileKind(output);
  if (in == out) return;
  const std::string files = input.string() + " -> " + output.string() + ": ";
  if (in == FileKind::Volume)
    throw CLI::ValidationError(files + "a volume (.vdb) can only be written as .vdb");
  throw CLI::ValidationError(files +
                             "a polygon soup or point cloud is written as .obj, .off or .ply, "
                             "not as a volume (.vdb)");
}

}  // namespace spacewarp::cli
