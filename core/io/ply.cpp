#include <spacewarp/core/io/ply.h>

#include <algorithm>
#include <bit>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <initializer_list>
#include <limits>
#include <optional>
#include <string>
#include <string_view>
#include <system_error>
#include <vector>

#include <spacewarp/core/errors.h>
#include <spacewarp/core/io/detail/ply_format.h>
#include <spacewarp/core/io/detail/text_format.h>

namespace spacewarp {
namespace {

// ---------------------------------------------------------------------------------------------
// Scalar types

constexpr std::size_t kMaxHeaderLine = 1 << 16;

std::size_t scalarSize(ScalarType type) {
  switch (type) {
    case ScalarType::Int8:
    case ScalarType::UInt8:
      return 1;
    case ScalarType::Int16:
    case ScalarType::UInt16:
      return 2;
    case ScalarType::Int32:
    case ScalarType::UInt32:
    case ScalarType::Float32:
      return 4;
    case ScalarType::Float64:
      return 8;
  }
  return 8;
}

bool isIntegral(ScalarType type) {
  return type != ScalarType::Float32 && type != ScalarType::Float64;
}

/// The classic PLY name of a type (the one written).
const char* typeName(ScalarType type) {
  switch (type) {
    case ScalarType::Int8:
      return "char";
    case ScalarType::UInt8:
      return "uchar";
    case ScalarType::Int16:
      return "short";
    case ScalarType::UInt16:
      return "ushort";
    case ScalarType::Int32:
      return "int";
    case ScalarType::UInt32:
      return "uint";
    case ScalarType::Float32:
      return "float";
    case ScalarType::Float64:
      return "double";
  }
  return "double";
}

std::optional<ScalarType> parseTypeName(std::string_view name) {
  struct Entry {
    std::string_view name;
    ScalarType type;
  };
  static constexpr Entry kTypes[] = {
      {"char", ScalarType::Int8},      {"int8", ScalarType::Int8},
      {"uchar", ScalarType::UInt8},    {"uint8", ScalarType::UInt8},
      {"short", ScalarType::Int16},    {"int16", ScalarType::Int16},
      {"ushort", ScalarType::UInt16},  {"uint16", ScalarType::UInt16},
      {"int", ScalarType::Int32},      {"int32", ScalarType::Int32},
      {"uint", ScalarType::UInt32},    {"uint32", ScalarType::UInt32},
      {"float", ScalarType::Float32},  {"float32", ScalarType::Float32},
      {"double", ScalarType::Float64}, {"float64", ScalarType::Float64},
  };
  for (const Entry& entry : kTypes)
    if (entry.name == name) return entry.type;
  return std::nullopt;
}

/// The range of an integer type.
void integerRange(ScalarType type, double& low, double& high) {
  switch (type) {
    case ScalarType::Int8:
      low = -128.0, high = 127.0;
      return;
    case ScalarType::UInt8:
      low = 0.0, high = 255.0;
      return;
    case ScalarType::Int16:
      low = -32768.0, high = 32767.0;
      return;
    case ScalarType::UInt16:
      low = 0.0, high = 65535.0;
      return;
    case ScalarType::Int32:
      low = -2147483648.0, high = 2147483647.0;
      return;
    case ScalarType::UInt32:
      low = 0.0, high = 4294967295.0;
      return;
    case ScalarType::Float32:
    case ScalarType::Float64:
      break;
  }
  low = -std::numeric_limits<double>::infinity();
  high = std::numeric_limits<double>::infinity();
}

/// Why a double cannot be stored in a type, or nullptr if it can (exactly for integer types,
/// rounded for Float32).
const char* unrepresentable(double value, ScalarType type) {
  if (isIntegral(type)) {
    double low = 0.0;
    double high = 0.0;
    integerRange(type, low, high);
    if (!(value >= low && value <= high)) return "is out of range";
    if (std::trunc(value) != value) return "is not an integer";
    return nullptr;
  }
  if (type == ScalarType::Float32 && std::isfinite(value) &&
      std::abs(value) > static_cast<double>(std::numeric_limits<float>::max())) {
    return "is out of range";
  }
  return nullptr;
}

/// Decodes one binary value of `type` from `bytes` (already in host byte order).
double decode(const unsigned char* bytes, ScalarType type) {
  switch (type) {
    case ScalarType::Int8: {
      std::int8_t v;
      std::memcpy(&v, bytes, sizeof v);
      return v;
    }
    case ScalarType::UInt8:
      return bytes[0];
    case ScalarType::Int16: {
      std::int16_t v;
      std::memcpy(&v, bytes, sizeof v);
      return v;
    }
    case ScalarType::UInt16: {
      std::uint16_t v;
      std::memcpy(&v, bytes, sizeof v);
      return v;
    }
    case ScalarType::Int32: {
      std::int32_t v;
      std::memcpy(&v, bytes, sizeof v);
      return v;
    }
    case ScalarType::UInt32: {
      std::uint32_t v;
      std::memcpy(&v, bytes, sizeof v);
      return v;
    }
    case ScalarType::Float32: {
      float v;
      std::memcpy(&v, bytes, sizeof v);
      return static_cast<double>(v);
    }
    case ScalarType::Float64: {
      double v;
      std::memcpy(&v, bytes, sizeof v);
      return v;
    }
  }
  return 0.0;
}

/// Encodes `value` (representable in `type`, see unrepresentable()) in host byte order.
void encode(double value, ScalarType type, unsigned char* bytes) {
  switch (type) {
    case ScalarType::Int8: {
      const auto v = static_cast<std::int8_t>(value);
      std::memcpy(bytes, &v, sizeof v);
      return;
    }
    case ScalarType::UInt8: {
      const auto v = static_cast<std::uint8_t>(value);
      std::memcpy(bytes, &v, sizeof v);
      return;
    }
    case ScalarType::Int16: {
      const auto v = static_cast<std::int16_t>(value);
      std::memcpy(bytes, &v, sizeof v);
      return;
    }
    case ScalarType::UInt16: {
      const auto v = static_cast<std::uint16_t>(value);
      std::memcpy(bytes, &v, sizeof v);
      return;
    }
    case ScalarType::Int32: {
      const auto v = static_cast<std::int32_t>(value);
      std::memcpy(bytes, &v, sizeof v);
      return;
    }
    case ScalarType::UInt32: {
      const auto v = static_cast<std::uint32_t>(value);
      std::memcpy(bytes, &v, sizeof v);
      return;
    }
    case ScalarType::Float32: {
      const auto v = static_cast<float>(value);
      std::memcpy(bytes, &v, sizeof v);
      return;
    }
    case ScalarType::Float64:
      std::memcpy(bytes, &value, sizeof value);
      return;
  }
}

// ---------------------------------------------------------------------------------------------
// Text

void tokenize(std::string_view line, std::vector<std::string_view>& tokens) {
  tokens.clear();
  std::size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && detail::isSpace(line[i])) ++i;
    if (i == line.size()) break;
    const std::size_t start = i;
    while (i < line.size() && !detail::isSpace(line[i])) ++i;
    tokens.push_back(line.substr(start, i - start));
  }
}

