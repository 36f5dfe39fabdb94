#include <spacewarp/core/io/off.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <string_view>
#include <vector>

#include <spacewarp/core/errors.h>
#include <spacewarp/core/io/detail/text_format.h>

namespace spacewarp {
namespace {

// ---------------------------------------------------------------------------------------------
// Reading

/// Reads the content lines of an OFF file (comments removed, blank lines skipped) as tokens,
/// and throws IoError messages that name the file and the current line. Lines are read as they
/// come (see detail::TextLines): binary or endless input fails at its first block or its first
/// overlong line.
class LineReader {
 public:
  LineReader(std::istream& in, const std::string& name)
      : lines_(in, name, /*loneCrEndsLine=*/false), name_(name) {}

  /// Moves to the next line with content; false at the end of the file.
  bool next() {
    std::string_view text;
    while (lines_.next(text)) {
      lineNumber_ = lines_.lineNumber();
      tokens_.clear();
      std::size_t i = 0;
      while (i < text.size()) {
        while (i < text.size() && detail::isSpace(text[i])) ++i;
        if (i == text.size() || text[i] == '#') break;
        const std::size_t start = i;
        while (i < text.size() && !detail::isSpace(text[i]) && text[i] != '#') ++i;
        tokens_.push_back(text.substr(start, i - start));
      }
      if (!tokens_.empty()) return true;
    }
    return false;
  }

  const std::vector<std::string_view>& tokens() const { return tokens_; }

  [[noreturn]] void fail(const std::string& message) const {
    detail::failAt(name_, lineNumber_, message);
  }

  /// "what index: 'token' problem" for token t (index < 0: no index).
  [[noreturn]] void fail(const char* what, std::int64_t index, const char* problem,
                         std::size_t t) const {
    fail(std::string(what) + (index >= 0 ? " " + std::to_string(index) : std::string()) + ": " +
         detail::quotedToken(tokens_[t]) + " " + problem);
  }

  /// Token t as a number (an overflowing one gives infinity); `what` and `index` name the
  /// element in the message ("vertex 3: 'abc' is not a number").
  double number(std::size_t t, const char* what, std::int64_t index) const {
    double value = 0.0;
    const detail::NumberStatus status = detail::parseDouble(tokens_[t], value);
    if (status == detail::NumberStatus::NotANumber) fail(what, index, "is not a number", t);
    if (status == detail::NumberStatus::OutOfRange) value = std::numeric_limits<double>::infinity();
    return value;
  }

  /// Token t as an integer.
  std::int64_t integer(std::size_t t, const char* what, std::int64_t index = -1) const {
    std::int64_t value = 0;
    if (!detail::parseInteger(tokens_[t], value)) fail(what, index, "is not an integer", t);
    return value;
  }

 private:
  detail::TextLines lines_;
  const std::string& name_;
  std::vector<std::string_view> tokens_;
  std::size_t lineNumber_ = 0;
};

struct Header {
  bool colours = false;
  bool normals = false;
  bool valid = false;
};

/// Recognises OFF, NOFF, COFF and CNOFF.
Header parseKeyword(std::string_view keyword) {
  Header header;
  if (!keyword.empty() && keyword.front() == 'C') {
    header.colours = true;
    keyword.remove_prefix(1);
  }
  if (!keyword.empty() && keyword.front() == 'N') {
    header.normals = true;
    keyword.remove_prefix(1);
  }
  header.valid = keyword == "OFF";
  return header;
}

constexpr const char* kColourNames[4] = {"red", "green", "blue", "alpha"};

/// Colours of one element kind (vertex or face), collected while reading: RGB or RGBA per
/// element, integers 0..255 (stored as uchar) or any other numbers (stored as float).
struct Colours {
  std::size_t components = 0;  ///< 3 or 4 once the first colour is seen.
  bool allBytes = true;        ///< Every value an integer token in 0..255.
  bool consistent = true;      ///< Every element has a colour of the same size.
  std::vector<double> values;  ///< components per element.

  void add(const LineReader& reader, std::size_t first, std::size_t count, const char* what,
           std::int64_t index) {
    if (count != 3 && count != 4) {
      consistent = false;
      return;
    }
    if (components == 0) components = count;
    if (count != components) {
      consistent = false;
      return;
    }
    for (std::size_t t = first; t < first + count; ++t) {
      std::int64_t integer = 0;
      allBytes = allBytes && detail::parseInteger(reader.tokens()[t], integer) && integer >= 0 &&
                 integer <= 255;
      const double value = reader.number(t, what, index);
      if (!std::isfinite(value)) reader.fail(what, index, "is not a finite colour value", t);
      values.push_back(value);
    }
  }

