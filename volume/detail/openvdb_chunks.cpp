#include <spacewarp/volume/detail/openvdb_chunks.h>

#include <dlfcn.h>

#include <cstdint>
#include <istream>
#include <string>

#include <openvdb/Exceptions.h>
#include <openvdb/io/Compression.h>

namespace {

using ChunkReader = void (*)(std::istream&, char*, std::size_t);

/// The mangled name of openvdb::<version>::io::<function>(std::istream&, char*, unsigned long).
std::string mangledName(const std::string& function) {
#define SPACEWARP_STRINGIFY_(x) #x
#define SPACEWARP_STRINGIFY(x) SPACEWARP_STRINGIFY_(x)
  const std::string version = SPACEWARP_STRINGIFY(OPENVDB_VERSION_NAME);
#undef SPACEWARP_STRINGIFY
#undef SPACEWARP_STRINGIFY_
  static_assert(sizeof(std::size_t) == sizeof(unsigned long));
  return "_ZN7openvdb" + std::to_string(version.size()) + version + "2io" +
         std::to_string(function.size()) + function + "ERSiPcm";
}

/// libopenvdb's own definition of `function`: the next one after this program's.
ChunkReader openVdbsOwn(const char* function) {
  void* symbol = dlsym(RTLD_NEXT, mangledName(function).c_str());
  if (symbol == nullptr) {
    OPENVDB_THROW(openvdb::RuntimeError,
                  std::string("spacewarp: OpenVDB's io::") + function + " was not found");
  }
  return reinterpret_cast<ChunkReader>(symbol);
}

/// Reads a chunk's size field and refuses a stored-uncompressed chunk whose size is not the
/// caller's buffer size, then rewinds and lets OpenVDB read the chunk. A stream that cannot
/// rewind (io::Stream over a pipe) or a chunk that is skipped (data == nullptr) goes to OpenVDB
/// unchecked: the first cannot be checked without reading it, the second writes nothing.
void readCheckedChunk(ChunkReader own, std::istream& is, char* data, std::size_t numBytes) {
  const std::istream::pos_type start = is.tellg();
  if (data != nullptr && start != std::istream::pos_type(-1)) {
    std::int64_t stored = 0;
    is.read(reinterpret_cast<char*>(&stored), sizeof stored);
    if (!is.good()) OPENVDB_THROW(openvdb::IoError, "stream failure reading a chunk's size");
    // A size <= 0 is a chunk stored uncompressed, of -size bytes.
    const bool fits = numBytes <= std::uint64_t(INT64_MAX) && stored == -std::int64_t(numBytes);
    if (stored <= 0 && !fits) {
      OPENVDB_THROW(openvdb::IoError, "a chunk stored uncompressed claims "
                                          << (std::uint64_t(0) - std::uint64_t(stored))
                                          << " bytes where " << numBytes << " are expected");
    }
    is.seekg(start);
  }
  own(is, data, numBytes);
}

}  // namespace

namespace openvdb {
OPENVDB_USE_VERSION_NAMESPACE
namespace OPENVDB_VERSION_NAME {
namespace io {

void unzipFromStream(std::istream& is, char* data, std::size_t numBytes) {
  static const ChunkReader own = openVdbsOwn("unzipFromStream");
  readCheckedChunk(own, is, data, numBytes);
}

void bloscFromStream(std::istream& is, char* data, std::size_t numBytes) {
  static const ChunkReader own = openVdbsOwn("bloscFromStream");
  readCheckedChunk(own, is, data, numBytes);
}

}  // namespace io
}  // namespace OPENVDB_VERSION_NAME
}  // namespace openvdb

namespace spacewarp::detail {

bool openVdbChunksChecked() {
  void* bound = dlsym(RTLD_DEFAULT, mangledName("unzipFromStream").c_str());
  return bound == reinterpret_cast<void*>(&openvdb::io::unzipFromStream);
}

}  // namespace spacewarp::detail
