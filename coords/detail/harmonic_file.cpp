#include <spacewarp/coords/detail/harmonic_file.h>

#include <bit>
#include <cmath>
#include <cstring>
#include <fstream>
#include <string>

#include <spacewarp/core/errors.h>
#include <spacewarp/core/io/atomic_file.h>

namespace spacewarp::detail {

namespace {

static_assert(std::endian::native == std::endian::little,
              "the harmonic coordinate file format is little-endian");

constexpr char kMagic[8] = {'S', 'W', 'H', 'A', 'R', 'M', 'C', '\0'};
// Version 2: the mesh vertices are stored in the cage's frame (version 1 stored them in world
// units and is still read).
constexpr std::uint32_t kVersion = 2;
constexpr std::size_t kHeaderSize = 72;

// FNV-1a, 64-bit, over bytes.
struct Fnv {
  std::uint64_t h = 0xcbf29ce484222325ull;
  void add(const void* data, std::size_t size) {
    const auto* p = static_cast<const unsigned char*>(data);
    std::uint64_t x = h;
    for (std::size_t i = 0; i < size; ++i) x = (x ^ p[i]) * 0x100000001b3ull;
    h = x;
  }
};

// Writes raw values into a buffer sized in advance.
struct Writer {
  char* at;
  void bytes(const void* data, std::size_t size) {
    std::memcpy(at, data, size);
    at += size;
  }
  template <typename T>
  void put(const T& value) {
    bytes(&value, sizeof(T));
  }
};

template <typename T>
T get(std::span<const char> in, std::size_t offset) {
  T value;
  std::memcpy(&value, in.data() + offset, sizeof(T));
  return value;
}

// Reads raw values in order from a file whose size has been checked.
struct Reader {
  std::span<const char> data;
  std::size_t offset;
  template <typename T>
  T next() {
    const T value = get<T>(data, offset);
    offset += sizeof(T);
    return value;
  }
};

std::vector<char> readAll(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw IoError(path.string() + ": cannot open the harmonic coordinate file");
  std::vector<char> data((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (in.bad()) throw IoError(path.string() + ": cannot read the harmonic coordinate file");
  return data;
}

HarmonicCoordinates::FileInfo parseHeader(std::span<const char> data, const std::string& name) {
  const std::string where = name + ": ";
  if (data.size() < kHeaderSize + 8) {
    throw IoError(where + "not a harmonic coordinate file: " + std::to_string(data.size()) +
                  " bytes, too short for the header");
  }
  if (std::memcmp(data.data(), kMagic, sizeof kMagic) != 0)
    throw IoError(where + "not a harmonic coordinate file (bad magic)");
  HarmonicCoordinates::FileInfo info;
  info.version = get<std::uint32_t>(data, 8);
  if (info.version != 1 && info.version != kVersion) {
    throw IoError(where + "unsupported harmonic coordinate file version " +
                  std::to_string(info.version) + " (this build reads versions 1 and " +
                  std::to_string(kVersion) + ")");
  }
  info.cageVertexCount = get<std::uint64_t>(data, 16);
  info.cageTriangleCount = get<std::uint64_t>(data, 24);
  info.cageHash = get<std::uint64_t>(data, 32);
  info.meshVertexCount = get<std::uint64_t>(data, 40);
  info.tetCount = get<std::uint64_t>(data, 48);
  info.radiusEdgeRatio = get<double>(data, 56);
  info.maxTetVolume = get<double>(data, 64);
  return info;
}

// ---- the stages of reading a file, in order; `where` is "path: " ----

// The header's cage is `cage`: counts and hash.
void requireSameCage(const HarmonicCoordinates::FileInfo& info, const Cage& cage,
                     const std::string& where) {
  if (info.cageVertexCount == cage.vertexCount() &&
      info.cageTriangleCount == cage.triangleCount() && info.cageHash == harmonicCageHash(cage))
    return;
  throw InvalidInput(
      where + "the harmonic coordinates were solved for another cage (" +
      std::to_string(info.cageVertexCount) + " vertices, " +
      std::to_string(info.cageTriangleCount) + " triangles; this cage has " +
      std::to_string(cage.vertexCount()) + " and " + std::to_string(cage.triangleCount()) +
      (info.cageVertexCount == cage.vertexCount() && info.cageTriangleCount == cage.triangleCount()
           ? ", but its vertices or triangles differ)"
           : ")"));
}

// The header's counts are possible and the file has exactly the size they give.
void requireConsistentSize(const HarmonicCoordinates::FileInfo& info, std::size_t size,
                           const std::string& where) {
  const std::uint64_t n = info.meshVertexCount, m = info.tetCount, k = info.cageVertexCount;
  constexpr std::uint64_t kLimit = std::uint64_t{1} << 40;
  if (n < k || n > kLimit || m == 0 || m > kLimit || k > (kLimit / n)) {
    throw IoError(where + "corrupt harmonic coordinate file: impossible counts (" +
                  std::to_string(n) + " mesh vertices, " + std::to_string(m) + " tets)");
  }
  const std::uint64_t expected = kHeaderSize + n * 24 + m * 16 + n * 4 + n * k * 8 + 8;
  if (size < expected) {
    throw IoError(where + "truncated harmonic coordinate file: " + std::to_string(size) +
                  " bytes, " + std::to_string(expected) + " expected");
  }
  if (size > expected) {
    throw IoError(where + "corrupt harmonic coordinate file: " + std::to_string(size - expected) +
                  " trailing bytes");
  }
}

void requireChecksum(std::span<const char> data, const std::string& where) {
  Fnv fnv;
  fnv.add(data.data(), data.size() - 8);
  if (fnv.h != get<std::uint64_t>(data, data.size() - 8))
    throw IoError(where + "corrupt harmonic coordinate file: checksum mismatch");
}

// The mesh vertices, finite, the first k being the cage's; both the world and the local copy.
void readVertices(Reader& in, const HarmonicCoordinates::FileInfo& info, const Cage& cage,
                  TetMesh& mesh, const std::string& where) {
  const std::size_t n = info.meshVertexCount, k = info.cageVertexCount;
  // Version 2 stores the vertices in the cage's frame, version 1 in world units.
  std::vector<Vec3>& stored = info.version == 1 ? mesh.vertices : mesh.localVertices;
  stored.resize(n);
  for (Vec3& p : stored) {
    const double x = in.next<double>();
    const double y = in.next<double>();
    const double z = in.next<double>();
    p = Vec3(x, y, z);
    if (!isFinite(p))
      throw IoError(where + "corrupt harmonic coordinate file: a vertex is not finite");
  }
  for (std::size_t i = 0; i < k; ++i) {
    if (info.version == 1 ? stored[i] != cage.vertices()[i]
                          : stored[i] != mesh.frame.toLocal(cage.vertices()[i])) {
      throw IoError(where + "corrupt harmonic coordinate file: mesh vertex " + std::to_string(i) +
                    " is not cage vertex " + std::to_string(i));
    }
  }
  if (info.version == 1) {
    mesh.localVertices.resize(n);
    for (std::size_t i = 0; i < n; ++i)
      mesh.localVertices[i] = mesh.frame.toLocal(mesh.vertices[i]);
  } else {
    mesh.vertices = worldVertices(cage, mesh.frame, mesh.localVertices);
  }
}

void readTets(Reader& in, const HarmonicCoordinates::FileInfo& info, TetMesh& mesh,
              const std::string& where) {
  mesh.tets.resize(info.tetCount);
  for (auto& tet : mesh.tets) {
    for (std::uint32_t& v : tet) {
      v = in.next<std::uint32_t>();
      if (v >= info.meshVertexCount)
        throw IoError(where + "corrupt harmonic coordinate file: a tet corner is out of range");
    }
  }
}

void readBoundary(Reader& in, const HarmonicCoordinates::FileInfo& info, TetMesh& mesh,
                  const std::string& where) {
  mesh.boundaryTriangle.resize(info.meshVertexCount);
  for (std::int32_t& b : mesh.boundaryTriangle) {
    b = in.next<std::int32_t>();
    if (b < -1 || (b >= 0 && static_cast<std::uint64_t>(b) >= info.cageTriangleCount))
      throw IoError(where +
                    "corrupt harmonic coordinate file: a boundary triangle is out of range");
  }
}

std::vector<double> readValues(Reader& in, const HarmonicCoordinates::FileInfo& info,
                               const std::string& where) {
  const std::size_t count = info.meshVertexCount * info.cageVertexCount;
  std::vector<double> values(count);
  std::memcpy(values.data(), in.data.data() + in.offset, count * sizeof(double));
  in.offset += count * sizeof(double);
  for (const double v : values) {
    if (!std::isfinite(v))
      throw IoError(where + "corrupt harmonic coordinate file: a coordinate value is not finite");
  }
  return values;
}

}  // namespace

std::uint64_t harmonicCageHash(const Cage& cage) {
  Fnv fnv;
  for (const Vec3& p : cage.vertices()) {
    const double xyz[3] = {p.x, p.y, p.z};
    fnv.add(xyz, sizeof xyz);
  }
  for (const Triangle& t : cage.triangles()) {
    const std::uint32_t abc[3] = {t.x, t.y, t.z};
    fnv.add(abc, sizeof abc);
  }
  return fnv.h;
}

std::vector<char> encodeHarmonicFile(const Cage& cage, const TetMesh& mesh,
                                     std::span<const double> values, double radiusEdgeRatio,
                                     double volumeBound) {
  const std::size_t n = mesh.vertices.size(), k = cage.vertexCount();
  const std::size_t size = kHeaderSize + n * (24 + 4 + 8 * k) + mesh.tets.size() * 16 + 8;
  std::vector<char> data(size);
  Writer w{data.data()};
  w.bytes(kMagic, sizeof kMagic);
  w.put(kVersion);
  w.put(std::uint32_t{0});
  w.put(static_cast<std::uint64_t>(k));
  w.put(static_cast<std::uint64_t>(cage.triangleCount()));
  w.put(harmonicCageHash(cage));
  w.put(static_cast<std::uint64_t>(n));
  w.put(static_cast<std::uint64_t>(mesh.tets.size()));
  w.put(radiusEdgeRatio);
  w.put(volumeBound);
  for (const Vec3& p : mesh.localVertices) {
    w.put(p.x);
    w.put(p.y);
    w.put(p.z);
  }
  for (const auto& tet : mesh.tets)
    for (const std::uint32_t v : tet) w.put(v);
  for (const std::int32_t b : mesh.boundaryTriangle) w.put(b);
  w.bytes(values.data(), values.size() * sizeof(double));
  Fnv fnv;
  fnv.add(data.data(), size - 8);
  w.put(fnv.h);
  return data;
}

void writeHarmonicFile(const std::filesystem::path& path, const Cage& cage, const TetMesh& mesh,
                       std::span<const double> values, double radiusEdgeRatio, double volumeBound) {
  const std::vector<char> data =
      encodeHarmonicFile(cage, mesh, values, radiusEdgeRatio, volumeBound);
  writeFileAtomically(path, [&](std::ostream& out) {
    out.write(data.data(), static_cast<std::streamsize>(data.size()));
  });
}

HarmonicCoordinates::FileInfo readHarmonicFileInfo(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw IoError(path.string() + ": cannot open the harmonic coordinate file");
  std::vector<char> header(kHeaderSize + 8);
  in.read(header.data(), static_cast<std::streamsize>(header.size()));
  header.resize(static_cast<std::size_t>(in.gcount()));
  return parseHeader(header, path.string());
}

HarmonicFileData readHarmonicFile(const std::filesystem::path& path, const Cage& cage) {
  return decodeHarmonicFile(readAll(path), cage, path.string());
}

HarmonicFileData decodeHarmonicFile(std::span<const char> data, const Cage& cage,
                                    const std::string& name) {
  const std::string where = name + ": ";
  const HarmonicCoordinates::FileInfo info = parseHeader(data, name);
  requireSameCage(info, cage, where);
  requireConsistentSize(info, data.size(), where);
  requireChecksum(data, where);

  HarmonicFileData file;
  file.radiusEdgeRatio = info.radiusEdgeRatio;
  file.volumeBound = info.maxTetVolume;
  file.mesh.frame = cage.frame();
  Reader in{data, kHeaderSize};
  readVertices(in, info, cage, file.mesh, where);
  readTets(in, info, file.mesh, where);
  readBoundary(in, info, file.mesh, where);
  file.values = readValues(in, info, where);
  return file;
}

}  // namespace spacewarp::detail
