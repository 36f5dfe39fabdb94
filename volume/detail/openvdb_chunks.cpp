#include <spacewarp/volume/detail/openvdb_chunks.h>

#include <dlfcn.h>
#include <elf.h>
#include <link.h>

#include <cstdint>
#include <cstring>
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
namespace {

/// What libopenvdb's own calls of `symbol` are bound to: the pointer in its global offset table
/// (libopenvdb is linked with BIND_NOW, so the slots are filled when it is loaded). Null when no
/// library named libopenvdb is loaded or it has no relocation for `symbol`.
struct GotLookup {
  const char* symbol;
  void* bound = nullptr;
  bool found = false;
};

int findGotSlot(dl_phdr_info* info, std::size_t, void* data) {
  auto& lookup = *static_cast<GotLookup*>(data);
  if (info->dlpi_name == nullptr || std::strstr(info->dlpi_name, "libopenvdb") == nullptr) return 0;
  const ElfW(Dyn)* dynamic = nullptr;
  for (int h = 0; h < info->dlpi_phnum; ++h)
    if (info->dlpi_phdr[h].p_type == PT_DYNAMIC)
      dynamic = reinterpret_cast<const ElfW(Dyn)*>(info->dlpi_addr + info->dlpi_phdr[h].p_vaddr);
  if (dynamic == nullptr) return 0;
  // glibc relocates these pointers in place on most targets; add the base where it did not.
  const auto address = [&](ElfW(Addr) p) { return p < info->dlpi_addr ? p + info->dlpi_addr : p; };
  const char* strings = nullptr;
  const ElfW(Sym)* symbols = nullptr;
  const ElfW(Rela) * tables[2] = {nullptr, nullptr};
  std::size_t sizes[2] = {0, 0};
  for (const ElfW(Dyn)* d = dynamic; d->d_tag != DT_NULL; ++d) {
    switch (d->d_tag) {
      case DT_STRTAB:
        strings = reinterpret_cast<const char*>(address(d->d_un.d_ptr));
        break;
      case DT_SYMTAB:
        symbols = reinterpret_cast<const ElfW(Sym)*>(address(d->d_un.d_ptr));
        break;
      case DT_JMPREL:
        tables[0] = reinterpret_cast<const ElfW(Rela)*>(address(d->d_un.d_ptr));
        break;
      case DT_PLTRELSZ:
        sizes[0] = d->d_un.d_val;
        break;
      case DT_RELA:
        tables[1] = reinterpret_cast<const ElfW(Rela)*>(address(d->d_un.d_ptr));
        break;
      case DT_RELASZ:
        sizes[1] = d->d_un.d_val;
        break;
      default:
        break;
    }
  }
  if (strings == nullptr || symbols == nullptr) return 0;
  for (int t = 0; t < 2; ++t) {
    for (std::size_t r = 0; tables[t] != nullptr && r < sizes[t] / sizeof(ElfW(Rela)); ++r) {
      const ElfW(Rela)& rela = tables[t][r];
#if __ELF_NATIVE_CLASS == 64
      const std::size_t index = ELF64_R_SYM(rela.r_info);
#else
      const std::size_t index = ELF32_R_SYM(rela.r_info);
#endif
      if (index == 0 || std::strcmp(strings + symbols[index].st_name, lookup.symbol) != 0) continue;
      lookup.bound = *reinterpret_cast<void**>(info->dlpi_addr + rela.r_offset);
      lookup.found = true;
      return 1;
    }
  }
  return 1;  // libopenvdb calls it directly (no relocation): it cannot be replaced
}

}  // namespace

bool openVdbChunksChecked() {
  const std::string name = mangledName("unzipFromStream");
  GotLookup lookup{name.c_str()};
  if (dl_iterate_phdr(findGotSlot, &lookup) == 0) {
    // No shared libopenvdb (a static build): this program's definition is the one.
    void* bound = dlsym(RTLD_DEFAULT, name.c_str());
    return bound == nullptr || bound == reinterpret_cast<void*>(&openvdb::io::unzipFromStream);
  }
  return lookup.found && lookup.bound == reinterpret_cast<void*>(&openvdb::io::unzipFromStream);
}

}  // namespace spacewarp::detail
