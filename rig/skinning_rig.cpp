#include <spacewarp/rig/detail/skinning_rig.h>

#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include <spacewarp/core/errors.h>
#include <spacewarp/core/io/mesh_io.h>
#include <spacewarp/nonlinear/mls.h>
#include <spacewarp/nonlinear/shepard.h>
#include <spacewarp/nonlinear/skinning.h>
#include <spacewarp/rbf/rbf_coordinates.h>

namespace spacewarp::detail {

namespace {

[[noreturn]] void bad(const std::filesystem::path& path, const std::string& what) {
  throw IoError(printable(path.string() + ": " + what));
}

// The numbers of one CSV line (separated by commas and/or blanks); false if some field is not a
// number.
bool parseCsvLine(std::string_view line, std::vector<double>& out) {
  out.clear();
  std::size_t i = 0;
  const auto separator = [](char c) { return c == ',' || c == ' ' || c == '\t' || c == '\r'; };
  while (i < line.size()) {
    while (i < line.size() && separator(line[i])) ++i;
    if (i == line.size()) break;
    double v = 0.0;
    const auto [end, ec] = std::from_chars(line.data() + i, line.data() + line.size(), v);
    if (ec != std::errc() || (end != line.data() + line.size() && !separator(*end))) return false;
    out.push_back(v);
    i = std::size_t(end - line.data());
  }
  return true;
}

std::vector<double> readCsv(const std::filesystem::path& path, std::size_t& columns) {
  std::ifstream in(path);
  if (!in) bad(path, "cannot open");
  std::vector<double> values, row;
  std::string line;
  columns = 0;
  for (std::size_t number = 1; std::getline(in, line); ++number) {
    if (!parseCsvLine(line, row)) {
      if (number == 1) continue;  // a header of column names
      bad(path, "line " + std::to_string(number) + " is not a row of numbers");
    }
    if (row.empty()) continue;
    if (columns == 0) columns = row.size();
    if (row.size() != columns)
      bad(path, "line " + std::to_string(number) + " has " + std::to_string(row.size()) +
                    " values, the first row " + std::to_string(columns));
    values.insert(values.end(), row.begin(), row.end());
  }
  if (in.bad()) bad(path, "read error");
  if (values.empty()) bad(path, "no rows of weights");
  return values;
}

// NumPy's .npy, versions 1 to 3: magic, version, header length, a Python dict literal, the data.
// A non-zero expectedRows/expectedColumns is checked against the header's shape before reading.
std::vector<double> readNpy(const std::filesystem::path& path, std::size_t& columns,
                            std::size_t expectedRows, std::size_t expectedColumns) {
  std::ifstream in(path, std::ios::binary);
  if (!in) bad(path, "cannot open");
  char magic[8];
  if (!in.read(magic, 8) || std::memcmp(magic, "\x93NUMPY", 6) != 0)
    bad(path, "not a NumPy .npy file");
  std::uint32_t headerLength = 0;
  unsigned char length[4] = {0, 0, 0, 0};
  if (!in.read(reinterpret_cast<char*>(length), magic[6] == 1 ? 2 : 4))
    bad(path, "truncated .npy header");
  headerLength = length[0] | (length[1] << 8) | (std::uint32_t(length[2]) << 16) |
                 (std::uint32_t(length[3]) << 24);
  if (headerLength > 65536) bad(path, ".npy header too long");
  std::string header(headerLength, '\0');
  if (!in.read(header.data(), headerLength)) bad(path, "truncated .npy header");
  const bool f8 = header.find("'<f8'") != std::string::npos;
  const bool f4 = header.find("'<f4'") != std::string::npos;
  if (!f8 && !f4)
    bad(path, "the .npy array must hold little-endian float64 or float32 ('<f8', '<f4')");
  const bool fortran = header.find("'fortran_order': True") != std::string::npos;
  if (!fortran && header.find("'fortran_order': False") == std::string::npos)
    bad(path, "the .npy header has no 'fortran_order'");
  const std::size_t shape = header.find("'shape':");
  const std::size_t open = header.find('(', shape), close = header.find(')', open);
  if (shape == std::string::npos || open == std::string::npos || close == std::string::npos)
    bad(path, "the .npy header has no shape");
  std::vector<double> dims;
  const std::string shapeText = header.substr(open + 1, close - open - 1);
  std::string inside = shapeText;
  for (char& c : inside)
    if (c == ',') c = ' ';
  if (!parseCsvLine(inside, dims) || dims.size() != 2 || dims[0] < 1 || dims[1] < 1)
    bad(path, "the .npy array must be 2-D (points × bones) and not empty");
  // The shape against the file's size and the model's, before anything is allocated or read.
  const std::size_t itemSize = f8 ? sizeof(double) : sizeof(float);
  const std::streamoff dataStart = in.tellg();
  in.seekg(0, std::ios::end);
  const double available = double(in.tellg() - dataStart);
  in.seekg(dataStart);
  if (dims[0] * dims[1] * double(itemSize) > available)
    bad(path, "the .npy shape (" + shapeText + ") is too large for the file, which has " +
                  std::to_string(std::size_t(available)) + " bytes of data");
  const std::size_t rows = std::size_t(dims[0]);
  columns = std::size_t(dims[1]);
  if (expectedColumns != 0 && columns != expectedColumns)
    bad(path, "has " + std::to_string(columns) + " columns, but there are " +
                  std::to_string(expectedColumns) + " bones (one column per bone)");
  if (expectedRows != 0 && rows != expectedRows)
    bad(path, "has " + std::to_string(rows) + " rows, but the model has " +
                  std::to_string(expectedRows) + " vertices (one row each)");
  const std::size_t count = rows * columns;
  std::vector<double> values(count);
  if (f8) {
    if (!in.read(reinterpret_cast<char*>(values.data()), std::streamsize(count * sizeof(double))))
      bad(path, "the .npy data is shorter than its shape (" + std::to_string(rows) + " × " +
                    std::to_string(columns) + ")");
  } else {
    std::vector<float> f(count);
    if (!in.read(reinterpret_cast<char*>(f.data()), std::streamsize(count * sizeof(float))))
      bad(path, "the .npy data is shorter than its shape (" + std::to_string(rows) + " × " +
                    std::to_string(columns) + ")");
    for (std::size_t i = 0; i < count; ++i) values[i] = f[i];
  }
  if (fortran) {  // column-major (NumPy's order='F'): transposed into rows of bones
    std::vector<double> rowMajor(count);
    for (std::size_t c = 0; c < columns; ++c)
      for (std::size_t i = 0; i < rows; ++i) rowMajor[i * columns + c] = values[c * rows + i];
    values.swap(rowMajor);
  }
  return values;
}

// "bones": a non-empty array of row-major 4 × 4 matrices.
std::vector<Mat4> readBones(RigReader& r) {
  const nlohmann::json& bones = r.array("bones");
  std::vector<Mat4> out;
  for (std::size_t b = 0; b < bones.size(); ++b) {
    const std::string key = "bones[" + std::to_string(b) + "]";
    const auto fail = [&](const std::string& what) { r.fail(key, what); };
    if (!bones[b].is_array() || bones[b].size() != 4) fail("must be an array of 4 rows");
    Mat4 m;
    for (int row = 0; row < 4; ++row) {
      const std::vector<double> v = finiteNumbers(bones[b][std::size_t(row)], 4, [&](auto what) {
        r.fail(key + "[" + std::to_string(row) + "]", what);
      });
      for (int c = 0; c < 4; ++c) m[c][row] = v[std::size_t(c)];
    }
    out.push_back(m);
  }
  return out;
}

}  // namespace

std::vector<double> readWeightMatrix(const std::filesystem::path& path, std::size_t& columns,
                                     std::size_t expectedRows, std::size_t expectedColumns) {
  std::string extension = path.extension().string();
  for (char& c : extension) c = char(std::tolower(static_cast<unsigned char>(c)));
  if (std::filesystem::is_directory(path)) bad(path, "is a folder");
  if (extension == ".npy") return readNpy(path, columns, expectedRows, expectedColumns);
  if (extension == ".csv" || extension == ".txt") return readCsv(path, columns);
  bad(path, "weights are read from .csv or .npy files");
}

Rig skinningRig(RigReader& r) {
  SkinningOptions options;
  if (r.has("mode")) {
    try {
      options.mode = skinningModeFromName(r.string("mode"));
    } catch (const InvalidInput& e) {
      r.fail("mode", e.what());
    }
  }
  const std::vector<Mat4> bones = readBones(r);
  for (std::size_t b = 0; b < bones.size(); ++b) {
    try {
      checkBones({&bones[b], 1}, options.mode);
    } catch (const InvalidInput& e) {
      std::string what = e.what();
      what.erase(0, what.find(": ") + 2);  // "bone 0: " : the key names the bone
      r.fail("bones[" + std::to_string(b) + "]", what);
    }
  }
  // Default: 4 of a weights file (what real-time skinning keeps), all of the handles'
  // coordinates (exact and smooth; truncated they are only continuous).
  const bool fromFile = r.has("weights") || r.has("model");
  const double influences = r.number("influences", fromFile ? 4.0 : 0.0);
  if (!(influences >= 0.0) || influences != std::floor(influences) || influences > 1e6)
    r.fail("influences", "must be an integer >= 0 (0 keeps every bone's weight)");
  options.maxInfluences = std::size_t(influences);

  if (fromFile) {
    if (r.has("handles")) r.fail("handles", "is not read when 'weights' are given: remove one");
    if (r.has("coordinates"))
      r.fail("coordinates", "is not read when 'weights' are given: remove one");
    const std::filesystem::path weightsPath = r.path("weights");
    const std::filesystem::path modelPath = r.path("model");
    std::size_t columns = 0;
    std::vector<double> dense;
    PolygonSoup model;
    try {
      model = readSoup(modelPath);
    } catch (const IoError& e) {
      r.fail("model", e.what());
    }
    try {
      dense = readWeightMatrix(weightsPath, columns, model.positions.size(), bones.size());
    } catch (const IoError& e) {
      r.fail("weights", e.what());
    }
    if (columns != bones.size())
      r.fail("weights", weightsPath.string() + " has " + std::to_string(columns) +
                            " columns, but there are " + std::to_string(bones.size()) +
                            " bones (one column per bone)");
    if (dense.size() / columns != model.positions.size())
      r.fail("weights", weightsPath.string() + " has " + std::to_string(dense.size() / columns) +
                            " rows, but the model has " + std::to_string(model.positions.size()) +
                            " vertices (one row each)");
    SkinningWeights weights;
    try {
      weights = sparseSkinningWeights(dense, columns, options.maxInfluences);
    } catch (const InvalidInput& e) {
      r.fail("weights", weightsPath.string() + ": " + e.what());
    }
    r.finish();
    if (r.checking()) return {};
    return {std::make_shared<SkinningWarp>(bones, std::move(model.positions), std::move(weights),
                                           options.mode),
            nullptr};
  }

  std::vector<Vec3> handles = r.points("handles");
  if (handles.size() != bones.size())
    r.fail("handles", "must have one point per bone (" + std::to_string(bones.size()) + "), not " +
                          std::to_string(handles.size()));
  const std::string kind = r.has("coordinates") ? r.string("coordinates") : "rbf";
  if (kind != "rbf" && kind != "mls-affine" && kind != "idw")
    r.fail("coordinates", "'" + kind + "' is not one of: idw, mls-affine, rbf");
  r.finish();
  std::shared_ptr<const Coordinates> coordinates;
  if (kind == "idw") {  // Shepard's weights: non-negative, any number of distinct handles
    coordinates = std::make_shared<ShepardCoordinates>(std::move(handles));
    if (r.checking()) return {};
    return {std::make_shared<SkinningWarp>(bones, coordinates, options), coordinates};
  }
  // RBF and affine MLS reproduce affine functions, so they need 4 handles not in one plane.
  const std::string needs = "the " + kind + " coordinates of the handles need at least 4 " +
                            "handles not in one plane (so at least 4 bones) to reproduce affine " +
                            "motions";
  const std::string fewer = "; with fewer bones give 'weights' and 'model' files";
  if (handles.size() < 4) r.fail("handles", needs + fewer);
  try {
    if (kind == "mls-affine") {
      coordinates = std::make_shared<MlsAffineCoordinates>(std::move(handles));
    } else {
      if (r.checking()) return {};  // the RBF fit is the expensive part
      coordinates = std::make_shared<RbfCoordinates>(handles);
    }
  } catch (const InvalidInput& e) {
    r.fail("handles", needs + " (" + e.what() + ")" + fewer);
  }
  if (r.checking()) return {};
  return {std::make_shared<SkinningWarp>(bones, coordinates, options), coordinates};
}

}  // namespace spacewarp::detail
