#pragma once
// The PLY format's pieces shared by the whole-file reader and writer (core/io/ply.cpp) and the
// streaming ones (core/io/ply_stream.cpp): scalar types, the header parser, the output header
// and value encoder. Internal: not part of the installed API's promises.

#include <algorithm>
#include <cstdint>
#include <istream>
#include <optional>
#include <ostream>
#include <string>
#include <string_view>
#include <vector>

#include <spacewarp/core/geometry.h>
#include <spacewarp/core/io/ply.h>

namespace spacewarp::detail {

/// Bytes of one binary value of `type`.
std::size_t plyScalarSize(ScalarType type);

/// The classic PLY name of a type (the one written).
const char* plyTypeName(ScalarType type);

/// True for the integer types.
bool plyIsIntegral(ScalarType type);

/// Decodes one binary value of `type` from `bytes` (already in host byte order).
double plyDecode(const unsigned char* bytes, ScalarType type);

/// True when binary values in `encoding` are in the other byte order than the host's.
bool plySwapsBytes(PlyEncoding encoding);

struct PlyProperty {
  std::string name;
  bool isList = false;
  ScalarType type = ScalarType::Float64;  ///< The scalar type, or a list's item type.
  ScalarType countType = ScalarType::UInt8;
};

struct PlyElement {
  std::string name;
  std::uint64_t count = 0;
  std::size_t line = 0;  ///< Header line of the element, for messages.
  std::vector<PlyProperty> properties;

  std::optional<std::size_t> find(std::string_view property) const {
    for (std::size_t p = 0; p < properties.size(); ++p)
      if (properties[p].name == property) return p;
    return std::nullopt;
  }
};

struct PlyHeader {
  PlyEncoding encoding = PlyEncoding::Ascii;
  std::vector<PlyElement> elements;
  std::uint64_t dataOffset = 0;  ///< Bytes from the start of the input to the first element.
};

/// The binary value grammar both readers share over their own byte source (whole-file reader in
/// core/io/ply.cpp, block-buffered streaming one in core/io/ply_stream.cpp). Source provides
/// `void readBytes(unsigned char* out, std::size_t n)` (fails at the end of the input),
/// `void skipItems(ScalarType type, std::uint64_t count)`, `double scalar(ScalarType)` and
/// `[[noreturn]] void fail(const std::string&) const`.
template <class Source>
class PlyValueSource {
 public:
  explicit PlyValueSource(PlyEncoding encoding) : swap_(plySwapsBytes(encoding)) {}

  std::uint64_t listLength(ScalarType countType) {
    const double length = self().scalar(countType);
    if (length < 0)
      self().fail("negative list length " + std::to_string(static_cast<std::int64_t>(length)));
    return static_cast<std::uint64_t>(length);
  }

  /// Reads and drops one property value (a scalar or a whole list).
  void skip(const PlyProperty& property) {
    if (!property.isList) {
      self().scalar(property.type);
      return;
    }
    self().skipItems(property.type, listLength(property.countType));
  }

  /// Reads one face's index list of `indices` into `out` (cleared first), refusing fewer than
  /// 3 vertices and indices outside [0, vertexCount).
  void readPolygon(const PlyProperty& indices, std::uint64_t vertexCount,
                   std::vector<std::uint32_t>& out) {
    const std::uint64_t length = listLength(indices.countType);
    if (length < 3)
      self().fail("polygon has " + std::to_string(length) + " vertices, at least 3 needed");
    out.clear();
    for (std::uint64_t k = 0; k < length; ++k) {
      const double index = self().scalar(indices.type);
      if (index < 0 || index >= static_cast<double>(vertexCount)) {
        self().fail("vertex index " + std::to_string(static_cast<std::int64_t>(index)) +
                    " is out of range (" + std::to_string(vertexCount) + " vertices)");
      }
      out.push_back(static_cast<std::uint32_t>(index));
    }
  }

 protected:
  double binaryScalar(ScalarType type) {
    unsigned char bytes[8];
    const std::size_t size = plyScalarSize(type);
    self().readBytes(bytes, size);
    if (swap_) std::reverse(bytes, bytes + size);
    return plyDecode(bytes, type);
  }

 private:
  Source& self() { return static_cast<Source&>(*this); }

  bool swap_;
};

/// Parses the header of a PLY file from `in` (readPly's parser and messages). The stream is
/// read ahead past the header: seek to dataOffset to read the data.
PlyHeader readPlyHeader(std::istream& in, const std::string& name);

/// What a soup read from a file with `header` does not keep (PolygonSoup::notKept).
std::vector<std::string> plyNotKept(const PlyHeader& header);

/// Where the vertex properties go.
struct PlyVertexLayout {
  std::size_t position[3] = {0, 0, 0};
  std::optional<std::size_t> normal[3];
  std::vector<std::size_t> attributeProperty;  ///< Property index of each attribute.
};

/// The vertex layout of `vertex` (x, y, z needed, nx, ny, nz all or none); appends an empty
/// attribute to `points` for each other scalar property. Throws IoError naming the header line.
PlyVertexLayout plyVertexLayout(const PlyElement& vertex, PointSet& points,
                                const std::string& name);

/// The index list property of a face element ("vertex_indices", else "vertex_index"). Throws
/// IoError naming the header line when it is missing, not a list or not integral.
std::size_t plyFaceIndexList(const PlyElement& face, const std::string& name);

/// What writePly() declares in its header.
struct PlyOutputHeader {
  std::uint64_t vertexCount = 0;
  bool normals = false;
  std::vector<std::pair<std::string, ScalarType>> vertexAttributes;
  bool faceElement = false;  ///< Declared (polygons or face attributes).
  std::uint64_t faceCount = 0;
  ScalarType lengthType = ScalarType::UInt8;
  ScalarType indexType = ScalarType::Int32;
  std::vector<std::pair<std::string, ScalarType>> faceAttributes;
};

/// The list types writePly() uses for the largest polygon and the vertex count.
ScalarType plyLengthType(std::uint64_t largestPolygon);
ScalarType plyIndexType(std::uint64_t vertexCount);

/// The header text writePly() writes, up to and including "end_header\n".
std::string plyHeaderText(const PlyOutputHeader& header, PlyEncoding encoding);

/// Collects output values in writePly()'s encoding and hands them to the stream in large
/// blocks.
class PlyValueWriter {
 public:
  PlyValueWriter(std::ostream& out, PlyEncoding encoding);

  void text(std::string_view s) { buffer_ += s; }

  /// One value: binary, or as text followed by `separator`.
  void value(double v, ScalarType type, char separator);

  /// Hands the buffer to the stream once it is large, or always if `force`.
  void drain(bool force = false);

 private:
  std::ostream& out_;
  PlyEncoding encoding_;
  bool swap_ = false;
  std::string buffer_;
};

}  // namespace spacewarp::detail
