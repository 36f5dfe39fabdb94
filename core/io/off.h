#pragma once
// Object File Format (OFF) polygon soups and point clouds.

#include <istream>
#include <ostream>
#include <string>

#include "core/geometry.h"

namespace spacewarp {

/// Reads an OFF file: a header line `OFF` (or `NOFF` with a normal after each position;
/// `COFF`/`CNOFF` with colour values, which are ignored), a counts line
/// `vertices faces [edges]` (it may also follow the keyword on the header line), one vertex
/// per line (`x y z`, world units, then `nx ny nz` for NOFF, then optional numbers that are
/// ignored), and one face per line (`k i0 ... ik-1`, 0-based, optionally followed by colour
/// numbers that are ignored). `#` starts a comment; blank lines are skipped. A file with
/// 0 faces reads as a point cloud.
///
/// `name` only appears in messages (usually the path). Throws IoError, and nothing else,
/// naming `name` and the line ("mesh.off:12: ...") for a missing or unknown header, a bad
/// counts line, fewer vertices or faces than declared, content after the last face, a
/// non-numeric token, a NaN or infinite coordinate or normal, k < 3, fewer than k indices,
/// an out-of-range index, or a read error.
PolygonSoup readOff(std::istream& in, const std::string& name);

/// Writes `soup` as OFF (as NOFF, with the normal after each position, when the soup has
/// normals): numbers in the shortest decimal form that reads back to the identical double,
/// 0-based indices, edge count 0. Attributes are not stored. Throws InvalidInput (from
/// soup.validate()) for an inconsistent soup; stream errors are left in the state of `out`.
void writeOff(const PolygonSoup& soup, std::ostream& out);

}  // namespace spacewarp
