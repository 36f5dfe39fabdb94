#include <spacewarp/core/io/ply_stream.h>

#include <algorithm>
#include <bit>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>
#include <memory>
#include <span>
#include <system_error>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <spacewarp/core/errors.h>
#include <spacewarp/core/io/atomic_file.h>
#include <spacewarp/core/io/detail/ply_format.h>
#include <spacewarp/core/io/detail/text_format.h>

namespace spacewarp {
namespace {

using detail::PlyElement;
using detail::PlyHeader;
using detail::PlyProperty;

// Large sequential reads: the page cache and the disk both prefer them.
constexpr std::size_t kReadBlock = std::size_t{1} << 20;
/// Bytes of raw rows decoded or encoded at a time: a default chunk of float xyz (1M rows) in one
/// block, and no more whatever the chunk.
constexpr std::size_t kCodecBlockBytes = std::size_t{16} << 20;

std::FILE* openForReading(const std::filesystem::path& path) {
  errno = 0;
  std::FILE* file = std::fopen(path.c_str(), "rb");
  if (!file) {
    const int code = errno;  // before path.string() may allocate
    detail::throwCannotOpen(path.string(), code);
  }
  return file;
}

struct FileCloser {
  void operator()(std::FILE* file) const { std::fclose(file); }
};
using File = std::unique_ptr<std::FILE, FileCloser>;

void seek(std::FILE* file, std::uint64_t offset, const std::string& name) {
  if (fseeko(file, static_cast<off_t>(offset), SEEK_SET) != 0)
    throw IoError(name + ": cannot seek: " + std::strerror(errno));
}

/// Reads up to n bytes; fewer only at the end of the file. Throws IoError at a read error.
std::size_t readSome(std::FILE* file, void* out, std::size_t n, const std::string& name) {
  const std::size_t got = std::fread(out, 1, n, file);
  if (got < n && std::ferror(file)) throw IoError(name + ": read error: " + std::strerror(errno));
  return got;
}

/// Reads the instances of a binary element value by value through a block buffer, with
/// readPly()'s messages ("cloud.ply: face 3: unexpected end of file").
class ElementReader : public detail::PlyValueSource<ElementReader> {
 public:
  ElementReader(std::FILE* file, const std::string& name, PlyEncoding encoding)
      : PlyValueSource(encoding), file_(file), name_(name), buffer_(kReadBlock) {}

  void start(const PlyElement& element, std::uint64_t offset) {
    seek(file_, offset, name_);
    offset_ = offset;
    pos_ = end_ = 0;
    element_ = &element;
  }
  void begin(std::uint64_t index) { index_ = index; }

  double scalar(ScalarType type) { return binaryScalar(type); }

  void readBytes(unsigned char* out, std::size_t n) {
    if (end_ - pos_ < n) refill(n);
    std::memcpy(out, buffer_.data() + pos_, n);
    pos_ += n;
  }

  /// Skips whole buffers rather than value by value: lists may be long.
  void skipItems(ScalarType type, std::uint64_t count) {
    const std::uint64_t bytes = count * detail::plyScalarSize(type);
    for (std::uint64_t done = 0; done < bytes;) {
      if (pos_ == end_) refill(1);
      const std::uint64_t take = std::min<std::uint64_t>(bytes - done, end_ - pos_);
      pos_ += static_cast<std::size_t>(take);
      done += take;
    }
  }

  /// The file offset of the next value.
  std::uint64_t offset() const { return offset_ + pos_; }

  [[noreturn]] void fail(const std::string& message) const {
    throw IoError(name_ + ": " + element_->name + " " + std::to_string(index_) + ": " + message);
  }

 private:
  /// Keeps the unread bytes and reads more, until at least `need` are buffered.
  void refill(std::size_t need) {
    std::memmove(buffer_.data(), buffer_.data() + pos_, end_ - pos_);
    offset_ += pos_;
    end_ -= pos_;
    pos_ = 0;
    while (end_ < need) {
      const std::size_t got = readSome(file_, buffer_.data() + end_, buffer_.size() - end_, name_);
      if (got == 0) fail("unexpected end of file");
      end_ += got;
    }
  }

