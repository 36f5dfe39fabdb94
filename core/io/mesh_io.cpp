#include <spacewarp/core/io/mesh_io.h>

#include <algorithm>
#include <cctype>
#include <cstring>
#include <fstream>
#include <new>
#include <string>
#include <system_error>
#include <vector>

#include <spacewarp/core/errors.h>
#include <spacewarp/core/io/atomic_file.h>
#include <spacewarp/core/io/detail/text_format.h>
#include <spacewarp/core/io/obj.h>
#include <spacewarp/core/io/off.h>

namespace spacewarp {
namespace {

std::string lowercase(std::string text) {
  for (char& c : text) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return text;
}

/// "what a, b, c" for the named attributes.
std::string namedList(const char* what, const std::vector<ScalarAttribute>& attributes) {
  std::string text = what;
  for (std::size_t a = 0; a < attributes.size(); ++a) {
    text += a == 0 ? " " : ", ";
    text += attributes[a].name;
  }
  return text;
}

}  // namespace

std::vector<std::string> unstoredContent(const PolygonSoup& soup, FileFormat format) {
  std::vector<std::string> lost;
  if (format != FileFormat::Ply) {
    // OFF stores colours, OBJ no attributes.
    const auto unstored = [&](const std::vector<ScalarAttribute>& attributes) {
      std::vector<ScalarAttribute> rest;
      const auto colours = format == FileFormat::Off ? offColours(attributes)
                                                     : std::vector<const ScalarAttribute*>{};
      for (const ScalarAttribute& a : attributes)
        if (std::find(colours.begin(), colours.end(), &a) == colours.end()) rest.push_back(a);
      return rest;
    };
    if (const auto rest = unstored(soup.attributes); !rest.empty())
      lost.push_back(namedList("vertex attributes", rest));
    if (const auto rest = unstored(soup.faceAttributes); !rest.empty())
      lost.push_back(namedList("face attributes", rest));
  }
  if (format != FileFormat::Obj) {
    if (!soup.texcoords.empty()) lost.emplace_back("texture coordinates");
    if (!soup.cornerNormals.empty()) lost.emplace_back("per-corner normals");
    if (!soup.objStatements.empty()) lost.emplace_back("OBJ groups and materials");
  }
  return lost;
}

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
  const std::string name = path.string();
  detail::refuseDirectory(path);  // before the extension: folders have none
  const FileFormat format = formatFromPath(path);
  std::ifstream in = detail::openInputFile(path);
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
