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

#include "core/errors.h"
#include "core/geometry.h"

namespace spacewarp::fuzz {

[[noreturn]] inline void finding(const char* what) {
  std::fprintf(stderr, "fuzz finding: %s\n", what);
  std::abort();
}

inline bool sameBits(const std::vector<Vec3>& a, const std::vector<Vec3>& b) {
  return a.size() == b.size() &&
         (a.empty() || std::memcmp(a.data(), b.data(), a.size() * sizeof(Vec3)) == 0);
}

/// Compares what both soups hold; attributes only when `withAttributes`.
inline void expectSame(const PolygonSoup& a, const PolygonSoup& b, bool withAttributes) {
  if (!sameBits(a.positions, b.positions)) finding("round trip changed the positions");
  if (!sameBits(a.normals, b.normals)) finding("round trip changed the normals");
  if (a.faceOffsets != b.faceOffsets || a.faceIndices != b.faceIndices)
    finding("round trip changed the polygons");
  if (!withAttributes) return;
  if (a.attributes.size() != b.attributes.size()) finding("round trip changed the attributes");
  for (std::size_t k = 0; k < a.attributes.size(); ++k) {
    const VertexAttribute& x = a.attributes[k];
    const VertexAttribute& y = b.attributes[k];
    if (x.name != y.name || x.type != y.type || x.values.size() != y.values.size())
      finding("round trip changed an attribute");
    for (std::size_t v = 0; v < x.values.size(); ++v) {
      const bool bothNan = x.values[v] != x.values[v] && y.values[v] != y.values[v];
      if (!bothNan && std::memcmp(&x.values[v], &y.values[v], sizeof(double)) != 0)
        finding("round trip changed an attribute value");
    }
  }
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
