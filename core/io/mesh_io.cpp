#include "core/io/mesh_io.h"

#include <cctype>
#include <cerrno>
#include <cstring>
#include <fstream>
#include <new>
#include <string>
#include <system_error>

#include "core/errors.h"
#include "core/io/atomic_file.h"
#include "core/io/obj.h"
#include "core/io/off.h"

namespace spacewarp {
namespace {

std::string lowercase(std::string text) {
  for (char& c : text) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return text;
}

}  // namespace

FileFormat formatFromPath(const std::filesystem::path& path) {
  const std::string extension = lowercase(path.extension().string());
  if (extension == ".obj") return FileFormat::Obj;
  if (extension == ".off") return FileFormat::Off;
  if (extension == ".ply") return FileFormat::Ply;
  if (extension.empty())
    throw IoError(path.string() + ": no file extension (expected .obj, .off or .ply)");
  throw IoError(path.string() + ": unknown file extension '" + path.extension().string() +
                "' (expected .obj, .off or .ply)");
}

PolygonSoup readSoup(const std::filesystem::path& path) {
  const FileFormat format = formatFromPath(path);
  const std::string name = path.string();
  std::error_code error;
  if (std::filesystem::is_directory(path, error))
    throw IoError("cannot open " + name + ": it is a directory");
  errno = 0;
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    const int code = errno;
    throw IoError("cannot open " + name +
                  (code != 0 ? ": " + std::string(std::strerror(code)) : ""));
  }
  PolygonSoup soup;
  switch (format) {
    case FileFormat::Obj:
      soup = readObj(in, name);
      break;
    case FileFormat::Off:
      soup = readOff(in, name);
      break;
    case FileFormat::Ply:
      soup = readPly(in, name);
      break;
  }
  try {
    soup.validate();
  } catch (const InvalidInput& e) {
    throw IoError(name + ": " + e.what());
  }
  // An empty file is valid OBJ (and a PLY or OFF may declare 0 vertices), but as an input it
  // is always a mistake, and every format must say so alike.
  if (soup.size() == 0) throw IoError(name + ": no vertices (an empty soup or point cloud)");
  return soup;
}

void writeSoup(const PolygonSoup& soup, const std::filesystem::path& path,
               const WriteOptions& options) {
  const FileFormat format = formatFromPath(path);
  writeFileAtomically(path, [&](std::ostream& out) {
    switch (format) {
      case FileFormat::Obj:
        writeObj(soup, out);
        break;
      case FileFormat::Off:
        writeOff(soup, out);
        break;
      case FileFormat::Ply:
        writePly(soup, out, options.plyEncoding);
        break;
    }
  });
}

}  // namespace spacewarp
