#include "apps/jobs.h"

#include <charconv>
#include <string>
#include <vector>

#include "core/deform.h"
#include "core/errors.h"
#include "core/io/atomic_file.h"
#include "core/io/mesh_io.h"

namespace spacewarp::cli {

void deformSoupFile(const Warp& warp, const std::filesystem::path& input,
                    const std::filesystem::path& output, bool ascii,
                    const ProgressCallback& progress) {
  formatFromPath(output);
  PolygonSoup soup = readSoup(input);
  try {
    deform(warp, soup, progress);
  } catch (const InvalidInput& e) {
    throw InvalidInput(input.string() + ": " + e.what());
  }
  WriteOptions options;
  if (ascii) options.plyEncoding = PlyEncoding::Ascii;
  writeSoup(soup, output, options);
}

void writeWeightsFile(const Coordinates& coordinates, const std::filesystem::path& pointsPath,
                      const std::filesystem::path& output) {
  formatFromPath(pointsPath);
  const PolygonSoup points = readSoup(pointsPath);
  const std::size_t m = coordinates.columnCount();
  std::vector<double> rows(points.size() * m);
  coordinates.weightsBatch(points.positions, rows);
  writeFileAtomically(output, [&](std::ostream& out) {
    for (std::size_t c = 0; c < m; ++c) out << (c ? "," : "") << coordinates.columnName(c);
    out << '\n';
    std::string line;
    char buffer[32];
    for (std::size_t i = 0; i < points.size(); ++i) {
      line.clear();
      for (std::size_t c = 0; c < m; ++c) {
        if (c) line += ',';
        const auto result = std::to_chars(buffer, buffer + sizeof buffer, rows[i * m + c]);
        line.append(buffer, result.ptr);
      }
      line += '\n';
      out << line;
    }
  });
}

void writeJsonFile(const nlohmann::json& j, const std::filesystem::path& path) {
  writeFileAtomically(path, [&](std::ostream& out) { out << j.dump(2) << '\n'; });
}

}  // namespace spacewarp::cli
