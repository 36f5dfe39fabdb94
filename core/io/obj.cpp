#include <spacewarp/core/io/obj.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <sstream>
#include <string>
#include <string_view>
#include <vector>

#include <tiny_obj_loader.h>

#include <spacewarp/core/errors.h>
#include <spacewarp/core/io/detail/text_format.h>

namespace spacewarp {
namespace {

// ---------------------------------------------------------------------------------------------
// Reading

constexpr std::int64_t kMaxVertices = std::numeric_limits<std::int32_t>::max();

/// Throws IoError messages that name the file and the line.
class ObjError {
 public:
  ObjError(const std::string& name, std::size_t line) : name_(name), line_(line) {}
  [[noreturn]] void fail(const std::string& message) const {
    detail::failAt(name_, line_, message);
  }

 private:
  const std::string& name_;
  std::size_t line_;
};

/// Splits a line into tokens separated by spaces and tabs (the separators tinyobjloader uses),
/// stopping at a '#' that starts a token (a trailing comment).
void tokenize(std::string_view line, std::vector<std::string_view>& tokens) {
  tokens.clear();
  std::size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && (line[i] == ' ' || line[i] == '\t')) ++i;
    if (i == line.size() || line[i] == '#') break;
    const std::size_t start = i;
    while (i < line.size() && line[i] != ' ' && line[i] != '\t') ++i;
    tokens.push_back(line.substr(start, i - start));
  }
}

/// Resolves a 1-based or negative (relative) OBJ index against `count` elements seen so far.
/// Returns false when the index is zero or out of range.
bool resolveIndex(std::int64_t index, std::int64_t count, std::int64_t& resolved) {
  if (index > 0 && index <= count) {
    resolved = index - 1;
    return true;
  }
  if (index < 0 && -index <= count) {
    resolved = count + index;
    return true;
  }
  return false;
}

/// Reads "x y z [more numbers]" after the keyword: the three first coordinates must be
/// finite, every token must be a number.
Vec3 parseTriple(const std::vector<std::string_view>& tokens, const ObjError& error,
                 const char* what) {
  if (tokens.size() < 4) error.fail(std::string(what) + " has fewer than 3 coordinates");
  double xyz[3] = {0.0, 0.0, 0.0};
  for (std::size_t t = 1; t < tokens.size(); ++t) {
    double value = 0.0;
    const detail::NumberStatus status = detail::parseDouble(tokens[t], value);
    if (status == detail::NumberStatus::NotANumber)
      error.fail(std::string(what) + ": " + detail::quotedToken(tokens[t]) + " is not a number");
    if (t <= 3) {
      if (status == detail::NumberStatus::OutOfRange || !std::isfinite(value))
        error.fail(std::string(what) + " has a non-finite coordinate");
      xyz[t - 1] = value;
    }
  }
  return {xyz[0], xyz[1], xyz[2]};
}

/// Reads "u [v [w]] [more numbers]" after `vt`: one to three finite coordinates (the missing
/// ones are 0), every token a number. Raises `dimension` to the count given.
Vec3 parseTexcoord(const std::vector<std::string_view>& tokens, const ObjError& error,
                   int& dimension) {
  if (tokens.size() < 2) error.fail("texture coordinate has no values");
  Vec3 uvw(0.0);
  for (std::size_t t = 1; t < tokens.size(); ++t) {
    double value = 0.0;
    const detail::NumberStatus status = detail::parseDouble(tokens[t], value);
    if (status == detail::NumberStatus::NotANumber)
      error.fail("texture coordinate: " + detail::quotedToken(tokens[t]) + " is not a number");
    if (t <= 3) {
      if (status == detail::NumberStatus::OutOfRange || !std::isfinite(value))
        error.fail("texture coordinate has a non-finite value");
      uvw[static_cast<int>(t) - 1] = value;
    }
  }
  dimension = std::max(dimension, static_cast<int>(std::min<std::size_t>(tokens.size() - 1, 3)));
  return uvw;
}