  std::FILE* file_;
  const std::string& name_;
  std::vector<unsigned char> buffer_;
  std::size_t pos_ = 0;
  std::size_t end_ = 0;
  std::uint64_t offset_ = 0;  ///< File offset of buffer_[0].
  const PlyElement* element_ = nullptr;
  std::uint64_t index_ = 0;
};

/// Reads the faces of `face` one by one, with readPly()'s checks, and calls
/// onFace(polygon, attributeValues) for each.
template <class OnFace>
void readFaces(ElementReader& reader, const PlyElement& face, std::uint64_t vertexCount,
               const std::string& name, OnFace&& onFace) {
  const std::size_t list = detail::plyFaceIndexList(face, name);
  const PlyProperty& indices = face.properties[list];
  std::vector<std::uint32_t> polygon;
  std::vector<double> attributes;
  std::uint64_t totalIndices = 0;
  for (std::uint64_t f = 0; f < face.count; ++f) {
    reader.begin(f);
    attributes.clear();
    for (std::size_t p = 0; p < face.properties.size(); ++p) {
      const PlyProperty& property = face.properties[p];
      if (p != list && !property.isList) {
        attributes.push_back(reader.scalar(property.type));
        continue;
      }
      if (p != list) {
        reader.skip(property);
        continue;
      }
      reader.readPolygon(indices, vertexCount, polygon);
    }
    totalIndices += polygon.size();
    if (totalIndices > std::numeric_limits<std::uint32_t>::max())
      reader.fail("too many face indices for 32-bit offsets");
    onFace(std::span<const std::uint32_t>(polygon), std::span<const double>(attributes));
  }
}

PlyHeader headerOf(const std::filesystem::path& path) {
  std::ifstream in = detail::openInputFile(path);
  return detail::readPlyHeader(in, path.string());
}

const PlyElement* findElement(const PlyHeader& header, std::string_view name) {
  for (const PlyElement& element : header.elements)
    if (element.name == name) return &element;
  return nullptr;
}

bool hasList(const PlyElement& element) {
  return std::any_of(element.properties.begin(), element.properties.end(),
                     [](const PlyProperty& p) { return p.isList; });
}

std::uint64_t rowBytes(const PlyElement& element) {
  std::uint64_t bytes = 0;
  for (const PlyProperty& property : element.properties)
    bytes += detail::plyScalarSize(property.type);
  return bytes;
}

/// Decodes the values of one property of `count` rows (`rowBytes` apart from `bytes`) into
/// out[i * stride], in parallel.
template <class T>
void decodeColumnAs(const unsigned char* bytes, std::uint64_t rowBytes, std::size_t count,
                    bool swap, double* out, std::size_t stride) {
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, count, 1 << 14),
                    [&](const tbb::blocked_range<std::size_t>& r) {
                      for (std::size_t i = r.begin(); i != r.end(); ++i) {
                        unsigned char raw[sizeof(T)];
                        std::memcpy(raw, bytes + i * rowBytes, sizeof(T));
                        if (swap) std::reverse(raw, raw + sizeof(T));
                        T value;
                        std::memcpy(&value, raw, sizeof(T));
                        out[i * stride] = static_cast<double>(value);
                      }
                    });
}

void decodeColumn(const unsigned char* bytes, std::uint64_t rowBytes, std::size_t count,
                  ScalarType type, bool swap, double* out, std::size_t stride) {
  switch (type) {
    case ScalarType::Int8:
      return decodeColumnAs<std::int8_t>(bytes, rowBytes, count, swap, out, stride);
    case ScalarType::UInt8:
      return decodeColumnAs<std::uint8_t>(bytes, rowBytes, count, swap, out, stride);
    case ScalarType::Int16:
      return decodeColumnAs<std::int16_t>(bytes, rowBytes, count, swap, out, stride);
    case ScalarType::UInt16:
      return decodeColumnAs<std::uint16_t>(bytes, rowBytes, count, swap, out, stride);
    case ScalarType::Int32:
      return decodeColumnAs<std::int32_t>(bytes, rowBytes, count, swap, out, stride);
    case ScalarType::UInt32:
      return decodeColumnAs<std::uint32_t>(bytes, rowBytes, count, swap, out, stride);
    case ScalarType::Float32:
      return decodeColumnAs<float>(bytes, rowBytes, count, swap, out, stride);
    case ScalarType::Float64:
      return decodeColumnAs<double>(bytes, rowBytes, count, swap, out, stride);
  }
}