/// A token shortened and escaped for messages.
std::string quote(std::string_view token) { return detail::quotedToken(token); }

/// Parses a whole token as a value of `type`: integers for integer types (an integral decimal
/// like "3.0" is accepted too), correctly rounded floats for Float32 and doubles for Float64
/// (overflow gives +-infinity there). Returns nullptr on success or the reason for failure.
const char* parseValue(std::string_view token, ScalarType type, double& value) {
  using detail::NumberStatus;
  if (isIntegral(type)) {
    std::int64_t integer = 0;
    if (detail::parseInteger(token, integer)) {
      value = static_cast<double>(integer);
    } else {
      const NumberStatus status = detail::parseDouble(token, value);
      if (status == NumberStatus::NotANumber) return "is not a number";
      if (status != NumberStatus::Ok) return "is out of range";
    }
    return unrepresentable(value, type);
  }
  if (type == ScalarType::Float32) {
    float single = 0.0f;
    if (detail::parseFloat(token, single) == NumberStatus::NotANumber) return "is not a number";
    value = static_cast<double>(single);
    return nullptr;
  }
  if (detail::parseDouble(token, value) == NumberStatus::NotANumber) return "is not a number";
  return nullptr;
}

// ---------------------------------------------------------------------------------------------
// Buffered input

/// Reads the stream in blocks: lines for the header and ASCII data, bytes for binary data.
/// Knows how many bytes remain when the stream is seekable, to bound reservations.
class Input {
 public:
  Input(std::istream& in, const std::string& name) : in_(in), name_(name), buffer_(1 << 16) {
    const std::streampos start = in_.tellg();
    if (start == std::streampos(-1)) {
      in_.clear(in_.rdstate() & ~std::ios::failbit);
      return;
    }
    in_.seekg(0, std::ios::end);
    const std::streampos end = in_.tellg();
    in_.clear(in_.rdstate() & ~(std::ios::failbit | std::ios::eofbit));
    in_.seekg(start);
    if (in_ && end != std::streampos(-1) && end >= start)
      streamRemaining_ = static_cast<std::uint64_t>(end - start);
    in_.clear(in_.rdstate() & ~std::ios::failbit);
  }

