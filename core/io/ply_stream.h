#pragma once
// Binary PLY in pieces: the byte layout of a file, its vertex rows read a range at a time, and
// the output of readPly() + writePly() written a piece at a time, so that files larger than
// memory can be converted (and warped, core/deform_stream.h) with bounded memory, or split into
// row ranges that separate processes handle (python spacewarp.dask.deform_ply).
//
// ASCII PLY is not streamed: its rows have no fixed size, so a row range cannot be found without
// reading everything before it (readPly() reads it whole).

#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <ostream>
#include <string>
#include <vector>

#include <spacewarp/core/geometry.h>
#include <spacewarp/core/io/ply.h>
#include <spacewarp/core/progress.h>

namespace spacewarp {

/// A scalar property of the vertex rows.
struct PlyPropertyLayout {
  std::string name;
  ScalarType type = ScalarType::Float64;
  std::uint64_t offset = 0;  ///< Byte offset within a row.
};

/// Where an element's data lies in the file.
struct PlyElementLayout {
  std::string name;
  std::uint64_t count = 0;   ///< Instances.
  std::uint64_t offset = 0;  ///< Byte offset of the first instance from the start of the file.
  std::uint64_t bytes = 0;   ///< Bytes of all its instances.
};

/// The byte layout of a binary PLY file whose vertex rows have a fixed size (scalar properties
/// only), as plyLayout() finds it.
struct PlyLayout {
  std::filesystem::path path;
  PlyEncoding encoding = PlyEncoding::BinaryLittleEndian;  ///< Never Ascii.
  std::uint64_t fileBytes = 0;
  std::uint64_t vertexCount = 0;
  std::uint64_t vertexOffset = 0;                   ///< Byte offset of vertex row 0.
  std::uint64_t vertexRowBytes = 0;                 ///< Bytes of one vertex row.
  std::vector<PlyPropertyLayout> vertexProperties;  ///< In row order.
  std::vector<PlyElementLayout> elements;           ///< Every element in file order (vertex too).
  std::uint64_t faceCount = 0;                      ///< Polygons (0 without a face element).
  std::uint64_t largestPolygon = 0;                 ///< Vertices of the largest polygon.
  std::vector<std::string> notKept;                 ///< As PolygonSoup::notKept.
};

/// True when `path` is a binary PLY file whose vertex element has scalar properties only, so
/// that plyLayout() and the streaming functions take it. Reads the header only; false for a
/// non-PLY extension, an ASCII PLY, a vertex list property or a path that is not a regular file
/// (a pipe, /dev/stdin: streaming reads the file twice; its header is then not read). Throws
/// IoError when the file cannot be opened or its header is malformed (readPly()'s messages).
bool isStreamablePly(const std::filesystem::path& path);

/// The layout of `path` (see isStreamablePly()). Reads the header and, when an element other
/// than the vertices has list properties (faces), reads that element through once to find its
/// size, checking its instances as readPly() does (polygons of at least 3 vertices with indices
/// in range, list lengths not negative). Throws IoError naming the file, and the header line or
/// the element and instance at fault, for everything readPly() refuses apart from non-finite
/// vertex values (found by PlyVertexReader): a malformed header, a truncated file ("cloud.ply:
/// vertex 12: unexpected end of file"), a bad polygon, no vertices, an ASCII file or vertex list
/// properties (not streamable). InvalidInput naming it for a path that is not a regular file (a
/// pipe: streaming reads it twice).
PlyLayout plyLayout(const std::filesystem::path& path);

/// Reads vertex rows of a file by range, as readPly() reads them.
class PlyVertexReader {
 public:
  /// Opens layout.path. Throws IoError naming it when it cannot be opened.
  explicit PlyVertexReader(const PlyLayout& layout);

  /// Reads rows [first, first + count) into `rows`: positions, normals (nx, ny, nz, if the
  /// file has them) and the other properties as attributes, exactly as readPly() does. Throws
  /// IoError naming the file and the vertex for a non-finite coordinate or normal and a file
  /// that ends early, and InvalidInput for a range past the vertex count.
  void read(std::uint64_t first, std::size_t count, PointSet& rows);

  ~PlyVertexReader();
  PlyVertexReader(const PlyVertexReader&) = delete;
  PlyVertexReader& operator=(const PlyVertexReader&) = delete;

 private:
  const PlyLayout& layout_;
  std::FILE* file_ = nullptr;
  std::uint64_t next_ = ~std::uint64_t{0};  // File offset after the last read; none yet.
  std::vector<unsigned char> buffer_;
  std::size_t position_[3] = {0, 0, 0};  // Property indices.
  int normal_[3] = {-1, -1, -1};
  std::vector<std::size_t> attributes_;
};

/// Writes what writePly(readPly(layout.path), out, encoding) writes, with the vertex rows
/// given a piece at a time: header(), then vertices() for consecutive row ranges covering all
/// rows in order, then faces(), which copies the input's faces (and face attributes) across in
/// the output's encoding. Other elements are dropped, as readPly() drops them.
class PlyStreamWriter {
 public:
  PlyStreamWriter(const PlyLayout& layout, std::ostream& out, PlyEncoding encoding);
  void header();
  /// Rows as PlyVertexReader::read() gives them (positions and normals may have been warped).
  void vertices(const PointSet& rows);
  /// Throws IoError naming the input when it cannot be read; Cancelled when `progress` asks.
  void faces(const ProgressCallback& progress = {});

 private:
  const PlyLayout& layout_;
  std::ostream& out_;
  PlyEncoding encoding_;
  std::vector<unsigned char> buffer_;
};

/// Whether `a` and `b` are the same existing file (also through a link): std::filesystem::
/// equivalent, false when either is missing.
bool sameFile(const std::filesystem::path& a, const std::filesystem::path& b);

/// Bytes of one vertex row of binary output (PlyStreamWriter, writePly) for `layout`.
std::uint64_t plyOutputRowBytes(const PlyLayout& layout);

/// Writes `output` atomically: the output header of `input` (binary little-endian, as
/// `spacewarp deform` writes it), the bytes of `parts` in order — vertex rows in the binary
/// output encoding, as deformPlyRows() writes them, together covering every vertex row — then
/// the input's faces. Parts are raw rows with no header: only their sizes are checked, so their
/// order and that they come from the same warp of this input are the caller's job (a part of
/// rows in the wrong place or of another warp gives a wrong output without an error). Throws
/// InvalidInput naming the part when a part is `input` itself, when a part's size is not a
/// whole number of output rows or the parts do not add up to the vertex count, IoError for files
/// that cannot be read or written. `output` may be `input` (it is replaced atomically).
void assemblePly(const std::filesystem::path& input,
                 const std::vector<std::filesystem::path>& parts,
                 const std::filesystem::path& output);

}  // namespace spacewarp