/// Encodes values[i * stride] of `count` rows as `T` in host byte order at bytes + i * rowBytes
/// (PlyValueWriter's conversion: a static_cast of a representable value), in parallel.
template <class T>
void encodeColumnAs(const double* values, std::size_t stride, std::size_t count,
                    unsigned char* bytes, std::size_t rowBytes) {
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, count, 1 << 14),
                    [&](const tbb::blocked_range<std::size_t>& r) {
                      for (std::size_t i = r.begin(); i != r.end(); ++i) {
                        const auto value = static_cast<T>(values[i * stride]);
                        std::memcpy(bytes + i * rowBytes, &value, sizeof(T));
                      }
                    });
}

void encodeColumn(const double* values, std::size_t stride, std::size_t count, ScalarType type,
                  unsigned char* bytes, std::size_t rowBytes) {
  switch (type) {
    case ScalarType::Int8:
      return encodeColumnAs<std::int8_t>(values, stride, count, bytes, rowBytes);
    case ScalarType::UInt8:
      return encodeColumnAs<std::uint8_t>(values, stride, count, bytes, rowBytes);
    case ScalarType::Int16:
      return encodeColumnAs<std::int16_t>(values, stride, count, bytes, rowBytes);
    case ScalarType::UInt16:
      return encodeColumnAs<std::uint16_t>(values, stride, count, bytes, rowBytes);
    case ScalarType::Int32:
      return encodeColumnAs<std::int32_t>(values, stride, count, bytes, rowBytes);
    case ScalarType::UInt32:
      return encodeColumnAs<std::uint32_t>(values, stride, count, bytes, rowBytes);
    case ScalarType::Float32:
      return encodeColumnAs<float>(values, stride, count, bytes, rowBytes);
    case ScalarType::Float64:
      return encodeColumnAs<double>(values, stride, count, bytes, rowBytes);
  }
}

}  // namespace

bool isStreamablePly(const std::filesystem::path& path) {
  std::string extension = path.extension().string();
  for (char& c : extension) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  if (extension != ".ply") return false;
  // Not a pipe, whose header would be consumed here: streaming reads the file twice (layout,
  // then rows), so only a regular file streams; anything else is read whole.
  std::error_code error;
  if (!std::filesystem::is_regular_file(path, error)) return false;
  const PlyHeader header = headerOf(path);
  if (header.encoding == PlyEncoding::Ascii) return false;
  const PlyElement* vertex = findElement(header, "vertex");
  return !vertex || !hasList(*vertex);
}

