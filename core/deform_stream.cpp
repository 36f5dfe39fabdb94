#include <spacewarp/core/deform_stream.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <future>
#include <string_view>
#include <vector>

#include <spacewarp/core/deform.h>
#include <spacewarp/core/errors.h>
#include <spacewarp/core/io/atomic_file.h>
#include <spacewarp/core/io/mesh_io.h>
#include <spacewarp/core/io/ply_stream.h>

namespace spacewarp {
namespace {

/// Chunks of fewer rows are read, warped and written in turn rather than three in flight.
constexpr std::uint64_t kPipelinedChunk = 4096;

/// Whether `c` is a character of a word (as a regex's \w).
bool wordChar(char c) { return std::isalnum(static_cast<unsigned char>(c)) || c == '_'; }

/// The run of decimal digits at `text[at]` (empty when there is none).
std::string_view digitsAt(std::string_view text, std::size_t at) {
  std::size_t n = 0;
  while (at + n < text.size() && std::isdigit(static_cast<unsigned char>(text[at + n]))) ++n;
  return text.substr(std::min(at, text.size()), n);
}

std::uint64_t number(std::string_view digits) { return std::stoull(std::string(digits)); }

/// `what` (an error of a warp or of deform() about the chunk of `count` rows that starts at
/// vertex `first`) with the indices of the chunk ("point 990") made indices of the whole file
/// of `total` vertices ("point 2990"), and its count of points ("1 of 1000 points") made one
/// of the file ("at least 1 of 3001 points": rows after the chunk were not warped, rows before
/// it were, without error; exactly that count when the chunk is the file's last and the run
/// started at vertex 0, so that the message is the whole-file path's). Scanned by hand: GCC
/// 12 warns falsely inside <regex> under ASan.
std::string fileIndices(std::string_view what, std::uint64_t first, std::size_t count,
                        std::uint64_t total, bool exact) {
  std::string out;
  for (std::size_t i = 0; i < what.size();) {
    const bool wordStart = i == 0 || !wordChar(what[i - 1]);
    bool replaced = false;
    for (const std::string_view word : {std::string_view("point "), std::string_view("vertex ")}) {
      if (!wordStart || what.substr(i, word.size()) != word) continue;
      const std::string_view digits = digitsAt(what, i + word.size());
      if (digits.empty()) continue;
      out.append(word).append(std::to_string(first + number(digits)));
      i += word.size() + digits.size();
      replaced = true;
      break;
    }
    if (!replaced) out += what[i++];
  }
  // The first "<n> of <m> points" that stands as words, when m is the chunk's count.
  for (std::size_t i = 0; i < out.size(); ++i) {
    if (i > 0 && wordChar(out[i - 1])) continue;
    const std::string_view view(out), done = digitsAt(view, i);
    if (done.empty() || view.substr(i + done.size(), 4) != " of ") continue;
    const std::string_view of = digitsAt(view, i + done.size() + 4);
    const std::size_t end = i + done.size() + 4 + of.size() + 7;
    if (of.empty() || view.substr(end - 7, 7) != " points" ||
        (end < view.size() && wordChar(view[end]))) {
      continue;
    }
    if (number(of) == count) {
      out = std::string(view.substr(0, i)) + (exact ? "" : "at least ") + std::string(done) +
            " of " + std::to_string(total) + " points" + std::string(view.substr(end));
    }
    break;
  }
  return out;
}

/// deform() of one chunk of `rows` (the same arithmetic as the whole-file path), its singular
/// normals counted. Rows start at vertex `first` of the file `name` of `total` vertices; its
/// errors name the file and the vertex by its index in the file (fileIndices()).
std::size_t deformRows(const Warp& warp, PointSet& rows, std::uint64_t first, std::uint64_t total,
                       bool exact, const std::string& name) {
  try {
    return deform(warp, rows).singularNormals;
  } catch (const InvalidInput& e) {
    throw InvalidInput(prefixed(name, fileIndices(e.what(), first, rows.size(), total, exact)));
  }
}

/// Reads, warps and writes rows [first, first + count) a chunk at a time, with three chunks in
/// flight: the next one read (and decoded) and the previous one written while this one is
/// warped, so that the disk, the page cache copies and the warp overlap. Each stage runs one
/// chunk at a time, in order, so the output and the first error reported are those of a
/// sequential loop.
void warpRows(const Warp& warp, const PlyLayout& layout, std::uint64_t first, std::uint64_t count,
              PlyStreamWriter& writer, const StreamDeformOptions& options,
              StreamDeformReport& report) {
  const std::string name = layout.path.string();
  PlyVertexReader reader(layout);
  ProgressTracker tracker(options.progress, "deform", count);
  // At most the rows there are: a chunk of the whole file is one buffer, not three.
  const std::uint64_t chunk =
      std::min<std::uint64_t>(options.chunkPoints, std::max<std::uint64_t>(count, 1));
  const auto size = [&](std::uint64_t begin) {
    return static_cast<std::size_t>(std::min<std::uint64_t>(chunk, count - begin));
  };
  const auto warpChunk = [&](std::uint64_t begin, PointSet& rows) {
    // Exact counts in errors when nothing before or after the chunk is left unwarped.
    const bool exact = first == 0 && begin + chunk >= count && first + count == layout.vertexCount;
    report.singularNormals +=
        deformRows(warp, rows, first + begin, layout.vertexCount, exact, name);
    report.points += rows.size();
    ++report.chunks;
  };
  if (chunk < kPipelinedChunk) {
    // Small chunks one after the other: starting threads per chunk would cost more than the
    // chunk's work.
    PointSet rows;
    for (std::uint64_t begin = 0; begin < count; begin += chunk) {
      reader.read(first + begin, size(begin), rows);
      warpChunk(begin, rows);
      writer.vertices(rows);
      tracker.advance(rows.size());
    }
    if (count == 0) tracker.finish();
    return;
  }
  std::array<PointSet, 3> rows;
  // Declared after what they use, so that on an exception they are waited for (a future of
  // std::async joins in its destructor) before it goes.
  std::future<void> reading, writing;
  const auto read = [&](std::uint64_t begin, PointSet& into) {
    return std::async(std::launch::async, [&reader, &size, first, begin, target = &into] {
      reader.read(first + begin, size(begin), *target);
    });
  };
  if (count > 0) reading = read(0, rows[0]);
  std::size_t slot = 0;
  std::size_t written = 0;  // Rows of the chunk being written, reported done once it is.
  for (std::uint64_t begin = 0; begin < count; begin += chunk, slot = (slot + 1) % 3) {
    reading.get();
    PointSet& current = rows[slot];
    if (begin + chunk < count) reading = read(begin + chunk, rows[(slot + 1) % 3]);
    warpChunk(begin, current);
    if (writing.valid()) writing.get();
    tracker.advance(written);
    written = current.size();
    writing = std::async(std::launch::async, [&writer, &current] { writer.vertices(current); });
  }
  if (writing.valid()) writing.get();
  // The last advance reports 100% once (a finish() after it would report it again).
  tracker.advance(written);
  if (count == 0) tracker.finish();
}

void checkChunk(const StreamDeformOptions& options) {
  if (options.chunkPoints == 0) throw InvalidInput("chunkPoints must be at least 1");
}

}  // namespace

StreamDeformReport deformFileStreaming(const Warp& warp, const std::filesystem::path& input,
                                       const std::filesystem::path& output,
                                       const StreamDeformOptions& options) {
  checkChunk(options);
  if (formatFromPath(output) != FileFormat::Ply)
    throw InvalidInput(output.string() + ": a streamed deform writes PLY only");
  const PlyLayout layout = plyLayout(input);
  StreamDeformReport report;
  report.faces = layout.faceCount;
  report.notKept = layout.notKept;
  const PlyEncoding encoding = options.ascii ? PlyEncoding::Ascii : PlyEncoding::BinaryLittleEndian;
  writeFileAtomically(output, [&](std::ostream& out) {
    PlyStreamWriter writer(layout, out, encoding);
    writer.header();
    warpRows(warp, layout, 0, layout.vertexCount, writer, options, report);
    writer.faces(options.progress);
  });
  return report;
}

StreamDeformReport deformPlyRows(const Warp& warp, const std::filesystem::path& input,
                                 std::uint64_t firstRow, std::uint64_t rowCount,
                                 const std::filesystem::path& part,
                                 const StreamDeformOptions& options) {
  checkChunk(options);
  // A part is raw rows, never a PLY: written over its input, it would destroy it.
  if (sameFile(part, input))
    throw InvalidInput(part.string() + ": the part is the input " + input.string());
  const PlyLayout layout = plyLayout(input);
  if (firstRow > layout.vertexCount || rowCount > layout.vertexCount - firstRow) {
    const std::string end = rowCount > ~std::uint64_t{0} - firstRow
                                ? "first_row + row_count overflows"
                                : "vertex rows " + std::to_string(firstRow) + " to " +
                                      std::to_string(firstRow + rowCount) + " are past the " +
                                      std::to_string(layout.vertexCount) + " vertices";
    throw InvalidInput(input.string() + ": " + end);
  }
  StreamDeformReport report;
  writeFileAtomically(part, [&](std::ostream& out) {
    PlyStreamWriter writer(layout, out, PlyEncoding::BinaryLittleEndian);
    warpRows(warp, layout, firstRow, rowCount, writer, options, report);
  });
  return report;
}

}  // namespace spacewarp