  /// Bytes left (buffered and in the stream) if known.
  std::optional<std::uint64_t> remaining() const {
    if (!streamRemaining_) return std::nullopt;
    return *streamRemaining_ + (end_ - pos_);
  }

  /// Reads the next line without its "\n" or "\r\n"; false at the end of the input. Throws
  /// IoError when the line holds a NUL byte (binary content where text belongs, checked as the
  /// bytes arrive) or is longer than `maxLength`.
  bool readLine(std::string& line, std::size_t maxLength) {
    line.clear();
    bool any = false;
    for (;;) {
      if (pos_ == end_ && !refill()) break;
      any = true;
      const char* begin = buffer_.data() + pos_;
      const auto* newline = static_cast<const char*>(std::memchr(begin, '\n', end_ - pos_));
      const std::size_t length = newline ? static_cast<std::size_t>(newline - begin) : end_ - pos_;
      detail::checkNoNul(std::string_view(begin, length), name_, line_ + 1, bufferOffset_ + pos_);
      if (line.size() + length > maxLength) {
        detail::failAt(name_, line_ + 1,
                       "line too long (more than " + std::to_string(maxLength) + " bytes)");
      }
      line.append(begin, length);
      pos_ += length;
      if (newline) {
        ++pos_;
        break;
      }
    }
    if (!any) return false;
    ++line_;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    return true;
  }

  /// Reads n bytes; false when the input ends first.
  bool readBytes(unsigned char* out, std::size_t n) {
    if (end_ - pos_ >= n) {
      std::memcpy(out, buffer_.data() + pos_, n);
      pos_ += n;
      return true;
    }
    while (n > 0) {
      if (pos_ == end_ && !refill()) return false;
      const std::size_t take = std::min(n, end_ - pos_);
      std::memcpy(out, buffer_.data() + pos_, take);
      pos_ += take;
      out += take;
      n -= take;
    }
    return true;
  }

  /// The number of the last line read.
  std::size_t line() const { return line_; }

  /// Bytes consumed from the start of the input.
  std::uint64_t offset() const { return bufferOffset_ + pos_; }

 private:
  bool refill() {
    if (eof_) return false;
    bufferOffset_ += end_;
    in_.read(buffer_.data(), static_cast<std::streamsize>(buffer_.size()));
    if (in_.bad()) throw IoError(name_ + ": read error");
    const auto count = static_cast<std::size_t>(in_.gcount());
    if (count < buffer_.size()) eof_ = true;
    pos_ = 0;
    end_ = count;
    if (streamRemaining_) *streamRemaining_ -= std::min<std::uint64_t>(*streamRemaining_, count);
    return count > 0;
  }

  std::istream& in_;
  const std::string& name_;
  std::vector<char> buffer_;
  std::size_t pos_ = 0;
  std::size_t end_ = 0;
  std::uint64_t bufferOffset_ = 0;  ///< Input offset of buffer_[0].
  bool eof_ = false;
  std::size_t line_ = 0;
  std::optional<std::uint64_t> streamRemaining_;
};

// ---------------------------------------------------------------------------------------------
// Header

using Property = detail::PlyProperty;
using Element = detail::PlyElement;
using Header = detail::PlyHeader;