namespace {

/// The vertex rows' part of `layout`, with readPly()'s checks and the streaming ones (32-bit
/// indices, no list properties).
void layOutVertexRows(const PlyElement& vertex, const std::string& name, PlyLayout& layout) {
  if (vertex.count > std::numeric_limits<std::uint32_t>::max())
    detail::failAt(name, vertex.line, "too many vertices for 32-bit indices");
  PointSet unused;
  detail::plyVertexLayout(vertex, unused, name);  // readPly()'s checks of x y z nx ny nz
  if (hasList(vertex)) {
    detail::failAt(name, vertex.line,
                   "the vertex element has list properties: its rows have no fixed size to "
                   "stream (read it whole)");
  }
  layout.vertexCount = vertex.count;
  std::uint64_t offset = 0;
  for (const PlyProperty& property : vertex.properties) {
    layout.vertexProperties.push_back({property.name, property.type, offset});
    offset += detail::plyScalarSize(property.type);
  }
  layout.vertexRowBytes = offset;
}

/// The bytes `element` takes from file offset `offset`: computed for fixed rows, read through
/// for lists (faces checked as readPly() does, their count and largest polygon noted).
std::uint64_t elementBytes(const PlyElement& element, std::uint64_t offset, ElementReader& reader,
                           const std::string& name, PlyLayout& layout) {
  const bool isFace = element.name == "face";
  if (isFace) detail::plyFaceIndexList(element, name);
  if (element.properties.empty()) return 0;  // whatever its count
  if (!hasList(element)) {
    const std::uint64_t row = rowBytes(element);
    const std::uint64_t available = layout.fileBytes > offset ? layout.fileBytes - offset : 0;
    if (element.count > available / row) {
      throw IoError(name + ": " + element.name + " " + std::to_string(available / row) +
                    ": unexpected end of file");
    }
    return element.count * row;
  }
  reader.start(element, offset);
  if (isFace) {
    layout.faceCount = element.count;
    readFaces(reader, element, layout.vertexCount, name,
              [&](std::span<const std::uint32_t> polygon, std::span<const double>) {
                layout.largestPolygon =
                    std::max<std::uint64_t>(layout.largestPolygon, polygon.size());
              });
  } else {
    for (std::uint64_t i = 0; i < element.count; ++i) {
      reader.begin(i);
      for (const PlyProperty& property : element.properties) reader.skip(property);
    }
  }
  return reader.offset() - offset;
}

}  // namespace

PlyLayout plyLayout(const std::filesystem::path& path) {
  const std::string name = path.string();
  std::error_code error;
  if (std::filesystem::exists(path, error) && !std::filesystem::is_regular_file(path, error)) {
    throw InvalidInput(name +
                       ": cannot stream a pipe or other file that is not a regular file (it is "
                       "read twice); read it whole");
  }
  const PlyHeader header = headerOf(path);
  if (header.encoding == PlyEncoding::Ascii)
    throw IoError(name + ": an ASCII PLY file has no fixed rows to stream (read it whole)");
  PlyLayout layout;
  layout.path = path;
  layout.encoding = header.encoding;
  layout.notKept = detail::plyNotKept(header);
  {
    std::error_code error;
    layout.fileBytes = std::filesystem::file_size(path, error);
    if (error) throw IoError(name + ": " + error.message());
  }

  if (const PlyElement* vertex = findElement(header, "vertex"))
    layOutVertexRows(*vertex, name, layout);

  File file(openForReading(path));
  ElementReader reader(file.get(), name, header.encoding);
  std::uint64_t offset = header.dataOffset;
  for (const PlyElement& element : header.elements) {
    PlyElementLayout range{element.name, element.count, offset, 0};
    if (element.name == "vertex") layout.vertexOffset = offset;
    range.bytes = elementBytes(element, offset, reader, name, layout);
    offset += range.bytes;
    layout.elements.push_back(std::move(range));
  }
  if (layout.vertexCount == 0) throw IoError(name + ": no vertices (an empty soup or point cloud)");
  return layout;
}

// ---------------------------------------------------------------------------------------------
// Vertex rows

PlyVertexReader::PlyVertexReader(const PlyLayout& layout)
    : layout_(layout), file_(openForReading(layout.path)) {
  // Reads in large blocks whatever the chunk size (the default FILE buffer is 4 KiB).
  std::setvbuf(file_, nullptr, _IOFBF, kReadBlock * 4);
  const PlyHeader header = headerOf(layout.path);
  const PlyElement* vertex = findElement(header, "vertex");
  PointSet unused;
  const detail::PlyVertexLayout vl = detail::plyVertexLayout(*vertex, unused, layout.path.string());
  for (int c = 0; c < 3; ++c) {
    position_[c] = vl.position[c];
    if (vl.normal[c]) normal_[c] = static_cast<int>(*vl.normal[c]);
  }
  attributes_ = vl.attributeProperty;
}

PlyVertexReader::~PlyVertexReader() {
  if (file_) std::fclose(file_);
}

