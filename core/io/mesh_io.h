#pragma once
// Reading and writing polygon soups and point clouds, with the format chosen by the file
// extension.

#include <filesystem>
#include <string>
#include <vector>

#include <spacewarp/core/geometry.h>
#include <spacewarp/core/io/ply.h>

namespace spacewarp {

/// The supported file formats.
enum class FileFormat { Obj, Off, Ply };

/// The format of `path` from its extension, compared case-insensitively: .obj, .off, .ply.
/// Throws IoError naming the file when the extension is missing or unknown.
FileFormat formatFromPath(const std::filesystem::path& path);

/// Reads a polygon soup (or a point cloud: a soup with no polygons) from `path`, in the format
/// its extension names (see readObj, readOff, readPly for what each keeps). The result passes
/// PolygonSoup::validate(). Throws IoError, and nothing else, naming the file: unknown
/// extension, a file that cannot be opened ("cannot open"), a directory, malformed content
/// (with the line or element at fault), a soup that fails validation, or a file with no
/// vertices ("model.obj: no vertices ..."), empty or not.
PolygonSoup readSoup(const std::filesystem::path& path);

/// What writing `soup` in `format` would drop because the format cannot store it, as short
/// phrases for a warning ("vertex attributes red, green", "face attributes material_index",
/// "texture coordinates", "per-corner normals", "OBJ groups and materials"); empty when
/// nothing is lost. OBJ stores no vertex or face attributes, PLY no per-corner data or OBJ
/// statements, OFF only colours (offColours()) of these.
std::vector<std::string> unstoredContent(const PolygonSoup& soup, FileFormat format);

/// Options of writeSoup().
struct WriteOptions {
  /// The encoding of .ply output; binary little-endian is compact and exact.
  PlyEncoding plyEncoding = PlyEncoding::BinaryLittleEndian;
};

/// Writes `soup` to `path` in the format its extension names (see writeObj, writeOff,
/// writePly), atomically through writeFileAtomically(): on failure no partial or temporary
/// file is left and an existing file at `path` is untouched. Throws IoError naming the file
/// for an unknown extension or an I/O failure (e.g. a missing or unwritable directory), and
/// InvalidInput for a soup that the format cannot store (see PolygonSoup::validate() and
/// writePly).
void writeSoup(const PolygonSoup& soup, const std::filesystem::path& path,
               const WriteOptions& options = {});

}  // namespace spacewarp
