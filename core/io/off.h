#pragma once
// Object File Format (OFF) polygon soups and point clouds.

#include <istream>
#include <ostream>
#include <string>
#include <vector>

#include <spacewarp/core/geometry.h>

namespace spacewarp {

/// Reads an OFF file: a header line `OFF` (or `NOFF` with a normal after each position;
/// `COFF`/`CNOFF` with a colour after that), a counts line `vertices faces [edges]` (it may
/// also follow the keyword on the header line), one vertex per line (`x y z`, world units,
/// then `nx ny nz` for NOFF, then `r g b [a]` for COFF, then optional numbers that are
/// ignored), and one face per line (`k i0 ... ik-1`, 0-based, optionally followed by a colour
/// `r g b [a]`). `#` starts a comment; blank lines are skipped. A file with 0 faces reads as a
/// point cloud. Colours become the vertex or face attributes red, green, blue [, alpha]:
/// uchar when every value is an integer in 0..255, float otherwise. Face colours are kept
/// only when every face has one with the same number of values, and dropped otherwise
/// (colour-map indices, mixed sizes).
///
/// `name` only appears in messages (usually the path). Throws IoError, and nothing else,
/// naming `name` and the line ("mesh.off:12: ...") for a missing or unknown header, a bad
/// counts line, fewer vertices or faces than declared, content after the last face, a
/// non-numeric token, a NaN or infinite coordinate or normal, k < 3, fewer than k indices,
/// an out-of-range index, COFF vertices without 3 or 4 colour values (or with different
/// counts), an infinite colour value, a NUL byte ("mesh.off:1: unexpected NUL byte (byte offset
/// 0): not a text file"), a line longer than 64 MiB, or a read error. The input is read line by
/// line as it comes, so binary or endless input (/dev/zero, a FIFO) fails early.
PolygonSoup readOff(std::istream& in, const std::string& name);

/// The attributes that OFF stores as colours: red, green, blue and, if present, alpha, when
/// the first three are all among `attributes` (vertex or face attributes); otherwise none.
std::vector<const ScalarAttribute*> offColours(const std::vector<ScalarAttribute>& attributes);

/// Writes `soup` as OFF (as NOFF, with the normal after each position, when the soup has
/// normals; with a C prefix when its vertices have colours): numbers in the shortest decimal
/// form that reads back to the identical double (colours that are not uchar with a decimal
/// point, so that they read back as float), 0-based indices, edge count 0. Vertex and face
/// colours (offColours()) are stored; other attributes are not. Throws InvalidInput (from
/// soup.validate()) for an inconsistent soup; stream errors are left in the state of `out`.
void writeOff(const PolygonSoup& soup, std::ostream& out);

}  // namespace spacewarp