Header parseHeader(Input& input, const std::string& name) {
  std::string line;
  std::vector<std::string_view> tokens;
  const auto fail = [&](const std::string& message) {
    detail::failAt(name, input.line(), message);
  };
  if (!input.readLine(line, kMaxHeaderLine)) throw IoError(name + ": empty file, not a PLY file");
  tokenize(line, tokens);
  if (tokens.size() != 1 || tokens[0] != "ply") fail("not a PLY file (no 'ply' magic)");

  Header header;
  bool haveFormat = false;
  for (;;) {
    if (!input.readLine(line, kMaxHeaderLine))
      fail("unexpected end of file in the header (no end_header)");
    tokenize(line, tokens);
    if (tokens.empty()) continue;
    const std::string_view keyword = tokens[0];
    if (keyword == "comment" || keyword == "obj_info") continue;
    if (keyword == "end_header") {
      if (!haveFormat) fail("end_header before any format line");
      break;
    }
    if (keyword == "format") {
      if (haveFormat) fail("a second format line");
      if (tokens.size() != 3) fail("expected 'format <encoding> <version>'");
      if (tokens[1] == "ascii")
        header.encoding = PlyEncoding::Ascii;
      else if (tokens[1] == "binary_little_endian")
        header.encoding = PlyEncoding::BinaryLittleEndian;
      else if (tokens[1] == "binary_big_endian")
        header.encoding = PlyEncoding::BinaryBigEndian;
      else
        fail("unknown format " + quote(tokens[1]));
      // PLY has one version; a file that claims another may mean anything by its header.
      if (tokens[2] != "1.0" && tokens[2] != "1")
        fail("unsupported PLY version " + quote(tokens[2]) + " (only 1.0 exists)");
      haveFormat = true;
    } else if (keyword == "element") {
      if (tokens.size() != 3) fail("expected 'element <name> <count>'");
      Element element;
      element.name = std::string(tokens[1]);
      element.line = input.line();
      const char* end = tokens[2].data() + tokens[2].size();
      const auto [ptr, ec] = std::from_chars(tokens[2].data(), end, element.count);
      if (ec != std::errc() || ptr != end) fail("bad element count " + quote(tokens[2]));
      for (const Element& other : header.elements)
        if (other.name == element.name) fail("a second element " + quote(element.name));
      header.elements.push_back(std::move(element));
    } else if (keyword == "property") {
      if (header.elements.empty()) fail("property before any element");
      Property property;
      if (tokens.size() >= 2 && tokens[1] == "list") {
        if (tokens.size() != 5) fail("expected 'property list <count type> <item type> <name>'");
        const auto countType = parseTypeName(tokens[2]);
        const auto itemType = parseTypeName(tokens[3]);
        if (!countType) fail("unknown property type " + quote(tokens[2]));
        if (!itemType) fail("unknown property type " + quote(tokens[3]));
        if (!isIntegral(*countType))
          fail("list count type " + quote(tokens[2]) + " is not integral");
        property.isList = true;
        property.countType = *countType;
        property.type = *itemType;
        property.name = std::string(tokens[4]);
      } else {
        if (tokens.size() != 3) fail("expected 'property <type> <name>'");
        const auto type = parseTypeName(tokens[1]);
        if (!type) fail("unknown property type " + quote(tokens[1]));
        property.type = *type;
        property.name = std::string(tokens[2]);
      }
      Element& element = header.elements.back();
      if (element.find(property.name))
        fail("a second property " + quote(property.name) + " in element " + quote(element.name));
      element.properties.push_back(std::move(property));
    } else {
      fail("unknown header keyword " + quote(keyword));
    }
  }
  return header;
}

// ---------------------------------------------------------------------------------------------
// Data

/// Reads the values of element instances in either encoding and throws IoError messages that
/// name the element and instance.
class ValueReader : public detail::PlyValueSource<ValueReader> {
 public:
  ValueReader(Input& input, const std::string& name, PlyEncoding encoding)
      : PlyValueSource(encoding), input_(input), name_(name), encoding_(encoding) {}

  bool ascii() const { return encoding_ == PlyEncoding::Ascii; }

  /// Starts instance `index` of `element` (for ASCII: reads its line).
  void begin(const Element& element, std::uint64_t index) {
    element_ = &element;
    index_ = index;
    if (!ascii()) return;
    do {
      if (!input_.readLine(line_, detail::kMaxTextLine)) fail("unexpected end of file");
      tokenize(line_, tokens_);
    } while (tokens_.empty());
    next_ = 0;
  }

  /// Ends the instance (for ASCII: checks that the line has no more values).
  void end() {
    if (ascii() && next_ < tokens_.size()) {
      fail("too many values on the line (" + std::to_string(tokens_.size()) + ", " +
           std::to_string(next_) + " expected)");
    }
  }

  double scalar(ScalarType type) {
    double value = 0.0;
    if (ascii()) {
      if (next_ == tokens_.size())
        fail("too few values on the line (" + std::to_string(tokens_.size()) + ")");
      const std::string_view token = tokens_[next_++];
      if (const char* problem = parseValue(token, type, value))
        fail("value " + quote(token) + " " + problem + " for type " + typeName(type));
      return value;
    }
    return binaryScalar(type);
  }

  void readBytes(unsigned char* out, std::size_t n) {
    if (!input_.readBytes(out, n)) fail("unexpected end of file");
  }

  void skipItems(ScalarType type, std::uint64_t count) {
    for (std::uint64_t i = 0; i < count; ++i) scalar(type);
  }