void PlyVertexReader::read(std::uint64_t first, std::size_t count, PointSet& rows) {
  const std::string name = layout_.path.string();
  if (first > layout_.vertexCount || count > layout_.vertexCount - first) {
    throw InvalidInput(name + ": vertex rows " + std::to_string(first) + " to " +
                       std::to_string(first + count) + " are past the " +
                       std::to_string(layout_.vertexCount) + " vertices");
  }
  const std::uint64_t row = layout_.vertexRowBytes;
  // Consecutive ranges need no seek, which would drop the FILE's read-ahead: small chunks then
  // cost a copy from it, not a system call each.
  const std::uint64_t offset = layout_.vertexOffset + first * row;
  if (offset != next_) seek(file_, offset, name);
  next_ = offset;

  const bool swap = detail::plySwapsBytes(layout_.encoding);
  const auto& properties = layout_.vertexProperties;
  const bool withNormals = normal_[0] >= 0;
  rows.positions.resize(count);
  rows.normals.resize(withNormals ? count : 0);
  rows.attributes.resize(attributes_.size());
  for (std::size_t a = 0; a < attributes_.size(); ++a) {
    rows.attributes[a].name = properties[attributes_[a]].name;
    rows.attributes[a].type = properties[attributes_[a]].type;
    rows.attributes[a].values.resize(count);
  }
  // The raw bytes a block at a time, so that a chunk of the whole file does not hold the file's
  // bytes besides its decoded rows.
  const std::size_t block = std::max<std::size_t>(1, kCodecBlockBytes / row);
  for (std::size_t begin = 0; begin < count; begin += block) {
    const std::size_t n = std::min(block, count - begin);
    buffer_.resize(n * row);
    const std::size_t got = readSome(file_, buffer_.data(), buffer_.size(), name);
    next_ += got;
    if (got < buffer_.size()) {
      throw IoError(name + ": vertex " + std::to_string(first + begin + got / row) +
                    ": unexpected end of file");
    }
    // Column by column, rows in parallel: the type switch stays out of the inner loop.
    const auto column = [&](std::size_t p, double* out, std::size_t stride) {
      decodeColumn(buffer_.data() + properties[p].offset, row, n, properties[p].type, swap,
                   out + begin * stride, stride);
    };
    for (int c = 0; c < 3; ++c) {
      column(position_[c], &rows.positions.data()->x + c, 3);
      if (withNormals) column(static_cast<std::size_t>(normal_[c]), &rows.normals.data()->x + c, 3);
    }
    for (std::size_t a = 0; a < attributes_.size(); ++a)
      column(attributes_[a], rows.attributes[a].values.data(), 1);
  }
  // readPly()'s checks, naming the first vertex at fault.
  for (std::size_t i = 0; i < count; ++i) {
    if (!isFinite(rows.positions[i]))
      throw IoError(name + ": vertex " + std::to_string(first + i) + ": non-finite coordinate");
    if (withNormals && !isFinite(rows.normals[i]))
      throw IoError(name + ": vertex " + std::to_string(first + i) + ": non-finite normal");
  }
}

// ---------------------------------------------------------------------------------------------
// Output

namespace {

/// The scalar face properties that readPly() keeps as face attributes.
std::vector<std::pair<std::string, ScalarType>> faceAttributes(const PlyElement& face,
                                                               const std::string& name) {
  const std::size_t list = detail::plyFaceIndexList(face, name);
  std::vector<std::pair<std::string, ScalarType>> attributes;
  for (std::size_t p = 0; p < face.properties.size(); ++p)
    if (p != list && !face.properties[p].isList)
      attributes.emplace_back(face.properties[p].name, face.properties[p].type);
  return attributes;
}

detail::PlyOutputHeader outputHeader(const PlyLayout& layout) {
  const std::string name = layout.path.string();
  const PlyHeader header = headerOf(layout.path);
  detail::PlyOutputHeader out;
  out.vertexCount = layout.vertexCount;
  PointSet attributes;
  const detail::PlyVertexLayout vl =
      detail::plyVertexLayout(*findElement(header, "vertex"), attributes, name);
  out.normals = vl.normal[0].has_value();
  for (const VertexAttribute& attribute : attributes.attributes)
    out.vertexAttributes.emplace_back(attribute.name, attribute.type);
  if (const PlyElement* face = findElement(header, "face")) {
    out.faceAttributes = faceAttributes(*face, name);
    // writePly()'s refusal of a face attribute that takes the index list's name.
    for (std::size_t a = 0; a < out.faceAttributes.size(); ++a) {
      const std::string& attribute = out.faceAttributes[a].first;
      if (attribute == "vertex_indices" || attribute == "vertex_index") {
        throw InvalidInput("face attribute " + std::to_string(a) + " '" + attribute +
                           "': the name is reserved for the face element");
      }
    }
  }
  out.faceCount = layout.faceCount;
  out.faceElement = layout.faceCount > 0 || !out.faceAttributes.empty();
  out.lengthType = detail::plyLengthType(layout.largestPolygon);
  out.indexType = detail::plyIndexType(layout.vertexCount);
  return out;
}

}  // namespace

