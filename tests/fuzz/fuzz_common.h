#pragma once
// Shared checks of the reader fuzzers. A reader may only throw IoError; whatever it returns
// must pass PolygonSoup::validate() and must survive a write-then-read round trip bit-exactly.
// Anything else (another exception, a crash, a sanitizer report) is a finding.

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <sstream>
#include <string>
#include <string_view>
#include <vector>

#include <spacewarp/core/errors.h>
#include <spacewarp/core/geometry.h>

namespace spacewarp::fuzz {

[[noreturn]] inline void finding(const char* what) {
  std::fprintf(stderr, "fuzz finding: %s\n", what);
  std::abort();
}

inline bool sameBits(const std::vector<Vec3>& a, const std::vector<Vec3>& b) {
  return a.size() == b.size() &&
         (a.empty() || std::memcmp(a.data(), b.data(), a.size() * sizeof(Vec3)) == 0);
}

inline void expectSameAttributes(const std::vector<ScalarAttribute>& a,
                                 const std::vector<ScalarAttribute>& b) {
  if (a.size() != b.size()) finding("round trip changed the attributes");
  for (std::size_t k = 0; k < a.size(); ++k) {
    const ScalarAttribute& x = a[k];
    const ScalarAttribute& y = b[k];
    if (x.name != y.name || x.type != y.type || x.values.size() != y.values.size())
      finding("round trip changed an attribute");
    for (std::size_t v = 0; v < x.values.size(); ++v) {
      const bool bothNan = x.values[v] != x.values[v] && y.values[v] != y.values[v];
      if (!bothNan && std::memcmp(&x.values[v], &y.values[v], sizeof(double)) != 0)
        finding("round trip changed an attribute value");
    }
  }
}

/// Compares what both soups hold; vertex and face attributes only when `withAttributes`.
inline void expectSame(const PolygonSoup& a, const PolygonSoup& b, bool withAttributes) {
  if (!sameBits(a.positions, b.positions)) finding("round trip changed the positions");
  if (!sameBits(a.normals, b.normals)) finding("round trip changed the normals");
  if (a.faceOffsets != b.faceOffsets || a.faceIndices != b.faceIndices)
    finding("round trip changed the polygons");
  // Per-corner data and OBJ statements: the format that reads them also writes them.
  if (!sameBits(a.texcoords.values, b.texcoords.values) ||
      a.texcoords.indices != b.texcoords.indices || a.texcoordDimension != b.texcoordDimension)
    finding("round trip changed the texture coordinates");
  if (!sameBits(a.cornerNormals.values, b.cornerNormals.values) ||
      a.cornerNormals.indices != b.cornerNormals.indices)
    finding("round trip changed the corner normals");
  if (a.objStatements.size() != b.objStatements.size())
    finding("round trip changed the OBJ statements");
  for (std::size_t k = 0; k < a.objStatements.size(); ++k) {
    if (a.objStatements[k].polygon != b.objStatements[k].polygon ||
        a.objStatements[k].text != b.objStatements[k].text)
      finding("round trip changed an OBJ statement");
  }
  if (!withAttributes) return;
  expectSameAttributes(a.attributes, b.attributes);
  expectSameAttributes(a.faceAttributes, b.faceAttributes);
}

/// Runs `read` on the bytes; if it succeeds, validates the soup, writes it with `write` and
/// reads it back with `read`, which must give the same soup.
template <typename Read, typename Write>
void check(const std::uint8_t* data, std::size_t size, Read read, Write write,
           bool withAttributes) {
  PolygonSoup soup;
  try {
    std::istringstream in(std::string(reinterpret_cast<const char*>(data), size));
    soup = read(in);
  } catch (const IoError& e) {
    // Malformed input, rejected the documented way, unless the own pass of the OBJ reader let
    // through something that tinyobjloader then refused or misread.
    const std::string_view message = e.what();
    if (message.starts_with("fuzz.obj: tinyobjloader") ||
        message.starts_with("fuzz.obj: inconsistent")) {
      std::fprintf(stderr, "%s\n", e.what());
      finding("the OBJ pre-pass and tinyobjloader disagree");
    }
    return;
  }
  try {
    soup.validate();
  } catch (const InvalidInput&) {
    finding("the reader returned a soup that fails validate()");
  }
  std::stringstream stream;
  write(soup, stream);
  PolygonSoup back;
  try {
    back = read(stream);
  } catch (const IoError& e) {
    std::fprintf(stderr, "%s\n", e.what());
    finding("a written soup could not be read back");
  }
  expectSame(soup, back, withAttributes);
}

}  // namespace spacewarp::fuzz