  [[noreturn]] void fail(const std::string& message) const {
    std::string where = name_;
    if (ascii()) where += ":" + std::to_string(input_.line());
    throw IoError(where + ": " + element_->name + " " + std::to_string(index_) + ": " + message);
  }

 private:
  Input& input_;
  const std::string& name_;
  PlyEncoding encoding_;
  const Element* element_ = nullptr;
  std::uint64_t index_ = 0;
  std::string line_;
  std::vector<std::string_view> tokens_;
  std::size_t next_ = 0;
};

/// The fewest bytes one instance of `element` can take in the file.
std::uint64_t minimumInstanceBytes(const Element& element, PlyEncoding encoding) {
  std::uint64_t bytes = 0;
  for (const Property& property : element.properties) {
    if (encoding == PlyEncoding::Ascii)
      bytes += 2;  // A digit and a separator.
    else
      bytes += scalarSize(property.isList ? property.countType : property.type);
  }
  return std::max<std::uint64_t>(bytes, 1);
}

/// How many instances to reserve room for: never more than the rest of the input could hold.
std::size_t reservation(const Element& element, PlyEncoding encoding, const Input& input) {
  const std::uint64_t bound = input.remaining()
                                  ? *input.remaining() / minimumInstanceBytes(element, encoding) + 1
                                  : std::uint64_t{1} << 12;
  return static_cast<std::size_t>(std::min(element.count, bound));
}

using VertexLayout = detail::PlyVertexLayout;

VertexLayout vertexLayout(const Element& vertex, PointSet& soup, const std::string& name) {
  const auto fail = [&](const std::string& message) { detail::failAt(name, vertex.line, message); };
  VertexLayout layout;
  const char* axes[3] = {"x", "y", "z"};
  const char* normalAxes[3] = {"nx", "ny", "nz"};
  int normalCount = 0;
  for (int c = 0; c < 3; ++c) {
    const auto p = vertex.find(axes[c]);
    if (!p) fail(std::string("the vertex element has no '") + axes[c] + "' property");
    if (vertex.properties[*p].isList)
      fail(std::string("vertex property '") + axes[c] + "' is a list");
    layout.position[c] = *p;
    layout.normal[c] = vertex.find(normalAxes[c]);
    if (layout.normal[c]) {
      ++normalCount;
      if (vertex.properties[*layout.normal[c]].isList)
        fail(std::string("vertex property '") + normalAxes[c] + "' is a list");
    }
  }
  if (normalCount != 0 && normalCount != 3)
    fail("the vertex element has some but not all of nx, ny, nz");
  for (std::size_t p = 0; p < vertex.properties.size(); ++p) {
    const Property& property = vertex.properties[p];
    if (property.isList) continue;
    bool used = false;
    for (int c = 0; c < 3; ++c) used = used || p == layout.position[c] || layout.normal[c] == p;
    if (used) continue;
    layout.attributeProperty.push_back(p);
    soup.attributes.push_back({property.name, property.type, {}});
  }
  return layout;
}

void readVertices(const Element& vertex, ValueReader& reader, const Input& input,
                  PlyEncoding encoding, PolygonSoup& soup, const std::string& name) {
  const VertexLayout layout = vertexLayout(vertex, soup, name);
  const bool withNormals = layout.normal[0].has_value();
  const std::size_t reserve = reservation(vertex, encoding, input);
  soup.positions.reserve(reserve);
  if (withNormals) soup.normals.reserve(reserve);
  for (VertexAttribute& attribute : soup.attributes) attribute.values.reserve(reserve);

  std::vector<double> values(vertex.properties.size(), 0.0);
  for (std::uint64_t i = 0; i < vertex.count; ++i) {
    reader.begin(vertex, i);
    for (std::size_t p = 0; p < vertex.properties.size(); ++p) {
      const Property& property = vertex.properties[p];
      if (property.isList)
        reader.skip(property);
      else
        values[p] = reader.scalar(property.type);
    }
    reader.end();
    const Vec3 position(values[layout.position[0]], values[layout.position[1]],
                        values[layout.position[2]]);
    if (!isFinite(position)) reader.fail("non-finite coordinate");
    soup.positions.push_back(position);
    if (withNormals) {
      const Vec3 normal(values[*layout.normal[0]], values[*layout.normal[1]],
                        values[*layout.normal[2]]);
      if (!isFinite(normal)) reader.fail("non-finite normal");
      soup.normals.push_back(normal);
    }
    for (std::size_t a = 0; a < layout.attributeProperty.size(); ++a)
      soup.attributes[a].values.push_back(values[layout.attributeProperty[a]]);
  }
}