std::uint64_t plyOutputRowBytes(const PlyLayout& layout) {
  const detail::PlyOutputHeader header = outputHeader(layout);
  std::uint64_t bytes = (header.normals ? 6 : 3) * sizeof(double);
  for (const auto& attribute : header.vertexAttributes)
    bytes += detail::plyScalarSize(attribute.second);
  return bytes;
}

PlyStreamWriter::PlyStreamWriter(const PlyLayout& layout, std::ostream& out, PlyEncoding encoding)
    : layout_(layout), out_(out), encoding_(encoding) {}

void PlyStreamWriter::header() {
  const std::string text = detail::plyHeaderText(outputHeader(layout_), encoding_);
  out_.write(text.data(), static_cast<std::streamsize>(text.size()));
}

void PlyStreamWriter::vertices(const PointSet& rows) {
  const bool withNormals = rows.hasNormals();
  if (encoding_ == PlyEncoding::BinaryLittleEndian && std::endian::native == std::endian::little) {
    // Column by column into one buffer: the bytes PlyValueWriter would give, far faster.
    std::size_t rowBytes = (withNormals ? 6 : 3) * sizeof(double);
    for (const VertexAttribute& attribute : rows.attributes)
      rowBytes += detail::plyScalarSize(attribute.type);
    const std::size_t total = rows.positions.size();
    // A block of rows at a time, so that the encoded bytes of a large chunk are not held whole.
    const std::size_t block = std::max<std::size_t>(1, kCodecBlockBytes / rowBytes);
    for (std::size_t begin = 0; begin < total; begin += block) {
      const std::size_t count = std::min(block, total - begin);
      buffer_.resize(count * rowBytes);
      std::size_t offset = 0;
      for (int c = 0; c < 3; ++c, offset += sizeof(double)) {
        encodeColumn(&rows.positions[begin].x + c, 3, count, ScalarType::Float64,
                     buffer_.data() + offset, rowBytes);
      }
      for (int c = 0; withNormals && c < 3; ++c, offset += sizeof(double)) {
        encodeColumn(&rows.normals[begin].x + c, 3, count, ScalarType::Float64,
                     buffer_.data() + offset, rowBytes);
      }
      for (const VertexAttribute& attribute : rows.attributes) {
        encodeColumn(attribute.values.data() + begin, 1, count, attribute.type,
                     buffer_.data() + offset, rowBytes);
        offset += detail::plyScalarSize(attribute.type);
      }
      out_.write(reinterpret_cast<const char*>(buffer_.data()),
                 static_cast<std::streamsize>(buffer_.size()));
    }
    return;
  }
  detail::PlyValueWriter output(out_, encoding_);
  const std::size_t values = 3 + (withNormals ? 3 : 0) + rows.attributes.size();
  for (std::size_t v = 0; v < rows.positions.size(); ++v) {
    // In ASCII, every value is followed by a space except the last of the line (writePly()).
    std::size_t remaining = values;
    const auto separator = [&remaining] { return --remaining == 0 ? '\n' : ' '; };
    for (int c = 0; c < 3; ++c)
      output.value(rows.positions[v][c], ScalarType::Float64, separator());
    if (withNormals) {
      for (int c = 0; c < 3; ++c)
        output.value(rows.normals[v][c], ScalarType::Float64, separator());
    }
    for (const VertexAttribute& attribute : rows.attributes)
      output.value(attribute.values[v], attribute.type, separator());
    output.drain();
  }
  output.drain(true);
}

