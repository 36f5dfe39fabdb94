#include "apps/jobs.h"

#include <bit>
#include <charconv>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "core/deform.h"
#include "core/errors.h"
#include "core/io/atomic_file.h"
#include "core/io/mesh_io.h"

namespace spacewarp::cli {

void deformSoup(const Warp& warp, PolygonSoup& soup, const std::filesystem::path& input,
                const std::filesystem::path& output, bool ascii, const CliContext& context) {
  DeformReport report;
  try {
    report = deform(warp, soup, context.progress());
  } catch (const InvalidInput& e) {
    throw InvalidInput(input.string() + ": " + e.what());
  }
  WriteOptions options;
  if (ascii) options.plyEncoding = PlyEncoding::Ascii;
  writeSoup(soup, output, options);
  if (const auto lost = unstoredContent(soup, formatFromPath(output)); !lost.empty()) {
    std::string line = output.string() + ": the format cannot store the input's ";
    for (std::size_t k = 0; k < lost.size(); ++k) line += (k ? "; " : "") + lost[k];
    context.warn(line + "; they are not written");
  }
  if (report.singularNormals > 0) {
    context.warn(input.string() + ": the warp is singular at " +
                 std::to_string(report.singularNormals) + " of " + std::to_string(soup.size()) +
                 " vertices; their normals are undefined (written as the flattened surface's "
                 "normal, or zero)");
  }
}

void deformSoupFile(const Warp& warp, const std::filesystem::path& input,
                    const std::filesystem::path& output, bool ascii,
                    const CliContext& context) {
  formatFromPath(output);
  PolygonSoup soup = readSoup(input);
  deformSoup(warp, soup, input, output, ascii, context);
}

namespace {

// NumPy's .npy format, version 1.0: magic, header length, a Python dict literal padded with
// spaces to a multiple of 64 bytes and ended by a newline, then the raw little-endian data.
void writeNpy(std::ostream& out, std::span<const double> values, std::size_t rows,
              std::size_t columns) {
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
  out.write(reinterpret_cast<const char*>(values.data()),
            static_cast<std::streamsize>(values.size() * sizeof(double)));
}

void writeCsv(std::ostream& out, const Coordinates& coordinates, std::span<const double> rows,
              std::size_t count) {
  const std::size_t m = coordinates.columnCount();
  for (std::size_t c = 0; c < m; ++c) out << (c ? "," : "") << coordinates.columnName(c);
  out << '\n';
  std::string line;
  char buffer[32];
  for (std::size_t i = 0; i < count; ++i) {
    line.clear();
    for (std::size_t c = 0; c < m; ++c) {
      if (c) line += ',';
      const auto result = std::to_chars(buffer, buffer + sizeof buffer, rows[i * m + c]);
      line.append(buffer, result.ptr);
    }
    line += '\n';
    out << line;
  }
}

}  // namespace

void writeWeightsFile(const Coordinates& coordinates, const std::filesystem::path& pointsPath,
                      const std::filesystem::path& output) {
  const std::string extension = output.extension().string();
  if (extension != ".csv" && extension != ".npy")
    throw InvalidInput(output.string() + ": weights are written as .csv or .npy");
  formatFromPath(pointsPath);
  const PolygonSoup points = readSoup(pointsPath);
  const std::size_t m = coordinates.columnCount();
  std::vector<double> rows(points.size() * m);
  coordinates.weightsBatch(points.positions, rows);
  writeFileAtomically(output, [&](std::ostream& out) {
    if (extension == ".npy")
      writeNpy(out, rows, points.size(), m);
    else
      writeCsv(out, coordinates, rows, points.size());
  });
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
