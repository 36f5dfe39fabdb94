#pragma once
// Stanford PLY polygon soups and point clouds, ASCII and binary.

#include <istream>
#include <ostream>
#include <string>

#include <spacewarp/core/geometry.h>

namespace spacewarp {

/// The encoding of the data section of a PLY file.
enum class PlyEncoding { Ascii, BinaryLittleEndian, BinaryBigEndian };

/// Reads a PLY file in any of the three encodings.
///
/// The `vertex` element must have scalar properties x, y, z (any scalar type; world units);
/// nx, ny, nz (all three or none) become the normals; every other scalar vertex property is
/// kept as a VertexAttribute with its PLY type and its values as double (float properties
/// keep their float value exactly). The optional `face` element needs a list property
/// `vertex_indices` (or `vertex_index`) with integer count and index types; each list is one
/// polygon (0-based, at least 3 vertices); every other scalar face property (per-face colour,
/// material index, ...) is kept as a face attribute (PolygonSoup::faceAttributes) in the same
/// way. A file without a face element reads as a point cloud. List properties other than the
/// face index list and other elements (edge, material, ...) are read through and dropped. Type
/// names and their sized aliases are both accepted (char/int8, uchar/uint8, short/int16,
/// ushort/uint16, int/int32, uint/uint32, float/float32, double/float64). In ASCII files every
/// element instance is one line; decimal values are parsed with correct rounding.
///
/// `name` only appears in messages (usually the path). Throws IoError, and nothing else:
/// header errors name the header line ("cloud.ply:3: unknown property type 'foo'"): bad
/// magic, unknown format or type, a missing x/y/z or partial normals, a missing face index
/// list, duplicate names, no end_header. Data errors name the element and its index ("cloud.ply:
/// vertex 12: unexpected end of file", with the line too for ASCII: "cloud.ply:20: vertex 12:
/// ..."): truncated data (fewer elements than declared), too few or too many values on an
/// ASCII line, non-numeric values, values out of range of their type, NaN or infinite
/// coordinates or normals, polygons with fewer than 3 vertices, out-of-range vertex indices,
/// data after the last element of an ASCII file, a NUL byte in the header or in ASCII data
/// ("cloud.ply:9: unexpected NUL byte (byte offset 106): not a text file"), an ASCII line longer
/// than 64 MiB (a header line longer than 64 KiB). Declared counts are not trusted: memory
/// grows with the data actually present, and endless input (/dev/zero, a FIFO) fails early.
PolygonSoup readPly(std::istream& in, const std::string& name);

/// Writes `soup` as PLY. Positions and normals are written as double, vertex and face
/// attributes in their own ScalarType (Float32 values rounded to float) after them, faces as
/// `list uchar int vertex_indices` (`list uint ...` when a polygon has more than 255 vertices,
/// `... uint vertex_indices` when an index exceeds the int range); a soup without polygons
/// gets no face element. Per-corner normals and texture coordinates are not stored. Binary
/// output reads back bit-exactly; ASCII output uses the shortest decimal form that reads back
/// to the identical value, so it does too.
///
/// Throws InvalidInput for an inconsistent soup (soup.validate()), an attribute whose name is
/// empty, contains white space, repeats another of its element or is one of x y z nx ny nz
/// (vertex) or vertex_indices vertex_index (face), or an attribute
/// value its integer type cannot hold (not integral or out of range) or that is finite but
/// beyond the float range for Float32. Stream errors are left in the state of `out`.
void writePly(const PolygonSoup& soup, std::ostream& out,
              PlyEncoding encoding = PlyEncoding::BinaryLittleEndian);

}  // namespace spacewarp
