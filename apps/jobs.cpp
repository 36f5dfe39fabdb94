#include "apps/jobs.h"

#include <algorithm>
#include <bit>
#include <charconv>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include <spacewarp/core/deform.h>
#include <spacewarp/core/detail/memory_budget.h>
#include <spacewarp/core/errors.h>
#include <spacewarp/core/io/atomic_file.h>
#include <spacewarp/core/io/mesh_io.h>
#include "apps/cli_context.h"
#include "apps/file_kinds.h"

namespace spacewarp::cli {

void writeSoupFile(const PolygonSoup& soup, const std::filesystem::path& output, bool ascii,
                   const CliContext& context) {
  WriteOptions options;
  if (ascii) options.plyEncoding = PlyEncoding::Ascii;
  writeSoup(soup, output, options);
  if (const auto lost = unstoredContent(soup, formatFromPath(output)); !lost.empty()) {
    std::string line = output.string() + ": the format cannot store the input's ";
    for (std::size_t k = 0; k < lost.size(); ++k) line += (k ? "; " : "") + lost[k];
    context.warn(line + "; they are not written");
  }
}

void warnNotKept(const std::filesystem::path& input, const PolygonSoup& soup,
                 const CliContext& context) {
  if (soup.notKept.empty()) return;
  std::string line = input.string() + ": spacewarp does not keep the input's ";
  for (std::size_t k = 0; k < soup.notKept.size(); ++k) line += (k ? "; " : "") + soup.notKept[k];
  context.warn(line + "; they are not in the output");
}

void warnSingularNormals(const std::filesystem::path& input, std::size_t singular,
                         std::size_t total, const CliContext& context) {
  if (singular == 0) return;
  context.warn(input.string() + ": the warp is singular at " + std::to_string(singular) + " of " +
               std::to_string(total) +
               " vertices; their normals are undefined (written as the flattened surface's "
               "normal, or zero)");
}

void deformSoup(const Warp& warp, PolygonSoup& soup, const std::filesystem::path& input,
                const std::filesystem::path& output, bool ascii, const CliContext& context) {
  const DeformReport report =
      namingFile(input.string(), [&] { return deform(warp, soup, context.progress()); });
  writeSoupFile(soup, output, ascii, context);
  warnNotKept(input, soup, context);
  warnSingularNormals(input, report.singularNormals, soup.size(), context);
}

void deformSoupFile(const Warp& warp, const std::filesystem::path& input,
                    const std::filesystem::path& output, bool ascii, const CliContext& context) {
  formatFromPath(output);
  PolygonSoup soup = readSoup(input);
  deformSoup(warp, soup, input, output, ascii, context);
}

namespace {

// NumPy's .npy format, version 1.0: magic, header length, a Python dict literal padded with
// spaces to a multiple of 64 bytes and ended by a newline; the raw little-endian data follows.
void writeNpyHeader(std::ostream& out, std::size_t rows, std::size_t columns) {
  static_assert(std::endian::native == std::endian::little, "the .npy writer assumes '<f8'");
  std::string header = "{'descr': '<f8', 'fortran_order': False, 'shape': (" +
                       std::to_string(rows) + ", " + std::to_string(columns) + "), }";
  const std::size_t prefix = 10;  // magic (6) + version (2) + header length (2)
  header.append(63 - (prefix + header.size()) % 64, ' ');
  header += '\n';
  const auto length = static_cast<std::uint16_t>(header.size());
  out.write("\x93NUMPY\x01\x00", 8);
  const char lengthBytes[2] = {static_cast<char>(length & 0xff), static_cast<char>(length >> 8)};
  out.write(lengthBytes, 2);
  out << header;
}

void writeCsvHeader(std::ostream& out, const Coordinates& coordinates) {
  for (std::size_t c = 0; c < coordinates.columnCount(); ++c)
    out << (c ? "," : "") << coordinates.columnName(c);
  out << '\n';
}

void writeCsvRows(std::ostream& out, std::span<const double> rows, std::size_t count,
                  std::size_t columns) {
  std::string line;
  char buffer[32];
  for (std::size_t i = 0; i < count; ++i) {
    line.clear();
    for (std::size_t c = 0; c < columns; ++c) {
      if (c) line += ',';
      const auto result = std::to_chars(buffer, buffer + sizeof buffer, rows[i * columns + c]);
      line.append(buffer, result.ptr);
    }
    line += '\n';
    out << line;
  }
}

// Rows of weights are computed and written in blocks of about this many bytes, so the matrix of
// millions of points by thousands of columns is never held at once.
constexpr std::size_t kWeightsBlockBytes = std::size_t{64} << 20;

}  // namespace

void writeWeightsFile(const Coordinates& coordinates, const std::filesystem::path& pointsPath,
                      const std::filesystem::path& output) {
  const std::string extension = lowerExtension(output);  // w.CSV as deform takes OUT.PLY
  if (extension != ".csv" && extension != ".npy")
    throw InvalidInput(output.string() + ": weights are written as .csv or .npy");
  formatFromPath(pointsPath);
  const PolygonSoup points = readSoup(pointsPath);
  const std::size_t n = points.size();
  const std::size_t m = coordinates.columnCount();
  // At least 64 rows a block, so that weightsBatch still has work for every core.
  const std::size_t rowBytes = std::max<std::size_t>(m, 1) * sizeof(double);
  const std::size_t block = std::min(n, std::max<std::size_t>(kWeightsBlockBytes / rowBytes, 64));
  detail::checkMemory(double(block) * double(m) * sizeof(double),
                      pointsPath.string() + ": the weights of " + std::to_string(block) +
                          " points (a block of the output) by " + std::to_string(m) + " columns");
  std::vector<double> rows(block * m);
  writeFileAtomically(output, [&](std::ostream& out) {
    if (extension == ".npy")
      writeNpyHeader(out, n, m);
    else
      writeCsvHeader(out, coordinates);
    for (std::size_t begin = 0; begin < n; begin += block) {
      const std::size_t count = std::min(block, n - begin);
      const std::span<double> values(rows.data(), count * m);
      // Named like deform's errors: "pts.ply: ShepardCoordinates: 146 of 208 points ...".
      namingFile(pointsPath.string(),
                 [&] { coordinates.weightsBatch(points.positions, begin, begin + count, values); });
      if (extension == ".npy")
        out.write(reinterpret_cast<const char*>(values.data()),
                  static_cast<std::streamsize>(values.size() * sizeof(double)));
      else
        writeCsvRows(out, values, count, m);
    }
  });
}

Rig loadRigFile(const std::filesystem::path& path, const CliContext& context) {
  Rig rig = loadRig(path, context.progress());
  for (const std::string& warning : rig.warnings) context.warn(warning);
  return rig;
}

void createOutputFolder(const std::filesystem::path& dir) {
  std::error_code error;
  std::filesystem::create_directories(dir, error);
  if (error) throw IoError(dir.string() + ": cannot create the output folder: " + error.message());
}

void writeJsonFile(const nlohmann::json& j, const std::filesystem::path& path) {
  writeFileAtomically(path, [&](std::ostream& out) { out << j.dump(2) << '\n'; });
}

}  // namespace spacewarp::cli