void PlyStreamWriter::faces(const ProgressCallback& progress) {
  if (layout_.faceCount == 0) return;
  const std::string name = layout_.path.string();
  const PlyHeader header = headerOf(layout_.path);
  const PlyElement& face = *findElement(header, "face");
  const std::uint64_t offset =
      std::find_if(layout_.elements.begin(), layout_.elements.end(), [](const PlyElementLayout& e) {
        return e.name == "face";
      })->offset;
  const ScalarType lengthType = detail::plyLengthType(layout_.largestPolygon);
  const ScalarType indexType = detail::plyIndexType(layout_.vertexCount);
  const std::size_t attributeCount = faceAttributes(face, name).size();
  std::vector<ScalarType> attributeTypes;
  for (const auto& attribute : faceAttributes(face, name))
    attributeTypes.push_back(attribute.second);

  File file(openForReading(layout_.path));
  ElementReader reader(file.get(), name, layout_.encoding);
  reader.start(face, offset);
  detail::PlyValueWriter output(out_, encoding_);
  ProgressTracker tracker(progress, "write faces", face.count);
  std::uint64_t done = 0;
  readFaces(reader, face, layout_.vertexCount, name,
            [&](std::span<const std::uint32_t> polygon, std::span<const double> attributes) {
              output.value(static_cast<double>(polygon.size()), lengthType, ' ');
              const bool last = attributeCount == 0;
              for (std::size_t k = 0; k < polygon.size(); ++k)
                output.value(polygon[k], indexType, last && k + 1 == polygon.size() ? '\n' : ' ');
              for (std::size_t a = 0; a < attributeCount; ++a)
                output.value(attributes[a], attributeTypes[a],
                             a + 1 == attributeCount ? '\n' : ' ');
              output.drain();
              if (++done % (1u << 16) == 0) tracker.advance(1u << 16);
            });
  output.drain(true);
  tracker.finish();
}

bool sameFile(const std::filesystem::path& a, const std::filesystem::path& b) {
  std::error_code error;
  // An error (one of them missing) means they are not the same existing file.
  return std::filesystem::equivalent(a, b, error) && !error;
}

void assemblePly(const std::filesystem::path& input,
                 const std::vector<std::filesystem::path>& parts,
                 const std::filesystem::path& output) {
  const PlyLayout layout = plyLayout(input);
  const std::uint64_t row = plyOutputRowBytes(layout);
  std::uint64_t rows = 0;
  for (const std::filesystem::path& part : parts) {
    if (sameFile(part, input))
      throw InvalidInput(part.string() + ": a part is the input " + input.string());
    std::error_code error;
    const std::uint64_t bytes = std::filesystem::file_size(part, error);
    if (error) throw IoError(part.string() + ": " + error.message());
    if (bytes % row != 0) {
      throw InvalidInput(part.string() + ": " + std::to_string(bytes) +
                         " bytes is not a whole number of output vertex rows of " + input.string() +
                         " (" + std::to_string(row) + " bytes each)");
    }
    rows += bytes / row;
  }
  if (rows != layout.vertexCount) {
    throw InvalidInput("the parts (" + std::to_string(parts.size()) + ") hold " +
                       std::to_string(rows) + " vertex rows, " + input.string() + " has " +
                       std::to_string(layout.vertexCount));
  }
  writeFileAtomically(output, [&](std::ostream& out) {
    PlyStreamWriter writer(layout, out, PlyEncoding::BinaryLittleEndian);
    writer.header();
    std::vector<char> buffer(kReadBlock);
    for (const std::filesystem::path& part : parts) {
      File file(openForReading(part));
      for (;;) {
        const std::size_t got = readSome(file.get(), buffer.data(), buffer.size(), part.string());
        if (got == 0) break;
        out.write(buffer.data(), static_cast<std::streamsize>(got));
      }
    }
    writer.faces();
  });
}

}  // namespace spacewarp
