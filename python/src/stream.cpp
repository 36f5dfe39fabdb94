// Files warped in pieces: deform_file (the CLI's deform of soups and clouds, streamed where the
// input allows), and the row-range pieces spacewarp.dask.deform_ply is built on.

#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>

#include <filesystem>
#include <string>
#include <vector>

#include <spacewarp/core/deform.h>
#include <spacewarp/core/deform_stream.h>
#include <spacewarp/core/errors.h>
#include <spacewarp/core/io/mesh_io.h>
#include <spacewarp/core/io/ply_stream.h>

#include "common.h"

namespace spacewarp::python {
namespace {

using namespace pybind11::literals;
using Path = std::filesystem::path;

/// NumPy's code of a PLY scalar type in the file's byte order ("<f4").
std::string numpyType(ScalarType type, PlyEncoding encoding) {
  const char order = encoding == PlyEncoding::BinaryBigEndian ? '>' : '<';
  switch (type) {
    case ScalarType::Int8:
      return "i1";
    case ScalarType::UInt8:
      return "u1";
    case ScalarType::Int16:
      return std::string(1, order) + "i2";
    case ScalarType::UInt16:
      return std::string(1, order) + "u2";
    case ScalarType::Int32:
      return std::string(1, order) + "i4";
    case ScalarType::UInt32:
      return std::string(1, order) + "u4";
    case ScalarType::Float32:
      return std::string(1, order) + "f4";
    case ScalarType::Float64:
      return std::string(1, order) + "f8";
  }
  return "f8";
}

const char* encodingName(PlyEncoding encoding) {
  switch (encoding) {
    case PlyEncoding::Ascii:
      return "ascii";
    case PlyEncoding::BinaryLittleEndian:
      return "binary_little_endian";
    case PlyEncoding::BinaryBigEndian:
      return "binary_big_endian";
  }
  return "";
}

StreamDeformOptions streamOptions(const std::optional<long long>& chunkPoints) {
  StreamDeformOptions options;
  if (chunkPoints) {
    if (*chunkPoints < 1) throw InvalidInput("chunk_points must be at least 1");
    options.chunkPoints = static_cast<std::size_t>(*chunkPoints);
  }
  return options;
}

py::dict reportDict(const StreamDeformReport& r, bool streamed) {
  return py::dict("points"_a = r.points, "faces"_a = r.faces, "chunks"_a = r.chunks,
                  "streamed"_a = streamed, "singular_normals"_a = r.singularNormals);
}

void warnReport(const Path& input, const StreamDeformReport& r) {
  std::vector<std::string> warnings;
  if (!r.notKept.empty()) {
    std::string line = input.string() + ": spacewarp does not keep the input's ";
    for (std::size_t k = 0; k < r.notKept.size(); ++k) line += (k ? "; " : "") + r.notKept[k];
    warnings.push_back(line + "; they are not in the output");
  }
  if (r.singularNormals > 0) {
    warnings.push_back(input.string() + ": the warp is singular at " +
                       std::to_string(r.singularNormals) + " of " + std::to_string(r.points) +
                       " vertices; their normals are undefined");
  }
  warnAll(warnings);
}

}  // namespace

void bindStream(py::module_& m) {
  m.def(
      "deform_file",
      [](const Warp& warp, const Path& input, const Path& output,
         const std::optional<long long>& chunkPoints, bool ascii, const py::object& progress) {
        StreamDeformOptions options;
        if (chunkPoints && *chunkPoints < 0) throw InvalidInput("chunk_points must be >= 0");
        if (chunkPoints && *chunkPoints > 0)
          options.chunkPoints = static_cast<std::size_t>(*chunkPoints);
        options.ascii = ascii;
        if (ascii && formatFromPath(output) != FileFormat::Ply)
          throw InvalidInput(output.string() + ": ascii applies to .ply output only");
        StreamDeformReport report;
        bool streamed = false;
        runCancellable(progress, [&](const ProgressCallback& callback) {
          streamed = (!chunkPoints || *chunkPoints > 0) &&
                     formatFromPath(output) == FileFormat::Ply && isStreamablePly(input);
          if (streamed) {
            options.progress = callback;
            report = deformFileStreaming(warp, input, output, options);
            return;
          }
          PolygonSoup soup = readSoup(input);
          report.singularNormals = namingFile(input.string(), [&] {
                                     return deform(warp, soup, callback);
                                   }).singularNormals;
          WriteOptions write;
          if (ascii) write.plyEncoding = PlyEncoding::Ascii;
          writeSoup(soup, output, write);
          report.points = soup.size();
          report.faces = soup.polygonCount();
          report.chunks = 1;
          report.notKept = soup.notKept;
        });
        warnReport(input, report);
        return reportDict(report, streamed);
      },
      "warp"_a, "input"_a, "output"_a, py::kw_only(), "chunk_points"_a = py::none(),
      "ascii"_a = false, "progress"_a = py::none(),
      R"(Warps the soup or point cloud file `input` (OBJ, OFF, PLY) into `output` (any of them),
as `spacewarp deform` does, with the same bytes. A binary PLY input written to PLY is streamed:
read, warped and written `chunk_points` rows at a time (default 1048576), so memory stays bounded
whatever the file size; chunk_points=0 reads the whole file instead, as do ASCII PLY input, a
pipe (it cannot be read twice) and OBJ/OFF on either side ('streamed' in the result says which).
A warp's domain error names `input` and the point by its index in the file, as the whole-file
path does, but counts "at least" the points of the first chunk that failed (exactly the file's
when that chunk is the last). ascii: write PLY as ASCII. The output is written atomically: after an
error or a cancel (Ctrl-C, or `progress(stage, fraction)` returning False) no output or
temporary file is left. Returns {'points', 'faces', 'chunks', 'streamed', 'singular_normals'}.)");

  m.def(
      "ply_layout",
      [](const Path& path) {
        PlyLayout layout;
        std::uint64_t outputRow = 0;
        withoutGil([&] {
          layout = plyLayout(path);
          outputRow = plyOutputRowBytes(layout);
        });
        py::list fields;
        py::list properties;
        for (const PlyPropertyLayout& p : layout.vertexProperties) {
          const std::string type = numpyType(p.type, layout.encoding);
          fields.append(py::make_tuple(p.name, type));
          properties.append(py::make_tuple(p.name, type, p.offset));
        }
        py::list elements;
        for (const PlyElementLayout& e : layout.elements) {
          elements.append(py::dict("name"_a = e.name, "count"_a = e.count, "offset"_a = e.offset,
                                   "bytes"_a = e.bytes));
        }
        const py::object dtype = py::module_::import("numpy").attr("dtype")(fields);
        return py::dict(
            "path"_a = layout.path.string(), "encoding"_a = encodingName(layout.encoding),
            "file_bytes"_a = layout.fileBytes, "vertex_count"_a = layout.vertexCount,
            "vertex_offset"_a = layout.vertexOffset, "vertex_row_bytes"_a = layout.vertexRowBytes,
            "vertex_properties"_a = properties, "dtype"_a = dtype, "elements"_a = elements,
            "face_count"_a = layout.faceCount, "largest_polygon"_a = layout.largestPolygon,
            "output_row_bytes"_a = outputRow);
      },
      "path"_a,
      R"(The byte layout of the binary PLY file `path` (vertex rows of scalar properties only), as
a dict: 'vertex_count', 'vertex_offset' (bytes from the start of the file to vertex row 0),
'vertex_row_bytes', 'vertex_properties' (a list of (name, NumPy type code, byte offset in the
row)), 'dtype' (the NumPy structured dtype of one vertex row, so that
np.memmap(path, dtype, 'r', vertex_offset, (vertex_count,)) views the rows), 'elements' (every
element in file order: {'name', 'count', 'offset', 'bytes'}), 'face_count', 'largest_polygon',
'file_bytes', 'encoding', 'path', and 'output_row_bytes' (bytes of one vertex row in the binary
output that deform_ply_rows writes). Reads through elements with list properties (faces) once,
checking them as the reader does. Raises IoError for an ASCII file, vertex list properties, a
malformed or truncated file; InvalidInput for a pipe (streaming reads a file twice).)");

  m.def(
      "deform_ply_rows",
      [](const Warp& warp, const Path& input, const Path& part, std::uint64_t firstRow,
         std::uint64_t rowCount, const std::optional<long long>& chunkPoints,
         const py::object& progress) {
        StreamDeformOptions options = streamOptions(chunkPoints);
        StreamDeformReport report;
        runCancellable(progress, [&](const ProgressCallback& callback) {
          options.progress = callback;
          report = deformPlyRows(warp, input, firstRow, rowCount, part, options);
        });
        warnReport(input, report);
        return reportDict(report, true);
      },
      "warp"_a, "input"_a, "part"_a, "first_row"_a, "row_count"_a, py::kw_only(),
      "chunk_points"_a = py::none(), "progress"_a = py::none(),
      R"(Warps vertex rows [first_row, first_row + row_count) of the binary PLY file `input` and
writes, atomically, to `part` exactly the bytes those rows take in the binary output of
deform_file (row_count × ply_layout(input)['output_row_bytes'] bytes: no header, no faces).
assemble_ply joins the parts. Errors name the file and the vertex by its index in the whole file
(a warp's "N of M points ..." counts "at least" the points of the first chunk that failed, out
of the file's vertices). Raises InvalidInput when `part` is `input` (also through a link).
Returns the same dict as deform_file.)");

  m.def(
      "assemble_ply",
      [](const Path& input, const std::vector<Path>& parts, const Path& output) {
        withoutGil([&] { assemblePly(input, parts, output); });
      },
      "input"_a, "parts"_a, "output"_a,
      R"(Writes `output` atomically: the PLY header deform_file writes for `input`, the files
`parts` in order (from deform_ply_rows, together every vertex row of `input`), then `input`'s
faces. The result is byte-identical to deform_file(warp, input, output). Parts are raw rows
with no header: only their sizes are checked, so their order (by first_row) and that they all
come from the same warp of this `input` are the caller's job; parts in the wrong order or from
another warp give a wrong output without an error. Raises InvalidInput naming the part that is
`input` itself or whose size is not a whole number of output rows, or when the parts do not add
up to the vertex count.)");
}

}  // namespace spacewarp::python