void readFaces(const Element& face, std::uint64_t vertexCount, ValueReader& reader,
               const Input& input, PlyEncoding encoding, PolygonSoup& soup,
               const std::string& name) {
  const std::optional<std::size_t> list = detail::plyFaceIndexList(face, name);
  const Property& indices = face.properties[*list];

  // Every other scalar property is kept; the attribute of property p is attributeOf[p].
  constexpr std::size_t kDropped = std::numeric_limits<std::size_t>::max();
  std::vector<std::size_t> attributeOf(face.properties.size(), kDropped);
  for (std::size_t p = 0; p < face.properties.size(); ++p) {
    const Property& property = face.properties[p];
    if (p == *list || property.isList) continue;
    attributeOf[p] = soup.faceAttributes.size();
    soup.faceAttributes.push_back({property.name, property.type, {}});
  }
  const std::size_t reserve = reservation(face, encoding, input);
  soup.faceOffsets.reserve(reserve + 1);
  for (ScalarAttribute& attribute : soup.faceAttributes) attribute.values.reserve(reserve);
  std::vector<std::uint32_t> polygon;
  for (std::uint64_t f = 0; f < face.count; ++f) {
    reader.begin(face, f);
    for (std::size_t p = 0; p < face.properties.size(); ++p) {
      if (attributeOf[p] != kDropped) {
        soup.faceAttributes[attributeOf[p]].values.push_back(
            reader.scalar(face.properties[p].type));
        continue;
      }
      if (p != *list) {
        reader.skip(face.properties[p]);
        continue;
      }
      reader.readPolygon(indices, vertexCount, polygon);
    }
    reader.end();
    if (soup.faceIndices.size() + polygon.size() > std::numeric_limits<std::uint32_t>::max())
      reader.fail("too many face indices for 32-bit offsets");
    soup.addPolygon(polygon);
  }
}

/// What the elements of `header` hold that a soup does not keep (PolygonSoup::notKept): list
/// properties other than the face index list, elements other than vertex and face.
std::vector<std::string> notKept(const Header& header) {
  std::vector<std::string> lost;
  for (const Element& element : header.elements) {
    if (element.count == 0) continue;
    if (element.name != "vertex" && element.name != "face") {
      lost.push_back("element " + detail::quotedToken(element.name));
      continue;
    }
    for (const Property& property : element.properties) {
      const bool indexList = element.name == "face" &&
                             (property.name == "vertex_indices" ||
                              (property.name == "vertex_index" && !element.find("vertex_indices")));
      if (property.isList && !indexList)
        lost.push_back(element.name + " list property " + detail::quotedToken(property.name));
    }
  }
  return lost;
}

PolygonSoup readPlyImpl(std::istream& in, const std::string& name) {
  Input input(in, name);
  const Header header = parseHeader(input, name);

  std::uint64_t vertexCount = 0;
  for (const Element& element : header.elements) {
    if (element.name == "vertex") {
      vertexCount = element.count;
      if (vertexCount > std::numeric_limits<std::uint32_t>::max())
        detail::failAt(name, element.line, "too many vertices for 32-bit indices");
    }
  }

  PolygonSoup soup;
  soup.notKept = notKept(header);
  ValueReader reader(input, name, header.encoding);
  for (const Element& element : header.elements) {
    if (element.name == "vertex") {
      readVertices(element, reader, input, header.encoding, soup, name);
    } else if (element.name == "face") {
      readFaces(element, vertexCount, reader, input, header.encoding, soup, name);
    } else if (!element.properties.empty()) {  // Nothing to read for an element without properties.
      for (std::uint64_t i = 0; i < element.count; ++i) {
        reader.begin(element, i);
        for (const Property& property : element.properties) reader.skip(property);
        reader.end();
      }
    }
  }

  if (header.encoding == PlyEncoding::Ascii) {
    std::string line;
    std::vector<std::string_view> tokens;
    while (input.readLine(line, detail::kMaxTextLine)) {
      tokenize(line, tokens);
      if (!tokens.empty())
        detail::failAt(name, input.line(), "unexpected data after the last element");
    }
  }
  return soup;
}

// ---------------------------------------------------------------------------------------------
// Writing

using Output = detail::PlyValueWriter;

