#pragma once
// Warping a binary PLY file that need not fit in memory: rows are read, warped and written a
// chunk at a time, and the output is the same, byte for byte, as reading the whole file,
// deform() and writePly(). Also the row-range pieces that let separate processes warp one file
// (python spacewarp.dask.deform_ply): deformPlyRows() and assemblePly() (core/io/ply_stream.h).

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include <spacewarp/core/progress.h>
#include <spacewarp/core/warp.h>

namespace spacewarp {

/// Options of deformFileStreaming() and deformPlyRows().
struct StreamDeformOptions {
  /// Vertex rows read, warped and written at a time (at most the rows there are). Three chunks
  /// are in flight (one read, one warped, one written) from 4096 rows up, so memory is about
  /// 3 × chunkPoints × (the input row + ~50 bytes) plus the warp's own data: ~200 MB for 1M
  /// rows of float xyz. Large enough that applyBatch keeps every core busy. Smaller chunks run
  /// one after the other, reads and writes still in blocks of MBs. At least 1.
  std::size_t chunkPoints = std::size_t{1} << 20;
  /// Write ASCII PLY rather than binary little-endian (deformFileStreaming only).
  bool ascii = false;
  /// Called with the stage "deform" (vertex rows) and then "write faces"; return false to
  /// cancel (throws Cancelled; no output is left).
  ProgressCallback progress;
};

/// What a streaming deform did.
struct StreamDeformReport {
  std::uint64_t points = 0;  ///< Vertex rows warped.
  std::uint64_t faces = 0;   ///< Polygons copied to the output.
  std::uint64_t chunks = 0;  ///< Chunks of vertex rows.
  /// Vertices whose normals were carried through a singular Jacobian (DeformReport).
  std::uint64_t singularNormals = 0;
  /// What readPly() reads through but does not keep (PolygonSoup::notKept): not in the output.
  std::vector<std::string> notKept;
};

/// Warps the binary PLY file `input` (see isStreamablePly()) into the PLY file `output`,
/// written atomically (writeFileAtomically(): on any error or cancel no output or temporary
/// file is left, an existing `output` is untouched), chunk by chunk. The output is byte for byte
/// writePly(deform(warp, readPly(input))): positions through Warp::applyBatch, normals by
/// J^-T n as deform() carries them, attributes and faces copied, other elements dropped.
///
/// Throws IoError naming `input` for what plyLayout() and PlyVertexReader refuse (malformed or
/// truncated file, bad polygon, non-finite coordinate, naming the element and index), and for
/// an output that cannot be written (a full disk, naming `output`); InvalidInput naming `input`
/// and the vertex when the warp sends a point to a non-finite position, and for an output whose
/// extension is not .ply or chunkPoints 0. Unlike readPly(), a non-finite coordinate in a
/// late chunk is found after the chunks before it are warped, so a warp failure in an earlier
/// chunk is reported first. A warp's error (points outside its domain) is that of the whole-file
/// path, naming `input` and the point by its index in the file, but counts the points of the
/// first chunk that failed: "at least 1 of 3001 points are outside the cage (the first is point
/// 2990)", without "at least" when that chunk is the last (the count is then the file's).
StreamDeformReport deformFileStreaming(const Warp& warp, const std::filesystem::path& input,
                                       const std::filesystem::path& output,
                                       const StreamDeformOptions& options = {});

/// Warps vertex rows [firstRow, firstRow + rowCount) of the binary PLY file `input` and writes
/// exactly the bytes those rows take in the binary little-endian output of
/// deformFileStreaming() (no header, no faces) to `part`, atomically. assemblePly() joins the
/// parts of all rows into the output. Errors as deformFileStreaming() (indices are those of
/// the whole file, counts "at least"); InvalidInput for a range past the vertex count and for a
/// `part` that is `input` (also through a link). options.ascii is ignored.
StreamDeformReport deformPlyRows(const Warp& warp, const std::filesystem::path& input,
                                 std::uint64_t firstRow, std::uint64_t rowCount,
                                 const std::filesystem::path& part,
                                 const StreamDeformOptions& options = {});

}  // namespace spacewarp