  /// The colours as attributes red, green, blue [, alpha]; none unless every one of the
  /// `count` elements had one of the same size.
  std::vector<ScalarAttribute> attributes(std::size_t count) const {
    std::vector<ScalarAttribute> result;
    if (!consistent || components == 0 || values.size() != components * count) return result;
    for (std::size_t c = 0; c < components; ++c) {
      ScalarAttribute attribute{
          kColourNames[c], allBytes ? ScalarType::UInt8 : ScalarType::Float32, {}};
      attribute.values.reserve(count);
      for (std::size_t e = 0; e < count; ++e)
        attribute.values.push_back(values[e * components + c]);
      result.push_back(std::move(attribute));
    }
    return result;
  }
};

PolygonSoup readOffImpl(std::istream& in, const std::string& name) {
  LineReader reader(in, name);
  if (!reader.next()) throw IoError(name + ": empty file, expected an 'OFF' header");
  const Header header = parseKeyword(reader.tokens().front());
  if (!header.valid) {
    reader.fail("not an OFF file: expected 'OFF', found " +
                detail::quotedToken(reader.tokens().front()));
  }
  std::size_t firstCount = 1;  // The counts may follow the keyword on the same line.
  if (reader.tokens().size() == 1) {
    if (!reader.next()) reader.fail("unexpected end of file: expected the counts line");
    firstCount = 0;
  }
  const std::size_t countTokens = reader.tokens().size() - firstCount;
  if (countTokens < 2 || countTokens > 3)
    reader.fail("expected the counts line 'vertices faces [edges]'");
  const std::int64_t vertexCount = reader.integer(firstCount, "vertex count");
  const std::int64_t faceCount = reader.integer(firstCount + 1, "face count");
  if (countTokens == 3) reader.integer(firstCount + 2, "edge count");
  if (vertexCount < 0 || faceCount < 0) reader.fail("negative count");
  if (vertexCount > std::numeric_limits<std::uint32_t>::max())
    reader.fail("too many vertices for 32-bit indices");

  PolygonSoup soup;
  const std::size_t valuesPerVertex = header.normals ? 6 : 3;
  Colours vertexColours;
  Colours faceColours;
  for (std::int64_t v = 0; v < vertexCount; ++v) {
    if (!reader.next()) {
      reader.fail("unexpected end of file: declared " + std::to_string(vertexCount) +
                  " vertices, found " + std::to_string(v));
    }
    const auto& tokens = reader.tokens();
    if (tokens.size() < valuesPerVertex) {
      reader.fail("vertex " + std::to_string(v) + " has " + std::to_string(tokens.size()) +
                  " values, expected " + std::to_string(valuesPerVertex));
    }
    double values[6] = {};
    for (std::size_t t = 0; t < tokens.size(); ++t) {
      const double value = reader.number(t, "vertex", v);
      if (t < valuesPerVertex) values[t] = value;
    }
    if (header.colours) {
      const std::size_t extra = tokens.size() - valuesPerVertex;
      vertexColours.add(reader, valuesPerVertex, std::min<std::size_t>(extra, 4), "vertex", v);
    }
    const Vec3 position(values[0], values[1], values[2]);
    if (!isFinite(position))
      reader.fail("vertex " + std::to_string(v) + " has a non-finite coordinate");
    soup.positions.push_back(position);
    if (header.normals) {
      const Vec3 normal(values[3], values[4], values[5]);
      if (!isFinite(normal))
        reader.fail("vertex " + std::to_string(v) + " has a non-finite normal");
      soup.normals.push_back(normal);
    }
  }

  std::vector<std::uint32_t> polygon;
  for (std::int64_t f = 0; f < faceCount; ++f) {
    if (!reader.next()) {
      reader.fail("unexpected end of file: declared " + std::to_string(faceCount) +
                  " faces, found " + std::to_string(f));
    }
    const auto& tokens = reader.tokens();
    const std::int64_t k = reader.integer(0, "face", f);
    const auto face = [f] { return "face " + std::to_string(f); };
    if (k < 3) reader.fail(face() + " has " + std::to_string(k) + " vertices, at least 3 needed");
    if (static_cast<std::uint64_t>(k) > tokens.size() - 1) {
      reader.fail(face() + " declares " + std::to_string(k) + " vertices but lists " +
                  std::to_string(tokens.size() - 1));
    }
    polygon.clear();
    for (std::size_t t = 1; t <= static_cast<std::size_t>(k); ++t) {
      const std::int64_t index = reader.integer(t, "face", f);
      if (index < 0 || index >= vertexCount) {
        reader.fail(face() + ": vertex index " + std::to_string(index) + " is out of range (" +
                    std::to_string(vertexCount) + " vertices)");
      }
      polygon.push_back(static_cast<std::uint32_t>(index));
    }
    const std::size_t colourStart = static_cast<std::size_t>(k) + 1;
    for (std::size_t t = colourStart; t < tokens.size(); ++t) reader.number(t, "face", f);
    faceColours.add(reader, colourStart, tokens.size() - colourStart, "face", f);
    if (soup.faceIndices.size() + polygon.size() > std::numeric_limits<std::uint32_t>::max())
      reader.fail("too many face indices for 32-bit offsets");
    soup.addPolygon(polygon);
  }

  if (reader.next()) {
    reader.fail("unexpected content after the last of the " + std::to_string(faceCount) +
                " declared faces");
  }
  if (header.colours && !vertexColours.consistent) {
    throw IoError(name +
                  ": COFF vertices need 3 or 4 colour values each, the same count on "
                  "every vertex");
  }
  soup.attributes = vertexColours.attributes(soup.size());
  soup.faceAttributes = faceColours.attributes(soup.polygonCount());
  return soup;
}

void appendColour(std::string& out, const std::vector<const ScalarAttribute*>& colours,
                  std::size_t element) {
  for (const ScalarAttribute* colour : colours) {
    out += ' ';
    const std::size_t start = out.size();
    detail::appendNumber(out, colour->values[element]);
    // Non-uchar colours keep a decimal point, so that they read back as float colours.
    const bool integral = out.find_first_not_of("-0123456789", start) == std::string::npos;
    if (colour->type != ScalarType::UInt8 && integral) out += ".0";
  }
}

}  // namespace

std::vector<const ScalarAttribute*> offColours(const std::vector<ScalarAttribute>& attributes) {
  std::vector<const ScalarAttribute*> colours;
  for (const char* name : kColourNames) {
    const auto it = std::find_if(attributes.begin(), attributes.end(),
                                 [&](const ScalarAttribute& a) { return a.name == name; });
    if (it == attributes.end()) break;
    colours.push_back(&*it);
  }
  if (colours.size() < 3) colours.clear();
  return colours;
}

PolygonSoup readOff(std::istream& in, const std::string& name) {
  try {
    return readOffImpl(in, name);
  } catch (...) {
    detail::rethrowAsIoError(name);
  }
}

void writeOff(const PolygonSoup& soup, std::ostream& out) {
  soup.validate();
  const bool withNormals = soup.hasNormals();
  const std::vector<const ScalarAttribute*> vertexColours = offColours(soup.attributes);
  const std::vector<const ScalarAttribute*> faceColours = offColours(soup.faceAttributes);
  std::string buffer;
  buffer.reserve(1u << 17);
  if (!vertexColours.empty()) buffer += 'C';
  buffer += withNormals ? "NOFF\n" : "OFF\n";
  detail::appendInteger(buffer, std::uint64_t{soup.positions.size()});
  buffer += ' ';
  detail::appendInteger(buffer, std::uint64_t{soup.polygonCount()});
  buffer += " 0\n";
  for (std::size_t v = 0; v < soup.positions.size(); ++v) {
    for (int c = 0; c < 3; ++c) {
      if (c > 0) buffer += ' ';
      detail::appendNumber(buffer, soup.positions[v][c]);
    }
    if (withNormals) {
      for (int c = 0; c < 3; ++c) {
        buffer += ' ';
        detail::appendNumber(buffer, soup.normals[v][c]);
      }
    }
    appendColour(buffer, vertexColours, v);
    buffer += '\n';
    detail::drain(buffer, out);
  }
  for (std::size_t p = 0; p < soup.polygonCount(); ++p) {
    const auto polygon = soup.polygon(p);
    detail::appendInteger(buffer, std::uint64_t{polygon.size()});
    for (std::uint32_t v : polygon) {
      buffer += ' ';
      detail::appendInteger(buffer, std::uint64_t{v});
    }
    appendColour(buffer, faceColours, p);
    buffer += '\n';
    detail::drain(buffer, out);
  }
  detail::drain(buffer, out, true);
}

}  // namespace spacewarp