/// Checks one face corner "v", "v/t", "v//n" or "v/t/n" against the element counts so far.
void checkCorner(std::string_view corner, std::int64_t vertexCount, std::int64_t texcoordCount,
                 std::int64_t normalCount, const ObjError& error) {
  std::string_view parts[3];
  int partCount = 0;
  std::size_t start = 0;
  for (;;) {
    const std::size_t slash = corner.find('/', start);
    if (partCount == 3) error.fail("malformed face corner " + detail::quotedToken(corner));
    parts[partCount++] =
        corner.substr(start, slash == std::string_view::npos ? slash : slash - start);
    if (slash == std::string_view::npos) break;
    start = slash + 1;
  }
  const std::int64_t counts[3] = {vertexCount, texcoordCount, normalCount};
  const char* kinds[3] = {"vertex", "texture coordinate", "normal"};
  const char* plurals[3] = {"vertices", "texture coordinates", "normals"};
  for (int p = 0; p < partCount; ++p) {
    if (p == 1 && parts[p].empty() && partCount == 3) continue;  // "v//n"
    std::int64_t index = 0;
    if (!detail::parseInteger(parts[p], index))
      error.fail("malformed face corner " + detail::quotedToken(corner));
    std::int64_t resolved = 0;
    if (!resolveIndex(index, counts[p], resolved)) {
      error.fail(std::string("face ") + kinds[p] + " index " + std::to_string(index) +
                 (index == 0 ? " is invalid (OBJ indices start at 1)"
                             : " is out of range (" + std::to_string(counts[p]) + " " + plurals[p] +
                                   " so far)"));
    }
  }
}

/// What the own pass over the lines collects: exact positions and normals, the size of every
/// face, and the text handed to tinyobjloader (only v, vn, vt and f lines, normalised, with
/// blank lines in place of everything else so that line numbers stay the same).
struct Scan {
  std::vector<Vec3> positions;
  std::vector<Vec3> normals;
  std::vector<Vec3> texcoords;  ///< u, v, w; the components a line omits are 0.
  int texcoordDimension = 0;    ///< The most components a `vt` line has.
  std::vector<ObjStatement> statements;
  std::vector<std::uint32_t> faceSizes;
  std::uint64_t cornerCount = 0;
  std::string forwarded;
};

/// One pass over the lines, read as they come (see detail::TextLines): binary or endless input
/// fails at its first block or its first overlong line, before it is held in memory.
Scan scanLines(std::istream& in, const std::string& name) {
  Scan scan;
  std::vector<std::string_view> tokens;
  // Lines end with "\n", "\r\n" or "\r", as in tinyobjloader.
  detail::TextLines lines(in, name, /*loneCrEndsLine=*/true);
  std::string_view line;
  while (lines.next(line)) {
    const ObjError error(name, lines.lineNumber());
    tokenize(line, tokens);
    if (tokens.empty()) {
      scan.forwarded += '\n';
      continue;
    }
    const std::string_view keyword = tokens.front();
    if (keyword == "v") {
      if (static_cast<std::int64_t>(scan.positions.size()) >= kMaxVertices)
        error.fail("too many vertices");
      scan.positions.push_back(parseTriple(tokens, error, "vertex"));
    } else if (keyword == "vn") {
      if (static_cast<std::int64_t>(scan.normals.size()) >= kMaxVertices)
        error.fail("too many normals");
      scan.normals.push_back(parseTriple(tokens, error, "normal"));
    } else if (keyword == "vt") {
      if (static_cast<std::int64_t>(scan.texcoords.size()) >= kMaxVertices)
        error.fail("too many texture coordinates");
      scan.texcoords.push_back(parseTexcoord(tokens, error, scan.texcoordDimension));
    } else if (keyword == "f") {
      if (tokens.size() < 4) error.fail("face has fewer than 3 vertices");
      for (std::size_t t = 1; t < tokens.size(); ++t) {
        checkCorner(tokens[t], static_cast<std::int64_t>(scan.positions.size()),
                    static_cast<std::int64_t>(scan.texcoords.size()),
                    static_cast<std::int64_t>(scan.normals.size()), error);
      }
      const std::uint64_t corners = tokens.size() - 1;
      if (scan.cornerCount + corners > std::numeric_limits<std::uint32_t>::max())
        error.fail("too many face indices for 32-bit offsets");
      scan.cornerCount += corners;
      scan.faceSizes.push_back(static_cast<std::uint32_t>(corners));
    } else {
      if (keyword == "o" || keyword == "g" || keyword == "s" || keyword == "usemtl" ||
          keyword == "mtllib") {
        ObjStatement statement{static_cast<std::uint32_t>(scan.faceSizes.size()), {}};
        for (std::size_t t = 0; t < tokens.size(); ++t) {
          if (t > 0) statement.text += ' ';
          statement.text += tokens[t];
        }
        scan.statements.push_back(std::move(statement));
      }
      scan.forwarded += '\n';  // Not needed by tinyobjloader: comments, groups, materials, ...
      continue;
    }
    for (std::size_t t = 0; t < tokens.size(); ++t) {
      if (t > 0) scan.forwarded += ' ';
      scan.forwarded += tokens[t];
    }
    scan.forwarded += '\n';
  }
  return scan;
}