/// Throws InvalidInput unless `attributes` can be written as the scalar properties of
/// `element` next to the properties named in `reserved`.
void checkAttributes(const std::vector<ScalarAttribute>& attributes, const std::string& element,
                     std::initializer_list<const char*> reserved) {
  const char* index = element == "vertex" ? "vertex " : "face ";
  for (std::size_t a = 0; a < attributes.size(); ++a) {
    const ScalarAttribute& attribute = attributes[a];
    const std::string label =
        element + " attribute " + std::to_string(a) + " '" + attribute.name + "'";
    if (attribute.name.empty())
      throw InvalidInput(element + " attribute " + std::to_string(a) + " has no name");
    for (char c : attribute.name) {
      if (detail::isSpace(c))
        throw InvalidInput(label + ": a PLY property name cannot contain white space");
    }
    for (const char* name : reserved) {
      if (attribute.name == name)
        throw InvalidInput(label + ": the name is reserved for the " + element + " element");
    }
    for (std::size_t b = 0; b < a; ++b) {
      if (attributes[b].name == attribute.name)
        throw InvalidInput(label + ": the name is used twice");
    }
    for (std::size_t v = 0; v < attribute.values.size(); ++v) {
      if (const char* problem = unrepresentable(attribute.values[v], attribute.type)) {
        throw InvalidInput(label + ": " + index + std::to_string(v) + ": value " +
                           std::to_string(attribute.values[v]) + " " + problem + " for type " +
                           typeName(attribute.type));
      }
    }
  }
}

}  // namespace

PolygonSoup readPly(std::istream& in, const std::string& name) {
  try {
    return readPlyImpl(in, name);
  } catch (...) {
    detail::rethrowAsIoError(name);
  }
}

void writePly(const PolygonSoup& soup, std::ostream& out, PlyEncoding encoding) {
  soup.validate();
  checkAttributes(soup.attributes, "vertex", {"x", "y", "z", "nx", "ny", "nz"});
  checkAttributes(soup.faceAttributes, "face", {"vertex_indices", "vertex_index"});
  const bool withNormals = soup.hasNormals();
  std::size_t largestPolygon = 0;
  for (std::size_t p = 0; p < soup.polygonCount(); ++p)
    largestPolygon = std::max(largestPolygon, soup.polygon(p).size());
  detail::PlyOutputHeader header;
  header.vertexCount = soup.positions.size();
  header.normals = withNormals;
  for (const VertexAttribute& attribute : soup.attributes)
    header.vertexAttributes.emplace_back(attribute.name, attribute.type);
  // Face attributes of a soup without polygons are kept as an empty face element's properties.
  header.faceElement = soup.polygonCount() > 0 || !soup.faceAttributes.empty();
  header.faceCount = soup.polygonCount();
  header.lengthType = detail::plyLengthType(largestPolygon);
  header.indexType = detail::plyIndexType(soup.positions.size());
  for (const ScalarAttribute& attribute : soup.faceAttributes)
    header.faceAttributes.emplace_back(attribute.name, attribute.type);
  const ScalarType lengthType = header.lengthType;
  const ScalarType indexType = header.indexType;

  Output output(out, encoding);
  output.text(detail::plyHeaderText(header, encoding));

  for (std::size_t v = 0; v < soup.positions.size(); ++v) {
    // In ASCII, every value is followed by a space except the last of the line.
    std::size_t remaining = 3 + (withNormals ? 3 : 0) + soup.attributes.size();
    const auto separator = [&remaining] { return --remaining == 0 ? '\n' : ' '; };
    for (int c = 0; c < 3; ++c)
      output.value(soup.positions[v][c], ScalarType::Float64, separator());
    if (withNormals) {
      for (int c = 0; c < 3; ++c)
        output.value(soup.normals[v][c], ScalarType::Float64, separator());
    }
    for (const VertexAttribute& attribute : soup.attributes)
      output.value(attribute.values[v], attribute.type, separator());
    output.drain();
  }
  for (std::size_t p = 0; p < soup.polygonCount(); ++p) {
    const auto polygon = soup.polygon(p);
    output.value(static_cast<double>(polygon.size()), lengthType, ' ');
    const bool last = soup.faceAttributes.empty();
    for (std::size_t k = 0; k < polygon.size(); ++k)
      output.value(polygon[k], indexType, last && k + 1 == polygon.size() ? '\n' : ' ');
    for (std::size_t a = 0; a < soup.faceAttributes.size(); ++a) {
      const ScalarAttribute& attribute = soup.faceAttributes[a];
      output.value(attribute.values[p], attribute.type,
                   a + 1 == soup.faceAttributes.size() ? '\n' : ' ');
    }
    output.drain();
  }
  output.drain(true);
}

