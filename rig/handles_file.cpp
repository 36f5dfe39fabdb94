#include <spacewarp/rig/handles_file.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include <spacewarp/core/errors.h>
#include <spacewarp/rig/detail/json_file.h>
#include <spacewarp/rig/detail/rig_reader.h>
#include <spacewarp/rig/rig.h>

namespace spacewarp {

namespace {

using nlohmann::json;

// Reads one handles file into regions of soup-vertex indices, with messages that name the file
// and the JSON path ("h.json: handles[2].vertices[5]: ..."). Range and shape checks are done
// here, where the path is known; resolveHandles() then finds only conflicts.
class HandlesReader {
 public:
  HandlesReader(std::string file, std::size_t vertexCount)
      : file_(std::move(file)), vertexCount_(vertexCount) {}

  std::vector<HandleRegion> read(const json& root) const {
    if (!root.is_object()) fail("", "must be a JSON object {\"handles\": [...]}");
    allowOnly(root, "", {"handles"});
    if (!root.contains("handles")) fail("handles", "is missing");
    const json& list = root.at("handles");
    if (!list.is_array() || list.empty())
      fail("handles", "must be a non-empty array of handle regions");
    std::vector<HandleRegion> regions;
    for (std::size_t r = 0; r < list.size(); ++r)
      regions.push_back(region(list[r], "handles[" + std::to_string(r) + "]"));
    return regions;
  }

 private:
  [[noreturn]] void fail(const std::string& at, const std::string& what) const {
    throw InvalidInput(printable(file_ + ": " + (at.empty() ? "" : at + ": ") + what));
  }

  // Unknown keys are errors, as in rigs: a misspelt key would otherwise be silently ignored.
  void allowOnly(const json& object, const std::string& at,
                 const std::vector<std::string>& keys) const {
    for (const auto& [key, value] : object.items()) {
      if (std::find(keys.begin(), keys.end(), key) != keys.end()) continue;
      std::string list;
      for (const std::string& k : keys) list += (list.empty() ? "" : ", ") + k;
      fail(at.empty() ? key : at + "." + key, "is not a key here (the keys: " + list + ")");
    }
  }

  HandleRegion region(const json& object, const std::string& at) const {
    if (!object.is_object())
      fail(at, "must be an object {\"vertices\": [...], \"matrix\" or \"targets\": [...]}");
    allowOnly(object, at, {"vertices", "matrix", "targets"});
    HandleRegion region;
    region.vertices = vertices(object, at);
    const bool matrix = object.contains("matrix"), targets = object.contains("targets");
    if (matrix && targets) fail(at, "has both 'matrix' and 'targets': give one");
    if (!matrix && !targets) fail(at, "needs 'matrix' (an affine map) or 'targets' (points)");
    if (matrix)
      region.matrix = affineMatrix(object.at("matrix"), at + ".matrix");
    else
      region.targets = points(object.at("targets"), at + ".targets", region.vertices.size());
    return region;
  }

  std::vector<std::uint32_t> vertices(const json& object, const std::string& at) const {
    if (!object.contains("vertices")) fail(at + ".vertices", "is missing");
    const json& list = object.at("vertices");
    if (!list.is_array() || list.empty())
      fail(at + ".vertices", "must be a non-empty array of vertex indices");
    std::vector<std::uint32_t> out;
    out.reserve(list.size());
    for (std::size_t k = 0; k < list.size(); ++k) {
      const std::string entry = at + ".vertices[" + std::to_string(k) + "]";
      const json& v = list[k];
      // Whole numbers from 0 (-0 is one too); negative and fractional numbers are not.
      if (!v.is_number_unsigned() && !(v.is_number_integer() && v.get<std::int64_t>() == 0))
        fail(entry, "must be a vertex index (a whole number from 0), not " + v.dump());
      const auto index = v.is_number_unsigned() ? v.get<std::uint64_t>() : std::uint64_t{0};
      if (index > std::numeric_limits<std::uint32_t>::max())
        fail(entry, std::to_string(index) + " is beyond the largest vertex index");
      if (index >= vertexCount_)
        fail(entry, std::to_string(index) + " is out of range (the model has " +
                        std::to_string(vertexCount_) + " vertices, 0.." +
                        std::to_string(vertexCount_ - 1) + " in file order)");
      out.push_back(static_cast<std::uint32_t>(index));
    }
    return out;
  }

  std::vector<double> numbers(const json& v, const std::string& at, std::size_t n) const {
    return detail::finiteNumbers(v, n, [&](const std::string& what) { fail(at, what); });
  }

  // Row-major rows, as rigs take them; GLM is column-major.
  Mat4 affineMatrix(const json& rows, const std::string& at) const {
    if (!rows.is_array() || rows.size() != 4) fail(at, "must be an array of 4 rows of 4 numbers");
    Mat4 m;
    for (int r = 0; r < 4; ++r) {
      const std::vector<double> row = numbers(rows[r], at + "[" + std::to_string(r) + "]", 4);
      for (int c = 0; c < 4; ++c) m[c][r] = row[c];
    }
    if (m[0][3] != 0.0 || m[1][3] != 0.0 || m[2][3] != 0.0 || m[3][3] != 1.0)
      fail(at + "[3]", "must be [0, 0, 0, 1]: the matrix must be affine");
    return m;
  }

  std::vector<Vec3> points(const json& list, const std::string& at, std::size_t count) const {
    if (!list.is_array())
      fail(at, "must be an array of [x, y, z] points, one for each of 'vertices'");
    if (list.size() != count)
      fail(at, "has " + std::to_string(list.size()) + " points but 'vertices' has " +
                   std::to_string(count) + ": give one target for each vertex");
    std::vector<Vec3> out;
    for (std::size_t k = 0; k < list.size(); ++k) {
      const std::vector<double> p = numbers(list[k], at + "[" + std::to_string(k) + "]", 3);
      out.emplace_back(p[0], p[1], p[2]);
    }
    return out;
  }

  std::string file_;
  std::size_t vertexCount_;
};

}  // namespace

std::vector<HandleRegion> parseHandlesJson(const nlohmann::json& root, const std::string& where,
                                           std::size_t vertexCount) {
  return HandlesReader(where, vertexCount).read(root);
}

std::vector<HandleRegion> readHandlesFile(const std::filesystem::path& path,
                                          std::size_t vertexCount) {
  // The rig files' reading (blocks, NUL bytes, duplicate keys, nesting depth, syntax error
  // positions), which is not specific to rigs.
  return parseHandlesJson(detail::readJsonFile(path, "handles file", "a handles file"),
                          printable(path.string()), vertexCount);
}

}  // namespace spacewarp