/// Per-vertex normals from the per-corner normal indices when they are unambiguous (see
/// readObj); false otherwise.
bool vertexNormals(PolygonSoup& soup, const std::vector<Vec3>& fileNormals,
                   const std::vector<int>& cornerNormals) {
  const std::size_t n = soup.positions.size();
  constexpr int kUnset = -1;
  std::vector<int> normalOf(n, kUnset);
  for (std::size_t c = 0; c < cornerNormals.size(); ++c) {
    const std::uint32_t v = soup.faceIndices[c];
    const int k = cornerNormals[c];
    if (k < 0) return false;
    if (normalOf[v] == kUnset) {
      normalOf[v] = k;
    } else if (normalOf[v] != k && fileNormals[static_cast<std::size_t>(normalOf[v])] !=
                                       fileNormals[static_cast<std::size_t>(k)]) {
      return false;  // Two different normals at one vertex (flat shading, creases).
    }
  }
  std::vector<Vec3> normals(n);
  for (std::size_t v = 0; v < n; ++v) {
    if (normalOf[v] != kUnset) {
      normals[v] = fileNormals[static_cast<std::size_t>(normalOf[v])];
    } else if (fileNormals.size() == n) {
      normals[v] = fileNormals[v];  // Unreferenced vertex: one vn per v.
    } else {
      return false;
    }
  }
  soup.normals = std::move(normals);
  return true;
}

/// The file's indexed corner values as a CornerAttribute (-1 in `corners`: no value).
CornerAttribute cornerAttribute(std::vector<Vec3> values, const std::vector<int>& corners) {
  CornerAttribute attribute;
  attribute.values = std::move(values);
  attribute.indices.reserve(corners.size());
  for (int k : corners)
    attribute.indices.push_back(k < 0 ? CornerAttribute::kNone : static_cast<std::uint32_t>(k));
  return attribute;
}

/// Normals per vertex when the file gives them unambiguously, otherwise per corner when faces
/// reference them (see readObj).
void assignNormals(PolygonSoup& soup, std::vector<Vec3> fileNormals,
                   const std::vector<int>& cornerNormals) {
  if (fileNormals.empty()) return;
  const bool anyReferenced =
      std::any_of(cornerNormals.begin(), cornerNormals.end(), [](int k) { return k >= 0; });
  if (!anyReferenced) {
    if (fileNormals.size() == soup.positions.size()) soup.normals = std::move(fileNormals);
    return;
  }
  if (vertexNormals(soup, fileNormals, cornerNormals)) return;
  soup.cornerNormals = cornerAttribute(std::move(fileNormals), cornerNormals);
}

PolygonSoup readObjImpl(std::istream& in, const std::string& name) {
  Scan scan = scanLines(in, name);

  tinyobj::attrib_t attrib;
  std::vector<tinyobj::shape_t> shapes;
  std::vector<tinyobj::material_t> materials;
  std::string warning;
  std::string error;
  std::istringstream forwarded(std::move(scan.forwarded));
  if (!tinyobj::LoadObj(&attrib, &shapes, &materials, &warning, &error, &forwarded,
                        /*readMatFn=*/nullptr, /*triangulate=*/false,
                        /*default_vcols_fallback=*/false)) {
    // Not expected after the own pass; tinyobjloader's messages end with a newline.
    while (!error.empty() && (error.back() == '\n' || error.back() == '.')) error.pop_back();
    throw IoError(name + ": tinyobjloader rejected the file: " + error);
  }
  if (attrib.vertices.size() != 3 * scan.positions.size() ||
      attrib.normals.size() != 3 * scan.normals.size() ||
      attrib.texcoords.size() != 2 * scan.texcoords.size()) {
    throw IoError(name +
                  ": inconsistent vertex, normal or texture coordinate count from "
                  "tinyobjloader");
  }

  PolygonSoup soup;
  soup.positions = std::move(scan.positions);
  soup.faceIndices.reserve(scan.cornerCount);
  std::vector<int> cornerNormals;
  std::vector<int> cornerTexcoords;
  cornerNormals.reserve(scan.cornerCount);
  cornerTexcoords.reserve(scan.cornerCount);
  const int vertexCount = static_cast<int>(soup.positions.size());
  const int normalCount = static_cast<int>(scan.normals.size());
  const int texcoordCount = static_cast<int>(scan.texcoords.size());
  bool anyTexcoord = false;
  for (const tinyobj::shape_t& shape : shapes) {
    for (const tinyobj::index_t& corner : shape.mesh.indices) {
      if (corner.vertex_index < 0 || corner.vertex_index >= vertexCount ||
          corner.normal_index < -1 || corner.normal_index >= normalCount ||
          corner.texcoord_index < -1 || corner.texcoord_index >= texcoordCount) {
        throw IoError(name + ": inconsistent face index from tinyobjloader");
      }
      soup.faceIndices.push_back(static_cast<std::uint32_t>(corner.vertex_index));
      cornerNormals.push_back(corner.normal_index);
      cornerTexcoords.push_back(corner.texcoord_index);
      anyTexcoord = anyTexcoord || corner.texcoord_index >= 0;
    }
  }
  if (soup.faceIndices.size() != scan.cornerCount)
    throw IoError(name + ": inconsistent face count from tinyobjloader");
  // tinyobjloader stores face sizes as unsigned char; the own pass has the true sizes.
  soup.faceOffsets.reserve(scan.faceSizes.size() + 1);
  std::uint32_t offset = 0;
  for (std::uint32_t size : scan.faceSizes) {
    offset += size;
    soup.faceOffsets.push_back(offset);
  }
  assignNormals(soup, std::move(scan.normals), cornerNormals);
  soup.objStatements = std::move(scan.statements);
  if (anyTexcoord) {
    soup.texcoords = cornerAttribute(std::move(scan.texcoords), cornerTexcoords);
    soup.texcoordDimension = scan.texcoordDimension;
  }
  return soup;
}