// ---------------------------------------------------------------------------------------------
// Shared with the streaming reader and writer (core/io/detail/ply_format.h)

namespace detail {

std::size_t plyScalarSize(ScalarType type) { return scalarSize(type); }
const char* plyTypeName(ScalarType type) { return typeName(type); }
bool plyIsIntegral(ScalarType type) { return isIntegral(type); }
double plyDecode(const unsigned char* bytes, ScalarType type) { return decode(bytes, type); }
bool plySwapsBytes(PlyEncoding encoding) {
  return (encoding == PlyEncoding::BinaryBigEndian) != (std::endian::native == std::endian::big);
}

PlyHeader readPlyHeader(std::istream& in, const std::string& name) {
  try {
    Input input(in, name);
    PlyHeader header = parseHeader(input, name);
    header.dataOffset = input.offset();
    return header;
  } catch (...) {
    rethrowAsIoError(name);
  }
}

std::vector<std::string> plyNotKept(const PlyHeader& header) { return notKept(header); }

PlyVertexLayout plyVertexLayout(const PlyElement& vertex, PointSet& points,
                                const std::string& name) {
  return vertexLayout(vertex, points, name);
}

std::size_t plyFaceIndexList(const PlyElement& face, const std::string& name) {
  std::optional<std::size_t> list = face.find("vertex_indices");
  if (!list) list = face.find("vertex_index");
  const auto fail = [&](const std::string& message) { failAt(name, face.line, message); };
  if (!list) fail("the face element has no 'vertex_indices' list");
  const PlyProperty& indices = face.properties[*list];
  if (!indices.isList) fail("face property '" + indices.name + "' is not a list");
  if (!isIntegral(indices.type)) fail("face property '" + indices.name + "' is not integral");
  return *list;
}

ScalarType plyLengthType(std::uint64_t largestPolygon) {
  return largestPolygon > 255 ? ScalarType::UInt32 : ScalarType::UInt8;
}

ScalarType plyIndexType(std::uint64_t vertexCount) {
  return vertexCount > static_cast<std::uint64_t>(std::numeric_limits<std::int32_t>::max())
             ? ScalarType::UInt32
             : ScalarType::Int32;
}

std::string plyHeaderText(const PlyOutputHeader& header, PlyEncoding encoding) {
  std::string text = "ply\nformat ";
  text += encoding == PlyEncoding::Ascii                ? "ascii"
          : encoding == PlyEncoding::BinaryLittleEndian ? "binary_little_endian"
                                                        : "binary_big_endian";
  text += " 1.0\ncomment written by spacewarp\nelement vertex ";
  text += std::to_string(header.vertexCount);
  text += "\nproperty double x\nproperty double y\nproperty double z\n";
  if (header.normals) text += "property double nx\nproperty double ny\nproperty double nz\n";
  const auto declare = [&](const std::pair<std::string, ScalarType>& attribute) {
    text += "property ";
    text += typeName(attribute.second);
    text += " ";
    text += attribute.first;
    text += "\n";
  };
  for (const auto& attribute : header.vertexAttributes) declare(attribute);
  if (header.faceElement) {
    text += "element face ";
    text += std::to_string(header.faceCount);
    text += "\nproperty list ";
    text += typeName(header.lengthType);
    text += " ";
    text += typeName(header.indexType);
    text += " vertex_indices\n";
    for (const auto& attribute : header.faceAttributes) declare(attribute);
  }
  text += "end_header\n";
  return text;
}

PlyValueWriter::PlyValueWriter(std::ostream& out, PlyEncoding encoding)
    : out_(out), encoding_(encoding) {
  buffer_.reserve(1 << 17);
  swap_ = plySwapsBytes(encoding);
}

void PlyValueWriter::value(double v, ScalarType type, char separator) {
  if (encoding_ != PlyEncoding::Ascii) {
    unsigned char bytes[8];
    const std::size_t size = scalarSize(type);
    encode(v, type, bytes);
    if (swap_) std::reverse(bytes, bytes + size);
    buffer_.append(reinterpret_cast<const char*>(bytes), size);
    return;
  }
  if (isIntegral(type))
    appendInteger(buffer_, static_cast<std::int64_t>(v));
  else if (type == ScalarType::Float32)
    appendNumber(buffer_, static_cast<float>(v));
  else
    appendNumber(buffer_, v);
  buffer_ += separator;
}

void PlyValueWriter::drain(bool force) { detail::drain(buffer_, out_, force); }

}  // namespace detail

}  // namespace spacewarp
