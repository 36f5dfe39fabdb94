#pragma once
// Wavefront OBJ polygon soups and point clouds.

#include <istream>
#include <ostream>
#include <string>

#include "core/geometry.h"

namespace spacewarp {

/// Reads an OBJ file (through tinyobjloader, plus a strict pass of its own over the lines).
///
/// Keeps every `v` position, referenced or not, in file order (world units; colour or weight
/// values after x y z are ignored), and every `f` polygon of any size (not triangulated), with
/// 0-based indices. Negative (relative) indices are resolved. Normals are kept as per-vertex
/// normals when the file gives one unambiguous normal to every vertex: either the faces
/// reference a normal at every corner and each vertex always gets the same normal (vertices
/// that no face references then need the positional convention, one `vn` per `v`), or no face
/// references normals and there is exactly one `vn` per `v`. Otherwise normals are dropped.
/// Texture coordinates, materials, groups, lines (`l`) and points (`p`) are ignored.
/// Coordinates are parsed with correct rounding, so values written with 17 significant
/// digits (or by writeObj) read back exactly.
///
/// `name` only appears in messages (usually the path). Throws IoError, and nothing else,
/// naming `name` and the line ("model.obj:17: vertex has a non-finite coordinate") for a `v`
/// or `vn` line with fewer than 3 numbers or with a non-numeric token, a NaN or infinite
/// (or overflowing) coordinate, a face with fewer than 3 corners, a malformed, zero or
/// out-of-range face index, or a read error.
PolygonSoup readObj(std::istream& in, const std::string& name);

/// Writes `soup` as OBJ: `v x y z` lines with the shortest decimal form that reads back to
/// the identical double, `vn` lines when the soup has normals, then `f` lines with 1-based
/// indices (`f a//a b//b c//c` with normals, `f a b c` without). Attributes are not stored.
/// Throws InvalidInput (from soup.validate()) for an inconsistent soup; stream errors are
/// left in the state of `out`.
void writeObj(const PolygonSoup& soup, std::ostream& out);

}  // namespace spacewarp