// ---------------------------------------------------------------------------------------------
// Writing

void appendVectorLine(std::string& out, const char* keyword, const Vec3& v) {
  out += keyword;
  for (int c = 0; c < 3; ++c) {
    out += ' ';
    detail::appendNumber(out, v[c]);
  }
  out += '\n';
}

}  // namespace

PolygonSoup readObj(std::istream& in, const std::string& name) {
  try {
    return readObjImpl(in, name);
  } catch (...) {
    detail::rethrowAsIoError(name);
  }
}

void writeObj(const PolygonSoup& soup, std::ostream& out) {
  soup.validate();
  constexpr std::uint32_t kNone = CornerAttribute::kNone;
  std::string buffer;
  buffer.reserve(1u << 17);
  for (const Vec3& p : soup.positions) {
    appendVectorLine(buffer, "v", p);
    detail::drain(buffer, out);
  }
  for (const Vec3& t : soup.texcoords.values) {
    buffer += "vt";
    for (int c = 0; c < soup.texcoordDimension; ++c) {
      buffer += ' ';
      detail::appendNumber(buffer, t[c]);
    }
    buffer += '\n';
    detail::drain(buffer, out);
  }
  const bool perVertex = soup.hasNormals();
  for (const Vec3& n : perVertex ? soup.normals : soup.cornerNormals.values) {
    appendVectorLine(buffer, "vn", n);
    detail::drain(buffer, out);
  }
  std::size_t nextStatement = 0;
  const auto statementsBefore = [&](std::size_t polygon) {
    for (; nextStatement < soup.objStatements.size() &&
           soup.objStatements[nextStatement].polygon <= polygon;
         ++nextStatement) {
      buffer += soup.objStatements[nextStatement].text;
      buffer += '\n';
    }
  };
  for (std::size_t p = 0; p < soup.polygonCount(); ++p) {
    statementsBefore(p);
    buffer += 'f';
    for (std::uint32_t c = soup.faceOffsets[p]; c < soup.faceOffsets[p + 1]; ++c) {
      const std::uint32_t v = soup.faceIndices[c];
      const std::uint32_t t = soup.texcoords.empty() ? kNone : soup.texcoords.indices[c];
      const std::uint32_t n = perVertex                    ? v
                              : soup.cornerNormals.empty() ? kNone
                                                           : soup.cornerNormals.indices[c];
      buffer += ' ';
      detail::appendInteger(buffer, std::uint64_t{v} + 1);
      if (t != kNone) {
        buffer += '/';
        detail::appendInteger(buffer, std::uint64_t{t} + 1);
      }
      if (n != kNone) {
        buffer += t != kNone ? "/" : "//";
        detail::appendInteger(buffer, std::uint64_t{n} + 1);
      }
    }
    buffer += '\n';
    detail::drain(buffer, out);
  }
  statementsBefore(soup.polygonCount());
  detail::drain(buffer, out, true);
}

}  // namespace spacewarp
