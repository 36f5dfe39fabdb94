#pragma once
// Wavefront OBJ polygon soups and point clouds.

#include <istream>
#include <ostream>
#include <string>

#include <spacewarp/core/geometry.h>

namespace spacewarp {

/// Reads an OBJ file (through tinyobjloader, plus a strict pass of its own over the lines).
///
/// Keeps every `v` position, referenced or not, in file order (world units; colour or weight
/// values after x y z are ignored), and every `f` polygon of any size (not triangulated), with
/// 0-based indices. Negative (relative) indices are resolved. Normals are kept as per-vertex
/// normals when the file gives one unambiguous normal to every vertex: either the faces
/// reference a normal at every corner and each vertex always gets the same normal (vertices
/// that no face references then need the positional convention, one `vn` per `v`), or no face
/// references normals and there is exactly one `vn` per `v`. Otherwise, when faces reference
/// normals, they are kept per corner (PolygonSoup::cornerNormals, every `vn` in file order,
/// the file's corner indices). Texture coordinates (`vt u [v [w]]`) that faces reference are
/// kept per corner (PolygonSoup::texcoords, every `vt` in file order, with as many components
/// as the longest `vt` line). Materials (`mtllib`, `usemtl`), groups, objects and smoothing
/// groups (`g`, `o`, `s`) are kept verbatim with the polygon they precede
/// (PolygonSoup::objStatements; the .mtl files are not read). Dropped: normals and texture
/// coordinates that no face uses (when normals are not one per `v`), lines (`l`), points (`p`)
/// and every other statement.
/// Coordinates are parsed with correct rounding, so values written with 17 significant
/// digits (or by writeObj) read back exactly.
///
/// `name` only appears in messages (usually the path). Throws IoError, and nothing else,
/// naming `name` and the line ("model.obj:17: vertex has a non-finite coordinate") for a `v`
/// or `vn` line with fewer than 3 numbers, a `vt` line with none, a non-numeric token on
/// them, a NaN or infinite (or overflowing) coordinate, a face with fewer than 3 corners, a
/// malformed, zero or out-of-range face index, a NUL byte ("model.obj:1: unexpected NUL byte
/// (byte offset 0): not a text file"), a line longer than 64 MiB, or a read error. The input is
/// read line by line as it comes (its `v`, `vn`, `vt` and `f` lines are kept for tinyobjloader),
/// so binary or endless input (/dev/zero, a FIFO) fails early instead of filling memory.
PolygonSoup readObj(std::istream& in, const std::string& name);

/// Writes `soup` as OBJ: `v x y z` lines with the shortest decimal form that reads back to
/// the identical double, `vt` lines (texcoordDimension numbers each) for its texture
/// coordinates, `vn` lines for its normals (per vertex, or the per-corner values), then `f`
/// lines with 1-based indices, each corner `v`, `v/t`, `v//n` or `v/t/n` (per-vertex normals
/// use the vertex's index), with the OBJ statements before the polygons they precede. Vertex
/// and face attributes are not stored.
/// Throws InvalidInput (from soup.validate()) for an inconsistent soup; stream errors are
/// left in the state of `out`.
void writeObj(const PolygonSoup& soup, std::ostream& out);

}  // namespace spacewarp
